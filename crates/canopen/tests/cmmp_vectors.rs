//! Worked examples of the Festo CMMP-AS manual (the vector catalogue kept beside the project, §1.2,
//! §1.4–1.6) that the CiA 301 layer and the device description decide.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod common;
use canopen::CanFrame;
use common::*;
use od::{StorageRequest, Value};

fn cmmp() -> Bench {
    Bench::new(&devices::CMMP_AS, 1)
}

/// CMMP-SDO-01: `601: 40 61 60 00` with 6061h = 1 → `581: 4F 61 60 00 01`.
#[test]
fn cmmp_sdo_01_read_mode_display() {
    let mut b = cmmp();
    b.od.set_value(0x6061, 0, Value::Signed(1)).unwrap();
    assert_eq!(
        b.sdo1(&[0x40, 0x61, 0x60, 0x00]),
        p8(&[0x4F, 0x61, 0x60, 0x00, 0x01])
    );
}

/// CMMP-SDO-02: `601: 2F 01 14 02 EF` → `581: 60 01 14 02` (RPDO2 disabled, Pre-Operational).
#[test]
fn cmmp_sdo_02_write_rpdo2_transmission_type() {
    let mut b = cmmp();
    assert_eq!(
        b.sdo1(&[0x2F, 0x01, 0x14, 0x02, 0xEF]),
        p8(&[0x60, 0x01, 0x14, 0x02])
    );
    assert_eq!(b.od.get_unsigned(0x1401, 2), Some(0xEF));
}

/// CMMP-SDO-03: `601: 40 41 60 00` with statusword 1234h → `581: 4B 41 60 00 34 12`.
#[test]
fn cmmp_sdo_03_read_statusword() {
    let mut b = cmmp();
    b.od.set_value(0x6041, 0, Value::Unsigned(0x1234)).unwrap();
    assert_eq!(
        b.sdo1(&[0x40, 0x41, 0x60, 0x00]),
        p8(&[0x4B, 0x41, 0x60, 0x00, 0x34, 0x12])
    );
}

/// CMMP-SDO-04: `601: 2B 40 60 00 E8 03` → `581: 60 40 60 00`.
#[test]
fn cmmp_sdo_04_write_controlword() {
    let mut b = cmmp();
    assert_eq!(
        b.sdo1(&[0x2B, 0x40, 0x60, 0x00, 0xE8, 0x03]),
        p8(&[0x60, 0x40, 0x60, 0x00])
    );
}

/// CMMP-SDO-05, CMMP-SDO-06: 6093h:01 := 12345678h, read back LSB first.
#[test]
fn cmmp_sdo_05_06_position_factor_numerator() {
    let mut b = cmmp();
    // Divisor first, so the factor stays inside the 2^24 limit (vectors.md note).
    assert_eq!(
        b.sdo1(&[0x23, 0x93, 0x60, 0x02, 0x13, 0, 0, 0]),
        p8(&[0x60, 0x93, 0x60, 0x02])
    );
    assert_eq!(
        b.sdo1(&[0x23, 0x93, 0x60, 0x01, 0x78, 0x56, 0x34, 0x12]),
        p8(&[0x60, 0x93, 0x60, 0x01])
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x93, 0x60, 0x01]),
        p8(&[0x43, 0x93, 0x60, 0x01, 0x78, 0x56, 0x34, 0x12])
    );
}

/// CMMP-SDO-07: a 32-bit write to the read-only statusword → abort 0601 0002h.
#[test]
fn cmmp_sdo_07_write_to_read_only_statusword() {
    let mut b = cmmp();
    assert_eq!(
        b.sdo1(&[0x23, 0x41, 0x60, 0x00, 0, 0, 0, 0]),
        p8(&[0x80, 0x41, 0x60, 0x00, 0x02, 0x00, 0x01, 0x06])
    );
}

