//! PDO configuration rules and transmission (CiA 301 §7.2.2, §7.5.2.35–38; CMMP-AS §3.3), with
//! the manual's TPDO1 example as vectors CMMP-PDO-01 to CMMP-PDO-09 and CMMP-SDO-14.

mod common;
use common::*;
use od::Value;

fn cmmp() -> Bench {
    Bench::new(&devices::CMMP_AS, 1)
}

fn u32le(v: u32) -> [u8; 4] {
    v.to_le_bytes()
}

fn w32(b: &mut Bench, index: u16, sub: u8, v: u32) -> [u8; 8] {
    let [i0, i1] = index.to_le_bytes();
    let d = u32le(v);
    b.sdo1(&[0x23, i0, i1, sub, d[0], d[1], d[2], d[3]])
}

fn w8(b: &mut Bench, index: u16, sub: u8, v: u8) -> [u8; 8] {
    let [i0, i1] = index.to_le_bytes();
    b.sdo1(&[0x2F, i0, i1, sub, v])
}

fn ok(index: u16, sub: u8) -> [u8; 8] {
    let [i0, i1] = index.to_le_bytes();
    p8(&[0x60, i0, i1, sub])
}

/// The manual's TPDO1 example, steps 1–8 (CMMP-PDO-01, CMMP-PDO-02, CMMP-PDO-03, CMMP-PDO-04,
/// CMMP-PDO-05, CMMP-PDO-06, CMMP-PDO-07, CMMP-PDO-08).
fn configure_tpdo1(b: &mut Bench) {
    // CMMP-PDO-01: deactivate with a new COB-ID.
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x18, 0x01, 0x87, 0x01, 0x00, 0xC0]),
        ok(0x1800, 1)
    );
    // CMMP-PDO-02.
    assert_eq!(b.sdo1(&[0x2F, 0x00, 0x1A, 0x00, 0x00]), ok(0x1A00, 0));
    // CMMP-PDO-03.
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x1A, 0x01, 0x10, 0x00, 0x41, 0x60]),
        ok(0x1A00, 1)
    );
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x1A, 0x02, 0x08, 0x00, 0x61, 0x60]),
        ok(0x1A00, 2)
    );
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x1A, 0x03, 0x20, 0x00, 0xFD, 0x60]),
        ok(0x1A00, 3)
    );
    // CMMP-PDO-04.
    assert_eq!(b.sdo1(&[0x2F, 0x00, 0x1A, 0x00, 0x03]), ok(0x1A00, 0));
    // CMMP-PDO-05.
    assert_eq!(b.sdo1(&[0x2F, 0x00, 0x18, 0x02, 0xFF]), ok(0x1800, 2));
    // CMMP-PDO-06.
    assert_eq!(
        b.sdo1(&[0x23, 0x14, 0x20, 0x02, 0x00, 0xFF, 0xFF, 0x00]),
        ok(0x2014, 2)
    );
    assert_eq!(
        b.sdo1(&[0x23, 0x14, 0x20, 0x01, 0x00, 0x00, 0x00, 0x00]),
        ok(0x2014, 1)
    );
    // CMMP-PDO-07: 100 × 100 µs.
    assert_eq!(b.sdo1(&[0x2B, 0x00, 0x18, 0x03, 0x64, 0x00]), ok(0x1800, 3));
    // CMMP-PDO-08: activate; bit 30 is ignored on write and reads 1.
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x18, 0x01, 0x87, 0x01, 0x00, 0x40]),
        ok(0x1800, 1)
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x00, 0x18, 0x01]),
        p8(&[0x43, 0x00, 0x18, 0x01, 0x87, 0x01, 0x00, 0x40])
    );
}

