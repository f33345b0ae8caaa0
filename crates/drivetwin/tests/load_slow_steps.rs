//! A slow load FMU is reported, never skipped (docs/cosimulation.md): a `doStep` that takes
//! longer in wall time than the virtual time it advances counts in the load's `slow_steps`
//! (and is logged), and the step is still made. The example conveyor FMU, FMI 3.0 and FMI
//! 2.0, stepped by a picosecond (no call into a library returns that fast) and then by a
//! second (20 000 substeps of the belt, milliseconds at most): the first are all slow, the
//! others none.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::path::PathBuf;
use std::time::Duration;

use drive::drive::external_load::{ExternalLoad, Shaft};
use drivetwin::cosim::{FmuLoad, LoadMapping};
use od::Instant;

#[path = "support/conveyor_fmus.rs"]
mod conveyor_fmus;
use conveyor_fmus::conveyor_fmus;

fn conveyor(fmu: PathBuf) -> FmuLoad {
    let mapping = LoadMapping {
        fmu,
        angle: Some("shaft_angle".into()),
        speed: Some("shaft_speed".into()),
        torque: None,
        load_torque: "load_torque".into(),
        position: Some("belt_position".into()),
        switches: Default::default(),
        parameters: Default::default(),
    };
    FmuLoad::open(&mapping, None, "conveyor").expect("the conveyor FMU")
}

#[test]
fn a_step_slower_than_the_time_it_advances_is_counted_and_still_made() {
    let dir = conveyor_fmus();
    for file in ["conveyor.fmu", "conveyor-fmi2.fmu"] {
        let mut load = conveyor(dir.join(file));
        let shaft = Shaft {
            motor_torque_nm: 0.0,
            angle_rad: 1.0,
            velocity_rad_s: 10.0,
        };
        let mut now = Instant::ZERO;
        for _ in 0..3 {
            load.plant_step(now, 1e-12, shaft)
                .expect("a picosecond step");
        }
        let r = load.report();
        assert_eq!((r.steps, r.slow_steps), (3, 3), "{file}: {r:?}");
        assert!(r.worst_step_ns > 0, "{file}: {r:?}");
        for _ in 0..3 {
            now = now + Duration::from_secs(1);
            load.plant_step(now, 1.0, shaft).expect("a one-second step");
        }
        let r = load.report();
        assert_eq!(
            (r.steps, r.slow_steps),
            (6, 3),
            "{file}: every step made: {r:?}"
        );
    }
}
