//! Cost of the simulated CMMO-ST stepper: one `Stepper::step` of 50 µs (one integration
//! sub-step) in open loop (micro-stepping at 300 min⁻¹) and in closed loop (servo-lite at
//! 300 min⁻¹ with feed-forward), and the CPU time per simulated second (20 000 steps).

use std::f64::consts::TAU;
use std::hint::black_box;
use std::time::Instant;

use criterion::{criterion_group, Criterion};
use drive::stepper::{Stepper, StepperData, StepperDemand, StepperMode, STEP_S};

/// 300 min⁻¹ in revolutions per step.
const REV_PER_STEP: f64 = 300.0 / 60.0 * STEP_S;

struct Run {
    stepper: Stepper,
    pos_rev: f64,
}

impl Run {
    fn new(mode: StepperMode) -> Self {
        let mut stepper = Stepper::new(StepperData::default());
        stepper.set_mode(mode);
        Run {
            stepper,
            pos_rev: 0.0,
        }
    }

    #[inline]
    fn step(&mut self) {
        self.pos_rev += REV_PER_STEP;
        let demand = match self.stepper.mode() {
            StepperMode::OpenLoop => StepperDemand::Position {
                microsteps: (self.pos_rev * 3200.0) as i64,
            },
            StepperMode::ClosedLoop => StepperDemand::PositionIncrements {
                increments: (self.pos_rev * 2000.0) as i64,
                velocity_ff_rpm: 300.0,
            },
        };
        self.stepper.step(STEP_S, black_box(demand));
    }
}

fn bench_step(c: &mut Criterion) {
    for (name, mode) in [
        ("stepper_step_open_loop", StepperMode::OpenLoop),
        ("stepper_step_closed_loop", StepperMode::ClosedLoop),
    ] {
        let mut run = Run::new(mode);
        c.bench_function(name, |b| {
            b.iter(|| {
                run.step();
                black_box(run.stepper.encoder_increments())
            })
        });
    }
}

/// Wall-clock figure outside criterion: 60 simulated seconds per mode, best of 5.
fn report_real_time() {
    let steps_per_s = (1.0 / STEP_S).round() as u64;
    let sim_s = 60;
    for (name, mode) in [
        ("open loop", StepperMode::OpenLoop),
        ("closed loop", StepperMode::ClosedLoop),
    ] {
        let mut best = f64::INFINITY;
        for _ in 0..5 {
            let mut run = Run::new(mode);
            let t0 = Instant::now();
            for _ in 0..steps_per_s * sim_s {
                run.step();
            }
            black_box(run.stepper.encoder_increments());
            let ns = t0.elapsed().as_nanos() as f64 / (steps_per_s * sim_s) as f64;
            best = best.min(ns);
            // The run really moved: 300 revolutions, no steps lost.
            assert_eq!(run.stepper.lost_steps(), 0);
            assert!((run.stepper.angle() / TAU - 300.0).abs() < 0.01);
        }
        let per_sim_s_ms = best * steps_per_s as f64 / 1e6;
        println!(
            "stepper {name}: {best:.1} ns per 50 µs step; {steps_per_s} steps per simulated \
             second → {per_sim_s_ms:.3} ms CPU per simulated second; {:.0} steppers in real \
             time per core",
            1000.0 / per_sim_s_ms
        );
    }
}

criterion_group!(benches, bench_step);

fn main() {
    benches();
    report_real_time();
    Criterion::default().configure_from_args().final_summary();
}
