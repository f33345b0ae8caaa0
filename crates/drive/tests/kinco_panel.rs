//! The Kinco LED panel (Kinco CD3 / FD3 manual ch. 4, ch. 9): the manual's key sequences on a Kinco
//! FD3.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod kinco_rig;

use drive::device_control::State;
use drive::vendors::kinco::panel::{Blink, PanelKey, DOT3, DOT4, DOT5};
use kinco_rig::Rig;
use od::ObjectAccess;

/// A short press (down, 50 ms, up).
fn press(r: &mut Rig, key: PanelKey) {
    r.d.kinco_panel_key(key, true);
    r.run_ms(50);
    r.d.kinco_panel_key(key, false);
    r.run_ms(10);
}

fn presses(r: &mut Rig, key: PanelKey, n: usize) {
    for _ in 0..n {
        press(r, key);
    }
}

fn text(r: &Rig) -> String {
    r.d.kinco_panel().text().to_string()
}

/// Browses menu `f` (1…9 = F001…tunE) from the monitor display to panel address `key`.
fn browse_to(r: &mut Rig, f: usize, key: &str) {
    presses(r, PanelKey::Mode, f);
    press(r, PanelKey::Set);
    for _ in 0..200 {
        if text(r).replace(' ', "") == key {
            return;
        }
        press(r, PanelKey::Up);
    }
    panic!("{key} not found, at {}", text(r));
}

/// §4, §9.1: after power-up the monitor display shows d1.25 Real_Speed_RPM; MODE steps
/// through F001…F007, EASY, tunE and back.
#[test]
fn monitor_and_menu_order() {
    let mut r = Rig::new();
    assert_eq!(text(&r), "    0");
    let mut seen = Vec::new();
    for _ in 0..10 {
        press(&mut r, PanelKey::Mode);
        seen.push(text(&r).trim().to_string());
    }
    assert_eq!(
        seen,
        ["F001", "F002", "F003", "F004", "F005", "F006", "F007", "EASY", "tunE", "0"]
    );
}

/// §4.3.3 step 2 / §9.3 d3.47: F003 → d3.47 Jog_RPM, SET shows 30, MODE moves to the tens
/// digit, ▲ twice, SET: 2FF0h:23 = 50 through the object write, point 5 lit.
#[test]
fn f003_edits_jog_rpm_through_the_object_write() {
    let mut r = Rig::new();
    browse_to(&mut r, 3, "d3.47");
    assert_eq!(
        r.d.kinco_panel().dots,
        DOT3,
        "point 3 separates group and address"
    );
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r), "   30");
    press(&mut r, PanelKey::Mode);
    assert_eq!(r.d.kinco_panel().cursor, Some(4));
    presses(&mut r, PanelKey::Up, 2);
    assert_eq!(text(&r), "   50");
    press(&mut r, PanelKey::Set);
    assert_eq!(r.i(0x2FF0, 0x23), 50);
    assert_eq!(text(&r), " d3.47.");
    assert_eq!(r.d.kinco_panel().dots & DOT5, DOT5);
}

/// A value out of range is refused as over the bus: Notch_N d2.03 (0…127) stays.
#[test]
fn panel_write_obeys_the_object_limits() {
    let mut r = Rig::new();
    browse_to(&mut r, 2, "d2.03");
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r), "   45");
    // cursor to the hundreds, +100 → 145 > 127
    presses(&mut r, PanelKey::Mode, 2);
    press(&mut r, PanelKey::Up);
    press(&mut r, PanelKey::Set);
    assert_eq!(r.i(0x60F9, 0x03), 45);
    assert_eq!(
        r.d.kinco_panel().dots & DOT5,
        0,
        "no point 5 on a refused write"
    );
}

/// §9.1 F001: choosing d1.09 writes Key_Address_F001 2FF0h:04 = 9; the monitor then shows
/// Real_DCBUS.
#[test]
fn f001_chooses_the_monitor_item() {
    let mut r = Rig::new();
    browse_to(&mut r, 1, "d1.09");
    press(&mut r, PanelKey::Set);
    assert_eq!(r.i(0x2FF0, 0x04), 9);
    assert_eq!(text(&r).trim(), r.i(0x60F7, 0x12).to_string());
}

/// On the panel (ch. 8): an error blinks its alarm code on the monitor (Overvoltage, Error_State
/// bit 5).
#[test]
fn kinco_diag_02_error_blinks_on_the_monitor() {
    let mut r = Rig::new();
    r.d.inject_fault(0x3210, 0x05);
    r.run_ms(5);
    let d = r.d.kinco_panel();
    assert_eq!(d.text().as_str(), " 002.0", "KINCO-DIAG-02");
    assert_eq!(d.blink, Blink::Error);
}

