//! The CiA 301 side of the Nanotec SMCI47-S (its CANopen reference manual; the vector catalogue
//! kept beside the project, §3.1–3.3 and §3.5): its NT-NODE, NT-SDO, NT-NMT and NT-PDO vectors,
//! each named at its test, frame by frame as the manual prints them (short request frames
//! included), on the device description `devices/nanotec-smci47s.toml` alone. What the drive does
//! with a controlword is the personality's, not tested here.

mod common;
use canopen::{CanFrame, NmtState, NodeEvent};
use common::*;
use od::{ObjectAccess, StorageRequest, Value};

fn smci(node: u8) -> Bench {
    Bench::new(&devices::NANOTEC_SMCI47S, node)
}

/// A remote frame (node guarding request / state query), as the manual's "RTR auf 0x700 +
/// Node-ID" (§9.5 L1770).
fn rtr(b: &mut Bench, id: u16) -> Vec<CanFrame> {
    let f = CanFrame::remote(id, 1);
    let mut out = Vec::new();
    b.node.on_frame(b.now, &f, &mut b.od, &mut |f| out.push(f));
    out
}

fn ok(index: u16, sub: u8) -> [u8; 8] {
    let [i0, i1] = index.to_le_bytes();
    p8(&[0x60, i0, i1, sub])
}

/// What the runtime does for a reset event: reload the stored set, boot again.
fn carry_out_reset(b: &mut Bench) -> Vec<CanFrame> {
    let mut out = Vec::new();
    while let Some(e) = b.node.take_event() {
        if matches!(
            e,
            NodeEvent::ResetApplication | NodeEvent::ResetCommunication
        ) {
            b.node.boot(b.now, &b.od, &mut |f| out.push(f));
        }
    }
    out
}

// ------------------------------------------------------------------------------------------
// 3.1 Node-ID and bit rate (the switch rules are in drive::vendors::nanotec::rotary_switches)

/// NT-NODE-08: node 34 (22h) answers SDOs on 5A2 to requests on 622, error control on 722.
#[test]
fn nt_node_08_cob_ids_of_node_34() {
    let mut b = smci(34);
    let r = b.send(0x622, &[0x40, 0x00, 0x10, 0x00]);
    assert_eq!(
        r,
        vec![frame(0x5A2, &[0x43, 0x00, 0x10, 0x00, 0x08, 0, 0, 0])]
    );
    assert_eq!(rtr(&mut b, 0x722), vec![frame(0x722, &[0x7F])]);
    assert!(
        b.send(0x601, &[0x40, 0x00, 0x10, 0x00]).is_empty(),
        "not node 1"
    );
}

/// NT-NODE-05, NT-NODE-06: 2005h takes the six codes 130…135 (`601: 2F 05 20 00 86` for
/// 500 kbit/s) and refuses anything else.
#[test]
fn nt_node_05_06_bit_rate_object() {
    let mut b = smci(1);
    assert_eq!(
        b.od.value(0x2005, 0),
        Some(Value::Unsigned(135)),
        "default 1 Mbit/s"
    );
    assert_eq!(b.sdo1(&[0x2F, 0x05, 0x20, 0x00, 0x86]), ok(0x2005, 0));
    assert_eq!(b.od.value(0x2005, 0), Some(Value::Unsigned(134)));
    for code in 130..=135u8 {
        assert_eq!(b.sdo1(&[0x2F, 0x05, 0x20, 0x00, code]), ok(0x2005, 0));
    }
    assert_eq!(
        b.sdo1(&[0x2F, 0x05, 0x20, 0x00, 136]),
        abort(0x2005, 0, 0x0609_0031)
    );
    assert_eq!(
        b.sdo1(&[0x2F, 0x05, 0x20, 0x00, 129]),
        abort(0x2005, 0, 0x0609_0032)
    );
}

// ------------------------------------------------------------------------------------------
// 3.2 SDO, store and restore

/// NT-SDO-01: "load" to 1011h:01 → `581: 60 11 10 01 00 00 00 00`; every object back to its
/// default, and the defaults go to EEPROM at once (the runtime does, `restore_writes_stored_set`);
/// 2005h and 2009h are kept.
#[test]
fn nt_sdo_01_restore_defaults() {
    let mut b = smci(1);
    b.sdo1(&[0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03]);
    b.sdo1(&[0x2F, 0x09, 0x20, 0x00, 0x07]);
    b.sdo1(&[0x2F, 0x05, 0x20, 0x00, 0x84]);
    b.sdo1(&[0x2F, 0x04, 0x20, 0x01, 0x32]);
    assert_eq!(
        b.sdo1(&[0x23, 0x11, 0x10, 0x01, 0x6C, 0x6F, 0x61, 0x64]),
        p8(&[0x60, 0x11, 0x10, 0x01, 0, 0, 0, 0])
    );
    assert_eq!(
        b.od.take_request(),
        Some(StorageRequest::Restore { sub: 1 })
    );
    assert!(devices::NANOTEC_SMCI47S.cia301.restore_writes_stored_set);
    assert_eq!(b.od.value(0x1017, 0), Some(Value::Unsigned(0)));
    assert_eq!(b.od.value(0x2004, 1), Some(Value::Unsigned(20)));
    assert_eq!(
        b.od.value(0x2009, 0),
        Some(Value::Unsigned(7)),
        "2009h kept"
    );
    assert_eq!(
        b.od.value(0x2005, 0),
        Some(Value::Unsigned(132)),
        "2005h kept"
    );
}

