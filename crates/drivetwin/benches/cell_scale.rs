//! A whole machine on the virtual clock:
//!
//! - the bus model's cost per frame (a frame submitted to the timed bus and taken off it when
//!   it has crossed), criterion;
//! - the CPU share of a 127-node cell of mixed personalities (CMMP-AS, Nanotec SMCI47-S, Kinco
//!   FD3 in turn, each with its simulated drive and motor), operational, SYNC every 1 ms on a
//!   1 Mbit/s bus, each TPDO1 at every 10th SYNC: the thread's CPU time per simulated second;
//! - the bus load of that cell (TPDO1 at every SYNC) against the bit rate at four SYNC
//!   periods, drawn into
//!   `docs/bus-load-127-nodes.png`.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use canopen::CanFrame;
use criterion::{criterion_group, Criterion};
use drive::drive::DriveSettings;
use drivetwin::cell::bus_timing::BusTiming;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::station::{Commissioning, Station};
use drivetwin::cell_loop::virtual_clock::run_virtual;
use od::Instant;
use support::thread_cpu_time;

#[path = "../../drive/benches/support/mod.rs"]
mod support;

const NODES: u8 = 127;
const PERSONALITIES: [&str; 3] = ["cmmp-as", "nanotec-smci47s", "kinco-fd3"];
const BIT_RATES: [u32; 5] = [125_000, 250_000, 500_000, 800_000, 1_000_000];
const SYNC_PERIODS_MS: [u64; 4] = [5, 10, 20, 50];

/// 127 nodes, TPDO1 synchronous (every `every`th SYNC), heartbeat 100 ms; `motors`: each
/// with its simulated drive and motor (else the CANopen side only).
fn cell(bitrate: u32, every: u8, motors: bool) -> CanCell {
    let drives = (1..=NODES)
        .map(|node| {
            let name = PERSONALITIES[usize::from(node) % PERSONALITIES.len()];
            let desc = devices::by_name(name).expect("a personality of the workspace");
            let commissioning = [
                (0x1017, 0, 100u16.to_le_bytes().to_vec()),
                (0x1800, 2, vec![every]),
            ]
            .into_iter()
            .map(|(index, sub, bytes)| Commissioning { index, sub, bytes })
            .collect();
            let settings = motors.then(DriveSettings::default);
            Station::with_settings(desc, node, None, commissioning, settings).expect("a drive")
        })
        .collect();
    CanCell::one_timed_bus(drives, bitrate, Duration::from_millis(1))
}

/// NMT start for all at 10 ms, then SYNC every `period` until `until`.
fn inputs(period: Duration, until: Duration) -> Vec<(Duration, CanFrame)> {
    let mut inputs = vec![(
        Duration::from_millis(10),
        CanFrame::new(0x000, &[0x01, 0x00]).expect("NMT"),
    )];
    let mut t = Duration::from_millis(20);
    while t < until {
        inputs.push((t, CanFrame::new(0x080, &[]).expect("SYNC")));
        t += period;
    }
    inputs
}

/// The CPU time of one simulated second of the 127-node cell with motors at 1 Mbit/s, SYNC
/// 1 ms, each TPDO1 at every 10th SYNC (88 % of the bus): the best of three runs of 1.2 s
/// each (the first 0.2 s of each not counted).
fn cpu_share() -> Duration {
    let until = Duration::from_millis(1200);
    let sync = inputs(Duration::from_millis(1), until);
    let mut best = Duration::MAX;
    for _ in 0..3 {
        let mut warm = cell(1_000_000, 10, true);
        let t0 = thread_cpu_time();
        run_virtual(&mut warm, &sync, Duration::from_millis(200), &mut |_, _| {});
        let run_up = thread_cpu_time() - t0;
        let mut c = cell(1_000_000, 10, true);
        let mut frames = 0u64;
        let t0 = thread_cpu_time();
        run_virtual(&mut c, &sync, until, &mut |_, f| {
            frames += 1;
            black_box(f);
        });
        best = best.min((thread_cpu_time() - t0).saturating_sub(run_up));
        black_box(frames);
    }
    best
}

/// The bus load (percent, over the last second: the cell's figure) of the 127-node cell after
/// 1.5 s, past its first window of boot-ups and NMT start.
fn bus_load(bitrate: u32, sync: Duration) -> f64 {
    let until = Duration::from_millis(1500);
    let mut c = cell(bitrate, 1, false);
    run_virtual(&mut c, &inputs(sync, until), until, &mut |_, _| {});
    let now = Instant::from_nanos(until.as_nanos() as u64);
    c.buses[0].bus_figures(now).map_or(0.0, |f| f.load_percent)
}

