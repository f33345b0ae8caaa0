//! One whole drive per personality — device logic, profile generator, every control loop and
//! the plant — stepped on the virtual clock in 1 ms calls while it moves, as a cell steps it:
//!
//! - CMMP-AS: profile position, the servo axis at the manual's controller cycles (6510h:B0–B3:
//!   current 125 µs, velocity 250 µs, position and device logic 500 µs, trajectory 1000 µs);
//! - Nanotec SMCI47-S: profile position, the hybrid stepper in open loop;
//! - CMMO-ST: FHPP jog (1 ms FHPP cycle), the same stepper model in closed loop (the
//!   CMMO-ST's default control structure, `FhppSettings::default`);
//! - Kinco FD3: profile position, the servo axis;
//! - the generic CiA 402 drive (`vendors::Cia402`) on the dictionary of an EDS that follows the
//!   maxon EPOS4's object list (`tests/interop/data/eds/epos4_like.eds`), profile position.
//!
//! Reports the CPU time per simulated second of one axis and how many axes one core runs in
//! real time (target ≥ 1000, i.e. ≤ 1 ms of CPU per simulated second), then draws the figures
//! with the baseline into `docs/axes-per-core.png`. The machine is shared: each figure is the
//! thread's CPU time (not wall time), the best of several runs.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drive::personality::Vendor;
use drive::vendors::festo_cmmp_as::CmmpAs;
use drive::vendors::kinco::Kinco;
use drive::vendors::nanotec::Nanotec;
use drive::vendors::Cia402;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, Criterion};
use drive::drive::{Drive, DriveSettings};
use drive::travel::TravelSettings;
use drive::vendors::festo_cmmo_st::device::{FhppDevice, FhppSettings};
use drive::vendors::festo_cmmo_st::fhpp::{Ccon, Cpos, OutputData};
use od::{Instant, ObjectAccess, ObjectDictionary};
use support::thread_cpu_time;

#[path = "support/mod.rs"]
mod support;

/// Axes in real time per core at commit c1c54dd (same bench and machine, best of two runs):
/// the reference the plot draws. The Kinco and the generic drive were not measured then
/// (NaN: no bar).
const BASELINE: [(&str, f64); 5] = [
    ("CMMP-AS", 754.0),
    ("Nanotec", 391.0),
    ("CMMO-ST", 402.0),
    ("Kinco FD3", f64::NAN),
    ("CiA 402 (EDS)", f64::NAN),
];

/// Simulated seconds per timed run, runs per figure.
const SIM_S: u64 = 4;
const RUNS: usize = 3;

/// Something the bench steps on the virtual clock.
trait Stepped {
    fn step_to(&mut self, now: Instant);
    /// The shaft's speed, min⁻¹ (to check that the axis really moved).
    fn speed_rpm(&self) -> f32;
}

impl<V: Vendor> Stepped for Drive<Vec<u8>, V> {
    fn step_to(&mut self, now: Instant) {
        self.step(now);
    }
    fn speed_rpm(&self) -> f32 {
        self.plant_velocity_rpm()
    }
}

impl Stepped for FhppDevice<Vec<u8>> {
    fn step_to(&mut self, now: Instant) {
        self.step(now);
    }
    fn speed_rpm(&self) -> f32 {
        self.stepper().velocity_rpm()
    }
}

/// `desc`'s drive in profile position towards `target` (user units).
fn moving<V: Vendor>(
    desc: &'static od::DeviceDescription,
    target: i32,
) -> (Drive<Vec<u8>, V>, Instant) {
    moving_after(desc, target, |_| {})
}

