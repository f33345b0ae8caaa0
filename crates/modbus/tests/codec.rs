//! The codec against the MODBUS Application Protocol V1.1b3 rules: every function code,
//! every exception, the MBAP checks, device identification access modes, stream framing,
//! the RTU CRC and the client encoders.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod common;

use common::{exchange, hex, Cmmo};
use modbus::client::{self, Response};
use modbus::framing::{adu_len, FRAMER_CAPACITY};
use modbus::{
    handle_adu, handle_pdu, rtu, AduError, ConformityLevel, Exception, FrameError, Framer,
    PduError, ReadDeviceIdCode, RegisterMap, MAX_ADU_LEN, MAX_PDU_LEN,
};
use proptest::prelude::*;

/// 1000 plain registers at 0…999; anything else is 02.
struct Plain {
    regs: Vec<u16>,
    fail: bool,
    objects: Vec<(u8, Vec<u8>)>,
}

impl Plain {
    fn new() -> Plain {
        Plain {
            regs: (0..1000).collect(),
            fail: false,
            objects: vec![
                (0, b"Vendor".to_vec()),
                (1, b"Code".to_vec()),
                (2, b"1.0".to_vec()),
            ],
        }
    }

    fn range(&self, address: u16, n: usize) -> Result<std::ops::Range<usize>, Exception> {
        if self.fail {
            return Err(Exception::ServerDeviceFailure);
        }
        let start = usize::from(address);
        if start + n > self.regs.len() {
            return Err(Exception::IllegalDataAddress);
        }
        Ok(start..start + n)
    }
}

impl RegisterMap for Plain {
    fn read(&mut self, address: u16, out: &mut [u16]) -> Result<(), Exception> {
        let r = self.range(address, out.len())?;
        out.copy_from_slice(&self.regs[r]);
        Ok(())
    }

    fn write(&mut self, address: u16, values: &[u16]) -> Result<(), Exception> {
        let r = self.range(address, values.len())?;
        self.regs[r].copy_from_slice(values);
        Ok(())
    }

    fn device_id(&self, object: u8) -> Option<&[u8]> {
        self.objects
            .iter()
            .find(|(id, _)| *id == object)
            .map(|(_, v)| v.as_slice())
    }
}

/// Wraps a PDU into an ADU with transaction id 0x1234, unit 0x11.
fn adu(pdu: &[u8]) -> Vec<u8> {
    let mut v = vec![0x12, 0x34, 0, 0];
    v.extend_from_slice(&((pdu.len() + 1) as u16).to_be_bytes());
    v.push(0x11);
    v.extend_from_slice(pdu);
    v
}

/// The response PDU to a request PDU, checking the MBAP echo on the way.
fn pdu(map: &mut impl RegisterMap, request: &[u8]) -> Vec<u8> {
    let resp = exchange(map, &adu(request)).expect("valid ADU");
    assert_eq!(
        resp[..4],
        [0x12, 0x34, 0, 0],
        "transaction id echoed, protocol 0"
    );
    assert_eq!(
        usize::from(u16::from_be_bytes([resp[4], resp[5]])),
        resp.len() - 6
    );
    assert_eq!(resp[6], 0x11, "unit id echoed");
    resp[7..].to_vec()
}

fn plain_pdu(request: &str) -> Vec<u8> {
    pdu(&mut Plain::new(), &hex(request))
}

// ---- 0x03 -------------------------------------------------------------------------------

#[test]
fn fc03_reads_registers_big_endian() {
    assert_eq!(plain_pdu("03 01 00 00 02"), hex("03 04 01 00 01 01"));
}

#[test]
fn fc03_quantity_limits() {
    assert_eq!(plain_pdu("03 00 00 00 00"), hex("83 03"));
    assert_eq!(plain_pdu("03 00 00 00 7E"), hex("83 03"));
    let max = plain_pdu("03 00 00 00 7D");
    assert_eq!(max.len(), 2 + 250);
    assert_eq!(max[..2], [0x03, 0xFA]);
    // 125 registers: the longest response ADU, 259 bytes
    let resp = exchange(&mut Plain::new(), &adu(&hex("03 00 00 00 7D"))).expect("valid");
    assert_eq!(resp.len(), 259);
}

