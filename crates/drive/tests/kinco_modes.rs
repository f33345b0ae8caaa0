//! Kinco operating modes through the drive (manual Tab. 6-5, L1272 of its text kept beside the
//! project): the controlword sequences of Tab. 6-5 move the motor, modes 3 / −3 / 4 / 6 and the
//! position table as the manual describes them; each vector is named at its test.

mod kinco_rig;

use kinco_rig::{dec_rpm, dec_rps2, Rig, INC_PER_REV};
use od::ObjectAccess;

/// Statusword state bits (CiA 402 mask 6Fh) of Operation Enabled.
const OPERATION_ENABLED: u16 = 0x0027;
const TARGET_REACHED: u16 = 0x0400;
const HOMING_ATTAINED: u16 = 0x1000;
const HOME_FOUND: u16 = 0x8000;

/// The factory set-up: the mode is Din_Mode0 (−4) while the Operation Mode Sel input is
/// inactive, and neither the controlword nor the mode takes a bus write (L1287).
#[test]
fn factory_inputs_own_the_controlword_and_the_mode() {
    let mut r = Rig::factory();
    assert_eq!(r.i(0x6061, 0), -4, "Din_Mode0");
    assert_eq!(r.try_cw(0x0F), Err(od::AbortCode::LOCAL_CONTROL));
    assert_eq!(r.i(0x6040, 0), 0x06, "the Enable input is inactive: 06h");
    assert!(r.d.write(0x6060, 0, &[3]).is_err());
    assert_eq!(r.sw() & 0x6F, 0x21, "ready to switch on");
}

/// KINCO-CW-05: in modes 3, −3, −4 and 4, and in the position table (mode 1 with a Start
/// PosTable input, §6.4.1), 0Fh (or 2Fh) after 06h enables the drive in that mode; the
/// table then runs from its start input.
#[test]
fn kinco_cw_05_enable_in_each_mode() {
    for (m, cw) in [(3, 0x0F), (-3, 0x2F), (-4, 0x0F), (4, 0x2F)] {
        let mut r = Rig::new();
        r.w8(0x6060, 0, m);
        r.cw(0x06);
        assert_eq!(r.sw() & 0x6F, 0x21, "mode {m}: 06h ready to switch on");
        r.cw(cw);
        r.run_ms(5);
        assert_eq!(
            r.sw() & 0x6F,
            OPERATION_ENABLED,
            "KINCO-CW-05: mode {m}: enabled by {cw:02X}h"
        );
        assert_eq!(r.i(0x6061, 0), i64::from(m));
        r.cw(0x06);
        assert_eq!(r.sw() & 0x6F, 0x21, "06h disables");
    }
    // The position table: DIN4 Start PosTable (9004h), one task to 20 000 increments.
    for cw in [0x0F, 0x2F] {
        let mut r = Rig::new();
        r.w16(0x2010, 0x06, 0x9004);
        let mut table = drive::vendors::kinco::table::PositionTable::default();
        table.tasks[0] = drive::vendors::kinco::table::Task {
            ctl: 0,
            position: 20_000,
            speed_rpm: 600,
            delay_ms: 0,
            acc: 0,
            dec: 0,
            loops: 0,
        };
        r.d.set_position_table(table);
        r.w8(0x6060, 0, 1);
        r.cw(0x06);
        r.cw(cw);
        r.run_ms(5);
        assert_eq!(
            (r.sw() & 0x6F, r.i(0x6061, 0)),
            (OPERATION_ENABLED, 1),
            "KINCO-CW-05: position table enabled by {cw:02X}h"
        );
        r.w16(0x2010, 0x02, 1 << 3);
        assert!(r.until_sw(TARGET_REACHED, 2_000), "the table's task ran");
        assert!(
            (r.position() - 20_000).abs() <= 20,
            "KINCO-CW-05: position table task 0 at {}",
            r.position()
        );
    }
}

/// KINCO-CW-01 (§8.15): 06h → 2Fh → 607Ah → 3Fh moves to the absolute target; target
/// reached follows, a second 2Fh → 3Fh with the same target does not move.
#[test]
fn kinco_cw_01_absolute_move() {
    let mut r = Rig::new();
    r.w8(0x6060, 0, 1);
    r.cw(0x06);
    r.cw(0x2F);
    r.w32(0x607A, 0, 50_000);
    r.cw(0x3F);
    assert_eq!(r.sw() & TARGET_REACHED, 0, "moving");
    assert!(r.until_sw(TARGET_REACHED, 10_000), "target reached");
    assert!((r.position() - 50_000).abs() <= 20, "at {}", r.position());
    r.cw(0x2F);
    r.cw(0x3F);
    r.run_ms(300);
    assert!((r.position() - 50_000).abs() <= 20, "absolute: stays");
}

