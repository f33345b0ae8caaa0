//! Cost of one simulated CMMP-AS axis: one `Axis::step` (one 125 µs current-controller cycle)
//! with all three loops active (position demand moving at 1000 min⁻¹ with feed-forward).
//!
//! Target: one core simulates ≥ 500 axes in real time, i.e. ≤ 2 ms of CPU per simulated
//! second per axis = ≤ 250 ns per step at 8000 steps/s.

use std::hint::black_box;
use std::time::Instant;

use criterion::{criterion_group, Criterion};
use drive::axis::{Axis, Demand};
use drive::control::ControlParams;
use drive::motor::MotorData;

/// Position demand of a 1000 min⁻¹ move: 65536·1000/60/8000 ≈ 136.5 increments per step.
const INC_PER_STEP: f64 = 65536.0 * 1000.0 / 60.0 / 8000.0;

struct Run {
    axis: Axis,
    demand: f64,
}

impl Run {
    fn new() -> Self {
        Run {
            axis: Axis::new(MotorData::default(), ControlParams::default()),
            demand: 0.0,
        }
    }

    #[inline]
    fn step(&mut self) {
        self.demand += INC_PER_STEP;
        self.axis.step(black_box(Demand::Position {
            increments: self.demand as i64,
            velocity_ff_rpm: 1000.0,
        }));
    }
}

fn bench_step(c: &mut Criterion) {
    let mut run = Run::new();
    c.bench_function("axis_step_position_all_loops", |b| {
        b.iter(|| {
            run.step();
            black_box(run.axis.position_increments())
        })
    });
}

/// Wall-clock figure outside criterion: simulate 60 s of one axis and report the CPU time per
/// step and per simulated second.
fn report_real_time() {
    let steps_per_s =
        (1.0 / Axis::new(MotorData::default(), ControlParams::default()).cycle_s()).round() as u64;
    let sim_s = 60;
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let mut run = Run::new();
        let t0 = Instant::now();
        for _ in 0..steps_per_s * sim_s {
            run.step();
        }
        black_box(run.axis.position_increments());
        let ns = t0.elapsed().as_nanos() as f64 / (steps_per_s * sim_s) as f64;
        best = best.min(ns);
    }
    let per_sim_s_ms = best * steps_per_s as f64 / 1e6;
    println!(
        "axis: {best:.1} ns per step; {steps_per_s} steps per simulated second → \
         {per_sim_s_ms:.3} ms CPU per simulated second per axis; \
         {:.0} axes in real time per core (target ≥ 500, ≤ 2 ms)",
        1000.0 / per_sim_s_ms
    );
}

criterion_group!(benches, bench_step);

fn main() {
    benches();
    report_real_time();
    Criterion::default().configure_from_args().final_summary();
}