/// §4.1: the warning triple blink while Warning_Word is not 0.
#[test]
fn warning_blinks() {
    let mut r = Rig::new();
    r.d.set_warnings(1);
    r.run_ms(5);
    assert_eq!(r.d.kinco_panel().blink, Blink::Warning);
}

fn jog_ready(r: &mut Rig) {
    presses(r, PanelKey::Mode, 6);
    press(r, PanelKey::Set);
    assert_eq!(text(r), " d6.40");
    press(r, PanelKey::Set);
    assert_eq!(text(r), " d6.40", "SET before the key check does nothing");
    presses(r, PanelKey::Down, 25);
    assert_eq!(text(r), " d6.15");
    presses(r, PanelKey::Up, 10);
    assert_eq!(text(r), " d6.25");
    press(r, PanelKey::Set);
    assert_eq!(text(r).trim(), "Jog");
}

/// §4.3.3 F006: d6.40, ▼ to d6.15, ▲ to d6.25, SET: "Jog"; holding ▲ enables the drive and
/// turns at +Jog_RPM in mode −3; release stops and disables; ▼ turns the other way.
#[test]
fn f006_jog_enables_while_held() {
    let mut r = Rig::new();
    r.w16(0x2FF0, 0x23, 300);
    jog_ready(&mut r);
    assert_ne!(r.d.state(), State::OperationEnabled);
    r.d.kinco_panel_key(PanelKey::Up, true);
    r.run_ms(400);
    assert_eq!(r.d.state(), State::OperationEnabled);
    assert_eq!(r.i(0x6061, 0), -3);
    assert!((r.rpm() - 300.0).abs() < 10.0, "{}", r.rpm());
    assert!(
        r.d.kinco_panel().dot5_blinks,
        "point 5 blinks while enabled"
    );
    r.d.kinco_panel_key(PanelKey::Up, false);
    r.run_ms(300);
    assert_ne!(r.d.state(), State::OperationEnabled);
    assert!(r.rpm().abs() < 10.0, "{}", r.rpm());
    r.d.kinco_panel_key(PanelKey::Down, true);
    r.run_ms(400);
    assert!((r.rpm() + 300.0).abs() < 10.0, "{}", r.rpm());
    r.d.kinco_panel_key(PanelKey::Down, false);
    r.run_ms(50);
    // §4.3.3: 20 s without a key ends jog.
    r.run_ms(20_100);
    assert_eq!(text(&r), "    0");
}

/// §4.3.4 Tab. 4-6: F007 shows the history: "02.00" the earliest (Following error, point 3),
/// "0100" neither (Chop resistor), "000.1" the latest (extended, point 4), and SET on it
/// shows Error_State2 (here External enable, bit 8).
#[test]
fn f007_history_tab_4_6() {
    let mut r = Rig::new();
    for code in [0x8611u16, 0x7110, 0x5443] {
        r.enable_in(3);
        r.d.inject_fault(code, 0x01);
        r.run_ms(5);
        r.d.clear_fault(code);
        r.cw(0x86);
        r.cw(0x06);
        r.run_ms(5);
    }
    assert_eq!(r.d.error_history().count(), 3);
    presses(&mut r, PanelKey::Mode, 7);
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r), " 000.1");
    assert_eq!(r.d.kinco_panel().dots, DOT4);
    press(&mut r, PanelKey::Set);
    assert_eq!(
        text(&r),
        " 010.0",
        "Error_State2 bit 8 External enable, the latest"
    );
    press(&mut r, PanelKey::Up);
    assert_eq!(text(&r), " 02.00");
    assert_eq!(r.d.kinco_panel().dots, DOT3);
    press(&mut r, PanelKey::Up);
    assert_eq!(text(&r), " 0100");
}