/// NT-SDO-02: "save" to 1010h:01 → `581: 60 10 10 01 00 00 00 00`; the runtime stores.
#[test]
fn nt_sdo_02_store_parameters() {
    let mut b = smci(1);
    assert_eq!(
        b.sdo1(&[0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65]),
        p8(&[0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0])
    );
    assert_eq!(b.od.take_request(), Some(StorageRequest::Save { sub: 1 }));
    // Everything a master sets is in the saved set; commands are not (file header).
    let saved: Vec<(u16, u8)> =
        b.od.storable_values(1)
            .map(|(e, _)| (e.index, e.sub))
            .collect();
    for key in [
        (0x1800, 3),
        (0x1600, 1),
        (0x2005, 0),
        (0x2009, 0),
        (0x6092, 1),
    ] {
        assert!(saved.contains(&key), "{key:04X?} saved");
    }
    for key in [(0x6040, 0), (0x607A, 0), (0x60C1, 1), (0x6041, 0)] {
        assert!(!saved.contains(&key), "{key:04X?} not saved");
    }
}

/// NT-SDO-03: 2005h := 132, restore, read 2005h → `581: 4F 05 20 00 84 00 00 00`.
#[test]
fn nt_sdo_03_restore_keeps_the_bit_rate() {
    let mut b = smci(1);
    assert_eq!(b.sdo1(&[0x2F, 0x05, 0x20, 0x00, 0x84]), ok(0x2005, 0));
    assert_eq!(
        b.sdo1(&[0x23, 0x11, 0x10, 0x01, 0x6C, 0x6F, 0x61, 0x64]),
        ok(0x1011, 1)
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x05, 0x20, 0x00]),
        p8(&[0x4F, 0x05, 0x20, 0x00, 0x84, 0, 0, 0])
    );
}

/// NT-SDO-04: `601: 40 00 21 00` (2100h is not in the dictionary) → `581: 80 00 21 00 00 00 02 06`.
#[test]
fn nt_sdo_04_unknown_object() {
    let mut b = smci(1);
    assert_eq!(
        b.sdo1(&[0x40, 0x00, 0x21, 0x00]),
        p8(&[0x80, 0x00, 0x21, 0x00, 0x00, 0x00, 0x02, 0x06])
    );
}

/// The manual's MiniMon requests are short frames (§2.4 L505–528: DLC 6, DLC 4; §2.5: DLC 5):
/// accepted, and always answered with DLC 8.
#[test]
fn short_request_frames_as_the_manual_sends_them() {
    let mut b = smci(34);
    let r = b.send(0x622, &[0x2B, 0x40, 0x60, 0x00, 0x06, 0x00]);
    assert_eq!(r, vec![frame(0x5A2, &[0x60, 0x40, 0x60, 0x00, 0, 0, 0, 0])]);
    assert_eq!(b.od.value(0x6040, 0), Some(Value::Unsigned(6)));
    b.od.set_value(0x6041, 0, Value::Unsigned(0x0221)).unwrap();
    let r = b.send(0x622, &[0x40, 0x41, 0x60, 0x00]);
    assert_eq!(
        r,
        vec![frame(0x5A2, &[0x4B, 0x41, 0x60, 0x00, 0x21, 0x02, 0, 0])]
    );
    let r = b.send(0x622, &[0x2F, 0x60, 0x60, 0x00, 0x01]);
    assert_eq!(r, vec![frame(0x5A2, &[0x60, 0x60, 0x60, 0x00, 0, 0, 0, 0])]);
    assert_eq!(b.od.value(0x6060, 0), Some(Value::Signed(1)));
}

// ------------------------------------------------------------------------------------------
// 3.3 NMT and error control

/// NT-NMT-01: MiniMon `0 1 22` = `000: 01 22` → node 34 Operational, state 05h on 722.
#[test]
fn nt_nmt_01_start_node_34() {
    let mut b = smci(34);
    assert_eq!(b.send(0x000, &[0x01, 0x22]), vec![frame(0x722, &[0x05])]);
    assert_eq!(b.node.nmt_state(), NmtState::Operational);
    assert_eq!(rtr(&mut b, 0x722), vec![frame(0x722, &[0x05])]);
}

/// NT-NMT-02: `000: 02 22` Stopped (04h); `000: 80 22` Pre-Operational (7Fh); `000: 81 22` and
/// `000: 82 22` restart with the settings last stored, then Pre-Operational (7Fh).
///
/// Decision: §2.2 (L459–465) gives 82h the text of 81h ("firmware restart, all CANopen
/// settings reset to the values last stored in EEPROM"); the twin follows CiA 301: 81h resets
/// the application (every object from the stored set), 82h the communication (1000h–1FFFh
/// from the stored set, `can/drive.rs`), which are "all CANopen settings" (docs/decisions.md).
#[test]
fn nt_nmt_02_node_control_commands() {
    let mut b = smci(34);
    assert_eq!(b.send(0x000, &[0x02, 0x22]), vec![frame(0x722, &[0x04])]);
    assert_eq!(b.node.nmt_state(), NmtState::Stopped);
    assert_eq!(b.send(0x000, &[0x80, 0x22]), vec![frame(0x722, &[0x7F])]);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    for cs in [0x81, 0x82] {
        b.events();
        assert!(b.send(0x000, &[cs, 0x22]).is_empty());
        let expected = if cs == 0x81 {
            NodeEvent::ResetApplication
        } else {
            NodeEvent::ResetCommunication
        };
        assert_eq!(b.node.take_event(), Some(expected));
        let mut out = Vec::new();
        b.node.boot(b.now, &b.od, &mut |f| out.push(f));
        assert_eq!(out, vec![frame(0x722, &[0x00])], "boot-up (CiA 301)");
        assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
        assert_eq!(rtr(&mut b, 0x722), vec![frame(0x722, &[0x7F])]);
    }
}