/// CMMP-SDO-08, CMMP-SDO-09: "save" to 1010h:01 asks the runtime to store; "load" to
/// 1011h:01 (output stage disabled) puts the defaults back in the current set.
#[test]
fn cmmp_sdo_08_save_and_09_restore() {
    let mut b = cmmp();
    assert_eq!(
        b.sdo1(&[0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65]),
        p8(&[0x60, 0x10, 0x10, 0x01])
    );
    assert_eq!(b.od.take_request(), Some(StorageRequest::Save { sub: 1 }));
    b.sdo1(&[0x2B, 0x17, 0x10, 0x00, 0x64, 0x00]);
    assert_eq!(
        b.sdo1(&[0x23, 0x11, 0x10, 0x01, 0x6C, 0x6F, 0x61, 0x64]),
        p8(&[0x60, 0x11, 0x10, 0x01])
    );
    assert_eq!(
        b.od.take_request(),
        Some(StorageRequest::Restore { sub: 1 })
    );
    assert_eq!(
        b.od.get_unsigned(0x1017, 0),
        Some(0),
        "defaults back in the current set"
    );
}

/// CMMP-SDO-11: a wrong signature to 1011h:01 (and 1010h:01) → abort 0800 0020h, nothing stored.
#[test]
fn cmmp_sdo_11_wrong_signature() {
    let mut b = cmmp();
    assert_eq!(
        b.sdo1(&[0x23, 0x11, 0x10, 0x01, 0, 0, 0, 0]),
        p8(&[0x80, 0x11, 0x10, 0x01, 0x20, 0x00, 0x00, 0x08])
    );
    assert_eq!(
        b.sdo1(&[0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x64]),
        abort(0x1010, 1, 0x0800_0020)
    );
    assert_eq!(b.od.take_request(), None);
}

/// CMMP-SDO-12: reading 1011h:01 and 1010h:01 returns 1 (function supported).
#[test]
fn cmmp_sdo_12_store_restore_read_one() {
    let mut b = cmmp();
    assert_eq!(
        b.sdo1(&[0x40, 0x11, 0x10, 0x01]),
        p8(&[0x43, 0x11, 0x10, 0x01, 1, 0, 0, 0])
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x10, 0x10, 0x01]),
        p8(&[0x43, 0x10, 0x10, 0x01, 1, 0, 0, 0])
    );
}

/// CMMP-SDO-13: TPDO communication records have subs 01–03 only: 1800h:05 → abort 0609 0011h.
#[test]
fn cmmp_sdo_13_tpdo_has_no_event_timer() {
    let mut b = cmmp();
    assert_eq!(
        b.sdo1(&[0x40, 0x00, 0x18, 0x05]),
        p8(&[0x80, 0x00, 0x18, 0x05, 0x11, 0x00, 0x09, 0x06])
    );
}

fn read_u32(b: &mut Bench, index: u16, sub: u8) -> u32 {
    let r = b.sdo1(&[0x40, index as u8, (index >> 8) as u8, sub]);
    assert_eq!(
        r[0] & 0xE3,
        0x43,
        "expedited upload of {index:04X}:{sub:02X}: {r:02X?}"
    );
    let n = 4 - ((r[0] >> 2) & 3) as usize;
    let mut v = [0u8; 4];
    v[..n].copy_from_slice(&r[4..4 + n]);
    u32::from_le_bytes(v)
}