/// §4.3 / KINCO-DIAG-05: a motor type changed from outside (6410h:01 over the bus) blinks
/// "FFF.F" and locks EASY to EA00 / EA01 and tunE to tn00; confirming EA01 unlocks.
#[test]
fn access_lock_and_ea01_confirm() {
    let mut r = Rig::new();
    assert!(!r.d.kinco_panel_locked());
    let motor = r.i(0x6410, 0x01);
    r.w16(0x6410, 0x01, motor ^ 0x0101);
    r.run_ms(5);
    assert!(r.d.kinco_panel_locked());
    let d = r.d.kinco_panel();
    assert_eq!((d.text().as_str(), d.blink), (" FFF.F", Blink::Error));
    presses(&mut r, PanelKey::Mode, 8);
    press(&mut r, PanelKey::Set);
    let mut easy = vec![text(&r).trim().to_string()];
    press(&mut r, PanelKey::Up);
    easy.push(text(&r).trim().to_string());
    assert!(easy.iter().all(|k| k == "EA00" || k == "EA01"), "{easy:?}");
    browse_to_confirm_ea01(&mut r);
    assert!(!r.d.kinco_panel_locked());
    press(&mut r, PanelKey::Mode);
    press(&mut r, PanelKey::Set);
    let mut n = 1;
    let first = text(&r);
    press(&mut r, PanelKey::Up);
    while text(&r) != first {
        n += 1;
        press(&mut r, PanelKey::Up);
    }
    assert!(n > 2, "full EASY menu again: {n} items");
}

fn browse_to_confirm_ea01(r: &mut Rig) {
    for _ in 0..4 {
        if text(r).trim() == "EA01" {
            press(r, PanelKey::Set);
            press(r, PanelKey::Set);
            return;
        }
        press(r, PanelKey::Up);
    }
    panic!("no EA01");
}

/// MODE held 1 s while editing goes back to the list without writing.
#[test]
fn long_mode_leaves_the_edit() {
    let mut r = Rig::new();
    browse_to(&mut r, 3, "d3.47");
    press(&mut r, PanelKey::Set);
    press(&mut r, PanelKey::Up);
    r.d.kinco_panel_key(PanelKey::Mode, true);
    r.run_ms(1100);
    r.d.kinco_panel_key(PanelKey::Mode, false);
    assert_eq!(text(&r), " d3.47");
    assert_eq!(r.i(0x2FF0, 0x23), 30);
}

/// §4.3.2 / §5.9: tn03 = 1 from the panel starts the inertia tuning (no WriteFUN_CTL needed
/// as over communication; 3041h:05 is back to 0 after); KINCO-SC-11: tn04 shows Safe_Dist 22.
#[test]
fn tune_tn03_starts_tuning_from_the_panel() {
    let mut r = Rig::new();
    r.enable_in(3);
    browse_to(&mut r, 9, "tn04");
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r), "   22");
    long_press(&mut r, PanelKey::Mode);
    assert_eq!(text(&r), " tn04", "a long MODE goes back to the list");
    up_to(&mut r, "tn03");
    press(&mut r, PanelKey::Set);
    press(&mut r, PanelKey::Up);
    press(&mut r, PanelKey::Set);
    assert_eq!(r.d.kinco_panel().dots & DOT5, DOT5, "tn03 := 1 accepted");
    assert_eq!(r.i(0x3041, 0x05), 0);
    r.run_ms(3000);
    assert_ne!(r.i(0x3040, 0x09), 0, "the run ended with a result");
}

fn long_press(r: &mut Rig, key: PanelKey) {
    r.d.kinco_panel_key(key, true);
    r.run_ms(1100);
    r.d.kinco_panel_key(key, false);
    r.run_ms(10);
}

fn up_to(r: &mut Rig, key: &str) {
    for _ in 0..10 {
        if text(r).trim() == key {
            return;
        }
        press(r, PanelKey::Up);
    }
    panic!("{key} not found");
}

/// §4.3: EA00 = 10 initialises the parameters (Store_Data 2FF0h:01 := 10) and locks EASY to
/// EA00 / EA01 and tunE to tn00, without "FFF.F" (the motor is unchanged); EA01 unlocks.
#[test]
fn ea00_initialise_locks_until_ea01() {
    let mut r = Rig::new();
    browse_to(&mut r, 8, "EA00");
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r), "    0");
    press(&mut r, PanelKey::Mode);
    press(&mut r, PanelKey::Up); // 10
    press(&mut r, PanelKey::Set);
    assert!(r.d.kinco_panel_locked());
    long_press(&mut r, PanelKey::Mode);
    press(&mut r, PanelKey::Mode); // tunE
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r), " tn00");
    press(&mut r, PanelKey::Up);
    assert_eq!(text(&r), " tn00", "tunE: only tn00 while locked");
    press(&mut r, PanelKey::Mode); // back to tunE
    press(&mut r, PanelKey::Mode); // monitor
    assert_eq!(r.d.kinco_panel().blink, Blink::Steady);
    browse_to(&mut r, 8, "EA01");
    press(&mut r, PanelKey::Set);
    press(&mut r, PanelKey::Set);
    assert!(!r.d.kinco_panel_locked());
}