/// NT-NMT-03: after power-on, `RTR 722` → `722: 7F`. Decision: the manual describes no toggle
/// bit (§2.3, L467–488); the twin keeps CiA 301's toggle in bit 7, which starts at 0, so the
/// first answer is the manual's 7Fh and the second 0xFF.
#[test]
fn nt_nmt_03_state_query_by_rtr() {
    let mut b = smci(34);
    assert_eq!(rtr(&mut b, 0x722), vec![frame(0x722, &[0x7F])]);
    assert_eq!(rtr(&mut b, 0x722), vec![frame(0x722, &[0xFF])]);
}

/// NT-NMT-04: Stopped: `622: 40 41 60 00` gets no answer; RPDOs are not applied.
#[test]
fn nt_nmt_04_stopped_serves_neither_sdo_nor_pdo() {
    let mut b = smci(34);
    b.send(0x000, &[0x01, 0x22]);
    b.send(0x000, &[0x02, 0x22]);
    assert!(b.send(0x622, &[0x40, 0x41, 0x60, 0x00]).is_empty());
    assert!(b.send(0x222, &[0x0F, 0x00]).is_empty());
    assert_eq!(b.od.value(0x6040, 0), Some(Value::Unsigned(0)));
    assert!(b.advance_ms(500).is_empty(), "no TPDO in Stopped");
}

/// NT-NMT-05: `000: 80 01` → `701: 7F`.
#[test]
fn nt_nmt_05_pre_operational_answer() {
    let mut b = smci(1);
    assert_eq!(b.send(0x000, &[0x80, 0x01]), vec![frame(0x701, &[0x7F])]);
}

/// NT-NMT-06: `000: 01 01` → `701: 05` (DLC 1; the manual prints "5"), then TPDO1.
#[test]
fn nt_nmt_06_operational_answer() {
    let mut b = smci(1);
    let r = b.send(0x000, &[0x01, 0x01]);
    assert_eq!(r, vec![frame(0x701, &[0x05])]);
    assert_eq!(r[0].len, 1);
}

/// NT-NMT-07: `601: 2B 17 10 00 E8 03` (1000 ms) → `581: 60 17 10 00 00 00 00 00`, then
/// `701: 7F` every 1000 ms in Pre-Operational; 0 switches it off.
#[test]
fn nt_nmt_07_heartbeat() {
    let mut b = smci(1);
    assert_eq!(b.sdo1(&[0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03]), ok(0x1017, 0));
    assert!(b.advance_ms(999).is_empty());
    assert_eq!(b.advance_ms(1), vec![frame(0x701, &[0x7F])]);
    assert!(b.advance_ms(999).is_empty());
    assert_eq!(b.advance_ms(1), vec![frame(0x701, &[0x7F])]);
    assert_eq!(b.sdo1(&[0x2B, 0x17, 0x10, 0x00, 0x00, 0x00]), ok(0x1017, 0));
    assert!(b.advance_ms(5000).is_empty());
}

/// NT-NMT-08: guard time 100 ms, life time factor 3; the RTRs stop → after 300 ms the
/// lifeguard error, Nanotec EMCY code 0004h (§13.3 L4275): `081: 04 00 11 00 00 00 00 00`
/// (error register: generic + communication, byte 3 unused).
#[test]
fn nt_nmt_08_life_guarding_error() {
    let mut b = smci(1);
    assert_eq!(b.sdo1(&[0x2B, 0x0C, 0x10, 0x00, 0x64, 0x00]), ok(0x100C, 0));
    assert_eq!(b.sdo1(&[0x2F, 0x0D, 0x10, 0x00, 0x03]), ok(0x100D, 0));
    assert_eq!(rtr(&mut b, 0x701), vec![frame(0x701, &[0x7F])]);
    assert!(b.advance_ms(299).is_empty());
    assert_eq!(
        b.advance_ms(1),
        vec![frame(0x081, &[0x04, 0x00, 0x11, 0x00, 0, 0, 0, 0])]
    );
    assert!(b.events().contains(&NodeEvent::LifeGuardingLost));
    assert_eq!(b.od.value(0x1001, 0), Some(Value::Unsigned(0x11)));
    // The next request ends the error: EMCY 0000h.
    let r = rtr(&mut b, 0x701);
    assert_eq!(r, vec![frame(0x701, &[0xFF])]);
    assert_eq!(
        b.advance_ms(1),
        vec![frame(0x081, &[0x00, 0x00, 0x00, 0x00, 0, 0, 0, 0])]
    );
}

