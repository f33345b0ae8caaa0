//! Kinco analog inputs through the drive (manual §6.2.1, §6.3; spec/kinco-fd-cd.md §5.2,
//! §5.3): the KINCO-SC-01/02 speed example and the analog torque command.

mod kinco_rig;

use kinco_rig::{dec_rpm, Rig};

/// KINCO-SC-01 / -02: Analog1_Dead = 1 V, Analog1_Offset = 2 V, Analog_Speed_Factor =
/// 100 rpm/V, Analog_Speed_Con = 1: AIN1 = +5 V runs 200 rpm (Analog1_out 2 V), −5 V runs
/// −600 rpm (−6 V).
#[test]
fn kinco_sc_01_02_analog_speed() {
    let mut r = Rig::new();
    r.w16(0x2FF0, 0x1D, 100);
    r.w16(0x2FF0, 0x1E, 200);
    r.w16(0x2502, 0x0A, 100);
    r.w8(0x2502, 0x07, 1);
    r.enable_in(-3);
    for (volts, out, rpm) in [(5.0, 200, 200.0), (-5.0, -600, -600.0)] {
        r.d.set_analog_input(1, volts);
        r.run_ms(500);
        assert_eq!(r.i(0x2FF0, 0x16), (volts * 100.0) as i64, "AN_V1");
        assert_eq!(r.i(0x2502, 0x0F), out, "Analog1_out");
        assert!((r.rpm() - rpm).abs() < 10.0, "{volts} V: {} rpm", r.rpm());
    }
    r.d.set_analog_input(1, 2.5);
    r.run_ms(300);
    assert!(r.rpm().abs() < 2.0, "inside the dead band: {}", r.rpm());
}

/// Analog torque (§6.3): Analog_Torque_Con = 1, Voltage_Torque_Factor 100 mN·m/V, 2 V =
/// 0.2 N·m drives the free motor up to Max_Speed 607Fh.
#[test]
fn analog_torque() {
    let mut r = Rig::new();
    r.w8(0x2502, 0x08, 1);
    r.w16(0x2FF0, 0x21, 100);
    r.w32(0x607F, 0, dec_rpm(300.0));
    r.enable_in(4);
    r.d.set_analog_input(1, 2.0);
    r.run_ms(20);
    assert!(r.rpm() > 5.0, "accelerating: {}", r.rpm());
    r.run_ms(1500);
    assert!((r.rpm() - 300.0).abs() < 20.0, "{}", r.rpm());
    r.d.set_analog_input(1, -2.0);
    r.run_ms(2000);
    assert!((r.rpm() + 300.0).abs() < 20.0, "{}", r.rpm());
}
