//! The cost of a load FMU per plant cycle (docs/cosimulation.md): a CMMP-AS as it powers on
//! is stepped 1 ms of virtual time (8 plant cycles of 125 µs) alone and with the example
//! conveyor FMU as its load (built and packed by `scripts/conveyor-fmu`, `--release` for the
//! figures in docs/cosimulation.md). The difference divided by 8 is the coupling's overhead per
//! plant step: setting the inputs, `fmi3DoStep`, reading the outputs, and the FMU's own work.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use drive::drive::DriveSettings;
use drivetwin::cell::station::Station;
use drivetwin::cosim::LoadMapping;
use od::Instant;

fn station(with_load: bool) -> Station {
    let desc = devices::by_name("cmmp-as").expect("the CMMP-AS");
    let mut s = Station::with_settings(desc, 1, None, Vec::new(), Some(DriveSettings::default()))
        .expect("a drive");
    if with_load {
        let fmu = std::env::var_os("CONVEYOR_FMU").map_or_else(
            || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/fmu/conveyor.fmu"),
            PathBuf::from,
        );
        let mapping = LoadMapping {
            fmu,
            angle: Some("shaft_angle".into()),
            speed: Some("shaft_speed".into()),
            torque: Some("motor_torque".into()),
            load_torque: "load_torque".into(),
            position: Some("belt_position".into()),
            switches: [("home".to_string(), "light_barrier".to_string())].into(),
            parameters: Default::default(),
        };
        s.model
            .couple_load(&mapping, 1)
            .expect("target/fmu/conveyor.fmu: run scripts/conveyor-fmu first");
    }
    s
}

fn coupling(c: &mut Criterion) {
    let mut g = c.benchmark_group("fmu_load");
    g.measurement_time(Duration::from_secs(3));
    for (name, with_load) in [("1 ms alone", false), ("1 ms with the conveyor FMU", true)] {
        let mut s = station(with_load);
        let mut now = Instant::ZERO;
        g.bench_function(name, |b| {
            b.iter(|| {
                now = now + Duration::from_millis(1);
                black_box(s.model.step(now))
            })
        });
    }
    g.finish();
}

criterion_group!(benches, coupling);
criterion_main!(benches);