#[test]
fn fc03_address_space_and_map_range() {
    // address + quantity past FFFFh: 02 from the codec
    assert_eq!(plain_pdu("03 FF FF 00 02"), hex("83 02"));
    // FF83h + 7Dh = 10000h is inside the address space; the map has no such register: 02
    assert_eq!(plain_pdu("03 FF 83 00 7D"), hex("83 02"));
    assert_eq!(plain_pdu("03 03 E7 00 02"), hex("83 02"));
    assert_eq!(plain_pdu("03 03 E7 00 01"), hex("03 02 03 E7"));
}

#[test]
fn fc03_wrong_pdu_length_is_illegal_value() {
    assert_eq!(plain_pdu("03"), hex("83 03"));
    assert_eq!(plain_pdu("03 00 00 00"), hex("83 03"));
    assert_eq!(plain_pdu("03 00 00 00 01 00"), hex("83 03"));
}

#[test]
fn server_device_failure_from_the_map() {
    let mut map = Plain::new();
    map.fail = true;
    assert_eq!(pdu(&mut map, &hex("03 00 00 00 01")), hex("83 04"));
    assert_eq!(pdu(&mut map, &hex("10 00 00 00 01 02 00 00")), hex("90 04"));
    assert_eq!(
        pdu(&mut map, &hex("17 00 00 00 01 00 00 00 01 02 00 00")),
        hex("97 04")
    );
}

// ---- 0x07 -------------------------------------------------------------------------------

#[test]
fn fc07_default_map_does_not_support_it() {
    assert_eq!(plain_pdu("07"), hex("87 01"));
}

#[test]
fn fc07_with_data_is_illegal_value() {
    assert_eq!(pdu(&mut Cmmo::new(false), &hex("07 00")), hex("87 03"));
    assert_eq!(pdu(&mut Cmmo::new(false), &hex("07")), hex("07 00"));
}

// ---- 0x10 -------------------------------------------------------------------------------

#[test]
fn fc10_writes_and_echoes() {
    let mut map = Plain::new();
    assert_eq!(
        pdu(&mut map, &hex("10 00 0A 00 02 04 AB CD 00 01")),
        hex("10 00 0A 00 02")
    );
    assert_eq!(map.regs[10..12], [0xABCD, 0x0001]);
}

#[test]
fn fc10_quantity_and_byte_count() {
    assert_eq!(plain_pdu("10 00 00 00 00 00"), hex("90 03"));
    // 124 registers cannot even fit into an ADU; the quantity alone decides
    assert_eq!(plain_pdu("10 00 00 00 7C F8 00 00"), hex("90 03"));
    assert_eq!(plain_pdu("10 00 00 FF FF FE 00 00"), hex("90 03"));
    let mut max = hex("10 00 00 00 7B F6");
    max.extend_from_slice(&[0; 246]);
    assert_eq!(plain_pdu_bytes(&max), hex("10 00 00 00 7B"));
    // byte count ≠ 2 × quantity
    assert_eq!(plain_pdu("10 00 00 00 02 03 00 00 00"), hex("90 03"));
    // data shorter or longer than the byte count
    assert_eq!(plain_pdu("10 00 00 00 02 04 00 00 00"), hex("90 03"));
    assert_eq!(plain_pdu("10 00 00 00 02 04 00 00 00 00 00"), hex("90 03"));
    // header cut short
    assert_eq!(plain_pdu("10 00 00 00"), hex("90 03"));
}

fn plain_pdu_bytes(request: &[u8]) -> Vec<u8> {
    pdu(&mut Plain::new(), request)
}

#[test]
fn fc10_address_checks() {
    assert_eq!(plain_pdu("10 FF FF 00 02 04 00 00 00 00"), hex("90 02"));
    let mut map = Plain::new();
    assert_eq!(
        pdu(&mut map, &hex("10 03 E7 00 02 04 00 00 00 00")),
        hex("90 02")
    );
    assert_eq!(map.regs[999], 999, "nothing written");
}

