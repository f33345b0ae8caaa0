//! Kinco analog inputs through the drive (manual §6.2.1, §6.3): the §6.2.1 speed example and the
//! analog torque command.

mod kinco_rig;

use kinco_rig::{dec_rpm, Rig};

/// The §6.2.1 example: Analog1_Dead = 1 V, Analog1_Offset = 2 V, Analog_Speed_Factor =
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
    for (id, volts, out, rpm) in [
        ("KINCO-SC-01", 5.0, 200, 200.0),
        ("KINCO-SC-02", -5.0, -600, -600.0),
    ] {
        r.d.set_analog_input(1, volts);
        r.run_ms(500);
        assert_eq!(r.i(0x2FF0, 0x16), (volts * 100.0) as i64, "{id}: AN_V1");
        assert_eq!(r.i(0x2502, 0x0F), out, "{id}: Analog1_out");
        assert!(
            (r.rpm() - rpm).abs() < 10.0,
            "{id}: {volts} V: {} rpm",
            r.rpm()
        );
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

/// Analog_Dead_High / Analog_Dead_Low 2502h:0D / :0E (§6.2.1, L1331-1336): the KINCO-SC-01
/// example with the window 1 V … −5 V. +5 V gives Analog1_out 2 V, above 1 V: speed 0;
/// −5 V gives −6 V, below −5 V: speed 0; +3.5 V gives 0.5 V: 50 rpm.
#[test]
fn analog_dead_high_and_low_window() {
    let mut r = Rig::new();
    r.w16(0x2FF0, 0x1D, 100);
    r.w16(0x2FF0, 0x1E, 200);
    r.w16(0x2502, 0x0A, 100);
    r.w16(0x2502, 0x0D, 100);
    r.w16(0x2502, 0x0E, -500);
    r.w8(0x2502, 0x07, 1);
    r.enable_in(-3);
    for (volts, out, rpm) in [(5.0, 200, 0.0), (-5.0, -600, 0.0), (3.5, 50, 50.0)] {
        r.d.set_analog_input(1, volts);
        r.run_ms(400);
        assert_eq!(r.i(0x2502, 0x0F), out, "{volts} V: Analog1_out");
        assert!((r.rpm() - rpm).abs() < 3.0, "{volts} V: {} rpm", r.rpm());
    }
    // Both edges 0: the window is off, +5 V runs 200 rpm again.
    r.w16(0x2502, 0x0D, 0);
    r.w16(0x2502, 0x0E, 0);
    r.d.set_analog_input(1, 5.0);
    r.run_ms(400);
    assert!((r.rpm() - 200.0).abs() < 5.0, "{} rpm", r.rpm());
}

/// Analog1_Filter 2502h:01 (ms): a step of 5 V reaches 1 − 1/e of itself after one time
/// constant: 316 (0.01 V) after 5 ms with the default 5 ms, 48 after 5 ms with 50 ms.
#[test]
fn analog_filter_time_constant() {
    for (tau, want) in [(5, 316), (50, 48)] {
        let mut r = Rig::new();
        r.w16(0x2502, 0x01, tau);
        r.run_ms(10);
        r.d.set_analog_input(1, 5.0);
        r.run_ms(5);
        let out = r.i(0x2502, 0x0F);
        assert!((out - want).abs() <= 12, "τ = {tau} ms: {out}");
        assert_eq!(r.i(0x2FF0, 0x16), 500, "AN_V1 is the unfiltered voltage");
        r.run_ms(20 * tau as u64);
        assert_eq!(r.i(0x2502, 0x0F), 500, "settled");
    }
}

/// Analog max torque (§6.2.1 L1343, §6.3 Tab. 6-11): Analog_MaxT_Con = 2, Voltage_MaxT_Factor
/// 100 mN·m/V, AIN2 = 2 V: the torque is held to 0.2 N·m. In mode 4 a command of 100 %
/// (1.41 N·m) accelerates the free motor (J = 0.3 kg·cm²) at 0.2 / 1.41 of its rate; in mode
/// −3 a step to 3000 rpm takes ω·J/T = 15.7 ms per 1000 rpm (friction aside): under 700 rpm
/// after 10 ms.
#[test]
fn analog_max_torque_limits_the_torque() {
    let accel = |maxt: bool| {
        let mut r = Rig::new();
        if maxt {
            r.w8(0x2502, 0x09, 2);
            r.w16(0x2FF0, 0x22, 100);
            r.d.set_analog_input(2, 2.0);
        }
        r.enable_in(4);
        let before = r.rpm();
        r.w16(0x6071, 0, 100);
        r.run_ms(4);
        r.rpm() - before
    };
    let (free, held) = (accel(false), accel(true));
    let ratio = held / free;
    assert!(
        (0.10..0.20).contains(&ratio),
        "{held} / {free} rpm = {ratio}"
    );

    let mut r = Rig::new();
    r.w8(0x2502, 0x09, 2);
    r.w16(0x2FF0, 0x22, 100);
    r.d.set_analog_input(2, 2.0);
    r.enable_in(-3);
    r.w32(0x60FF, 0, dec_rpm(3000.0));
    r.run_ms(10);
    assert!(
        (400.0..700.0).contains(&r.rpm()),
        "after 10 ms: {} rpm",
        r.rpm()
    );
    // AIN2 = 0 V: no torque at all once the 5 ms filter has settled; the motor coasts.
    r.d.set_analog_input(2, 0.0);
    r.run_ms(30);
    let v = r.rpm();
    r.run_ms(20);
    assert!(r.rpm() <= v + 1.0, "no torque: {} after {v}", r.rpm());
}

/// Analog1_out and AN_V1 are not recomputed while the voltage and the filter stand (0 V
/// from power-on); Analog1_Offset written then shows at the next logic cycle, and the values
/// overwritten in the dictionary are stored again.
#[test]
fn analog_values_follow_writes_while_the_voltage_stands() {
    let mut r = Rig::new();
    r.run_ms(50);
    assert_eq!(r.i(0x2502, 0x0F), 0);
    r.w16(0x2FF0, 0x1E, 200);
    r.run_ms(1);
    assert_eq!(r.i(0x2502, 0x0F), -200, "0 V − 2 V offset");
    r.run_ms(20);
    let od = r.d.od_mut();
    for (index, sub) in [(0x2502, 0x0F), (0x2FF0, 0x16)] {
        let e = od.description().entry(index, sub).unwrap();
        od.store(e, &[0x34, 0x12][..e.capacity as usize]);
    }
    r.run_ms(1);
    assert_eq!(r.i(0x2502, 0x0F), -200);
    assert_eq!(r.i(0x2FF0, 0x16), 0);
}