// ------------------------------------------------------------------------------------------
// 3.5 PDO mapping (§12.2, node 1)

/// NT-PDO-01 … NT-PDO-11: the manual's RPDO1 re-mapping, frame by frame; where it prints a
/// frame wrong (NT-PDO-07's answer, NT-PDO-08's command byte) the corrected one, see below.
fn remap_rpdo1(b: &mut Bench) {
    // NT-PDO-01
    assert_eq!(b.send(0x000, &[0x80, 0x01]), vec![frame(0x701, &[0x7F])]);
    // NT-PDO-02
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x14, 0x01, 0x00, 0x00, 0x00, 0x80]),
        ok(0x1400, 1)
    );
    // NT-PDO-03
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x14, 0x01, 0x01, 0x02, 0x00, 0x80]),
        ok(0x1400, 1)
    );
    // NT-PDO-04
    assert_eq!(
        b.sdo1(&[0x2F, 0x00, 0x14, 0x02, 0xFF, 0x00, 0x00, 0x00]),
        ok(0x1400, 2)
    );
    // NT-PDO-05
    assert_eq!(
        b.sdo1(&[0x2F, 0x00, 0x16, 0x00, 0x00, 0x00, 0x00, 0x00]),
        ok(0x1600, 0)
    );
    // NT-PDO-06: the length bits 7–0 are left 0, the firmware fills them in.
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x16, 0x01, 0x00, 0x00, 0x40, 0x60]),
        ok(0x1600, 1)
    );
    // NT-PDO-07 (corrected): the manual prints the answer as `60 00 16 00 01 00 00 00`; bytes
    // 4–7 of a download response are reserved (CiA 301 §7.2.4.3.3) and go out as 00.
    assert_eq!(
        b.sdo1(&[0x2F, 0x00, 0x16, 0x00, 0x01, 0x00, 0x00, 0x00]),
        p8(&[0x60, 0x00, 0x16, 0x00, 0, 0, 0, 0])
    );
    // NT-PDO-08 (corrected): command 23h for the UNSIGNED32 COB-ID (the manual prints 2Fh).
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x14, 0x01, 0x01, 0x02, 0x00, 0x00]),
        ok(0x1400, 1)
    );
    // NT-PDO-09
    assert_eq!(b.send(0x000, &[0x01, 0x01]), vec![frame(0x701, &[0x05])]);
}

#[test]
fn nt_pdo_01_to_10_rpdo1_remapping_as_printed() {
    let mut b = smci(1);
    remap_rpdo1(&mut b);
    // NT-PDO-10: the optional store.
    assert_eq!(
        b.sdo1(&[0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65]),
        p8(&[0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0])
    );
    assert_eq!(b.od.take_request(), Some(StorageRequest::Save { sub: 1 }));
}

/// NT-PDO-08 as printed: command 2Fh (one byte) for a four-byte COB-ID. Decision: CiA 301 wins over
/// the example (the vector catalogue kept beside the project, §5.3 corrects it): the size the
/// client indicates is the size written, so the frame is refused with 0607 0013h and RPDO1 stays
/// disabled.
#[test]
fn nt_pdo_08_printed_command_byte_is_refused() {
    let mut b = smci(1);
    b.send(0x000, &[0x80, 0x01]);
    b.sdo1(&[0x23, 0x00, 0x14, 0x01, 0x01, 0x02, 0x00, 0x80]);
    assert_eq!(
        b.sdo1(&[0x2F, 0x00, 0x14, 0x01, 0x01, 0x02, 0x00, 0x00]),
        abort(0x1400, 1, 0x0607_0013)
    );
    assert_eq!(b.od.get_unsigned(0x1400, 1).map(|v| v >> 31), Some(1));
}

/// NT-PDO-11: after NT-PDO-06, `601: 40 00 16 01` → `581: 43 00 16 01 10 00 40 60` (60400010h).
#[test]
fn nt_pdo_11_firmware_filled_in_the_length() {
    let mut b = smci(1);
    remap_rpdo1(&mut b);
    b.send(0x000, &[0x80, 0x01]);
    assert_eq!(
        b.sdo1(&[0x40, 0x00, 0x16, 0x01]),
        p8(&[0x43, 0x00, 0x16, 0x01, 0x10, 0x00, 0x40, 0x60])
    );
}

/// NT-PDO-12: after the re-mapping, in Operational, `201: 0F 00` sets the controlword to 000Fh
/// at once (transmission type 255).
#[test]
fn nt_pdo_12_rpdo1_applies_at_once() {
    let mut b = smci(1);
    remap_rpdo1(&mut b);
    assert!(b.send(0x201, &[0x0F, 0x00]).is_empty());
    assert_eq!(b.od.value(0x6040, 0), Some(Value::Unsigned(0x000F)));
}