/// [`moving`], with `setup` applied to the drive at power-on.
fn moving_after<V: Vendor>(
    desc: &'static od::DeviceDescription,
    target: i32,
    setup: impl Fn(&mut Drive<Vec<u8>, V>),
) -> (Drive<Vec<u8>, V>, Instant) {
    let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).expect("storage");
    // No limit switches or hard stops: the axis travels for as long as the bench runs (the
    // default travel's positive limit switch would stop it after 64 revolutions, ≈ 4 s).
    let travel = TravelSettings {
        negative_stop: None,
        negative_limit: None,
        positive_limit: None,
        positive_stop: None,
        ..TravelSettings::default()
    };
    let settings = DriveSettings {
        travel,
        ..DriveSettings::default()
    };
    let mut d = Drive::new(od, settings);
    setup(&mut d);
    let mut now = Instant::ZERO;
    let mut step = |d: &mut Drive<Vec<u8>, V>, ms: u64| {
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

fn cmmp_as() -> (Drive<Vec<u8>, CmmpAs>, Instant) {
    moving(&devices::CMMP_AS, 1_000_000_000)
}

fn nanotec() -> (Drive<Vec<u8>, Nanotec>, Instant) {
    moving(&devices::NANOTEC_SMCI47S, 100_000_000)
}

/// The Kinco as a bus master sets it up (EA02 = 8): no DIN owns the controlword (2010h:03)
/// or the mode (2010h:05), so the master's 6040h / 6060h writes are taken.
fn kinco() -> (Drive<Vec<u8>, Kinco>, Instant) {
    let (mut d, mut now) = moving_after(&devices::KINCO_FD3, 100_000_000, |d| {
        for sub in [0x03, 0x05] {
            d.write(0x2010, sub, &0u16.to_le_bytes())
                .expect("DIN function");
        }
        // Profile velocity 600 min⁻¹, acceleration and deceleration 100 rps/s, in the
        // Kinco's DEC units (§8.2: rpm × 512 × 10 000 / 1875, rps/s × 65536 × 10 000 / 4e6).
        let rpm = (600.0f64 * 512.0 * 10_000.0 / 1875.0).round() as u32;
        let rps2 = (100.0f64 * 65536.0 * 10_000.0 / 4_000_000.0).round() as u32;
        for (index, value) in [(0x6081, rpm), (0x6083, rps2), (0x6084, rps2)] {
            d.write(index, 0, &value.to_le_bytes()).expect("profile");
        }
    });
    // Kinco §8.15 (KINCO-CW-01): a new set-point is 2Fh → 3Fh.
    for cw in [0x2Fu16, 0x3F] {
        d.write(0x6040, 0, &cw.to_le_bytes()).expect("cw");
        now = now + Duration::from_millis(2);
        d.step(now);
    }
    (d, now)
}

/// The generic drive on the dictionary of an EDS, read once.
fn generic() -> (Drive<Vec<u8>, Cia402>, Instant) {
    use std::sync::OnceLock;
    static DESC: OnceLock<&'static od::DeviceDescription> = OnceLock::new();
    let desc = DESC.get_or_init(|| {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../tests/interop/data/eds/epos4_like.eds");
        let eds = devdesc::eds::load_file(&path).expect("EDS");
        devdesc::runtime::leak(&eds.device)
    });
    moving(desc, 1_000_000_000)
}

/// The CMMO-ST enabled and jogging positive (CPOS.JOGP held), on the virtual clock.
fn cmmo_st() -> (FhppDevice<Vec<u8>>, Instant) {
    let desc = &devices::CMMO_ST;
    let od = ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).expect("storage");
    let mut dev = FhppDevice::new(od, FhppSettings::default());
    let mut now = Instant::ZERO;
    let enabled = Ccon(0x03);
    for out in [
        OutputData::record(enabled, Cpos::HALT, 0),
        OutputData::record(enabled, Cpos::HALT | Cpos::JOGP, 0),
    ] {
        dev.set_outputs(&out.to_bytes()).expect("outputs");
        for _ in 0..3 {
            now = now + Duration::from_millis(1);
            dev.step(now);
        }
    }
    (dev, now)
}

/// CPU time of one simulated second of `make`'s axis, stepped in 1 ms calls after a 200 ms
/// run-up: the best of [`RUNS`] runs of [`SIM_S`] s each.
fn per_simulated_second<D: Stepped>(make: impl Fn() -> (D, Instant)) -> Duration {
    let mut best = Duration::MAX;
    for _ in 0..RUNS {
        let (mut d, mut now) = make();
        for _ in 0..200 {
            now = now + Duration::from_millis(1);
            d.step_to(now);
        }
        let t = thread_cpu_time();
        for _ in 0..SIM_S * 1000 {
            now = now + Duration::from_millis(1);
            d.step_to(black_box(now));
        }
        let per_s = (thread_cpu_time() - t) / SIM_S as u32;
        assert!(
            d.speed_rpm().abs() > 1.0,
            "the axis stands at the end: {} min⁻¹",
            d.speed_rpm()
        );
        best = best.min(per_s);
    }
    best
}

fn criterion_1ms(c: &mut Criterion) {
    let (mut d, mut now) = cmmp_as();
    c.bench_function("drive_1ms_simulated", |b| {
        b.iter(|| {
            now = now + Duration::from_millis(1);
            d.step(now)
        })
    });
    let (mut d, mut now) = nanotec();
    c.bench_function("nanotec_1ms_simulated", |b| {
        b.iter(|| {
            now = now + Duration::from_millis(1);
            d.step(now)
        })
    });
    let (mut d, mut now) = cmmo_st();
    c.bench_function("cmmo_st_1ms_simulated", |b| {
        b.iter(|| {
            now = now + Duration::from_millis(1);
            d.step(now)
        })
    });
}

/// Axes per core of each personality, printed and drawn against the baseline.
fn report() {
    let figures = [
        ("CMMP-AS", per_simulated_second(cmmp_as)),
        ("Nanotec", per_simulated_second(nanotec)),
        ("CMMO-ST", per_simulated_second(cmmo_st)),
        ("Kinco FD3", per_simulated_second(kinco)),
        ("CiA 402 (EDS)", per_simulated_second(generic)),
    ];
    let mut axes = [0.0; 5];
    for ((name, per_s), (base_name, base)) in figures.iter().zip(BASELINE) {
        debug_assert_eq!(*name, base_name);
        let n = 1.0 / per_s.as_secs_f64();
        println!(
            "{name}: {:.3} ms of CPU per simulated second → {n:.0} axes in real time on one \
             core (baseline {base:.0}, target ≥ 1000)",
            per_s.as_secs_f64() * 1e3,
        );
        axes[figures.iter().position(|f| f.0 == *name).unwrap_or(0)] = n;
    }
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/axes-per-core.png");
    match plot::axes_per_core(&path, &axes) {
        Ok(()) => println!("plot: {}", path.display()),
        Err(e) => println!("plot not drawn: {e}"),
    }
}

