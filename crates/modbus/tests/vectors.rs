//! The Modbus TCP vectors of the vector catalogue kept beside the project, §2.3, by ID
//! (FHPP-MB-01 … FHPP-MB-08).

mod common;

use common::{exchange, hex, Cmmo, PRODUCT_CODE, REVISION, VENDOR};
use modbus::watchdog::{effective_timeout_ms, Watchdog};

/// FHPP-MB-01: FC 10h, FHPP Std, record selection, ENABLE + STOP, HALT, record 1.
#[test]
fn fhpp_mb_01_write_multiple_registers() {
    let mut map = Cmmo::new(false);
    let resp = exchange(
        &mut map,
        &hex("00 01 00 00 00 0F 00 10 00 00 00 04 08 03 01 01 00 00 00 00 00"),
    )
    .expect("valid ADU");
    assert_eq!(resp, hex("00 01 00 00 00 06 00 10 00 00 00 04"));
    // CCON:CPOS, record:reserved, bytes 5-8 - big-endian registers
    assert_eq!(map.outputs[..4], [0x0301, 0x0100, 0x0000, 0x0000]);
}

/// FHPP-MB-02: FC 03h after FHPP-MB-01 returns the input telegram, register 0 = SCON:SPOS.
#[test]
fn fhpp_mb_02_read_holding_registers() {
    let mut map = Cmmo::new(false);
    exchange(
        &mut map,
        &hex("00 01 00 00 00 0F 00 10 00 00 00 04 08 03 01 01 00 00 00 00 00"),
    )
    .expect("write");
    // What the FHPP device answers after the enable (FHPP-CB-03): SCON 13h, SPOS 05h.
    map.inputs[..4].copy_from_slice(&[0x1305, 0x0100, 0x0001, 0x2345]);
    let resp = exchange(&mut map, &hex("00 02 00 00 00 06 00 03 00 00 00 04")).expect("read");
    assert_eq!(resp[..11], hex("00 02 00 00 00 0B 00 03 08 13 05")[..]);
    assert_eq!(resp[11..], hex("01 00 00 01 23 45")[..]);
}

/// FHPP-MB-03: FC 17h cyclic exchange, direct mode, absolute position 10000 SINC, 100 %.
#[test]
fn fhpp_mb_03_read_write_multiple_registers() {
    let mut map = Cmmo::new(false);
    let cycle1 = hex("00 03 00 00 00 13 00 17 00 00 00 04 00 00 00 04 08 43 01 00 64 00 00 27 10");
    let mut cycle2 = cycle1.clone();
    cycle2[18] = 0x03;
    exchange(&mut map, &cycle1).expect("cycle 1");
    assert_eq!(map.outputs[..4], [0x4301, 0x0064, 0x0000, 0x2710]);
    // SCON 53h, SPOS 83h (REF + ACK + HALT), SDIR 00, velocity 64h, position 0
    map.inputs[..4].copy_from_slice(&[0x5383, 0x0064, 0x0000, 0x0000]);
    let resp = exchange(&mut map, &cycle2).expect("cycle 2");
    assert_eq!(map.outputs[..4], [0x4303, 0x0064, 0x0000, 0x2710]);
    assert_eq!(
        resp,
        hex("00 03 00 00 00 0B 00 17 08 53 83 00 64 00 00 00 00")
    );
}

/// FHPP-MB-04: FC 17h with quantity 8: FHPP + FPC, read PNU 1041:1 via EFPC.
#[test]
fn fhpp_mb_04_read_write_with_fpc() {
    let mut map = Cmmo::new(true);
    let req = hex(
        "00 04 00 00 00 1B 00 17 00 00 00 08 00 00 00 08 10 43 01 00 00 00 00 00 00 16 01 04 11 00 00 00 00",
    );
    map.inputs = [0x5305, 0, 0, 0x2710, 0x1501, 0x0411, 0x0000, 0x2710];
    let resp = exchange(&mut map, &req).expect("valid");
    assert_eq!(map.outputs[4..], [0x1601, 0x0411, 0, 0]);
    assert_eq!(
        resp,
        hex("00 04 00 00 00 13 00 17 10 53 05 00 00 00 00 27 10 15 01 04 11 00 00 27 10")
    );
    // With profile FHPP Standard, quantity 8 is a value the device does not take.
    let mut std = Cmmo::new(false);
    assert_eq!(
        exchange(&mut std, &req).expect("valid"),
        hex("00 04 00 00 00 03 00 97 03")
    );
    assert_eq!(std.writes, 0);
}