// ---- 0x17 -------------------------------------------------------------------------------

#[test]
fn fc17_writes_before_it_reads() {
    let mut map = Plain::new();
    let resp = pdu(&mut map, &hex("17 00 04 00 03 00 05 00 02 04 BE EF CA FE"));
    // registers 4, 5, 6 read after 5 and 6 were written
    assert_eq!(resp, hex("17 06 00 04 BE EF CA FE"));
}

#[test]
fn fc17_quantity_limits() {
    // read quantity 0 and 126
    assert_eq!(
        plain_pdu("17 00 00 00 00 00 00 00 01 02 00 00"),
        hex("97 03")
    );
    assert_eq!(
        plain_pdu("17 00 00 00 7E 00 00 00 01 02 00 00"),
        hex("97 03")
    );
    // write quantity 0 and 122
    assert_eq!(plain_pdu("17 00 00 00 01 00 00 00 00 00"), hex("97 03"));
    assert_eq!(
        plain_pdu("17 00 00 00 01 00 00 00 7A F4 00 00"),
        hex("97 03")
    );
    let mut w121 = hex("17 00 00 00 7D 00 00 00 79 F2");
    w121.extend_from_slice(&[0; 242]);
    let resp = plain_pdu_bytes(&w121);
    assert_eq!(resp[..2], [0x17, 0xFA]);
    // byte count mismatch, short data, extra data, cut header
    assert_eq!(
        plain_pdu("17 00 00 00 01 00 00 00 01 04 00 00"),
        hex("97 03")
    );
    assert_eq!(
        plain_pdu("17 00 00 00 01 00 00 00 02 04 00 00"),
        hex("97 03")
    );
    assert_eq!(
        plain_pdu("17 00 00 00 01 00 00 00 01 02 00 00 00"),
        hex("97 03")
    );
    assert_eq!(plain_pdu("17 00 00 00 01 00 00"), hex("97 03"));
}

#[test]
fn fc17_address_checks() {
    assert_eq!(
        plain_pdu("17 FF FF 00 02 00 00 00 01 02 00 00"),
        hex("97 02")
    );
    assert_eq!(
        plain_pdu("17 00 00 00 01 FF FF 00 02 04 00 00 00 00"),
        hex("97 02")
    );
    assert_eq!(
        plain_pdu("17 03 E8 00 01 00 00 00 01 02 00 00"),
        hex("97 02")
    );
}

#[test]
fn cmmo_fc17_wrong_range_writes_nothing() {
    let mut map = Cmmo::new(false);
    let resp = pdu(
        &mut map,
        &hex("17 00 01 00 04 00 00 00 04 08 03 01 01 00 00 00 00 00"),
    );
    assert_eq!(resp, hex("97 02"));
    assert_eq!(map.writes, 0);
}

// ---- unknown function codes ---------------------------------------------------------------

#[test]
fn unsupported_function_codes_are_illegal_function() {
    for fc in [
        0x00u8, 0x01, 0x02, 0x04, 0x05, 0x06, 0x08, 0x0F, 0x11, 0x16, 0x18, 0x2C, 0x41, 0x7F,
    ] {
        assert_eq!(
            plain_pdu_bytes(&[fc, 0, 0, 0, 1]),
            vec![fc | 0x80, 0x01],
            "FC {fc:02X}"
        );
    }
    // a function code with bit 7 set (an exception code) in a request
    assert_eq!(plain_pdu("83 00 00 00 01"), hex("83 01"));
    assert_eq!(plain_pdu("FF"), hex("FF 01"));
}

// ---- 0x2B / 0x0E --------------------------------------------------------------------------

