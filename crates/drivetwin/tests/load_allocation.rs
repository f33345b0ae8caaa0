//! The importer's plant step allocates nothing (docs/cosimulation.md, "Limits"): a CMMP-AS
//! stepped 100 ms of virtual time (800 plant cycles) with the example conveyor FMU as its load,
//! FMI 3.0 and FMI 2.0, makes as many heap allocations as the same drive alone. Counted with a
//! global allocator on the test's own thread; the FMU's library has its own allocator, so only
//! the drive, the coupling and the `fmi` crate's calls are counted.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::path::PathBuf;
use std::time::Duration;

use drive::drive::DriveSettings;
use drivetwin::cell::station::Station;
use drivetwin::cosim::LoadMapping;
use od::Instant;
use platform::alloc::Counting;

#[global_allocator]
static ALLOCATOR: Counting = Counting;

#[path = "support/conveyor_fmus.rs"]
mod conveyor_fmus;
use conveyor_fmus::conveyor_fmus;

fn station(fmu: Option<PathBuf>) -> Station {
    let desc = devices::by_name("cmmp-as").expect("the CMMP-AS");
    let mut s = Station::with_settings(desc, 1, None, Vec::new(), Some(DriveSettings::default()))
        .expect("a drive");
    if let Some(fmu) = fmu {
        let mapping = LoadMapping {
            fmu,
            angle: Some("shaft_angle".into()),
            speed: Some("shaft_speed".into()),
            torque: Some("motor_torque".into()),
            load_torque: "load_torque".into(),
            position: Some("belt_position".into()),
            switches: [("home".to_string(), "light_barrier".to_string())].into(),
            parameters: [("mass".to_string(), 0.8)].into(),
        };
        s.model.couple_load(&mapping, 1).expect("the conveyor FMU");
    }
    s
}

/// Heap allocations of 100 ms of steps, after 10 ms that initialise the FMU.
fn allocations(mut s: Station) -> u64 {
    let mut now = Instant::ZERO;
    for _ in 0..10 {
        now = now + Duration::from_millis(1);
        s.model.step(now);
    }
    let count = Counting::count(|| {
        for _ in 0..100 {
            now = now + Duration::from_millis(1);
            s.model.step(now);
        }
    });
    assert!(s.model.drive().unwrap().load_failure().is_none());
    count
}

#[test]
fn a_plant_step_with_a_load_fmu_allocates_nothing_more_than_without() {
    let dir = conveyor_fmus();
    let alone = allocations(station(None));
    for fmu in ["conveyor.fmu", "conveyor-fmi2.fmu"] {
        let with = allocations(station(Some(dir.join(fmu))));
        assert_eq!(with, alone, "{fmu}: allocations in 800 plant cycles");
    }
    assert_eq!(alone, 0, "the drive alone allocates in its plant cycles");
}