/// CMMP-PDO-10, CMMP-PDO-11, CMMP-PDO-12, CMMP-PDO-13, CMMP-PDO-14, CMMP-PDO-15,
/// CMMP-PDO-16: the printed TPDO/RPDO defaults and transmit masks of node 1.
#[test]
fn cmmp_pdo_10_to_16_default_pdo_configuration() {
    let mut b = cmmp();
    // TPDO communication and mapping defaults (node 1), one vector per TPDO.
    let tpdo = [
        (
            "CMMP-PDO-10",
            0x1800,
            0xC000_0181u32,
            0x1A00,
            vec![0x6041_0010u32],
        ),
        (
            "CMMP-PDO-11",
            0x1801,
            0xC000_0281,
            0x1A01,
            vec![0x6041_0010, 0x6061_0008],
        ),
        (
            "CMMP-PDO-12",
            0x1802,
            0xC000_0381,
            0x1A02,
            vec![0x6041_0010, 0x6064_0020],
        ),
        (
            "CMMP-PDO-13",
            0x1803,
            0xC000_0481,
            0x1A03,
            vec![0x6041_0010, 0x606C_0020],
        ),
    ];
    for (id, comm, cob, map, entries) in tpdo {
        assert_eq!(read_u32(&mut b, comm, 0), 3, "{id}");
        assert_eq!(read_u32(&mut b, comm, 1), cob, "{id}");
        assert_eq!(read_u32(&mut b, comm, 2), 0xFF, "{id}");
        assert_eq!(read_u32(&mut b, comm, 3), 0, "{id}");
        assert_eq!(read_u32(&mut b, map, 0), entries.len() as u32, "{id}");
        for sub in 1..=4u8 {
            let want = entries.get(sub as usize - 1).copied().unwrap_or(0);
            assert_eq!(read_u32(&mut b, map, sub), want, "{id}: {map:04X}:{sub}");
        }
    }
    // CMMP-PDO-14: transmit masks.
    for idx in 0x2014..=0x2017 {
        assert_eq!(read_u32(&mut b, idx, 0), 2);
        assert_eq!(read_u32(&mut b, idx, 1), 0xFFFF_FFFF);
        assert_eq!(read_u32(&mut b, idx, 2), 0xFFFF_FFFF);
    }
    // CMMP-PDO-15, CMMP-PDO-16: RPDOs, no inhibit time.
    let rpdo = [
        (0x1400, 0xC000_0201u32, 0x1600, vec![0x6040_0010u32]),
        (0x1401, 0xC000_0301, 0x1601, vec![0x6040_0010, 0x6060_0008]),
        (0x1402, 0xC000_0401, 0x1602, vec![0x6040_0010, 0x607A_0020]),
        (0x1403, 0xC000_0501, 0x1603, vec![0x6040_0010, 0x60FF_0020]),
    ];
    for (comm, cob, map, entries) in rpdo {
        assert_eq!(read_u32(&mut b, comm, 0), 2);
        assert_eq!(read_u32(&mut b, comm, 1), cob);
        assert_eq!(read_u32(&mut b, comm, 2), 0xFF);
        assert_eq!(
            b.sdo1(&[0x40, comm as u8, (comm >> 8) as u8, 3]),
            abort(comm, 3, 0x0609_0011)
        );
        assert_eq!(read_u32(&mut b, map, 0), entries.len() as u32);
        for (i, e) in entries.iter().enumerate() {
            assert_eq!(read_u32(&mut b, map, i as u8 + 1), *e);
        }
    }
}

#[test]
fn pdo_cob_ids_follow_the_node_id() {
    // The manual prints the default COB-IDs for node 1; they are $NODEID-relative.
    let mut b = Bench::new(&devices::CMMP_AS, 27);
    assert_eq!(read_u32(&mut b, 0x1800, 1), 0xC000_0180 + 27);
    assert_eq!(read_u32(&mut b, 0x1014, 0), 0x80 + 27);
}

/// CMMP-NMT-01 (boot-up `701: 00`, checked by `Bench::new`), CMMP-NMT-09 (1016h reads 0).
#[test]
fn cmmp_nmt_01_boot_up_and_09_consumer_time_reads_zero() {
    let mut b = cmmp();
    // CMMP-NMT-01 is checked by Bench::new (701: 00). CMMP-NMT-09: 1016h always reads 0.
    let v = (5u32 << 16 | 200).to_le_bytes();
    assert_eq!(
        b.sdo1(&[0x23, 0x16, 0x10, 0x01, v[0], v[1], v[2], v[3]]),
        p8(&[0x60, 0x16, 0x10, 0x01])
    );
    assert_eq!(read_u32(&mut b, 0x1016, 1), 0);
    // ...and no consumer runs: no event when node 5 falls silent.
    b.send(0x705, &[0x05]);
    b.advance_ms(1000);
    assert!(b
        .events()
        .iter()
        .all(|e| !matches!(e, canopen::NodeEvent::Heartbeat(_))));
}

