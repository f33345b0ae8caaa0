//! Kinco Modbus RTU (Kinco CD3 / FD3 manual §12.3) on the FD3's dictionary and its register map
//! (devices/kinco-fd3.toml `modbus` keys).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drive::vendors::kinco::rtu::{ErrorStyle, Ignored, KincoRtu, RegisterMapping, MAX_FRAME};
use modbus::rtu;
use od::{ObjectAccess, ObjectDictionary, Value};

fn fd3() -> ObjectDictionary<Vec<u8>> {
    let d = &devices::KINCO_FD3;
    ObjectDictionary::new(d, 1, vec![0; d.storage_size]).unwrap()
}

fn map() -> Vec<RegisterMapping> {
    devices::addresses("kinco-fd3")
        .unwrap()
        .modbus
        .iter()
        .map(|r| RegisterMapping {
            register: r.register,
            index: r.index,
            sub: r.sub,
        })
        .collect()
}

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}

fn with_crc(mut f: Vec<u8>) -> Vec<u8> {
    let crc = rtu::crc_bytes(&f);
    f.extend_from_slice(&crc);
    f
}

fn exchange(
    od: &mut ObjectDictionary<Vec<u8>>,
    errors: ErrorStyle,
    frame: &[u8],
) -> Result<Vec<u8>, Ignored> {
    let map = map();
    let server = KincoRtu {
        station: 1,
        map: &map,
        errors,
    };
    let mut out = [0u8; MAX_FRAME];
    server
        .handle_frame(frame, od, &mut out)
        .map(|n| out[..n].to_vec())
}

/// KINCO-MB-01: `01 03 32 00 00 02 CA B3` reads two registers from 3200h (the statusword):
/// `01 03 04 r0 r1 r2 r3` + CRC; the register after the 16-bit statusword reads 0.
#[test]
fn kinco_mb_01_read_statusword() {
    let mut od = fd3();
    od.write_internal(0x6041, 0, &0x0637u16.to_le_bytes())
        .unwrap();
    let frame = hex("01 03 32 00 00 02 CA B3");
    assert!(rtu::check_frame(&frame), "the printed CRC");
    let reply = exchange(&mut od, ErrorStyle::Read81h, &frame).unwrap();
    assert_eq!(reply, with_crc(hex("01 03 04 06 37 00 00")));
}

/// KINCO-MB-02: `01 06 31 00 00 0F C7 32` writes 000Fh to 3100h (the controlword); the
/// reply is the identical echo.
#[test]
fn kinco_mb_02_write_controlword_echo() {
    let mut od = fd3();
    let frame = hex("01 06 31 00 00 0F C7 32");
    assert!(rtu::check_frame(&frame));
    assert_eq!(
        exchange(&mut od, ErrorStyle::Read81h, &frame).unwrap(),
        frame
    );
    assert_eq!(od.get_unsigned(0x6040, 0), Some(0x0F));
}

/// KINCO-MB-03: `01 10 6F 00 00 02 04 55 55 00 08 1A 47` writes 0008 5555h to 6F00h (target
/// velocity 60FFh), low word first; the CRC on the wire is `1A 47` (the message line's
/// "47 1A" is the misprint). Reply `01 10 6F 00 00 02 5C DC`.
#[test]
fn kinco_mb_03_write_target_velocity_low_word_first() {
    let mut od = fd3();
    let frame = hex("01 10 6F 00 00 02 04 55 55 00 08 1A 47");
    assert!(rtu::check_frame(&frame), "1A 47, low byte first");
    assert!(!rtu::check_frame(&hex(
        "01 10 6F 00 00 02 04 55 55 00 08 47 1A"
    )));
    let reply = exchange(&mut od, ErrorStyle::Read81h, &frame).unwrap();
    assert_eq!(reply, hex("01 10 6F 00 00 02 5C DC"));
    assert_eq!(od.value(0x60FF, 0), Some(Value::Signed(0x0008_5555)));
    // And read back the same way: two registers, low word first.
    let read = with_crc(hex("01 03 6F 00 00 02"));
    let reply = exchange(&mut od, ErrorStyle::Read81h, &read).unwrap();
    assert_eq!(reply, with_crc(hex("01 03 04 55 55 00 08")));
}