#[test]
fn fc2b_request_checks() {
    // MEI 0x0D (CANopen general reference) is not implemented
    assert_eq!(plain_pdu("2B 0D 00 00"), hex("AB 01"));
    assert_eq!(plain_pdu("2B"), hex("AB 03"));
    assert_eq!(plain_pdu("2B 0E 01"), hex("AB 03"));
    assert_eq!(plain_pdu("2B 0E 01 00 00"), hex("AB 03"));
    assert_eq!(plain_pdu("2B 0E 00 00"), hex("AB 03"));
    assert_eq!(plain_pdu("2B 0E 05 00"), hex("AB 03"));
}

#[test]
fn fc2b_default_conformity_and_individual_access() {
    // only basic objects: 81h (basic, stream + individual)
    let resp = plain_pdu("2B 0E 04 01");
    assert_eq!(resp, hex("2B 0E 04 81 00 00 01 01 04 43 6F 64 65"));
    assert_eq!(plain_pdu("2B 0E 04 05"), hex("AB 02"));
    // a regular request above the basic level is answered at the basic level
    let resp = plain_pdu("2B 0E 02 00");
    assert_eq!(resp[..7], hex("2B 0E 02 81 00 00 03")[..]);
}

#[test]
fn fc2b_stream_from_an_object_and_restart() {
    let mut map = Cmmo::new(false);
    // basic from object 1: objects 1 and 2
    let resp = pdu(&mut map, &hex("2B 0E 01 01"));
    assert_eq!(resp[..7], hex("2B 0E 01 01 00 00 02")[..]);
    assert_eq!(resp[7], 0x01);
    // regular from 4: 4 and 6
    let resp = pdu(&mut map, &hex("2B 0E 02 04"));
    assert_eq!(resp[..8], hex("2B 0E 02 02 00 00 02 04")[..]);
    // an object that does not exist (05) or is outside the category (basic from 04):
    // restart at object 0
    let resp = pdu(&mut map, &hex("2B 0E 02 05"));
    assert_eq!(resp[..8], hex("2B 0E 02 02 00 00 06 00")[..]);
    let resp = pdu(&mut map, &hex("2B 0E 01 04"));
    assert_eq!(resp[..8], hex("2B 0E 01 01 00 00 03 00")[..]);
    // extended asked of a regular device: regular objects, level 02
    let resp = pdu(&mut map, &hex("2B 0E 03 00"));
    assert_eq!(resp[..7], hex("2B 0E 03 02 00 00 06")[..]);
    // the CMMO-ST offers codes 01 and 02 only: no individual access
    assert_eq!(pdu(&mut map, &hex("2B 0E 04 00")), hex("AB 03"));
}

#[test]
fn fc2b_more_follows_over_several_transactions() {
    let mut map = Plain::new();
    for id in 0x80..=0x83u8 {
        map.objects.push((id, vec![id; 100]));
    }
    let resp = pdu(&mut map, &hex("2B 0E 03 00"));
    let Response::ReadDeviceIdentification(first) = Response::parse(&resp).expect("parses") else {
        panic!("not a device identification response")
    };
    assert_eq!(first.conformity_level, 0x83);
    assert!(first.more_follows);
    let ids: Vec<u8> = first.objects.map(|(id, _)| id).collect();
    assert_eq!(ids, [0, 1, 2, 0x80, 0x81]);
    assert_eq!(first.next_object_id, 0x82);
    assert!(resp.len() <= MAX_PDU_LEN);

    let resp = pdu(&mut map, &[0x2B, 0x0E, 0x03, first.next_object_id]);
    let Response::ReadDeviceIdentification(second) = Response::parse(&resp).expect("parses") else {
        panic!("not a device identification response")
    };
    assert!(!second.more_follows);
    assert_eq!(second.next_object_id, 0);
    let objects: Vec<(u8, Vec<u8>)> = second.objects.map(|(id, v)| (id, v.to_vec())).collect();
    assert_eq!(objects, [(0x82, vec![0x82; 100]), (0x83, vec![0x83; 100])]);

    // individual access to an extended object
    let resp = pdu(&mut map, &hex("2B 0E 04 83"));
    assert_eq!(resp[..9], hex("2B 0E 04 83 00 00 01 83 64")[..]);
    assert_eq!(resp.len(), 9 + 100);
}