#[test]
fn cmmp_emcy_07_clear_error_history() {
    let mut b = cmmp();
    b.od.set_value(0x1003, 0, Value::Unsigned(1)).unwrap();
    b.od.set_value(0x1003, 1, Value::Unsigned(0x2312)).unwrap();
    assert_eq!(
        b.sdo1(&[0x2F, 0x03, 0x10, 0x00, 0x00]),
        p8(&[0x60, 0x03, 0x10, 0x00])
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x03, 0x10, 0x00]),
        p8(&[0x4F, 0x03, 0x10, 0x00, 0x00])
    );
    // CiA 301: anything but 0 is an invalid value.
    assert_eq!(
        b.sdo1(&[0x2F, 0x03, 0x10, 0x00, 0x01]),
        abort(0x1003, 0, 0x0609_0030)
    );
}

/// CMMP-NMT-07: 1017h := 100 ms → `701: 7F`, then `701: 05` in Operational, `701: 04` in Stopped.
#[test]
fn cmmp_nmt_07_heartbeat_in_each_state() {
    let mut b = cmmp();
    assert_eq!(
        b.sdo1(&[0x2B, 0x17, 0x10, 0x00, 0x64, 0x00]),
        p8(&[0x60, 0x17, 0x10, 0x00])
    );
    assert_eq!(b.advance_ms(100), vec![frame(0x701, &[0x7F])]);
    b.send(0x000, &[0x01, 0x01]);
    assert_eq!(b.advance_ms(100), vec![frame(0x701, &[0x05])]);
    b.send(0x000, &[0x02, 0x01]);
    assert_eq!(
        b.advance_ms(100),
        vec![CanFrame::new(0x701, &[0x04]).unwrap()]
    );
}

/// CMMP-NMT-05: `000: 82 05` resets communication of node 5 only: boot-up `705: 00`,
/// Pre-Operational, and the guarding toggle starts again at 0.
#[test]
fn cmmp_nmt_05_reset_communication_of_node_5() {
    let mut b = Bench::new(&devices::CMMP_AS, 5);
    b.send(0x000, &[0x01, 0x05]);
    assert_eq!(b.send(0x705, &[]), vec![frame(0x705, &[0x05])]);
    b.events();
    // Addressed to node 1: not this node.
    b.send(0x000, &[0x82, 0x01]);
    assert_eq!(b.node.nmt_state(), canopen::NmtState::Operational);
    b.send(0x000, &[0x82, 0x05]);
    assert_eq!(b.events(), vec![canopen::NodeEvent::ResetCommunication]);
    assert_eq!(b.boot(), vec![frame(0x705, &[0x00])]);
    assert_eq!(b.node.nmt_state(), canopen::NmtState::PreOperational);
    assert_eq!(b.send(0x705, &[]), vec![frame(0x705, &[0x7F])], "toggle 0");
}

/// CMMP-NMT-13: the manual asks the master for ≥ 1 ms between NMT frames; the twin accepts
/// faster traffic (two commands 100 µs apart both take effect).
#[test]
fn cmmp_nmt_13_nmt_frames_closer_than_1_ms_are_accepted() {
    let mut b = cmmp();
    b.send(0x000, &[0x01, 0x01]);
    b.now = od::Instant::from_nanos(b.now.as_nanos() + 100_000);
    b.send(0x000, &[0x02, 0x01]);
    assert_eq!(b.node.nmt_state(), canopen::NmtState::Stopped);
    b.now = od::Instant::from_nanos(b.now.as_nanos() + 100_000);
    b.send(0x000, &[0x80, 0x00]);
    assert_eq!(b.node.nmt_state(), canopen::NmtState::PreOperational);
}