/// NT-PDO-13: the default TPDO1 carries the statusword, is sent on every change (TT 255) and
/// keeps the default inhibit time of 1000 × 100 µs: two changes 30 ms apart go out 100 ms
/// apart, one TPDO each; a change inside the inhibit time waits, the newest value goes.
#[test]
fn nt_pdo_13_statusword_on_change_with_100_ms_inhibit() {
    let mut b = smci(1);
    assert_eq!(b.od.value(0x1800, 3), Some(Value::Unsigned(1000)));
    b.od.set_value(0x6041, 0, Value::Unsigned(0x0260)).unwrap();
    let r = b.send(0x000, &[0x01, 0x01]);
    assert_eq!(r, vec![frame(0x701, &[0x05])]);
    // Operational: the first TPDO goes out at once.
    assert_eq!(b.advance_ms(0), vec![frame(0x181, &[0x60, 0x02])]);
    assert!(b.advance_ms(200).is_empty(), "no change, no TPDO");
    b.od.set_value(0x6041, 0, Value::Unsigned(0x0221)).unwrap();
    assert_eq!(b.advance_ms(1), vec![frame(0x181, &[0x21, 0x02])]);
    // Sent at t = 201 ms; the next change at 230 ms waits until 301 ms.
    b.advance_ms(29);
    b.od.set_value(0x6041, 0, Value::Unsigned(0x0233)).unwrap();
    let mut sent = Vec::new();
    for _ in 0..70 {
        sent.extend(b.advance_ms(1));
    }
    assert!(
        sent.is_empty(),
        "held back by the inhibit time: {sent:02X?}"
    );
    assert_eq!(b.advance_ms(1), vec![frame(0x181, &[0x33, 0x02])]);
    // Two changes inside one inhibit time: only the newest value goes out.
    b.od.set_value(0x6041, 0, Value::Unsigned(0x0237)).unwrap();
    b.advance_ms(10);
    b.od.set_value(0x6041, 0, Value::Unsigned(0x0637)).unwrap();
    let mut sent = Vec::new();
    for _ in 0..100 {
        sent.extend(b.advance_ms(1));
    }
    assert_eq!(sent, vec![frame(0x181, &[0x37, 0x06])]);
}

// ------------------------------------------------------------------------------------------
// PDO rules of the manual beyond the example

/// Dummy objects 0002h–0007h map into RPDOs and skip bytes (§12.3); 0001h cannot be mapped
/// (§9.44 L2790); dummies are no TPDO content.
#[test]
fn dummy_objects_in_rpdos() {
    let mut b = smci(1);
    // RPDO2: an s32 dummy masking the other axis, then this axis' set-point (§7.9).
    assert_eq!(
        b.sdo1(&[0x23, 0x01, 0x14, 0x01, 0x01, 0x03, 0x00, 0x80]),
        ok(0x1401, 1)
    );
    assert_eq!(
        b.sdo1(&[0x23, 0x01, 0x16, 0x01, 0x20, 0x00, 0x04, 0x00]),
        ok(0x1601, 1)
    );
    assert_eq!(
        b.sdo1(&[0x23, 0x01, 0x16, 0x02, 0x00, 0x01, 0xC1, 0x60]),
        ok(0x1601, 2)
    );
    assert_eq!(b.sdo1(&[0x2F, 0x01, 0x16, 0x00, 0x02]), ok(0x1601, 0));
    assert_eq!(
        b.od.get_unsigned(0x1601, 2),
        Some(0x60C1_0120),
        "length filled in"
    );
    assert_eq!(
        b.sdo1(&[0x23, 0x01, 0x14, 0x01, 0x01, 0x03, 0x00, 0x00]),
        ok(0x1401, 1)
    );
    b.send(0x000, &[0x01, 0x01]);
    b.send(0x301, &[0xAA, 0xBB, 0xCC, 0xDD, 0x10, 0x00, 0x00, 0x00]);
    assert_eq!(b.od.value(0x60C1, 1), Some(Value::Signed(16)));
    b.send(0x000, &[0x80, 0x01]);
    // Every dummy type 0002h…0007h, with or without its length.
    b.sdo1(&[0x23, 0x01, 0x14, 0x01, 0x01, 0x03, 0x00, 0x80]);
    b.sdo1(&[0x2F, 0x01, 0x16, 0x00, 0x00]);
    for (i, bits) in [(2u8, 8u8), (3, 16), (5, 8), (6, 0), (7, 0)] {
        assert_eq!(
            b.sdo1(&[0x23, 0x01, 0x16, 0x01, bits, 0x00, i, 0x00]),
            ok(0x1601, 1),
            "dummy {i:04X}h"
        );
    }
    // 0001h (BOOLEAN) is not mappable, in either length.
    for bits in [0u8, 1, 8] {
        assert_eq!(
            b.sdo1(&[0x23, 0x01, 0x16, 0x01, bits, 0x00, 0x01, 0x00]),
            abort(0x1601, 1, 0x0604_0041)
        );
    }
    // No dummy in a TPDO.
    b.sdo1(&[0x23, 0x01, 0x18, 0x01, 0x81, 0x02, 0x00, 0x80]);
    b.sdo1(&[0x2F, 0x01, 0x1A, 0x00, 0x00]);
    assert_eq!(
        b.sdo1(&[0x23, 0x01, 0x1A, 0x01, 0x10, 0x00, 0x03, 0x00]),
        abort(0x1A01, 1, 0x0604_0041)
    );
    // The dummies are objects too: SDO writes have no other effect.
    assert_eq!(b.sdo1(&[0x2B, 0x03, 0x00, 0x00, 0x34, 0x12]), ok(0x0003, 0));
}

