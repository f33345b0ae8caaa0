//! Worked examples of the Festo CMMP-AS manual (spec/vectors.md §1.2, §1.4–1.6) that the
//! CiA 301 layer and the device description decide.

mod common;
use canopen::CanFrame;
use common::*;
use od::{StorageRequest, Value};

fn cmmp() -> Bench {
    Bench::new(&devices::CMMP_AS, 1)
}

#[test]
fn cmmp_sdo_01_read_mode_display() {
    let mut b = cmmp();
    b.od.set_value(0x6061, 0, Value::Signed(1)).unwrap();
    assert_eq!(
        b.sdo1(&[0x40, 0x61, 0x60, 0x00]),
        p8(&[0x4F, 0x61, 0x60, 0x00, 0x01])
    );
}

#[test]
fn cmmp_sdo_02_write_rpdo2_transmission_type() {
    let mut b = cmmp();
    assert_eq!(
        b.sdo1(&[0x2F, 0x01, 0x14, 0x02, 0xEF]),
        p8(&[0x60, 0x01, 0x14, 0x02])
    );
    assert_eq!(b.od.get_unsigned(0x1401, 2), Some(0xEF));
}

#[test]
fn cmmp_sdo_03_read_statusword() {
    let mut b = cmmp();
    b.od.set_value(0x6041, 0, Value::Unsigned(0x1234)).unwrap();
    assert_eq!(
        b.sdo1(&[0x40, 0x41, 0x60, 0x00]),
        p8(&[0x4B, 0x41, 0x60, 0x00, 0x34, 0x12])
    );
}

#[test]
fn cmmp_sdo_04_write_controlword() {
    let mut b = cmmp();
    assert_eq!(
        b.sdo1(&[0x2B, 0x40, 0x60, 0x00, 0xE8, 0x03]),
        p8(&[0x60, 0x40, 0x60, 0x00])
    );
}

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

#[test]
fn cmmp_sdo_07_write_to_read_only_statusword() {
    let mut b = cmmp();
    assert_eq!(
        b.sdo1(&[0x23, 0x41, 0x60, 0x00, 0, 0, 0, 0]),
        p8(&[0x80, 0x41, 0x60, 0x00, 0x02, 0x00, 0x01, 0x06])
    );
}

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

#[test]
fn cmmp_pdo_10_to_16_default_pdo_configuration() {
    let mut b = cmmp();
    // CMMP-PDO-10…13: TPDO communication and mapping defaults (node 1).
    let tpdo = [
        (0x1800, 0xC000_0181u32, 0x1A00, vec![0x6041_0010u32]),
        (0x1801, 0xC000_0281, 0x1A01, vec![0x6041_0010, 0x6061_0008]),
        (0x1802, 0xC000_0381, 0x1A02, vec![0x6041_0010, 0x6064_0020]),
        (0x1803, 0xC000_0481, 0x1A03, vec![0x6041_0010, 0x606C_0020]),
    ];
    for (comm, cob, map, entries) in tpdo {
        assert_eq!(read_u32(&mut b, comm, 0), 3);
        assert_eq!(read_u32(&mut b, comm, 1), cob);
        assert_eq!(read_u32(&mut b, comm, 2), 0xFF);
        assert_eq!(read_u32(&mut b, comm, 3), 0);
        assert_eq!(read_u32(&mut b, map, 0), entries.len() as u32);
        for sub in 1..=4u8 {
            let want = entries.get(sub as usize - 1).copied().unwrap_or(0);
            assert_eq!(read_u32(&mut b, map, sub), want, "{map:04X}:{sub}");
        }
    }
    // CMMP-PDO-14: transmit masks.
    for idx in 0x2014..=0x2017 {
        assert_eq!(read_u32(&mut b, idx, 0), 2);
        assert_eq!(read_u32(&mut b, idx, 1), 0xFFFF_FFFF);
        assert_eq!(read_u32(&mut b, idx, 2), 0xFFFF_FFFF);
    }
    // CMMP-PDO-15/16: RPDOs, no inhibit time.
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
    // spec §9: defaults printed for node 1 are $NODEID-relative.
    let mut b = Bench::new(&devices::CMMP_AS, 27);
    assert_eq!(read_u32(&mut b, 0x1800, 1), 0xC000_0180 + 27);
    assert_eq!(read_u32(&mut b, 0x1014, 0), 0x80 + 27);
}

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