#[test]
fn fc2b_overlong_object_is_cut_to_fit() {
    let mut map = Plain::new();
    map.objects = vec![(0, vec![b'x'; 300])];
    let resp = pdu(&mut map, &hex("2B 0E 01 00"));
    assert_eq!(resp.len(), MAX_PDU_LEN);
    assert_eq!(resp[7..9], [0x00, 244]);
}

#[test]
fn fc2b_without_objects() {
    struct Bare;
    impl RegisterMap for Bare {
        fn read(&mut self, _: u16, _: &mut [u16]) -> Result<(), Exception> {
            Err(Exception::IllegalDataAddress)
        }
        fn write(&mut self, _: u16, _: &[u16]) -> Result<(), Exception> {
            Err(Exception::IllegalDataAddress)
        }
    }
    assert_eq!(
        pdu(&mut Bare, &hex("2B 0E 01 00")),
        hex("2B 0E 01 81 00 00 00")
    );
    assert_eq!(pdu(&mut Bare, &hex("2B 0E 04 00")), hex("AB 02"));
    assert_eq!(ConformityLevel::from_objects(&Bare), ConformityLevel::BASIC);
}

// ---- MBAP ---------------------------------------------------------------------------------

#[test]
fn mbap_checks() {
    let mut map = Plain::new();
    let mut out = [0u8; MAX_ADU_LEN];
    let ok = hex("00 01 00 00 00 06 00 03 00 00 00 01");
    assert!(handle_adu(&ok, &mut map, &mut out).is_ok());

    let mut bad_protocol = ok.clone();
    bad_protocol[3] = 1;
    assert_eq!(
        handle_adu(&bad_protocol, &mut map, &mut out),
        Err(AduError::ProtocolId(1))
    );

    let mut long_field = ok.clone();
    long_field[5] = 7;
    assert_eq!(
        handle_adu(&long_field, &mut map, &mut out),
        Err(AduError::LengthMismatch {
            declared: 7,
            actual: 6
        })
    );
    let mut short_field = ok.clone();
    short_field[5] = 5;
    assert_eq!(
        handle_adu(&short_field, &mut map, &mut out),
        Err(AduError::LengthMismatch {
            declared: 5,
            actual: 6
        })
    );
    assert_eq!(
        handle_adu(&ok[..7], &mut map, &mut out),
        Err(AduError::TooShort { len: 7 })
    );
    assert_eq!(
        handle_adu(&[], &mut map, &mut out),
        Err(AduError::TooShort { len: 0 })
    );
    let huge = vec![0u8; 261];
    assert_eq!(
        handle_adu(&huge, &mut map, &mut out),
        Err(AduError::TooLong { len: 261 })
    );
    let mut small = [0u8; 20];
    assert_eq!(
        handle_adu(&ok, &mut map, &mut small),
        Err(AduError::ResponseBufferTooSmall)
    );
}

#[test]
fn mbap_echoes_transaction_and_unit() {
    let resp = exchange(
        &mut Plain::new(),
        &hex("BE EF 00 00 00 06 FF 03 00 02 00 01"),
    )
    .expect("valid");
    assert_eq!(resp, hex("BE EF 00 00 00 05 FF 03 02 00 02"));
}

#[test]
fn handle_pdu_errors() {
    let mut out = [0u8; MAX_PDU_LEN];
    assert_eq!(
        handle_pdu(&[], &mut Plain::new(), &mut out),
        Err(PduError::Empty)
    );
    let mut small = [0u8; 10];
    assert_eq!(
        handle_pdu(&[0x07], &mut Plain::new(), &mut small),
        Err(PduError::ResponseBufferTooSmall)
    );
    assert_eq!(handle_pdu(&[0x07], &mut Cmmo::new(false), &mut out), Ok(2));
}

// ---- framing ------------------------------------------------------------------------------