/// CMMP-PDO-09 (after CMMP-PDO-01 to CMMP-PDO-08): in Operational a statusword change sends
/// nothing, a DIN0 change sends `187:` (DLC 7) no sooner than 10 ms after the previous TPDO1.
#[test]
fn cmmp_pdo_01_to_09_tpdo1_on_masked_change_with_inhibit_time() {
    let mut b = cmmp();
    configure_tpdo1(&mut b);
    b.od.set_value(0x6061, 0, Value::Signed(1)).unwrap();
    b.send(0x000, &[0x01, 0x01]);
    // Entering Operational sends the event-driven TPDO once.
    let out = b.advance_ms(1);
    let tpdo: Vec<_> = out.iter().filter(|f| f.id == 0x187).collect();
    assert_eq!(tpdo.len(), 1, "{out:?}");
    assert_eq!(tpdo[0].len, 7, "16 + 8 + 32 bits");
    assert_eq!(tpdo[0].payload(), &[0, 0, 1, 0, 0, 0, 0]);
    // (a) statusword and 60FDh bits 0–15 are masked out: no frame.
    b.od.set_value(0x6041, 0, Value::Unsigned(0x0237)).unwrap();
    b.od.set_value(0x60FD, 0, Value::Unsigned(0x0000_FFFF))
        .unwrap();
    let out = b.advance_ms(50);
    assert!(out.iter().all(|f| f.id != 0x187), "{out:?}");
    // (b) DIN0 = 60FDh bit 24 (PDO byte 6): one frame with the current data.
    b.od.set_value(0x60FD, 0, Value::Unsigned(0x0100_FFFF))
        .unwrap();
    let out = b.advance_ms(2);
    let tpdo: Vec<_> = out.iter().filter(|f| f.id == 0x187).collect();
    assert_eq!(tpdo.len(), 1);
    assert_eq!(tpdo[0].payload(), &[0x37, 0x02, 1, 0xFF, 0xFF, 0x00, 0x01]);
    // Changes within the inhibit time wait for it: at most one frame every 10 ms.
    let mut times = Vec::new();
    for i in 0..10u64 {
        b.od.set_value(0x60FD, 0, Value::Unsigned(((i % 2) << 16) | 0x0200_0000))
            .unwrap();
        for f in b.advance_ms(2) {
            if f.id == 0x187 {
                times.push(b.now.as_nanos());
            }
        }
    }
    assert!(times.len() >= 2);
    for w in times.windows(2) {
        assert!(w[1] - w[0] >= 10_000_000, "inhibit time 10 ms: {times:?}");
    }
}

/// CMMP-PDO-17: an RPDO received in Pre-Operational is ignored; in Operational it sets 6040h.
#[test]
fn cmmp_pdo_17_rpdo_works_only_in_operational() {
    let mut b = cmmp();
    assert_eq!(w32(&mut b, 0x1400, 1, 0x4000_0201), ok(0x1400, 1));
    b.send(0x201, &[0x0F, 0x00]);
    assert_eq!(
        b.od.get_unsigned(0x6040, 0),
        Some(0),
        "ignored in Pre-Operational"
    );
    b.send(0x000, &[0x01, 0x01]);
    b.send(0x201, &[0x0F, 0x00]);
    assert_eq!(b.od.get_unsigned(0x6040, 0), Some(0x0F));
}

#[test]
fn short_rpdo_is_ignored_with_emcy_8210() {
    let mut b = cmmp();
    w32(&mut b, 0x1403, 1, 0x4000_0501); // RPDO4: controlword + target velocity, 6 bytes
    b.send(0x000, &[0x01, 0x01]);
    b.advance_ms(1);
    b.send(0x501, &[0x0F, 0x00, 1, 2]);
    let out = b.advance_ms(1);
    assert_eq!(b.od.get_unsigned(0x6040, 0), Some(0), "not processed");
    let emcy: Vec<_> = out.iter().filter(|f| f.id == 0x81).collect();
    assert_eq!(emcy.len(), 1);
    assert_eq!(emcy[0].data, [0x10, 0x82, 0x11, 0, 0, 0, 0, 0]);
    // The right length again: processed, error cleared with EMCY 0000h.
    b.send(0x501, &[0x0F, 0x00, 0x10, 0x27, 0, 0]);
    let out = b.advance_ms(1);
    assert_eq!(b.od.get_unsigned(0x6040, 0), Some(0x0F));
    assert_eq!(b.od.value(0x60FF, 0), Some(Value::Signed(10000)));
    let emcy: Vec<_> = out.iter().filter(|f| f.id == 0x81).collect();
    assert_eq!(emcy[0].data, [0, 0, 0, 0, 0, 0, 0, 0]);
}

