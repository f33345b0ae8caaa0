//! One drive: device logic, profile generator, all control loops and the plant, stepped on
//! the virtual clock during a profile-position move. Reports ns per simulated second of one
//! axis and how many axes one core runs in real time.

use std::time::{Duration, Instant as WallInstant};

use criterion::{criterion_group, criterion_main, Criterion};
use drive::drive::{Drive, DriveSettings};
use od::{Instant, ObjectAccess, ObjectDictionary};

fn moving_drive() -> (Drive<Vec<u8>>, Instant) {
    moving(&devices::CMMP_AS, 1_000_000_000)
}

/// `desc`'s drive in profile position towards `target` (user units).
fn moving(desc: &'static od::DeviceDescription, target: i32) -> (Drive<Vec<u8>>, Instant) {
    let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).expect("storage");
    let mut d = Drive::new(od, DriveSettings::default());
    let mut now = Instant::ZERO;
    let mut step = |d: &mut Drive<Vec<u8>>, ms: u64| {
        now = now + Duration::from_millis(ms);
        d.step(now);
    };
    d.write(0x6060, 0, &[1]).expect("mode");
    for cw in [0x06u16, 0x07, 0x0F] {
        d.write(0x6040, 0, &cw.to_le_bytes()).expect("cw");
        step(&mut d, 2);
    }
    // A long move so the axis is busy for the whole measurement.
    d.write(0x607A, 0, &target.to_le_bytes()).expect("target");
    d.write(0x6040, 0, &0x1Fu16.to_le_bytes()).expect("cw");
    step(&mut d, 1);
    (d, now)
}

fn drive_step(c: &mut Criterion) {
    let (mut d, mut now) = moving_drive();
    // One simulated second, timed directly: the figure the issue asks for.
    let t = WallInstant::now();
    now = now + Duration::from_secs(1);
    d.step(now);
    let per_second = t.elapsed();
    println!(
        "one CMMP-AS axis: {:?} of CPU per simulated second (8000 current-loop cycles) → {:.0} axes in real time on one core",
        per_second,
        1.0 / per_second.as_secs_f64()
    );
    c.bench_function("drive_1ms_simulated", |b| {
        b.iter(|| {
            now = now + Duration::from_millis(1);
            d.step(now)
        })
    });
}

/// The Nanotec SMCI47-S on the hybrid stepper (open loop, 50 µs integration steps) in a
/// long profile-position move.
fn nanotec_step(c: &mut Criterion) {
    let (mut d, mut now) = moving(&devices::NANOTEC_SMCI47S, 100_000_000);
    let t = WallInstant::now();
    now = now + Duration::from_secs(1);
    d.step(now);
    let per_second = t.elapsed();
    println!(
        "one Nanotec axis: {:?} of CPU per simulated second → {:.0} axes in real time on one core",
        per_second,
        1.0 / per_second.as_secs_f64()
    );
    c.bench_function("nanotec_1ms_simulated", |b| {
        b.iter(|| {
            now = now + Duration::from_millis(1);
            d.step(now)
        })
    });
}

criterion_group!(benches, drive_step, nanotec_step);
criterion_main!(benches);
