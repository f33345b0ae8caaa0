//! An RTU server whose registers map onto a dictionary's objects (`modbus::object_registers`),
//! on the test bench's dictionary and a table of three registers.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use modbus::object_registers::{ErrorStyle, Ignored, ObjectRegisters, RegisterMapping};
use modbus::rtu::{crc_bytes, MAX_FRAME};
use od::{ObjectAccess, ObjectDictionary};

const MAP: [RegisterMapping; 3] = [
    RegisterMapping {
        register: 0x0010,
        index: 0x1017,
        sub: 0,
    },
    RegisterMapping {
        register: 0x0020,
        index: 0x1000,
        sub: 0,
    },
    RegisterMapping {
        register: 0x0030,
        index: 0x2003,
        sub: 0,
    },
];

fn bench() -> ObjectDictionary<Vec<u8>> {
    let d = &devices::TESTBENCH;
    ObjectDictionary::new(d, 1, vec![0; d.storage_size]).unwrap()
}

fn frame(station: u8, pdu: &[u8]) -> Vec<u8> {
    let mut f = vec![station];
    f.extend_from_slice(pdu);
    let crc = crc_bytes(&f);
    f.extend_from_slice(&crc);
    f
}

fn exchange(
    od: &mut ObjectDictionary<Vec<u8>>,
    errors: ErrorStyle,
    request: &[u8],
) -> Result<Vec<u8>, Ignored> {
    let server = ObjectRegisters {
        station: 1,
        map: &MAP,
        errors,
    };
    let mut out = [0u8; MAX_FRAME];
    let n = server.handle_frame(request, od, &mut out)?;
    Ok(out[..n].to_vec())
}

#[test]
fn a_register_reads_and_writes_its_object() {
    let mut od = bench();
    let write = frame(1, &[0x06, 0x00, 0x10, 0x03, 0xE8]);
    assert_eq!(
        exchange(&mut od, ErrorStyle::Standard, &write),
        Ok(write.clone())
    );
    assert_eq!(od.read_u16(0x1017, 0), Some(1000));
    let read = frame(1, &[0x03, 0x00, 0x10, 0x00, 0x01]);
    assert_eq!(
        exchange(&mut od, ErrorStyle::Standard, &read),
        Ok(frame(1, &[0x03, 0x02, 0x03, 0xE8]))
    );
}

/// A 32-bit object is two registers, the low word first, each word big-endian.
#[test]
fn a_32_bit_object_is_two_registers_low_word_first() {
    let mut od = bench();
    let v = od.read_u32(0x1000, 0).unwrap();
    let [b0, b1, b2, b3] = v.to_le_bytes();
    let read = frame(1, &[0x03, 0x00, 0x20, 0x00, 0x02]);
    assert_eq!(
        exchange(&mut od, ErrorStyle::Standard, &read),
        Ok(frame(1, &[0x03, 0x04, b1, b0, b3, b2]))
    );
}

/// An FC 03h error: 83h as the standard has it, or 81h; the exception byte either way.
#[test]
fn a_read_error_answers_in_the_chosen_style() {
    let mut od = bench();
    let read = frame(1, &[0x03, 0x00, 0x99, 0x00, 0x01]);
    assert_eq!(
        exchange(&mut od, ErrorStyle::Standard, &read),
        Ok(frame(1, &[0x83, 0x02]))
    );
    assert_eq!(
        exchange(&mut od, ErrorStyle::Read81h, &read),
        Ok(frame(1, &[0x81, 0x02]))
    );
}

/// Station 0 is carried out and not answered; another station's frame and a bad CRC are not
/// answered (Modbus over Serial Line §2.2).
#[test]
fn broadcasts_other_stations_and_bad_crcs_get_no_answer() {
    let mut od = bench();
    let broadcast = frame(0, &[0x06, 0x00, 0x10, 0x00, 0x64]);
    assert_eq!(
        exchange(&mut od, ErrorStyle::Standard, &broadcast),
        Err(Ignored::Broadcast)
    );
    assert_eq!(od.read_u16(0x1017, 0), Some(100));
    let other = frame(2, &[0x03, 0x00, 0x10, 0x00, 0x01]);
    assert_eq!(
        exchange(&mut od, ErrorStyle::Standard, &other),
        Err(Ignored::OtherStation)
    );
    let mut bad = frame(1, &[0x03, 0x00, 0x10, 0x00, 0x01]);
    *bad.last_mut().unwrap() ^= 0xFF;
    assert_eq!(
        exchange(&mut od, ErrorStyle::Standard, &bad),
        Err(Ignored::Crc)
    );
}