/// CMMP-SDO-14: 32 + 32 + 16 bits > 64 → abort 0604 0042h, 1A00h:00 stays 0.
#[test]
fn cmmp_sdo_14_mapping_longer_than_64_bits() {
    let mut b = cmmp();
    assert_eq!(w8(&mut b, 0x1A00, 0, 0), ok(0x1A00, 0));
    assert_eq!(w32(&mut b, 0x1A00, 1, 0x6064_0020), ok(0x1A00, 1));
    assert_eq!(w32(&mut b, 0x1A00, 2, 0x606C_0020), ok(0x1A00, 2));
    assert_eq!(w32(&mut b, 0x1A00, 3, 0x6041_0010), ok(0x1A00, 3));
    assert_eq!(
        w8(&mut b, 0x1A00, 0, 3),
        p8(&[0x80, 0x00, 0x1A, 0x00, 0x42, 0x00, 0x04, 0x06])
    );
    assert_eq!(b.od.get_unsigned(0x1A00, 0), Some(0));
}

#[test]
fn mapping_errors_get_the_cia_301_abort_and_keep_the_old_mapping() {
    let mut b = cmmp();
    // Valid PDO: mapping refused (CCT PDO 24 → 0601 0000h) — first make TPDO2 valid.
    assert_eq!(w32(&mut b, 0x1801, 1, 0x4000_0281), ok(0x1801, 1));
    assert_eq!(w8(&mut b, 0x1A01, 0, 0), abort(0x1A01, 0, 0x0601_0000));
    // CMMP-AS: parameters of a valid PDO are locked.
    assert_eq!(w8(&mut b, 0x1801, 2, 1), abort(0x1801, 2, 0x0609_0030));
    // Entry while sub 0 ≠ 0 (CCT PDO 23).
    assert_eq!(
        w32(&mut b, 0x1A00, 1, 0x6041_0010),
        abort(0x1A00, 1, 0x0601_0000)
    );
    w8(&mut b, 0x1A00, 0, 0);
    // Not mappable (1017h), wrong direction (controlword into a TPDO is fine, statusword into
    // an RPDO is not), wrong length, missing object / sub-index.
    assert_eq!(
        w32(&mut b, 0x1A00, 1, 0x1017_0010),
        abort(0x1A00, 1, 0x0604_0041)
    );
    w8(&mut b, 0x1600, 0, 0);
    assert_eq!(
        w32(&mut b, 0x1600, 1, 0x6041_0010),
        abort(0x1600, 1, 0x0604_0041)
    );
    assert_eq!(
        w32(&mut b, 0x1A00, 1, 0x6041_0008),
        abort(0x1A00, 1, 0x0604_0041)
    );
    assert_eq!(
        w32(&mut b, 0x1A00, 1, 0x5FFF_0008),
        abort(0x1A00, 1, 0x0602_0000)
    );
    assert_eq!(
        w32(&mut b, 0x1A00, 1, 0x6041_0510),
        abort(0x1A00, 1, 0x0609_0011)
    );
    assert_eq!(
        w32(&mut b, 0x1A00, 1, 0x6041_0048),
        abort(0x1A00, 1, 0x0604_0042)
    );
    // More entries than the mapping has (CCT PDO 25: 0604 0042h).
    assert_eq!(w8(&mut b, 0x1A00, 0, 5), abort(0x1A00, 0, 0x0604_0042));
    // Dummy entries map into RPDOs only.
    assert_eq!(w32(&mut b, 0x1600, 1, 0x0005_0008), ok(0x1600, 1));
    assert_eq!(
        w32(&mut b, 0x1A00, 1, 0x0005_0008),
        abort(0x1A00, 1, 0x0604_0041)
    );
    // A PDO without mapping cannot be made valid; restricted COB-IDs are refused.
    assert_eq!(
        w32(&mut b, 0x1800, 1, 0x4000_0181),
        abort(0x1800, 1, 0x0609_0030)
    );
    assert_eq!(
        w32(&mut b, 0x1802, 1, 0x4000_0581),
        abort(0x1802, 1, 0x0609_0030)
    );
    // Transmission types: 0…240, 254, 255 (CMMP-AS table vs OD range decided by CiA 301).
    assert_eq!(w8(&mut b, 0x1802, 2, 0xF1), abort(0x1802, 2, 0x0609_0030));
    assert_eq!(w8(&mut b, 0x1802, 2, 0xFD), abort(0x1802, 2, 0x0609_0030));
    assert_eq!(w8(&mut b, 0x1802, 2, 0x00), ok(0x1802, 2));
    // The old TPDO2 mapping still works.
    b.send(0x000, &[0x01, 0x01]);
    let out = b.advance_ms(1);
    assert!(out.iter().any(|f| f.id == 0x281 && f.len == 3), "{out:?}");
}

