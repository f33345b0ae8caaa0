//! Kinco auto-tuning through the drive (manual §7.1, §4.3.2):
//! WriteFUN_CTL, the oscillation within Safe_Dist, the results for the plant's inertia and the
//! stiffness table's rows as the drive sets them.

mod kinco_rig;

use drive::drive::DriveSettings;
use drive::motor::MotorData;
use kinco_rig::Rig;
use od::ObjectAccess;

/// The Kinco motor of the device file (Kt 0.5 N·m/A, Jr 0.30 kg·cm², 2.83 A / 8.49 A) with
/// `inertia` for motor and load.
fn rig_with_inertia(inertia: f64) -> Rig {
    let motor = MotorData {
        torque_constant: 0.5,
        inertia,
        rated_current: 2.83,
        peak_current: 8.49,
        max_speed_rpm: 5000.0,
        ..MotorData::default()
    };
    let mut r = Rig::with(DriveSettings {
        motor,
        ..DriveSettings::default()
    });
    r.w16(0x2010, 0x03, 0);
    r.w16(0x2010, 0x05, 0);
    r.run_ms(2);
    r
}

fn tune(r: &mut Rig) {
    r.w8(0x3041, 0x05, 1);
    r.w8(0x3040, 0x01, 1);
    r.run_ms(1000);
}

#[test]
fn tuning_needs_write_fun_ctl_and_the_enable() {
    let mut r = rig_with_inertia(3.0e-5);
    assert_eq!(
        r.d.write(0x3040, 0x01, &[1]),
        Err(od::AbortCode::DEVICE_STATE),
        "WriteFUN_CTL 3041h:05 = 0"
    );
    tune(&mut r);
    assert_eq!(r.i(0x3040, 0x09), 0, "the drive is not enabled: result 0");
    assert_eq!(r.i(0x3040, 0x0B), 30);
}

/// Success (J_load = 2 · J_motor → 30): the motor oscillates within Safe_Dist (0.22 rev) and
/// comes back; Stiffness 12 − 1 = 11 and Kpp 889 of Tab. 7-2.
#[test]
fn tuning_measures_the_inertia_ratio() {
    let mut r = rig_with_inertia(9.0e-5);
    r.enable_in(3);
    let start = r.position();
    r.w8(0x3041, 0x05, 1);
    r.w8(0x3040, 0x01, 1);
    let mut span = (start, start);
    for _ in 0..100 {
        r.run_ms(10);
        let p = r.position();
        span = (span.0.min(p), span.1.max(p));
    }
    assert!(span.1 - span.0 > 500, "it moved: {span:?}");
    assert!(
        span.1 - span.0 <= 2_300,
        "within Safe_Dist 0.22 rev: {span:?}"
    );
    assert!(
        (r.position() - start).abs() < 50,
        "back where it started: {} from {start}",
        r.position()
    );
    assert_eq!(r.i(0x3040, 0x01), 1, "Tuning_Method reads 1");
    assert_eq!(r.i(0x3040, 0x09), 1);
    assert_eq!(r.i(0x3040, 0x0B), 30, "KINCO-SC-10: (2 + 1) · 10 / 1");
    assert_eq!(r.i(0x3040, 0x08), 11);
    assert_eq!(r.i(0x60FB, 0x01), 889);
}

/// KINCO-SC-13 through the drive: Stiffness 3040h:08 = 0, 12, 23, 31 written over the bus
/// sets Kpp[0] 60FBh:01 and Kvp[0] 60F9h:01 to the row of Tab. 4-5 / 7-2 (Kvp at Inertia_Ratio
/// 1.0, 3040h:0B = 10; at the default 3.0 three times the column), Velocity_BW 2FF0h:0A to its
/// Hz. The row's output-filter column does not change Output_Filter_N (kinco_loops.rs).
#[test]
fn kinco_sc_13_stiffness_rows_through_the_drive() {
    let mut r = rig_with_inertia(3.0e-5);
    let filter = r.i(0x60F9, 0x15);
    for (stiffness, kpp, kvp) in [
        (0, 70, 25),
        (12, 1056, 380),
        (23, 5556, 2000),
        (31, 13889, 5000),
    ] {
        r.w16(0x3040, 0x0B, 10);
        r.w8(0x3040, 0x08, stiffness);
        assert_eq!(
            (r.i(0x60FB, 0x01), r.i(0x60F9, 0x01)),
            (kpp, kvp),
            "KINCO-SC-13: stiffness {stiffness}: Kpp, Kvp at ratio 1.0"
        );
        assert_eq!(r.i(0x2FF0, 0x0A), kvp / 10, "KINCO-SC-13: Velocity_BW, Hz");
        r.w16(0x3040, 0x0B, 30);
        assert_eq!(
            r.i(0x60F9, 0x01),
            (kvp * 3).min(32767),
            "KINCO-SC-13: stiffness {stiffness}: Kvp at ratio 3.0"
        );
        assert_eq!(r.i(0x60F9, 0x15), filter, "Output_Filter_N untouched");
    }
}

/// A ratio above 250 gives −3 with the measured value, above 500 −4 with 30.
#[test]
fn kinco_sc_12_tuning_failures() {
    for (inertia, result, ratio) in [(9.0e-4, -3, 300), (1.8e-3, -4, 30)] {
        let mut r = rig_with_inertia(inertia);
        r.enable_in(3);
        tune(&mut r);
        assert_eq!(r.i(0x3040, 0x09), result, "KINCO-SC-12: J = {inertia}");
        assert_eq!(r.i(0x3040, 0x0B), ratio, "KINCO-SC-12: J = {inertia}");
    }
}