/// A mapping longer than 8 bytes is refused when it is activated (§2.6: 8 bytes at most):
/// 0604 0042h, the PDO keeps its old (empty) mapping.
#[test]
fn mapping_longer_than_eight_bytes_is_refused() {
    let mut b = smci(1);
    b.sdo1(&[0x23, 0x01, 0x18, 0x01, 0x81, 0x02, 0x00, 0x80]);
    for (sub, (lo, hi)) in [(0x64u8, 0x60u8), (0x62, 0x60), (0x41, 0x60)]
        .into_iter()
        .enumerate()
    {
        b.sdo1(&[0x23, 0x01, 0x1A, sub as u8 + 1, 0x00, 0x00, lo, hi]);
    }
    assert_eq!(
        b.sdo1(&[0x2F, 0x01, 0x1A, 0x00, 0x03]),
        abort(0x1A01, 0, 0x0604_0042)
    );
    assert_eq!(b.od.value(0x1A01, 0), Some(Value::Unsigned(0)));
    assert_eq!(b.sdo1(&[0x2F, 0x01, 0x1A, 0x00, 0x02]), ok(0x1A01, 0));
}

/// Transmission types: 0…240 and 255 (§9.10–9.21); 241…254 are refused with 0609 0030h.
/// An RPDO with type 0…240 takes effect at the next SYNC, with 255 at once.
#[test]
fn transmission_types_and_synchronous_rpdo() {
    let mut b = smci(1);
    b.sdo1(&[0x23, 0x00, 0x14, 0x01, 0x01, 0x02, 0x00, 0x80]);
    for tt in [241u8, 252, 254] {
        assert_eq!(
            b.sdo1(&[0x2F, 0x00, 0x14, 0x02, tt]),
            abort(0x1400, 2, 0x0609_0030),
            "type {tt}"
        );
        assert_eq!(
            b.sdo1(&[0x2F, 0x00, 0x18, 0x02, tt]),
            abort(0x1800, 2, 0x0609_0030),
            "type {tt}"
        );
    }
    assert_eq!(b.sdo1(&[0x2F, 0x00, 0x14, 0x02, 0x00]), ok(0x1400, 2));
    b.sdo1(&[0x23, 0x00, 0x14, 0x01, 0x01, 0x02, 0x00, 0x00]);
    b.send(0x000, &[0x01, 0x01]);
    b.send(0x201, &[0x06, 0x00]);
    assert_eq!(
        b.od.value(0x6040, 0),
        Some(Value::Unsigned(0)),
        "waits for SYNC"
    );
    b.send(0x080, &[]);
    assert_eq!(
        b.od.value(0x6040, 0),
        Some(Value::Unsigned(6)),
        "applied at SYNC"
    );
}

/// PDO parameters are written in Pre-Operational (§12.2 L4149): in Operational they are
/// refused with 0800 0022h.
#[test]
fn pdo_parameters_only_outside_operational() {
    let mut b = smci(1);
    b.send(0x000, &[0x01, 0x01]);
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x14, 0x01, 0x00, 0x00, 0x00, 0x80]),
        abort(0x1400, 1, 0x0800_0022)
    );
}

/// The PDO default COB-IDs follow the node-ID only when the defaults are loaded (§9.10:
/// "nicht durch Ändern der Node-ID wirksam, sondern nur durch einen EEPROM-Reset"): a node-ID
/// change leaves them; a restore takes the node-ID of that moment.
#[test]
fn default_cob_ids_follow_the_node_id_at_restore_only() {
    let mut b = smci(1);
    assert_eq!(b.od.get_unsigned(0x1800, 1), Some(0x181));
    b.od.set_node_id(5);
    b.node.set_node_id(5);
    assert_eq!(b.od.get_unsigned(0x1800, 1), Some(0x181), "unchanged");
    assert_eq!(b.od.get_unsigned(0x1400, 1), Some(0x201), "unchanged");
    b.sdo1(&[0x23, 0x11, 0x10, 0x01, 0x6C, 0x6F, 0x61, 0x64]);
    for (index, base) in [
        (0x1400u16, 0x200u64),
        (0x1401, 0x300),
        (0x1402, 0x400),
        (0x1403, 0x500),
        (0x1800, 0x180),
        (0x1801, 0x280),
        (0x1802, 0x380),
        (0x1803, 0x480),
    ] {
        assert_eq!(b.od.get_unsigned(index, 1), Some(base + 5), "{index:04X}h");
    }
}

/// Decision (device file): the manual never names LSS, so the Nanotec does not answer it: an
/// "identify remote slave" / switch-state-global on 7E5h gets nothing back.
#[test]
fn no_lss_on_the_nanotec() {
    let mut b = smci(1);
    assert!(b.send(0x7E5, &[0x04, 0x01, 0, 0, 0, 0, 0, 0]).is_empty());
    assert!(b.send(0x7E5, &[0x5E, 0, 0, 0, 0, 0, 0, 0]).is_empty());
    assert!(b.send(0x7E5, &[0x11, 0x05, 0, 0, 0, 0, 0, 0]).is_empty());
    assert_eq!(b.node.node_id(), 1);
}

/// An NMT reset reloads what was last stored: the runtime's part (carry_out_reset) boots the
/// node again on the same dictionary.
#[test]
fn nmt_reset_boots_again() {
    let mut b = smci(1);
    b.send(0x000, &[0x01, 0x01]);
    b.send(0x000, &[0x81, 0x01]);
    assert_eq!(carry_out_reset(&mut b), vec![frame(0x701, &[0x00])]);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
}