fn drain(framer: &mut Framer, out: &mut Vec<Vec<u8>>) -> Result<(), FrameError> {
    while let Some(adu) = framer.next_adu()? {
        out.push(adu.to_vec());
    }
    Ok(())
}

fn frame_all(chunks: &[&[u8]]) -> Result<Vec<Vec<u8>>, FrameError> {
    let mut framer = Framer::new();
    let mut adus = Vec::new();
    for chunk in chunks {
        let mut rest = *chunk;
        while !rest.is_empty() {
            let n = framer.push(rest);
            rest = &rest[n..];
            drain(&mut framer, &mut adus)?;
        }
    }
    Ok(adus)
}

#[test]
fn framing_split_byte_by_byte() {
    let a = hex("00 01 00 00 00 0F 00 10 00 00 00 04 08 03 01 01 00 00 00 00 00");
    let chunks: Vec<&[u8]> = a.chunks(1).collect();
    assert_eq!(frame_all(&chunks).expect("valid"), vec![a.clone()]);
    // split inside the header and inside the body
    assert_eq!(
        frame_all(&[&a[..5], &a[5..9], &a[9..]]).expect("valid"),
        vec![a]
    );
}

#[test]
fn framing_coalesced_adus() {
    let a = hex("00 01 00 00 00 06 00 03 00 00 00 04");
    let b = hex("00 02 00 00 00 02 00 07");
    let c = hex("00 03 00 00 00 05 00 2B 0E 01 00");
    let all: Vec<u8> = [a.clone(), b.clone(), c.clone()].concat();
    assert_eq!(
        frame_all(&[&all]).expect("valid"),
        vec![a.clone(), b.clone(), c.clone()]
    );
    // the third cut in two, the first ending mid-chunk
    assert_eq!(
        frame_all(&[&all[..15], &all[15..25], &all[25..]]).expect("valid"),
        vec![a, b, c]
    );
}

#[test]
fn framing_many_adus_beyond_the_buffer() {
    let one = hex("00 01 00 00 00 06 00 03 00 00 00 04");
    let stream: Vec<u8> = one.iter().copied().cycle().take(one.len() * 500).collect();
    assert!(stream.len() > FRAMER_CAPACITY);
    let adus = frame_all(&[&stream]).expect("valid");
    assert_eq!(adus.len(), 500);
    assert!(adus.iter().all(|a| *a == one));
    // maximal ADUs back to back
    let mut max = hex("00 09 00 00 00 FE 00 10 00 00 00 7B F6");
    max.extend_from_slice(&[0xA5; 247]);
    assert_eq!(max.len(), MAX_ADU_LEN);
    let three = [max.clone(), max.clone(), max.clone()].concat();
    assert_eq!(frame_all(&[&three]).expect("valid").len(), 3);
}

#[test]
fn framing_rejects_impossible_lengths() {
    for length in [0u16, 1, 255, 0x0100, 0xFFFF] {
        let mut h = hex("00 01 00 00");
        h.extend_from_slice(&length.to_be_bytes());
        assert_eq!(adu_len(&h), Err(FrameError::InvalidLength(length)));
        let mut framer = Framer::new();
        framer.push(&h);
        assert_eq!(framer.next_adu(), Err(FrameError::InvalidLength(length)));
        assert_eq!(
            framer.next_adu(),
            Err(FrameError::InvalidLength(length)),
            "sticky"
        );
        framer.clear();
        assert_eq!(framer.next_adu(), Ok(None));
    }
    // HTTP is not Modbus: "GET / HTTP/1.1" has length field "/ " = 2F20h
    assert_eq!(
        frame_all(&[b"GET / HTTP/1.1\r\n\r\n"]),
        Err(FrameError::InvalidLength(0x2F20))
    );
    assert_eq!(adu_len(&hex("00 01 00 00 00")), Ok(None));
    assert_eq!(adu_len(&hex("00 01 00 00 00 02 00")), Ok(None));
    assert_eq!(adu_len(&hex("00 01 00 00 00 02 00 07 99")), Ok(Some(8)));
}

