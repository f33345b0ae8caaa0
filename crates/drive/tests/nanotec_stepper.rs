//! The Nanotec on the CMMO-ST's hybrid stepper model (crates/drive/src/stepper.rs): in open
//! loop a load above the pull-out torque costs steps (commanded and encoder position
//! diverge); in closed loop (2001h ≠ 0 with an encoder, 200Ah = 1) the same load is held
//! and the axis arrives.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod nanotec_rig;

use drive::drive::DriveSettings;
use drive::stepper::{StepperData, StepperMode};
use nanotec_rig::Rig;

/// A stepper whose closed loop may use 1.5 × the rated current (peak 0.75 N·m), the open
/// loop the rated current (holding torque 0.5 N·m).
fn rig() -> Rig {
    Rig::with(DriveSettings {
        stepper: Some(StepperData {
            max_current: 3.0,
            ..StepperData::default()
        }),
        ..DriveSettings::default()
    })
}

/// A move of 10 000 units (5 revolutions) at 150 min⁻¹ against `load` N·m: (position
/// demand 6062h, position actual 6064h, lost full steps) after 5 s.
fn move_against(r: &mut Rig, load: f64) -> (i64, i64, i64) {
    r.enable_pp();
    r.w32(0x6081, 0, 5000);
    r.w32(0x6083, 0, 20_000);
    r.w32(0x6084, 0, 20_000);
    r.d.stepper_mut().unwrap().set_load_torque(load);
    r.w32(0x607A, 0, 10_000);
    r.cw(0x001F);
    r.cw(0x000F);
    r.run_ms(5000);
    let lost = r.d.stepper().unwrap().lost_steps();
    (r.i(0x6062, 0), r.i(0x6064, 0), lost)
}

#[test]
fn open_loop_loses_steps_above_the_pull_out_torque() {
    let mut r = rig();
    assert_eq!(r.d.stepper().unwrap().mode(), StepperMode::OpenLoop);
    assert_eq!(r.i(0x200A, 0), 0);
    // Below the pull-out torque the open loop arrives.
    let (demand, actual, lost) = move_against(&mut r, 0.2);
    assert_eq!((demand, lost), (10_000, 0));
    assert!((actual - 10_000).abs() <= 10, "{actual}");
    let mut r = rig();
    let (demand, actual, lost) = move_against(&mut r, 0.6);
    assert_eq!(demand, 10_000, "the set-point went all the way");
    assert_ne!(lost, 0, "steps lost");
    assert!(
        (demand - actual).abs() > 100,
        "commanded {demand} and encoder {actual} diverge"
    );
    // §4.3: bit 13 following error is a closed-loop bit; the open loop does not know it.
    assert_eq!(r.sw() & 0x2000, 0);
}

#[test]
fn closed_loop_holds_the_same_load() {
    let mut r = rig();
    r.w8(0x2001, 0, 1);
    r.run_ms(2);
    assert_eq!(r.d.stepper().unwrap().mode(), StepperMode::ClosedLoop);
    assert_eq!(r.i(0x200A, 0), 1, "CL is enabled");
    let (demand, actual, lost) = move_against(&mut r, 0.6);
    assert_eq!(demand, 10_000);
    assert_eq!(lost, 0, "no step lost");
    assert!((actual - 10_000).abs() <= 2, "arrived: {actual}");
}

/// §4.1: in closed loop a blocked shaft is a following error beyond 6065h for 6066h: bit 13.
#[test]
fn closed_loop_following_error_bit_13() {
    let mut r = rig();
    r.w8(0x2001, 0, 1);
    r.run_ms(2);
    r.enable_pp();
    r.d.stepper_mut().unwrap().set_blocked(true);
    r.w32(0x607A, 0, 10_000);
    r.cw(0x001F);
    r.cw(0x000F);
    r.run_ms(1000);
    assert_ne!(r.sw() & 0x2000, 0, "following error");
}