/// KINCO-DIAG-06 on the panel: an Error_State2 error (External enable, bit 8) blinks
/// "000.1" (extended error); SET shows its Error_State2 code "010.0", SET again "000.1".
#[test]
fn kinco_diag_06_set_opens_error_state2() {
    let mut r = Rig::new();
    r.d.inject_fault(0x5443, 0x01);
    r.run_ms(5);
    assert_eq!(text(&r), " 000.1");
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r), " 010.0");
    assert_eq!(r.d.kinco_panel().blink, Blink::Error);
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r), " 000.1");
}

/// §4.1: a 32-bit value beyond five digits shows in HEX halves; a long SET on the monitor
/// toggles to the high half (point 3). d1.19 Pos_Actual after a move past 99 999.
#[test]
fn monitor_32_bit_halves() {
    let mut r = Rig::new();
    browse_to(&mut r, 1, "d1.19");
    press(&mut r, PanelKey::Set);
    r.w16(0x2FF0, 0x23, 3000);
    r.enable_in(3);
    r.d.jog(1);
    r.run_ms(1500);
    r.d.jog(0);
    r.run_ms(500);
    let pos = r.i(0x6063, 0);
    assert!(pos > 99_999, "{pos}");
    let low = r.d.kinco_panel();
    assert_eq!(low.dots & (DOT3 | DOT4), DOT4, "HEX, low half");
    let want = format!("{:04X}", pos & 0xFFFF);
    assert_eq!(low.text().replace(['.', ' '], ""), want);
    r.d.kinco_panel_key(PanelKey::Set, true);
    r.run_ms(1100);
    r.d.kinco_panel_key(PanelKey::Set, false);
    let high = r.d.kinco_panel();
    assert_eq!(high.dots & (DOT3 | DOT4), DOT3 | DOT4, "HEX, high half");
    let want = format!("{:04X}", (r.i(0x6063, 0) >> 16) & 0xFFFF);
    assert_eq!(high.text().replace(['.', ' '], ""), want);
}

/// §4.3.3 "independent of other settings": on the factory set-up (DIN1 Enable owns the
/// controlword, DIN3 the mode) jog still enables and turns.
#[test]
fn f006_jog_on_the_factory_set_up() {
    let mut r = Rig::factory();
    r.w16(0x2FF0, 0x23, 200);
    jog_ready(&mut r);
    r.d.kinco_panel_key(PanelKey::Down, true);
    r.run_ms(400);
    assert_eq!(r.d.state(), State::OperationEnabled);
    assert!((r.rpm() + 200.0).abs() < 10.0, "{}", r.rpm());
    r.d.kinco_panel_key(PanelKey::Down, false);
    r.run_ms(300);
    assert_ne!(r.d.state(), State::OperationEnabled);
}

/// Browses EASY to `key`, opens it and enters `value` digit by digit from the right
/// (▲ on each digit, MODE to the next), then SET.
fn easy_enter(r: &mut Rig, key: &str, value: u32) {
    browse_to(r, 8, key);
    press(r, PanelKey::Set);
    let mut v = value;
    let mut shown = text(r).trim().parse::<u32>().unwrap_or(0);
    for _ in 0..5 {
        let (want, have) = (v % 10, shown % 10);
        presses(r, PanelKey::Up, ((want + 10 - have) % 10) as usize);
        press(r, PanelKey::Mode);
        v /= 10;
        shown /= 10;
    }
    press(r, PanelKey::Set);
}

/// From an EASY item (browsing or editing) back to the monitor display: a long MODE leaves
/// the edit, then MODE to EASY, tunE and the monitor.
fn back_to_monitor(r: &mut Rig) {
    long_press(r, PanelKey::Mode);
    for _ in 0..4 {
        if text(r).trim() == "tunE" {
            press(r, PanelKey::Mode);
            return;
        }
        press(r, PanelKey::Mode);
    }
}

/// EA00 = 2 (§4.3.1 Tab. 4-2: "save the control and motor parameters and reboot"): Store_Data
/// and Store_Motor_Data read 1, the runtime is asked to save and then to reboot; 3 only
/// reboots.
#[test]
fn ea00_2_saves_and_reboots_3_reboots() {
    use drive::drive::DriveEvent;
    let mut r = Rig::new();
    r.events();
    easy_enter(&mut r, "EA00", 2);
    assert_eq!((r.i(0x2FF0, 0x01), r.i(0x2FF0, 0x03)), (1, 1));
    assert_eq!(
        r.d.od_mut().take_request(),
        Some(od::StorageRequest::Save { sub: 1 }),
        "the save"
    );
    assert!(r.events().contains(&DriveEvent::Reboot), "the reboot");
    back_to_monitor(&mut r);
    easy_enter(&mut r, "EA00", 3);
    assert_eq!(r.d.od_mut().take_request(), None, "3: no save");
    assert!(r.events().contains(&DriveEvent::Reboot));
}