// ------------------------------------------------------------------------------------------
// The SDO abort codes of §16, each for its cause

#[test]
fn sdo_abort_codes_for_their_causes() {
    let mut b = smci(1);
    // 0504 0001h: an unknown command specifier.
    assert_eq!(
        b.sdo1(&[0xE0, 0x00, 0x10, 0x00]),
        abort(0x1000, 0, 0x0504_0001)
    );
    // 0601 0002h: write to a read-only object (statusword, device type).
    assert_eq!(
        b.sdo1(&[0x2B, 0x41, 0x60, 0x00, 0x00, 0x00]),
        abort(0x6041, 0, 0x0601_0002)
    );
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x10, 0x00, 0, 0, 0, 0]),
        abort(0x1000, 0, 0x0601_0002)
    );
    // 0602 0000h: no such object.
    assert_eq!(
        b.sdo1(&[0x40, 0x16, 0x10, 0x00]),
        abort(0x1016, 0, 0x0602_0000)
    );
    // 0609 0011h: no such sub-index.
    assert_eq!(
        b.sdo1(&[0x40, 0x18, 0x10, 0x05]),
        abort(0x1018, 5, 0x0609_0011)
    );
    // 0607 0012h / 0607 0013h: too many / too few bytes for the type.
    assert_eq!(
        b.sdo1(&[0x23, 0x40, 0x60, 0x00, 0, 0, 0, 0]),
        abort(0x6040, 0, 0x0607_0012)
    );
    assert_eq!(
        b.sdo1(&[0x2F, 0x7A, 0x60, 0x00, 0x01]),
        abort(0x607A, 0, 0x0607_0013)
    );
    // 0609 0031h / 0609 0032h: above / below the range (607Ah ±100000000, 6060h −2…7).
    assert_eq!(
        b.sdo1(&[0x23, 0x7A, 0x60, 0x00, 0x01, 0xE1, 0xF5, 0x05]),
        abort(0x607A, 0, 0x0609_0031)
    );
    assert_eq!(
        b.sdo1(&[0x2F, 0x60, 0x60, 0x00, 0xFD]),
        abort(0x6060, 0, 0x0609_0032)
    );
    // 0800 0020h: a wrong store signature (CiA 301 §7.5.2.13).
    assert_eq!(
        b.sdo1(&[0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x64]),
        abort(0x1010, 1, 0x0800_0020)
    );
    // 0604 0041h: the object cannot be mapped (6085h, the quick-stop deceleration).
    b.sdo1(&[0x23, 0x01, 0x18, 0x01, 0x81, 0x02, 0x00, 0x80]);
    b.sdo1(&[0x2F, 0x01, 0x1A, 0x00, 0x00]);
    assert_eq!(
        b.sdo1(&[0x23, 0x01, 0x1A, 0x01, 0x20, 0x00, 0x85, 0x60]),
        abort(0x1A01, 1, 0x0604_0041)
    );
    // 0601 0000h: a mapping entry changed while the PDO is valid (TPDO1).
    assert_eq!(
        b.sdo1(&[0x23, 0x00, 0x1A, 0x01, 0x20, 0x00, 0x64, 0x60]),
        abort(0x1A00, 1, 0x0601_0000)
    );
    // 0503 0000h: a segment with the wrong toggle bit (a segmented download to 2021h).
    assert_eq!(
        b.sdo1(&[0x21, 0x21, 0x20, 0x00, 0x04, 0, 0, 0]),
        ok(0x2021, 0)
    );
    assert_eq!(
        b.sdo1(&[0x10, 0x01, 0x02, 0x03, 0x04, 0, 0, 0]),
        abort(0x2021, 0, 0x0503_0000)
    );
    // 0504 0000h: the client falls silent in a transfer.
    assert_eq!(
        b.sdo1(&[0x21, 0x21, 0x20, 0x00, 0x04, 0, 0, 0]),
        ok(0x2021, 0)
    );
    let r = b.advance_ms(2000);
    assert_eq!(
        r,
        vec![CanFrame::full(0x581, abort(0x2021, 0, 0x0504_0000))]
    );
    // 0609 0036h: VL max amount below the min amount (6046h, §6.6).
    assert_eq!(
        b.sdo1(&[0x23, 0x46, 0x60, 0x01, 30, 0, 0, 0]),
        ok(0x6046, 1)
    );
    assert_eq!(
        b.sdo1(&[0x23, 0x46, 0x60, 0x02, 20, 0, 0, 0]),
        abort(0x6046, 2, 0x0609_0036)
    );
    assert_eq!(b.od.value(0x6046, 2), Some(Value::Unsigned(25000)));
    // 0609 0030h: a 60FEh:02 mask with a bit outside 16…18 is discarded (§9.3 L1727); the
    // reserved bits 0…5 of the polarity 607Eh.
    assert_eq!(
        b.sdo1(&[0x23, 0xFE, 0x60, 0x02, 0x00, 0x00, 0x08, 0x00]),
        abort(0x60FE, 2, 0x0609_0030)
    );
    assert_eq!(b.od.value(0x60FE, 2), Some(Value::Unsigned(0x0007_0000)));
    assert_eq!(
        b.sdo1(&[0x23, 0xFE, 0x60, 0x02, 0x00, 0x00, 0x05, 0x00]),
        ok(0x60FE, 2)
    );
    assert_eq!(
        b.sdo1(&[0x2F, 0x7E, 0x60, 0x00, 0x01]),
        abort(0x607E, 0, 0x0609_0030)
    );
    assert_eq!(b.sdo1(&[0x2F, 0x7E, 0x60, 0x00, 0xC0]), ok(0x607E, 0));
    // 0504 0002h: a block upload with block size 0.
    assert_eq!(
        b.sdo1(&[0xA0, 0x21, 0x20, 0x00, 0x00, 0x00, 0, 0]),
        abort(0x2021, 0, 0x0504_0002)
    );
    // 0504 0003h: a block download segment with sequence number 0.
    assert_eq!(
        b.sdo1(&[0xC6, 0x21, 0x20, 0x00, 0x04, 0, 0, 0]),
        p8(&[0xA4, 0x21, 0x20, 0x00, 127, 0, 0, 0])
    );
    assert_eq!(
        b.sdo1(&[0x00, 1, 2, 3, 4, 0, 0, 0]),
        abort(0x2021, 0, 0x0504_0003)
    );
    // 0504 0004h: a block download whose CRC does not match.
    b.sdo1(&[0xC6, 0x21, 0x20, 0x00, 0x04, 0, 0, 0]);
    assert_eq!(
        b.sdo1(&[0x81, 1, 2, 3, 4, 0, 0, 0]),
        p8(&[0xA2, 1, 127, 0, 0, 0, 0, 0])
    );
    assert_eq!(
        b.sdo1(&[0xCD, 0xAD, 0xDE, 0, 0, 0, 0, 0]),
        abort(0x2021, 0, 0x0504_0004)
    );
    assert_eq!(
        b.od.value(0x2021, 0),
        Some(Value::Unsigned(0)),
        "old value kept"
    );
    // 0604 0043h: guard time × life time factor beyond one minute (§11.23 L3822).
    assert_eq!(b.sdo1(&[0x2B, 0x0C, 0x10, 0x00, 0x60, 0xEA]), ok(0x100C, 0));
    assert_eq!(b.sdo1(&[0x2F, 0x0D, 0x10, 0x00, 0x01]), ok(0x100D, 0));
    assert_eq!(
        b.sdo1(&[0x2F, 0x0D, 0x10, 0x00, 0x02]),
        abort(0x100D, 0, 0x0604_0043)
    );
    assert_eq!(
        b.sdo1(&[0x2B, 0x0C, 0x10, 0x00, 0x61, 0xEA]),
        abort(0x100C, 0, 0x0604_0043)
    );
    assert_eq!(b.od.value(0x100D, 0), Some(Value::Unsigned(1)));
    // 0800 0022h: PDO parameters in Operational (pdo_parameters_only_outside_operational).
    b.send(0x000, &[0x01, 0x01]);
    assert_eq!(
        b.sdo1(&[0x2F, 0x00, 0x18, 0x02, 0x01]),
        abort(0x1800, 2, 0x0800_0022)
    );
}