fn report() {
    let per_s = cpu_share();
    println!(
        "127-node cell (CMMP-AS, Nanotec, Kinco with motors), 1 Mbit/s, SYNC 1 ms, TPDO1 \
         every 10th SYNC: {:.1} ms of CPU per simulated second = {:.1} % of one core",
        per_s.as_secs_f64() * 1e3,
        per_s.as_secs_f64() * 100.0
    );
    let mut loads = Vec::new();
    for period in SYNC_PERIODS_MS {
        let row: Vec<f64> = BIT_RATES
            .iter()
            .map(|&b| bus_load(b, Duration::from_millis(period)))
            .collect();
        println!(
            "bus load, SYNC {period} ms: {}",
            BIT_RATES
                .iter()
                .zip(&row)
                .map(|(b, l)| format!("{} kbit/s {l:.0} %", b / 1000))
                .collect::<Vec<_>>()
                .join(", ")
        );
        loads.push(row);
    }
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/bus-load-127-nodes.png");
    match plot::bus_load(&path, &loads) {
        Ok(()) => println!("plot: {}", path.display()),
        Err(e) => println!("plot not drawn: {e}"),
    }
}

/// The bus model per frame: 127 sources with a frame each, all taken off the bus.
fn bus_model(c: &mut Criterion) {
    let frames: Vec<CanFrame> = (1..=u16::from(NODES))
        .map(|n| CanFrame::new(0x180 + n, &[0x37, 0x06]).expect("a TPDO"))
        .collect();
    let mut g = c.benchmark_group("bus_model");
    g.throughput(criterion::Throughput::Elements(frames.len() as u64));
    g.bench_function("submit_and_cross_127_frames", |b| {
        let mut bus = BusTiming::new(1_000_000, Duration::from_millis(1));
        let mut now = Instant::ZERO;
        b.iter(|| {
            for (source, f) in frames.iter().enumerate() {
                bus.submit(now, source as u16, *f);
            }
            now = Instant::from_nanos(now.as_nanos() + 20_000_000);
            while let Some(tx) = bus.poll(now) {
                black_box(tx);
            }
        })
    });
    g.finish();
}

mod plot {
    //! Bus load against the bit rate, one line per SYNC period, the 100 % line.

    use std::path::Path;

    use plotters::prelude::*;

    pub fn bus_load(path: &Path, loads: &[Vec<f64>]) -> Result<(), String> {
        crate::support::load_font()?;
        let root = BitMapBackend::new(path, (900, 540)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let top = loads
            .iter()
            .flatten()
            .copied()
            .fold(120.0, f64::max)
            .min(2000.0);
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "127 nodes, TPDO1 synchronous, heartbeat 100 ms: bus load",
                ("sans-serif", 24),
            )
            .margin(16)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d((100.0..1050.0).log_scale(), (5.0..top).log_scale())
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("bit rate, kbit/s")
            .y_desc("bus load, % (500 ms window)")
            .x_label_formatter(&|x: &f64| format!("{x:.0}"))
            .y_label_formatter(&|y: &f64| format!("{y:.0}"))
            .label_style(("sans-serif", 16))
            .draw()
            .map_err(|e| e.to_string())?;
        let colors = [
            RGBColor(170, 40, 40),
            RGBColor(200, 120, 20),
            RGBColor(40, 90, 170),
            RGBColor(40, 140, 60),
        ];
        for ((period, row), color) in super::SYNC_PERIODS_MS.iter().zip(loads).zip(colors) {
            let points: Vec<(f64, f64)> = super::BIT_RATES
                .iter()
                .zip(row)
                .map(|(b, l)| (f64::from(*b) / 1000.0, l.clamp(5.0, top)))
                .collect();
            chart
                .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(format!("SYNC every {period} ms"))
                .legend(crate::support::line_swatch(color.stroke_width(2)));
            chart
                .draw_series(
                    points
                        .into_iter()
                        .map(|p| Circle::new(p, 4, color.filled())),
                )
                .map_err(|e| e.to_string())?;
        }
        chart
            .draw_series(LineSeries::new(
                [(100.0, 100.0), (1050.0, 100.0)],
                BLACK.stroke_width(1),
            ))
            .map_err(|e| e.to_string())?
            .label("100 %: the bus is full, frames wait and are lost")
            .legend(crate::support::line_swatch(BLACK.stroke_width(1)));
        crate::support::draw_legend(&mut chart, SeriesLabelPosition::LowerLeft)?;
        root.present().map_err(|e| e.to_string())
    }
}

criterion_group!(benches, bus_model);

fn main() {
    report();
    benches();
    Criterion::default().configure_from_args().final_summary();
}