/// EA06 (Tab. 4-2, default 1001: belt, P2P, limit switches, OUT5 normally open) at 3041h:03:
/// 1102 over the panel removes the P limit± functions at once (DIN5 / DIN6 0010h / 0020h
/// → 0) and keeps OUT5 normally open; the EA00 save then sets the loop of a ball screw
/// (tn01 13, tn02 30: Kpp 1250 of Tab. 7-2). 0102 makes OUT5 normally closed; 1003 is
/// refused.
#[test]
fn ea06_load_type_limit_switches_out5() {
    let mut r = Rig::new();
    browse_to(&mut r, 8, "EA06");
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r), " 1001");
    back_to_monitor(&mut r);
    easy_enter(&mut r, "EA06", 1102);
    assert_eq!(r.i(0x3041, 0x03), 1102);
    assert_eq!(
        (r.i(0x2010, 0x07), r.i(0x2010, 0x08)),
        (0, 0),
        "limit switches removed"
    );
    assert_ne!(r.i(0x2010, 0x0D) & 0x10, 0, "OUT5 normally open");
    assert_eq!(r.i(0x3040, 0x08), 12, "the load type waits for the save");
    back_to_monitor(&mut r);
    easy_enter(&mut r, "EA00", 1);
    assert_eq!((r.i(0x3040, 0x08), r.i(0x3040, 0x0B)), (13, 30));
    assert_eq!(r.i(0x60FB, 0x01), 1250);
    r.d.write(0x3041, 0x03, &102u16.to_le_bytes()).unwrap();
    assert_eq!(r.i(0x2010, 0x0D) & 0x10, 0, "OUT5 normally closed");
    assert_eq!(
        r.d.write(0x3041, 0x03, &1003u16.to_le_bytes()),
        Err(od::AbortCode::INVALID_VALUE)
    );
}

/// EA03 / EA04 (Tab. 4-2: gear numerator / denominator, "DEC; above 9999 HEX") are
/// Gear_Factor[0] / Gear_Divider[0]: 1000 in DEC; 12000 as 2EE0 with point 4.
#[test]
fn ea03_ea04_gear_in_dec_then_hex() {
    let mut r = Rig::new();
    browse_to(&mut r, 8, "EA03");
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r), " 1000");
    back_to_monitor(&mut r);
    r.w16(0x2508, 0x01, 12000);
    browse_to(&mut r, 8, "EA03");
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r).replace('.', ""), " 2EE0");
    assert_eq!(r.d.kinco_panel().dots & DOT4, DOT4, "HEX");
    back_to_monitor(&mut r);
    browse_to(&mut r, 8, "EA04");
    press(&mut r, PanelKey::Set);
    assert_eq!(text(&r), " 1000");
}

/// KINCO-SC-14 through the drive: Motor_Num 6410h:01 written over the bus with a motor code
/// reads back as the two ASCII characters (the first in the low byte); on the drive it is the
/// motor type the panel guards (§4.3): a code that is not the confirmed motor blinks "FFF.F"
/// and locks EASY / tunE until EA01 confirms it.
#[test]
fn kinco_sc_14_motor_num_through_the_drive() {
    for (code, value) in [
        (*b"JY", 0x594A),
        (*b"Y0", 0x3059),
        (*b"Y1", 0x3159),
        (*b"Y2", 0x3259),
    ] {
        let mut r = Rig::new();
        assert_eq!(r.d.write(0x6410, 0x01, &code), Ok(()));
        r.run_ms(5);
        assert_eq!(r.i(0x6410, 0x01), value, "KINCO-SC-14: {code:?}");
        assert!(r.d.kinco_panel_locked(), "KINCO-SC-14: another motor");
        let d = r.d.kinco_panel();
        assert_eq!(
            (d.text().as_str(), d.blink),
            (" FFF.F", Blink::Error),
            "KINCO-SC-14: {code:?}"
        );
        presses(&mut r, PanelKey::Mode, 8);
        press(&mut r, PanelKey::Set);
        browse_to_confirm_ea01(&mut r);
        assert!(!r.d.kinco_panel_locked(), "KINCO-SC-14: {code:?} confirmed");
        assert_eq!(r.i(0x6410, 0x01), value);
    }
}