// ---- RTU CRC ------------------------------------------------------------------------------

#[test]
fn rtu_crc_vectors() {
    // CRC-16/MODBUS catalogue check value
    assert_eq!(rtu::crc16(b"123456789"), 0x4B37);
    // Kinco FD3 manual §12.3: KINCO-MB-01, KINCO-MB-02 and KINCO-MB-03
    // (corrected: 1A 47)
    assert_eq!(rtu::crc_bytes(&hex("01 03 32 00 00 02")), [0xCA, 0xB3]);
    assert_eq!(rtu::crc_bytes(&hex("01 06 31 00 00 0F")), [0xC7, 0x32]);
    assert_eq!(
        rtu::crc_bytes(&hex("01 10 6F 00 00 02 04 55 55 00 08")),
        [0x1A, 0x47]
    );
    assert_eq!(rtu::crc16(&hex("01 10 6F 00 00 02 04 55 55 00 08")), 0x471A);
    assert_eq!(rtu::crc_bytes(&hex("01 10 6F 00 00 02")), [0x5C, 0xDC]);
    let frame = hex("01 03 32 00 00 02 CA B3");
    assert!(rtu::check_frame(&frame));
    assert_eq!(rtu::strip_crc(&frame), Some(&frame[..6]));
    assert!(!rtu::check_frame(&hex("01 03 32 00 00 02 B3 CA")));
    assert!(!rtu::check_frame(&hex("01 03 FF")));
    // an RTU request PDU through the same server code
    let mut out = [0u8; MAX_PDU_LEN];
    let n = handle_pdu(&frame[1..6], &mut Plain::new(), &mut out).expect("pdu");
    assert_eq!(out[..n], hex("83 02")[..], "3200h is outside the plain map");
}

// ---- client -------------------------------------------------------------------------------

#[test]
fn client_encoders_match_the_vectors() {
    let mut buf = [0u8; MAX_ADU_LEN];
    let n = client::write_multiple_registers(&mut buf, 1, 0, 0, &[0x0301, 0x0100, 0, 0])
        .expect("encode");
    assert_eq!(
        buf[..n],
        hex("00 01 00 00 00 0F 00 10 00 00 00 04 08 03 01 01 00 00 00 00 00")[..]
    );
    let n = client::read_write_multiple_registers(
        &mut buf,
        3,
        0,
        0,
        4,
        0,
        &[0x4301, 0x0064, 0, 0x2710],
    )
    .expect("encode");
    assert_eq!(
        buf[..n],
        hex("00 03 00 00 00 13 00 17 00 00 00 04 00 00 00 04 08 43 01 00 64 00 00 27 10")[..]
    );
    let n = client::read_holding_registers(&mut buf, 2, 0, 0, 4).expect("encode");
    assert_eq!(buf[..n], hex("00 02 00 00 00 06 00 03 00 00 00 04")[..]);
    let n = client::read_exception_status(&mut buf, 5, 0).expect("encode");
    assert_eq!(buf[..n], hex("00 05 00 00 00 02 00 07")[..]);
    let n = client::read_device_identification(&mut buf, 6, 0, ReadDeviceIdCode::Basic, 0)
        .expect("encode");
    assert_eq!(buf[..n], hex("00 06 00 00 00 05 00 2B 0E 01 00")[..]);

    assert_eq!(
        client::read_holding_registers(&mut buf, 1, 0, 0, 0),
        Err(client::ClientError::InvalidQuantity)
    );
    assert_eq!(
        client::write_multiple_registers(&mut buf, 1, 0, 0, &[0; 124]),
        Err(client::ClientError::InvalidQuantity)
    );
    assert_eq!(
        client::read_holding_registers(&mut buf[..8], 1, 0, 0, 1),
        Err(client::ClientError::BufferTooSmall)
    );
}