/// KINCO-CW-02: 4Fh → 5Fh moves by 607Ah from where it stands, each time.
#[test]
fn kinco_cw_02_relative_moves() {
    let mut r = Rig::new();
    r.w8(0x6060, 0, 1);
    r.cw(0x06);
    r.cw(0x4F);
    r.w32(0x607A, 0, 10_000);
    for n in 1..=2 {
        r.cw(0x5F);
        r.cw(0x4F);
        assert!(r.until_sw(TARGET_REACHED, 10_000), "move {n}");
        assert!(
            (r.position() - 10_000 * n).abs() <= 20,
            "at {}",
            r.position()
        );
    }
}

/// 103Fh … (bit 5 in 2Fh / 3Fh): a new absolute target during a move is taken at once.
#[test]
fn kinco_change_set_immediately() {
    let mut r = Rig::new();
    r.w8(0x6060, 0, 1);
    r.cw(0x06);
    r.cw(0x2F);
    r.w32(0x607A, 0, 200_000);
    r.cw(0x3F);
    r.run_ms(100);
    r.cw(0x2F);
    r.w32(0x607A, 0, -5_000);
    r.cw(0x3F);
    assert!(r.until_sw(TARGET_REACHED, 20_000));
    assert!((r.position() + 5_000).abs() <= 20, "at {}", r.position());
}

/// KINCO-CW-03: mode 6, 0Fh → 1Fh starts homing; method 35 homes where the motor stands;
/// bit 12 homing attained and bit 15 home found. Home_Offset_Mode 6099h:05 = 1: the home
/// point reads Home_Offset 607Ch; 0 (default): the drive moves Home_Offset on and reads 0
/// there (§6.6).
#[test]
fn kinco_cw_03_homing_starts() {
    for (offset_mode, moved) in [(1i8, 0i64), (0, 1234)] {
        let mut r = Rig::new();
        r.w32(0x607C, 0, 1234);
        r.w8(0x6099, 0x05, offset_mode);
        r.w32(0x6099, 0x01, dec_rpm(300.0));
        r.w32(0x609A, 0, dec_rps2(100.0));
        r.w8(0x6098, 0, 35);
        r.enable_in(6);
        assert_eq!(r.sw() & HOME_FOUND, 0);
        let start = r.d.plant_position();
        r.cw(0x1F);
        assert!(r.until_sw(HOMING_ATTAINED, 2000), "sw {:04X}", r.sw());
        assert_ne!(r.sw() & HOME_FOUND, 0, "bit 15 reference found");
        // The loop settles on the set-point (stiffness 12, kinco_loops.rs).
        r.run_ms(100);
        let travelled = (r.d.plant_position() - start) * INC_PER_REV / 65_536;
        assert!(
            (travelled - moved).abs() <= 5,
            "mode {offset_mode}: moved {travelled}"
        );
        let want = if offset_mode == 1 { 1234 } else { 0 };
        assert!(
            (r.position() - want).abs() <= 5,
            "mode {offset_mode}: at {}",
            r.position()
        );
    }
}

/// KINCO-CW-04: a fault is reset by 06h → 86h.
#[test]
fn kinco_cw_04_fault_reset() {
    let mut r = Rig::new();
    r.enable_in(3);
    r.d.inject_fault(0x4210, 0x09);
    r.run_ms(10);
    assert_eq!(r.sw() & 0x4F, 0x08, "fault");
    assert_eq!(
        r.i(0x2601, 0),
        1 << 4,
        "Error_State bit 4 Controller Temperature"
    );
    r.d.clear_fault(0x4210);
    r.cw(0x06);
    assert_eq!(r.sw() & 0x4F, 0x08, "06h alone does not reset");
    r.cw(0x86);
    r.cw(0x06);
    assert_eq!(r.sw() & 0x6F, 0x21, "reset, then ready to switch on");
    assert_eq!(r.i(0x2601, 0), 0);
}

/// Mode 3 ramps with 6083h, mode −3 jumps to the speed (§5.2).
#[test]
fn mode_3_ramps_and_mode_minus_3_does_not() {
    let speed_after = |m: i8| {
        let mut r = Rig::new();
        r.w32(0x6083, 0, dec_rps2(10.0)); // 600 rpm/s
        r.enable_in(m);
        r.w32(0x60FF, 0, dec_rpm(1000.0));
        r.run_ms(100);
        r.rpm()
    };
    let ramped = speed_after(3);
    let immediate = speed_after(-3);
    assert!(
        (40.0..80.0).contains(&ramped),
        "mode 3 after 0.1 s: {ramped} rpm"
    );
    assert!(
        (immediate - 1000.0).abs() < 20.0,
        "mode −3: {immediate} rpm"
    );
}

/// Mode 3: the speed is reached and held; 606Ch reads it in DEC, 2FF0h:14 in rpm.
#[test]
fn mode_3_reaches_the_speed() {
    let mut r = Rig::new();
    r.enable_in(3);
    r.w32(0x60FF, 0, dec_rpm(-300.0));
    r.run_ms(500);
    assert!((r.rpm() + 300.0).abs() < 5.0, "{} rpm", r.rpm());
    assert!((r.i(0x606C, 0) - dec_rpm(-300.0)).abs() < dec_rpm(5.0));
    assert_eq!(r.i(0x2FF0, 0x14), -300);
    assert_ne!(r.sw() & TARGET_REACHED, 0);
    let p0 = r.position();
    r.run_ms(1000);
    let travelled = r.position() - p0;
    assert!(
        (travelled + 5 * INC_PER_REV).abs() < 100,
        "300 rpm = 5 rev/s: {travelled}"
    );
}