/// KINCO-MB-04: errors answer 81h to FC 03h (as printed; 83h in the standard style), 86h to
/// FC 06h and 90h to FC 10h, followed by the standard exception byte (the decision).
#[test]
fn kinco_mb_04_error_function_codes() {
    let mut od = fd3();
    let read_missing = with_crc(hex("01 03 12 34 00 01"));
    let r = exchange(&mut od, ErrorStyle::Read81h, &read_missing).unwrap();
    assert_eq!(r, with_crc(hex("01 81 02")));
    let r = exchange(&mut od, ErrorStyle::Standard, &read_missing).unwrap();
    assert_eq!(r, with_crc(hex("01 83 02")));
    // FC 06h to the read-only statusword, and to a register that maps nothing.
    let r = exchange(
        &mut od,
        ErrorStyle::Read81h,
        &with_crc(hex("01 06 32 00 00 01")),
    )
    .unwrap();
    assert_eq!(r, with_crc(hex("01 86 02")));
    let r = exchange(
        &mut od,
        ErrorStyle::Read81h,
        &with_crc(hex("01 06 12 34 00 01")),
    )
    .unwrap();
    assert_eq!(r, with_crc(hex("01 86 02")));
    // FC 10h to a non-existent address; half of the 32-bit target velocity.
    let r = exchange(
        &mut od,
        ErrorStyle::Read81h,
        &with_crc(hex("01 10 12 34 00 01 02 00 01")),
    )
    .unwrap();
    assert_eq!(r, with_crc(hex("01 90 02")));
    let r = exchange(
        &mut od,
        ErrorStyle::Read81h,
        &with_crc(hex("01 10 6F 00 00 01 02 00 01")),
    )
    .unwrap();
    assert_eq!(r, with_crc(hex("01 90 02")));
    // A value out of range: 03.
    let r = exchange(
        &mut od,
        ErrorStyle::Read81h,
        &with_crc(hex("01 06 47 00 00 02")),
    )
    .unwrap();
    assert_eq!(
        r,
        with_crc(hex("01 86 03")),
        "Invert_Dir 607Eh takes 0 or 1"
    );
    // FC 06h on a 32-bit object is refused (half a value).
    let r = exchange(
        &mut od,
        ErrorStyle::Read81h,
        &with_crc(hex("01 06 6F 00 00 01")),
    )
    .unwrap();
    assert_eq!(r, with_crc(hex("01 86 02")));
}

/// A bad CRC or another station: no reply. A broadcast is carried out, not answered.
#[test]
fn bad_crc_other_station_and_broadcast() {
    let mut od = fd3();
    assert_eq!(
        exchange(
            &mut od,
            ErrorStyle::Read81h,
            &hex("01 06 31 00 00 0F C7 33")
        ),
        Err(Ignored::Crc)
    );
    assert_eq!(
        exchange(
            &mut od,
            ErrorStyle::Read81h,
            &with_crc(hex("02 06 31 00 00 0F"))
        ),
        Err(Ignored::OtherStation)
    );
    assert_eq!(od.get_unsigned(0x6040, 0), Some(0));
    assert_eq!(
        exchange(
            &mut od,
            ErrorStyle::Read81h,
            &with_crc(hex("00 06 31 00 00 06"))
        ),
        Err(Ignored::Broadcast)
    );
    assert_eq!(od.get_unsigned(0x6040, 0), Some(6));
    assert_eq!(
        exchange(&mut od, ErrorStyle::Read81h, &[0x01]),
        Err(Ignored::Crc)
    );
}

/// The 8-bit Operation_Mode 6060h (3500h) through FC 06h: −4 may come as FFFCh.
#[test]
fn eight_bit_objects_through_one_register() {
    let mut od = fd3();
    let f = with_crc(hex("01 06 35 00 FF FC"));
    assert_eq!(exchange(&mut od, ErrorStyle::Read81h, &f).unwrap(), f);
    assert_eq!(od.value(0x6060, 0), Some(Value::Signed(-4)));
    let r = exchange(
        &mut od,
        ErrorStyle::Read81h,
        &with_crc(hex("01 03 35 00 00 01")),
    )
    .unwrap();
    assert_eq!(r, with_crc(hex("01 03 02 FF FC")));
    // Two registers from a negative 16-bit value read as its 32-bit value.
    od.write(0x6071, 0, &(-100i16).to_le_bytes()).unwrap();
    let r = exchange(
        &mut od,
        ErrorStyle::Read81h,
        &with_crc(hex("01 03 3C 00 00 02")),
    )
    .unwrap();
    assert_eq!(r, with_crc(hex("01 03 04 FF 9C FF FF")));
    let r = exchange(
        &mut od,
        ErrorStyle::Read81h,
        &with_crc(hex("01 06 35 00 01 00")),
    )
    .unwrap();
    assert_eq!(r, with_crc(hex("01 86 03")));
}

/// FC 10h over several objects: Profile_Speed 4A00h, Profile_Acc 4B00h… are each two
/// registers, written in one request when they lie back to back (here: one object).
#[test]
fn write_multiple_covers_whole_objects() {
    let mut od = fd3();
    let f = with_crc(hex("01 10 40 00 00 02 04 86 A0 00 01"));
    let r = exchange(&mut od, ErrorStyle::Read81h, &f).unwrap();
    assert_eq!(r, with_crc(hex("01 10 40 00 00 02")));
    assert_eq!(od.value(0x607A, 0), Some(Value::Signed(100_000)));
    // Byte count that does not match the quantity.
    let r = exchange(
        &mut od,
        ErrorStyle::Read81h,
        &with_crc(hex("01 10 40 00 00 02 02 00 01")),
    )
    .unwrap();
    assert_eq!(r, with_crc(hex("01 90 03")));
}