/// The strings 1009h and 100Ah in Nanotec's layout (§11.20, §11.21): sub 0 the length, then
/// one character per sub-index.
#[test]
fn version_strings_one_character_per_sub_index() {
    let mut b = smci(1);
    let len = b.od.get_unsigned(0x100A, 0).unwrap() as u8;
    let text: String = (1..=len)
        .map(|s| b.od.get_unsigned(0x100A, s).unwrap() as u8 as char)
        .collect();
    assert_eq!(text, "24-10-2011");
    assert_eq!(
        b.sdo1(&[0x40, 0x09, 0x10, 0x00]),
        p8(&[0x4F, 0x09, 0x10, 0x00, 3, 0, 0, 0])
    );
    assert_eq!(
        b.sdo1(&[0x40, 0x09, 0x10, 0x01]),
        p8(&[0x4F, 0x09, 0x10, 0x01, b'1', 0, 0, 0])
    );
    let mut buf = [0u8; 8];
    assert_eq!(
        b.od.read(0x1009, 4, &mut buf),
        Err(od::AbortCode::NO_SUB_INDEX)
    );
}

/// PDOs 2–4 default to valid COB-IDs with nothing mapped (§9.11–9.21 print 0x300 + node-ID
/// and no mapping): a master that disables and writes them back as it read them (python-canopen's
/// `PdoMap.save`) is not refused; an empty PDO carries nothing.
#[test]
fn empty_pdo_may_be_valid_again() {
    let mut b = smci(1);
    assert_eq!(b.od.get_unsigned(0x1401, 1), Some(0x301));
    assert_eq!(b.od.get_unsigned(0x1601, 0), Some(0));
    b.sdo1(&[0x23, 0x01, 0x14, 0x01, 0x01, 0x03, 0x00, 0x80]);
    assert_eq!(
        b.sdo1(&[0x23, 0x01, 0x14, 0x01, 0x01, 0x03, 0x00, 0x00]),
        ok(0x1401, 1)
    );
    b.send(0x000, &[0x01, 0x01]);
    assert!(b.send(0x301, &[1, 2, 3, 4]).is_empty());
    let frames = b.advance_ms(300);
    assert!(
        frames.iter().all(|f| f.id == 0x181),
        "only TPDO1 goes out: {frames:02X?}"
    );
}