#[test]
fn pdo_parameters_are_refused_in_operational() {
    let mut b = cmmp();
    b.send(0x000, &[0x01, 0x01]);
    assert_eq!(
        w32(&mut b, 0x1800, 1, 0xC000_0187),
        abort(0x1800, 1, 0x0800_0022)
    );
    assert_eq!(w8(&mut b, 0x1A00, 0, 0), abort(0x1A00, 0, 0x0800_0022));
}

#[test]
fn sync_driven_tpdo_every_nth_sync_and_rpdo_on_sync() {
    let mut b = cmmp();
    // TPDO3 (statusword + position) every 2nd SYNC.
    w8(&mut b, 0x1802, 2, 2);
    w32(&mut b, 0x1802, 1, 0x4000_0381);
    // RPDO3 (controlword + target position) synchronous: takes effect at the next SYNC.
    w8(&mut b, 0x1402, 2, 1);
    w32(&mut b, 0x1402, 1, 0x4000_0401);
    b.send(0x000, &[0x01, 0x01]);
    b.advance_ms(1);
    b.od.set_value(0x6064, 0, Value::Signed(-5)).unwrap();
    let mut sent = Vec::new();
    for i in 0..6 {
        let out = b.send(0x080, &[]);
        if out.iter().any(|f| f.id == 0x381) {
            sent.push(i);
        }
    }
    assert_eq!(sent, vec![1, 3, 5]);
    let out = b.send(0x080, &[]);
    assert!(out.is_empty());
    let out = b.send(0x080, &[]);
    assert_eq!(out[0].payload(), &[0, 0, 0xFB, 0xFF, 0xFF, 0xFF]);
    b.send(0x401, &[0x0F, 0x00, 0x10, 0x00, 0x00, 0x00]);
    assert_eq!(
        b.od.value(0x607A, 0),
        Some(Value::Signed(0)),
        "waits for SYNC"
    );
    b.send(0x080, &[]);
    assert_eq!(b.od.value(0x607A, 0), Some(Value::Signed(16)));
    assert_eq!(b.od.get_unsigned(0x6040, 0), Some(0x0F));
}

#[test]
fn tpdos_only_in_operational() {
    let mut b = cmmp();
    w8(&mut b, 0x1802, 2, 1);
    w32(&mut b, 0x1802, 1, 0x4000_0381);
    assert!(b.send(0x080, &[]).is_empty());
    b.send(0x000, &[0x01, 0x01]);
    assert_eq!(b.send(0x080, &[]).len(), 1);
    b.send(0x000, &[0x02, 0x01]);
    assert!(b.send(0x080, &[]).is_empty());
}

/// CMMP-NMT-11: guarding replies 7Fh, FFh, then 05h, 85h; the toggle restarts after Reset
/// Communication.
#[test]
fn cmmp_nmt_11_guarding_toggle() {
    let mut b = cmmp();
    let rtr = canopen::CanFrame::remote(0x701, 1);
    let guard = |b: &mut Bench| {
        let mut out = Vec::new();
        b.node
            .on_frame(b.now, &rtr, &mut b.od, &mut |f| out.push(f));
        out
    };
    assert_eq!(guard(&mut b), vec![frame(0x701, &[0x7F])]);
    assert_eq!(guard(&mut b), vec![frame(0x701, &[0xFF])]);
    b.send(0x000, &[0x01, 0x01]);
    assert_eq!(guard(&mut b), vec![frame(0x701, &[0x05])]);
    assert_eq!(guard(&mut b), vec![frame(0x701, &[0x85])]);
    // Over socketcand the request is a zero-length data frame.
    assert_eq!(b.send(0x701, &[]), vec![frame(0x701, &[0x05])]);
    // Reset communication resets the toggle.
    b.send(0x000, &[0x82, 0x01]);
    b.boot();
    assert_eq!(b.send(0x701, &[]), vec![frame(0x701, &[0x7F])]);
}