#[test]
fn client_parses_responses() {
    match Response::parse(&hex("03 04 13 05 00 01")).expect("parse") {
        Response::ReadHoldingRegisters(r) => assert_eq!(r.iter().collect::<Vec<_>>(), [0x1305, 1]),
        other => panic!("{other:?}"),
    }
    assert_eq!(
        Response::parse(&hex("10 00 00 00 04")).expect("parse"),
        Response::WriteMultipleRegisters {
            address: 0,
            quantity: 4
        }
    );
    assert_eq!(
        Response::parse(&hex("07 2F")).expect("parse"),
        Response::ReadExceptionStatus(0x2F)
    );
    assert_eq!(
        Response::parse(&hex("97 02")).expect("parse"),
        Response::Exception(modbus::ExceptionResponse::new(
            0x17,
            Exception::IllegalDataAddress
        ))
    );
    assert!(Response::parse(&hex("03 05 00 00")).is_err());
    assert!(Response::parse(&hex("2B 0E 01 01 00 00 02 00 01 41")).is_err());
}

// ---- robustness ---------------------------------------------------------------------------

/// A seed request, mutated: one byte changed, cut short, lengthened, or replaced by noise;
/// half the time its MBAP length and protocol identifier are made consistent again, so the
/// PDU checks behind the framing are reached.
fn mutated_request() -> impl Strategy<Value = Vec<u8>> {
    let seeds = prop::sample::select(vec![
        hex("00 01 00 00 00 0F 00 10 00 00 00 04 08 03 01 01 00 00 00 00 00"),
        hex("00 03 00 00 00 13 00 17 00 00 00 04 00 00 00 04 08 43 01 00 64 00 00 27 10"),
        hex("00 06 00 00 00 05 00 2B 0E 01 00"),
        hex("00 02 00 00 00 06 00 03 00 00 00 04"),
    ]);
    let mutated = (
        seeds,
        any::<prop::sample::Index>(),
        any::<u8>(),
        0usize..8,
        any::<u8>(),
    )
        .prop_map(|(mut m, at, byte, extra, how)| {
            match how % 3 {
                0 => {
                    let i = at.index(m.len());
                    m[i] = byte;
                }
                1 => m.truncate(at.index(m.len() + 1)),
                _ => m.extend(std::iter::repeat_n(byte, extra)),
            }
            m
        });
    (
        prop_oneof![3 => mutated, 1 => prop::collection::vec(any::<u8>(), 0..40)],
        any::<bool>(),
    )
        .prop_map(|(mut m, consistent)| {
            if consistent && m.len() >= 7 {
                let l = (m.len() - 6) as u16;
                m[4..6].copy_from_slice(&l.to_be_bytes());
                m[2] = 0;
                m[3] = 0;
            }
            m
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 16384, ..ProptestConfig::default() })]

    /// Random and mutated input never panics; every ADU the server accepts gets a response
    /// with a consistent MBAP length, and one it refuses has a length field that does not
    /// match its bytes (or is no Modbus TCP ADU at all); the framer never panics either.
    #[test]
    fn random_input_never_panics(requests in prop::collection::vec(mutated_request(), 1..8)) {
        let mut out = [0u8; MAX_ADU_LEN];
        let mut framer = Framer::new();
        let mut cmmo = Cmmo::new(true);
        let mut plain = Plain::new();
        for m in &requests {
            for map in [&mut cmmo as &mut dyn RegisterMap, &mut plain] {
                if let Ok(n) = handle_adu(m, map, &mut out) {
                    prop_assert!((9..=MAX_ADU_LEN).contains(&n));
                    prop_assert_eq!(usize::from(u16::from_be_bytes([out[4], out[5]])), n - 6);
                } else if m.len() >= 8 && m.len() <= MAX_ADU_LEN && m[2..4] == [0, 0] {
                    prop_assert_ne!(usize::from(u16::from_be_bytes([m[4], m[5]])), m.len() - 6);
                }
            }
            framer.push(m);
            loop {
                match framer.next_adu() {
                    Ok(Some(_)) => {}
                    Ok(None) => break,
                    Err(_) => {
                        framer.clear();
                        break;
                    }
                }
            }
        }
    }
}