/// Mode 4 (§5.3): 6071h in % of the rated torque accelerates the free motor until Max_Speed
/// 607Fh holds it.
#[test]
fn mode_4_torque_with_speed_limit() {
    let mut r = Rig::new();
    r.w32(0x607F, 0, dec_rpm(500.0));
    r.enable_in(4);
    r.w16(0x6071, 0, 20);
    r.run_ms(20);
    assert!(r.rpm() > 10.0, "accelerating: {}", r.rpm());
    r.run_ms(1000);
    assert!(
        (r.rpm() - 500.0).abs() < 30.0,
        "held at the limit: {}",
        r.rpm()
    );
    r.w16(0x6071, 0, -20);
    r.run_ms(2000);
    assert!(
        (r.rpm() + 500.0).abs() < 30.0,
        "and the other way: {}",
        r.rpm()
    );
}

/// Homing −17 / −18 (Tab. 6-19): on the negative / positive mechanical stop (the travel's
/// hard stops at −22 and +66 revolutions: −220 000 / +660 000 increments).
#[test]
fn homing_on_the_mechanical_stop() {
    for (method, stop) in [(-17i8, -220_000i64), (-18, 660_000)] {
        let mut r = Rig::new();
        // Without limit switches: the method ignores them, the wiring is removed.
        r.w16(0x2010, 0x07, 0);
        r.w16(0x2010, 0x08, 0);
        r.w8(0x6099, 0x05, 1);
        r.w32(0x6099, 1, dec_rpm(3000.0));
        r.w32(0x6099, 2, dec_rpm(60.0));
        r.w32(0x609A, 0, dec_rps2(500.0));
        r.w8(0x6098, 0, method);
        r.enable_in(6);
        r.cw(0x1F);
        assert!(
            r.until_sw(HOMING_ATTAINED, 30_000),
            "{method}: {:04X}",
            r.sw()
        );
        let at = r.d.plant_position() * INC_PER_REV / 65_536;
        assert!((at - stop).abs() < 500, "{method}: at {at}");
        assert_eq!(r.sw() & 0x2000, 0, "no homing error");
    }
}

/// The CD3 (RS232 only, same firmware) runs on the same personality.
#[test]
fn cd3_runs_as_a_kinco() {
    let desc = devices::by_name("kinco-cd3").expect("the CD3 device file");
    let od = od::ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).expect("dictionary");
    let mut d: drive::drive::Drive<_, drive::vendors::kinco::Kinco> =
        drive::drive::Drive::new(od, drive::drive::DriveSettings::default());
    let mut now = od::Instant::ZERO;
    let mut run = |d: &mut drive::drive::Drive<Vec<u8>, drive::vendors::kinco::Kinco>, ms: u64| {
        now = now + std::time::Duration::from_millis(ms);
        d.step(now);
    };
    run(&mut d, 1);
    assert_eq!(
        d.write(0x6040, 0, &[0x0F, 0]),
        Err(od::AbortCode::LOCAL_CONTROL)
    );
    for (i, s, v) in [(0x2010u16, 3u8, 0u16), (0x2010, 5, 0)] {
        d.write(i, s, &v.to_le_bytes()).unwrap();
    }
    d.write(0x6060, 0, &[0xFD]).unwrap(); // −3
    for cw in [0x06u16, 0x0F] {
        d.write(0x6040, 0, &cw.to_le_bytes()).unwrap();
        run(&mut d, 5);
    }
    d.write(0x60FF, 0, &(dec_rpm(120.0) as i32).to_le_bytes())
        .unwrap();
    run(&mut d, 300);
    assert!(
        (d.plant_velocity_rpm() - 120.0).abs() < 3.0,
        "{}",
        d.plant_velocity_rpm()
    );
}

/// Jog (F006): −3 at Jog_RPM (30 rpm by default) without the limit switches; ending it
/// returns to the mode before.
#[test]
fn jog_runs_at_jog_rpm_past_the_limit_switch() {
    let mut r = Rig::new();
    r.w16(0x2FF0, 0x23, 600);
    r.enable_in(1);
    r.d.jog(-1);
    r.run_ms(300);
    assert_eq!(r.i(0x6061, 0), -3);
    assert!((r.rpm() + 600.0).abs() < 10.0, "{}", r.rpm());
    // The negative limit switch is at −200 000 increments: 2 s at 10 rev/s; jog goes on.
    r.run_ms(2200);
    assert!(r.position() < -205_000, "past the switch: {}", r.position());
    r.d.jog(0);
    r.run_ms(20);
    assert_eq!(r.i(0x6061, 0), 1);
}
