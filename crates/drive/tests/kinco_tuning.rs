//! Kinco auto-tuning through the drive (manual §7.1, §4.3.2; spec/kinco-fd-cd.md §5.9,
//! KINCO-SC-10, -12, -13): WriteFUN_CTL, the oscillation within Safe_Dist, and the results
//! for the plant's inertia.

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

/// Success (KINCO-SC-10: J_load = 2 · J_motor → 30): the motor oscillates within Safe_Dist
/// (0.22 rev) and comes back; Stiffness 12 − 1 = 11 and Kpp 889 of Tab. 7-2 (KINCO-SC-13).
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
    assert_eq!(r.i(0x3040, 0x0B), 30);
    assert_eq!(r.i(0x3040, 0x08), 11);
    assert_eq!(r.i(0x60FB, 0x01), 889);
}

/// KINCO-SC-12: a ratio above 250 gives −3 with the measured value, above 500 −4 with 30.
#[test]
fn kinco_sc_12_tuning_failures() {
    for (inertia, result, ratio) in [(9.0e-4, -3, 300), (1.8e-3, -4, 30)] {
        let mut r = rig_with_inertia(inertia);
        r.enable_in(3);
        tune(&mut r);
        assert_eq!(r.i(0x3040, 0x09), result, "J = {inertia}");
        assert_eq!(r.i(0x3040, 0x0B), ratio, "J = {inertia}");
    }
}