/// FHPP-MB-05: FC 07h answers 00 without a fault, the fault number otherwise.
#[test]
fn fhpp_mb_05_read_exception_status() {
    let mut map = Cmmo::new(false);
    let req = hex("00 05 00 00 00 02 00 07");
    assert_eq!(
        exchange(&mut map, &req).expect("valid"),
        hex("00 05 00 00 00 03 00 07 00")
    );
    map.fault = 0x2F;
    assert_eq!(
        exchange(&mut map, &req).expect("valid"),
        hex("00 05 00 00 00 03 00 07 2F")
    );
}

/// FHPP-MB-06: FC 2Bh / 0Eh basic device identification: objects 00, 01, 02 with conformity
/// 01; regular adds 03, 04, 06 with conformity 02.
#[test]
fn fhpp_mb_06_read_device_identification() {
    let mut map = Cmmo::new(false);
    let resp = exchange(&mut map, &hex("00 06 00 00 00 05 00 2B 0E 01 00")).expect("valid");
    let mut pdu = hex("2B 0E 01 01 00 00 03");
    for (id, v) in [(0u8, VENDOR), (1, PRODUCT_CODE), (2, REVISION)] {
        pdu.push(id);
        pdu.push(v.len() as u8);
        pdu.extend_from_slice(v);
    }
    let mut expected = hex("00 06 00 00");
    expected.extend_from_slice(&((pdu.len() + 1) as u16).to_be_bytes());
    expected.push(0x00);
    expected.extend_from_slice(&pdu);
    assert_eq!(resp, expected);

    let resp = exchange(&mut map, &hex("00 06 00 00 00 05 00 2B 0E 02 00")).expect("valid");
    assert_eq!(resp[7..14], hex("2B 0E 02 02 00 00 06")[..]);
    let pdu = &resp[7..];
    let objects: Vec<u8> = match modbus::client::Response::parse(pdu).expect("parses") {
        modbus::client::Response::ReadDeviceIdentification(d) => {
            d.objects.map(|(id, _)| id).collect()
        }
        other => panic!("unexpected {other:?}"),
    };
    assert_eq!(objects, [0, 1, 2, 3, 4, 6]);
}

/// FHPP-MB-07: start address 1 → exception 02, quantity ≠ 4/8 → 03, unsupported FC 06h → 01.
#[test]
fn fhpp_mb_07_exceptions() {
    let mut map = Cmmo::new(false);
    assert_eq!(
        exchange(&mut map, &hex("00 07 00 00 00 06 00 03 00 01 00 04")).expect("valid"),
        hex("00 07 00 00 00 03 00 83 02")
    );
    assert_eq!(
        exchange(&mut map, &hex("00 07 00 00 00 06 00 03 00 00 00 05")).expect("valid"),
        hex("00 07 00 00 00 03 00 83 03")
    );
    assert_eq!(
        exchange(&mut map, &hex("00 07 00 00 00 06 00 06 00 00 00 01")).expect("valid"),
        hex("00 07 00 00 00 03 00 86 01")
    );
}

/// FHPP-MB-08: watchdog 0 disabled, 50 ms acts as 100 ms, 5000 ms; any message restarts it.
#[test]
fn fhpp_mb_08_watchdog() {
    assert_eq!(effective_timeout_ms(0), None);
    assert_eq!(effective_timeout_ms(50), Some(100));
    assert_eq!(effective_timeout_ms(5000), Some(5000));

    let mut off = Watchdog::new(0);
    off.start(0);
    assert_eq!(off.deadline_ms(), None);
    assert!(!off.poll(u64::MAX));

    let mut wd = Watchdog::new(50);
    wd.start(1_000);
    assert!(!wd.poll(1_099));
    wd.on_message(1_090); // restarts
    assert!(!wd.poll(1_189));
    assert!(wd.poll(1_190));
    assert!(!wd.poll(1_191), "fires once");

    let mut slow = Watchdog::new(5000);
    slow.start(0);
    assert!(!slow.poll(4_999));
    assert!(slow.poll(5_000));
}