/// CMMP-NMT-10: with 1017h ≠ 0 and 100Ch ≠ 0 only heartbeat is active.
#[test]
fn cmmp_nmt_10_heartbeat_wins_over_guarding() {
    let mut b = cmmp();
    b.sdo1(&[0x2B, 0x17, 0x10, 0x00, 0x64, 0x00]);
    b.sdo1(&[0x2B, 0x0C, 0x10, 0x00, 0x64, 0x00]);
    b.sdo1(&[0x2F, 0x0D, 0x10, 0x00, 0x01]);
    b.events();
    assert!(
        b.send(0x701, &[]).is_empty(),
        "no guarding answer while heartbeat runs"
    );
    b.advance_ms(500);
    assert!(
        !b.events().contains(&canopen::NodeEvent::LifeGuardingLost),
        "no guarding supervision, no error 12-4"
    );
}

/// CMMP-NMT-12: 100Ch = 100 ms, 100Dh = 1: no error before the first RTR, then error 12-4
/// (life guarding lost, EMCY 8130h) when none follows within 100 ms.
#[test]
fn cmmp_nmt_12_life_guarding_starts_with_the_first_request() {
    let mut b = cmmp();
    b.sdo1(&[0x2B, 0x0C, 0x10, 0x00, 0x64, 0x00]);
    b.sdo1(&[0x2F, 0x0D, 0x10, 0x00, 0x01]);
    b.events();
    b.advance_ms(500);
    assert!(
        b.events().is_empty(),
        "no supervision before the first request"
    );
    b.send(0x701, &[]);
    b.advance_ms(99);
    assert!(!b.events().contains(&canopen::NodeEvent::LifeGuardingLost));
    let out = b.advance_ms(2);
    assert!(b.events().contains(&canopen::NodeEvent::LifeGuardingLost));
    let emcy: Vec<_> = out.iter().filter(|f| f.id == 0x81).collect();
    assert_eq!(emcy[0].data, [0x30, 0x81, 0x11, 0, 0, 0, 0, 0]);
    b.send(0x701, &[]);
    assert!(b
        .events()
        .contains(&canopen::NodeEvent::LifeGuardingResumed));
}

#[test]
fn cmmp_emcy_vectors() {
    let mut b = cmmp();
    b.advance_ms(1);
    // CMMP-EMCY-02: I²t motor error 31-0, code 2312h, register generic + current.
    b.node
        .raise_error(&mut b.od, 0x2312, canopen::emcy::register::CURRENT, [0; 5]);
    let out = b.advance_ms(1);
    assert_eq!(out, vec![frame(0x81, &[0x12, 0x23, 0x03, 0, 0, 0, 0, 0])]);
    // CMMP-EMCY-06: history.
    assert_eq!(
        b.sdo1(&[0x40, 0x03, 0x10, 0x00]),
        p8(&[0x4F, 0x03, 0x10, 0x00, 0x01])
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x03, 0x10, 0x01]),
        p8(&[0x43, 0x03, 0x10, 0x01, 0x12, 0x23, 0, 0])
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x03, 0x10, 0x02]),
        abort(0x1003, 2, 0x0800_0024)
    );
    // CMMP-EMCY-05 (a): a second error → its own EMCY; (b) clearing one of two → no EMCY.
    b.node.raise_error(
        &mut b.od,
        0x4310,
        canopen::emcy::register::TEMPERATURE,
        [0; 5],
    );
    let out = b.advance_ms(1);
    assert_eq!(out, vec![frame(0x81, &[0x10, 0x43, 0x0B, 0, 0, 0, 0, 0])]);
    b.node.clear_error(&mut b.od, 0x2312);
    assert!(b.advance_ms(1).is_empty());
    assert_eq!(b.od.get_unsigned(0x1001, 0), Some(0x09));
    // CMMP-EMCY-01: the last one goes → 081: 00 00 00 00 00 00 00 00.
    b.node.clear_error(&mut b.od, 0x4310);
    assert_eq!(b.advance_ms(1), vec![frame(0x81, &[0; 8])]);
    assert_eq!(b.od.get_unsigned(0x1001, 0), Some(0));
    assert_eq!(
        b.sdo1(&[0x40, 0x03, 0x10, 0x00]),
        p8(&[0x4F, 0x03, 0x10, 0x00, 0x02])
    );
}