mod plot {
    //! The bar chart: axes per core by personality, baseline against now, the target line.

    use std::path::Path;

    use plotters::prelude::*;

    pub fn axes_per_core(path: &Path, now: &[f64; 5]) -> Result<(), String> {
        crate::support::load_font()?;
        let root = BitMapBackend::new(path, (900, 540)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let top = super::BASELINE
            .iter()
            .map(|b| b.1)
            .chain(now.iter().copied())
            .filter(|v| v.is_finite())
            .fold(1000.0, f64::max)
            * 1.15;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Axes in real time per core (whole drive, 1 ms calls, moving)",
                ("sans-serif", 24),
            )
            .margin(16)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..5.0, 0.0..top)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            // Labels at 0, 0.5, 1, … 3: the halves are the personalities.
            .x_labels(11)
            .x_label_formatter(&|x: &f64| {
                let i = (*x - 0.5).round() as usize;
                super::BASELINE
                    .get(i)
                    .filter(|_| (*x - 0.5 - i as f64).abs() < 0.01)
                    .map_or(String::new(), |b| b.0.to_string())
            })
            .y_label_formatter(&|y: &f64| format!("{y:.0}"))
            .y_desc("axes per core")
            .label_style(("sans-serif", 16))
            .draw()
            .map_err(|e| e.to_string())?;
        let grey = RGBColor(170, 170, 170);
        let blue = RGBColor(40, 90, 170);
        for (i, ((_, base), n)) in super::BASELINE.iter().zip(now).enumerate() {
            let x = i as f64;
            for (x0, x1, v, color) in [
                (x + 0.12, x + 0.48, *base, grey),
                (x + 0.52, x + 0.88, *n, blue),
            ] {
                if !v.is_finite() {
                    continue;
                }
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(x0, 0.0), (x1, v)],
                        color.filled(),
                    )))
                    .map_err(|e| e.to_string())?;
                chart
                    .draw_series(std::iter::once(Text::new(
                        format!("{v:.0}"),
                        ((x0 + x1) / 2.0 - 0.06, v + top * 0.045),
                        ("sans-serif", 15).into_font().color(&BLACK),
                    )))
                    .map_err(|e| e.to_string())?;
            }
        }
        chart
            .draw_series(LineSeries::new(
                [(0.0, 1000.0), (5.0, 1000.0)],
                RED.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?
            .label("target 1000 axes (≤ 1 ms CPU per simulated second)")
            .legend(crate::support::line_swatch(RED.stroke_width(2)));
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(0.0, 0.0), (0.0, 0.0)],
                grey.filled(),
            )))
            .map_err(|e| e.to_string())?
            .label("before (c1c54dd)")
            .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 20, y + 6)], grey.filled()));
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(0.0, 0.0), (0.0, 0.0)],
                blue.filled(),
            )))
            .map_err(|e| e.to_string())?
            .label("now")
            .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 20, y + 6)], blue.filled()));
        crate::support::draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
        root.present().map_err(|e| e.to_string())
    }
}

criterion_group!(benches, criterion_1ms);

/// `DRIVE_BENCH_PROFILE=cmmp-as|nanotec|cmmo-st` (and `DRIVE_BENCH_MS`, default 1000): only
/// step that axis for so many simulated milliseconds after the run-up, for a profiler
/// (`valgrind --tool=callgrind --toggle-collect='*run_steps*'` counts just the steps).
fn profile(which: &str) {
    let ms = std::env::var("DRIVE_BENCH_MS")
        .ok()
        .and_then(|m| m.parse().ok())
        .unwrap_or(1000);
    match which {
        "cmmp-as" => profiled_steps(cmmp_as, ms),
        "nanotec" => profiled_steps(nanotec, ms),
        "cmmo-st" => profiled_steps(cmmo_st, ms),
        "kinco" => profiled_steps(kinco, ms),
        "cia402" => profiled_steps(generic, ms),
        _ => println!("DRIVE_BENCH_PROFILE: cmmp-as, nanotec, cmmo-st, kinco or cia402"),
    }
}

#[inline(never)]
fn profiled_steps<D: Stepped>(make: impl Fn() -> (D, Instant), ms: u64) {
    let (mut d, mut now) = make();
    for _ in 0..200 {
        now = now + Duration::from_millis(1);
        d.step_to(now);
    }
    run_steps(&mut d, now, ms);
}

#[inline(never)]
fn run_steps<D: Stepped>(d: &mut D, mut now: Instant, ms: u64) {
    for _ in 0..ms {
        now = now + Duration::from_millis(1);
        d.step_to(black_box(now));
    }
}

fn main() {
    if let Ok(which) = std::env::var("DRIVE_BENCH_PROFILE") {
        profile(&which);
        return;
    }
    report();
    benches();
    Criterion::default().configure_from_args().final_summary();
}
