//! The simulated CMMO-ST stepper plant: open-loop micro-stepping (following, lost steps, pull-out
//! torque falling with speed, holding), closed loop (servo-lite), determinism, and the SINC scaling
//! vectors of the vector catalogue kept beside the project, §2.5 (FHPP-SC-01, FHPP-SC-02,
//! FHPP-SC-03) by their IDs.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::f64::consts::TAU;

use drive::stepper::{
    si_to_sinc, sinc_to_si, sinc_to_unit, unit_to_sinc, SincUnit, Stepper, StepperData,
    StepperDemand, StepperMode, ENCODER_INCREMENTS_PER_REV, MAX_STEP_CLOSED_LOOP_S,
    MAX_STEP_OPEN_LOOP_S, RAD_S_TO_RPM, RPM_TO_RAD_S, STEP_S,
};

/// Integration steps per simulated second (50 µs).
const STEPS_PER_S: usize = 20_000;
/// Encoder increments per revolution, micro-steps per revolution (200 × 16), per full step.
const INC_REV: f64 = ENCODER_INCREMENTS_PER_REV as f64;
const MICRO_REV: f64 = 3200.0;
const INC_PER_FULL_STEP: i64 = 10;

/// Position (rad) and speed (rad/s) at `t` of a trapezoidal move over `dist` rad.
fn trapezoid(t: f64, dist: f64, vmax: f64, acc: f64) -> (f64, f64) {
    let mut ta = vmax / acc;
    let mut v = vmax;
    let mut da = 0.5 * acc * ta * ta;
    if 2.0 * da > dist {
        ta = (dist / acc).sqrt();
        v = acc * ta;
        da = dist / 2.0;
    }
    let tc = (dist - 2.0 * da) / v;
    if t < ta {
        (0.5 * acc * t * t, acc * t)
    } else if t < ta + tc {
        (da + v * (t - ta), v)
    } else if t < 2.0 * ta + tc {
        let u = 2.0 * ta + tc - t;
        (dist - 0.5 * acc * u * u, acc * u)
    } else {
        (dist, 0.0)
    }
}

/// A move profile: distance (rev), top speed (min⁻¹), acceleration (rad/s²).
#[derive(Clone, Copy)]
struct Profile {
    revs: f64,
    rpm: f64,
    acc: f64,
}

/// Moderate: 3 revolutions at 300 min⁻¹, 2000 rad/s² (J·α = 0.04 N·m, 8 % of holding).
const MODERATE: Profile = Profile {
    revs: 3.0,
    rpm: 300.0,
    acc: 2000.0,
};

/// Demanding: 3 revolutions at 600 min⁻¹, 20 000 rad/s² (J·α = 0.4 N·m, 80 % of holding,
/// switched on and off at once).
const DEMANDING: Profile = Profile {
    revs: 3.0,
    rpm: 600.0,
    acc: 20_000.0,
};

/// What a run saw.
#[derive(Debug, Default)]
struct Seen {
    /// Largest |set-point − encoder|, increments.
    max_following_error: i64,
    /// Largest |commanded − actual|, full steps.
    max_error_full_steps: f64,
    /// Largest current-vector amplitude, A.
    max_current: f64,
    /// First non-zero lost_steps() seen.
    first_lost: i64,
}

/// Runs `p` for one second (plus the settling in it), open loop in micro-steps or closed loop
/// in increments with the speed feed-forward.
fn run_profile(s: &mut Stepper, p: Profile, seconds: f64) -> Seen {
    let dist = p.revs * TAU;
    let vmax = p.rpm * RPM_TO_RAD_S;
    let mut seen = Seen::default();
    let n = (seconds * STEPS_PER_S as f64) as usize;
    for k in 1..=n {
        let (pos, vel) = trapezoid(k as f64 * STEP_S, dist, vmax, p.acc);
        let demand = match s.mode() {
            StepperMode::OpenLoop => StepperDemand::Position {
                microsteps: (pos / TAU * MICRO_REV).round() as i64,
            },
            StepperMode::ClosedLoop => StepperDemand::PositionIncrements {
                increments: (pos / TAU * INC_REV).round() as i64,
                velocity_ff_rpm: (vel * RAD_S_TO_RPM) as f32,
            },
        };
        s.step(STEP_S, demand);
        seen.max_following_error = seen
            .max_following_error
            .max(s.following_error_increments().abs());
        seen.max_error_full_steps = seen
            .max_error_full_steps
            .max(s.position_error_full_steps().abs());
        seen.max_current = seen.max_current.max(s.current_a());
        if seen.first_lost == 0 {
            seen.first_lost = s.lost_steps();
        }
    }
    seen
}

fn stepper(mode: StepperMode) -> Stepper {
    let mut s = Stepper::new(StepperData::default());
    s.set_mode(mode);
    s
}

// ---- open loop ------------------------------------------------------------------------------

#[test]
fn open_loop_follows_moderate_trapezoid_exactly() {
    let mut s = stepper(StepperMode::OpenLoop);
    let seen = run_profile(&mut s, MODERATE, 1.0);
    assert_eq!(seen.first_lost, 0, "no step lost on the way");
    assert!(
        seen.max_following_error < INC_PER_FULL_STEP,
        "encoder within one full step of the command: {seen:?}"
    );
    assert!(seen.max_error_full_steps < 1.0, "{seen:?}");
    // At the end: exactly where commanded, in both units.
    assert_eq!(s.commanded_microsteps(), 3 * 3200);
    assert_eq!(s.lost_steps(), 0);
    assert_eq!(s.actual_microsteps(), 3 * 3200);
    assert!(
        (s.encoder_increments() - 6000).abs() <= 1,
        "{}",
        s.encoder_increments()
    );
    // Open loop runs at the rated current whatever the load.
    assert!((s.current_a() - 2.0).abs() < 1e-9, "{}", s.current_a());
    assert!(s.velocity_rpm().abs() < 1.0);
}

#[test]
fn open_loop_too_steep_acceleration_loses_steps() {
    let mut s = stepper(StepperMode::OpenLoop);
    let seen = run_profile(&mut s, DEMANDING, 1.0);
    let lost = s.lost_steps();
    assert!(lost > 0, "steps lost: {lost} ({seen:?})");
    assert!(seen.first_lost != 0);
    // The rotor slips by whole electrical periods of 4 full steps.
    assert_eq!(lost % 4, 0, "{lost}");
    // The encoder shows it: it lags the command by the lost steps (10 increments each).
    let shortfall = 6000 - s.encoder_increments();
    assert!(
        (shortfall - lost * INC_PER_FULL_STEP).abs() < INC_PER_FULL_STEP,
        "encoder {} vs lost {lost}",
        s.encoder_increments()
    );
    assert_eq!(
        s.commanded_microsteps(),
        3 * 3200,
        "the command itself is complete"
    );
}

#[test]
fn open_loop_excessive_load_loses_steps_at_standstill() {
    let mut s = stepper(StepperMode::OpenLoop);
    for _ in 0..STEPS_PER_S / 10 {
        s.step(STEP_S, StepperDemand::Position { microsteps: 0 });
    }
    assert_eq!(s.lost_steps(), 0);
    // 0.6 N·m > 0.5 N·m holding torque pulls the rotor backwards for 20 ms...
    s.set_load_torque(0.6);
    for _ in 0..STEPS_PER_S / 50 {
        s.step(STEP_S, StepperDemand::Hold);
    }
    // ... then the load is gone and the rotor locks again at another equilibrium.
    s.set_load_torque(0.0);
    for _ in 0..STEPS_PER_S {
        s.step(STEP_S, StepperDemand::Hold);
    }
    let lost = s.lost_steps();
    assert!(lost > 0, "{lost}");
    assert_eq!(lost % 4, 0);
    assert!(
        s.velocity_rpm().abs() < 1.0,
        "locked again: {}",
        s.velocity_rpm()
    );
    assert!(
        (s.encoder_increments() + lost * INC_PER_FULL_STEP).abs() <= 1,
        "encoder {} for {lost} lost steps",
        s.encoder_increments()
    );
    assert_eq!(s.commanded_microsteps(), 0);
}

/// Open loop at a constant `rpm`, then the load rises at 0.2 N·m/s until a step is lost:
/// the load at that moment, N·m.
fn open_loop_pull_out(rpm: f64) -> f64 {
    let mut s = stepper(StepperMode::OpenLoop);
    let w = rpm * RPM_TO_RAD_S;
    let acc = 1000.0;
    let (mut pos, mut vel, mut load) = (0.0_f64, 0.0_f64, 0.0_f64);
    let settle = w / acc + 0.2;
    for k in 1..=20 * STEPS_PER_S {
        vel = (vel + acc * STEP_S).min(w);
        pos += vel * STEP_S;
        if k as f64 * STEP_S > settle {
            load += 0.2 * STEP_S;
            s.set_load_torque(load);
        }
        s.step(
            STEP_S,
            StepperDemand::Position {
                microsteps: (pos / TAU * MICRO_REV).round() as i64,
            },
        );
        if s.lost_steps() != 0 {
            return load;
        }
    }
    panic!("no pull-out up to {load} N·m at {rpm} min⁻¹");
}

#[test]
fn pull_out_torque_falls_with_speed() {
    let d = StepperData::default();
    let speeds = [100.0, 500.0, 800.0, 1000.0];
    let pull_out: Vec<f64> = speeds.iter().map(|&n| open_loop_pull_out(n)).collect();
    // Near standstill: the holding torque less friction.
    assert!(
        pull_out[0] > 0.9 * d.holding_torque && pull_out[0] < d.holding_torque,
        "{pull_out:?}"
    );
    for i in 1..speeds.len() {
        assert!(
            pull_out[i] < pull_out[i - 1] - 0.005,
            "pull-out must fall with speed: {speeds:?} → {pull_out:?}"
        );
    }
    // Well below at 1000 min⁻¹ (the supply voltage limits the current).
    assert!(pull_out[3] < 0.7 * pull_out[0], "{pull_out:?}");
    // Never above the steady-state torque–speed curve of the winding.
    for (&n, &t) in speeds.iter().zip(&pull_out) {
        let bound = d.peak_torque(n, d.rated_current);
        assert!(t <= bound, "{n} min⁻¹: pull-out {t} > curve {bound}");
    }
}

#[test]
fn torque_speed_curve_from_winding_and_supply() {
    let d = StepperData::default();
    let k = d.torque_constant();
    assert!((k - 0.25).abs() < 1e-12);
    // Full torque at standstill and below the corner speed.
    assert!((d.peak_torque(0.0, 2.0) - 0.5).abs() < 1e-12);
    assert!((d.peak_torque(500.0, 2.0) - 0.5).abs() < 1e-12);
    // Falling monotonically above it, symmetric in the direction.
    let mut last = d.peak_torque(600.0, 2.0);
    for n in (700..=3000).step_by(100) {
        let t = d.peak_torque(n as f64, 2.0);
        assert!(t < last, "{n} min⁻¹: {t} !< {last}");
        assert_eq!(t, d.peak_torque(-(n as f64), 2.0));
        last = t;
    }
    assert!(d.peak_torque(1000.0, 2.0) < 0.8 * 0.5);
    // A higher supply voltage moves the corner up.
    let d48 = StepperData {
        supply_voltage: 48.0,
        ..d
    };
    assert!(d48.peak_torque(1000.0, 2.0) > d.peak_torque(1000.0, 2.0));
    assert!((d48.peak_torque(1000.0, 2.0) - 0.5).abs() < 1e-12);
    // Less current, less torque; no current or no data, none.
    assert!((d.peak_torque(100.0, 1.0) - 0.25).abs() < 1e-12);
    assert_eq!(d.peak_torque(100.0, 0.0), 0.0);
    assert_eq!(d.peak_torque(f64::NAN, 2.0), 0.0);
}

#[test]
fn open_loop_holds_against_a_load_below_holding_torque() {
    let mut s = stepper(StepperMode::OpenLoop);
    s.set_load_torque(0.25);
    for _ in 0..STEPS_PER_S {
        s.step(STEP_S, StepperDemand::Position { microsteps: 0 });
    }
    assert_eq!(s.lost_steps(), 0);
    assert_eq!(s.velocity(), 0.0, "at rest");
    // Static load angle: T_load = T_hold·sin(N_r·Δθ) (± detent and friction) → ≈ 30°
    // electrical = 0.6° = 3.3 increments behind.
    let expected = -(0.25_f64 / 0.5).asin() / 50.0;
    assert!(
        (s.angle() - expected).abs() < 0.1 * expected.abs(),
        "{} vs {expected}",
        s.angle()
    );
    assert!(
        (-5..=-2).contains(&s.encoder_increments()),
        "{}",
        s.encoder_increments()
    );
    assert!(s.position_error_full_steps() > 0.0 && s.position_error_full_steps() < 1.0);
}

#[test]
fn positions_in_increments_and_microsteps() {
    let mut s = stepper(StepperMode::OpenLoop);
    // An increment set-point in open loop rounds to the nearest micro-step (1.6 per increment).
    s.step(
        STEP_S,
        StepperDemand::PositionIncrements {
            increments: 1001,
            velocity_ff_rpm: 0.0,
        },
    );
    assert_eq!(s.commanded_microsteps(), 1602);
    assert_eq!(s.commanded_increments(), 1001);
    s.step(STEP_S, StepperDemand::Position { microsteps: -3 });
    assert_eq!(s.commanded_increments(), -2, "⌊−3 / 1.6⌋");
    // A slow move of one revolution: 2000 increments, 3200 micro-steps.
    for k in 1..=STEPS_PER_S {
        let m = (k as f64 / STEPS_PER_S as f64 * 1.0 * MICRO_REV) as i64;
        s.step(STEP_S, StepperDemand::Position { microsteps: m });
    }
    for _ in 0..STEPS_PER_S / 5 {
        s.step(STEP_S, StepperDemand::Hold);
    }
    assert_eq!(s.actual_microsteps(), 3200);
    assert!((s.encoder_increments() - 2000).abs() <= 1);
}

// ---- closed loop ----------------------------------------------------------------------------

#[test]
fn closed_loop_follows_demanding_profile_without_losing_position() {
    let mut s = stepper(StepperMode::ClosedLoop);
    let d = *s.data();
    let seen = run_profile(&mut s, DEMANDING, 1.0);
    assert_eq!(seen.first_lost, 0, "{seen:?}");
    assert_eq!(s.lost_steps(), 0);
    // The following error stays below one full step (10 increments) throughout.
    assert!(seen.max_following_error < INC_PER_FULL_STEP, "{seen:?}");
    // The current never exceeds the limit.
    assert!(seen.max_current <= d.max_current * (1.0 + 1e-9), "{seen:?}");
    // In position at the end, and the current has fallen to what the friction needs.
    assert!(
        (s.encoder_increments() - 6000).abs() <= 1,
        "{}",
        s.encoder_increments()
    );
    assert!(s.current_a() < 0.2 * d.max_current, "{}", s.current_a());
    // The same profile loses steps in open loop (test above); moderate is easy, too.
    let mut s = stepper(StepperMode::ClosedLoop);
    let seen = run_profile(&mut s, MODERATE, 1.0);
    assert!(seen.max_following_error < INC_PER_FULL_STEP, "{seen:?}");
    assert!(
        seen.max_current < 0.5 * d.max_current,
        "current adapts: {seen:?}"
    );
}

#[test]
fn closed_loop_holds_against_load_with_adapted_current() {
    let mut s = stepper(StepperMode::ClosedLoop);
    let d = *s.data();
    for _ in 0..STEPS_PER_S / 5 {
        s.step(STEP_S, StepperDemand::Hold);
    }
    assert!(
        s.current_a() < 0.1,
        "no load, little current: {}",
        s.current_a()
    );
    s.set_load_torque(0.3);
    for _ in 0..STEPS_PER_S {
        s.step(STEP_S, StepperDemand::Hold);
    }
    assert_eq!(s.lost_steps(), 0);
    assert!(
        s.following_error_increments().abs() <= 1,
        "{}",
        s.following_error_increments()
    );
    // T = k·I: about 0.3 N·m / 0.25 N·m/A = 1.2 A (± Coulomb friction, detent).
    let i = s.current_a();
    assert!((i - 1.2).abs() < 0.15, "{i} A");
    assert!(s.torque_set() > 0.25 && s.torque_set() < 0.35);
    // 0.45 N·m, still below the peak torque: holds as well.
    s.set_load_torque(0.45);
    for _ in 0..STEPS_PER_S {
        s.step(STEP_S, StepperDemand::Hold);
    }
    assert!(s.following_error_increments().abs() <= 1);
    assert!(s.current_a() <= d.max_current * (1.0 + 1e-9));
    // Above the peak torque even the closed loop is pushed back.
    s.set_load_torque(0.7);
    for _ in 0..STEPS_PER_S / 10 {
        s.step(STEP_S, StepperDemand::Hold);
    }
    assert!(s.following_error_increments() > 100);
}

#[test]
fn blocked_shaft_and_output_stage_off() {
    let mut s = stepper(StepperMode::OpenLoop);
    s.set_blocked(true);
    for k in 1..=STEPS_PER_S / 10 {
        s.step(
            STEP_S,
            StepperDemand::Position {
                microsteps: k as i64,
            },
        );
    }
    assert_eq!(s.angle(), 0.0);
    assert_eq!(s.lost_steps(), 4 * ((2000.0_f64 / 64.0).round() as i64));
    s.set_blocked(false);
    s.step(STEP_S, StepperDemand::Off);
    assert_eq!(s.current_a(), 0.0);
    assert!(!s.energised());
    // Off, a load turns the shaft freely (only detent and friction hold it).
    s.set_load_torque(0.1);
    for _ in 0..STEPS_PER_S / 10 {
        s.step(STEP_S, StepperDemand::Off);
    }
    assert!(s.encoder_increments() < -100);
}

/// Closed loop at standstill half a full step off a detent position (the detent's unstable
/// point), with and without a load: the axis settles at the set-point and stays there, it
/// does not hunt between the neighbouring detent positions (it did, by ±5 increments,
/// before the controller compensated the detent), and a load stays held.
#[test]
fn closed_loop_stands_still_between_detent_positions() {
    for load in [0.0, 0.05, 0.2] {
        for target in [5i64, 15, 55, 95, 13, 40] {
            let mut s = stepper(StepperMode::ClosedLoop);
            s.set_load_torque(load);
            // There at 300 min⁻¹ (10 increments per ms), then the set-point stands.
            let mut sp = 0;
            while sp < target {
                sp = (sp + 10).min(target);
                s.step(
                    1e-3,
                    StepperDemand::PositionIncrements {
                        increments: sp,
                        velocity_ff_rpm: 300.0,
                    },
                );
            }
            let hold = StepperDemand::PositionIncrements {
                increments: target,
                velocity_ff_rpm: 0.0,
            };
            for _ in 0..300 {
                s.step(1e-3, hold);
            }
            for ms in 0..2000 {
                s.step(1e-3, hold);
                assert_eq!(
                    s.encoder_increments(),
                    target,
                    "load {load} N·m, target {target}: {ms} ms into the standstill"
                );
            }
        }
    }
}

// ---- determinism and robustness -------------------------------------------------------------

fn fingerprint(mode: StepperMode) -> Vec<u64> {
    let mut s = stepper(mode);
    s.set_load_torque(0.05);
    run_profile(&mut s, DEMANDING, 0.3);
    let (ia, ib) = s.phase_currents();
    vec![
        s.angle().to_bits(),
        s.velocity().to_bits(),
        ia.to_bits(),
        ib.to_bits(),
        s.encoder_increments() as u64,
        s.lost_steps() as u64,
        s.torque_set().to_bits(),
    ]
}

#[test]
fn deterministic_bit_for_bit() {
    for mode in [StepperMode::OpenLoop, StepperMode::ClosedLoop] {
        assert_eq!(fingerprint(mode), fingerprint(mode));
    }
    // A clone continues exactly like the original.
    let mut a = stepper(StepperMode::ClosedLoop);
    run_profile(&mut a, MODERATE, 0.1);
    let mut b = a.clone();
    for s in [&mut a, &mut b] {
        for _ in 0..1000 {
            s.step(STEP_S, StepperDemand::Hold);
        }
    }
    assert_eq!(a.angle().to_bits(), b.angle().to_bits());
    assert_eq!(a.phase_currents(), b.phase_currents());
}

#[test]
fn long_calls_are_sub_stepped() {
    // 1 ms calls = 8 sub-steps of 125 µs in open loop: the same, bit for bit, as 8 calls of
    // 125 µs while holding; and within 2·10⁻⁵ rad (a hundredth of an encoder increment) of
    // 20 calls of 50 µs (a finer fixed sub-step).
    let mut a = stepper(StepperMode::OpenLoop);
    let mut b = a.clone();
    let mut c = a.clone();
    for s in [&mut a, &mut b, &mut c] {
        s.set_load_torque(0.2);
    }
    let demand = StepperDemand::Position { microsteps: 5 };
    for _ in 0..100 {
        a.step(1e-3, demand);
        for _ in 0..8 {
            b.step(MAX_STEP_OPEN_LOOP_S, demand);
        }
        for _ in 0..20 {
            c.step(STEP_S, demand);
        }
    }
    assert_eq!(a.angle().to_bits(), b.angle().to_bits());
    assert!(
        (a.angle() - c.angle()).abs() < 2e-5,
        "{} {}",
        a.angle(),
        c.angle()
    );
    // Closed loop: 10 sub-steps of 100 µs.
    let mut a = stepper(StepperMode::ClosedLoop);
    let mut b = a.clone();
    let demand = StepperDemand::PositionIncrements {
        increments: 40,
        velocity_ff_rpm: 0.0,
    };
    for _ in 0..100 {
        a.step(1e-3, demand);
        for _ in 0..10 {
            b.step(MAX_STEP_CLOSED_LOOP_S, demand);
        }
    }
    assert_eq!(a.angle().to_bits(), b.angle().to_bits());
    assert_eq!(a.encoder_increments(), 40);
    // A 1 s call stays stable.
    a.step(1.0, StepperDemand::Hold);
    assert!(a.angle().is_finite() && a.lost_steps() == 0);
}

#[test]
fn bad_inputs_do_not_poison_the_state() {
    let mut s = stepper(StepperMode::ClosedLoop);
    s.step(f64::NAN, StepperDemand::Hold);
    s.step(-1.0, StepperDemand::Hold);
    s.step(f64::INFINITY, StepperDemand::Hold);
    assert_eq!(s.steps(), 0);
    for _ in 0..100 {
        s.step(
            STEP_S,
            StepperDemand::PositionIncrements {
                increments: 0,
                velocity_ff_rpm: f32::NAN,
            },
        );
    }
    assert!(s.angle().is_finite() && s.current_a().is_finite());
    // Extreme set-points saturate instead of overflowing.
    s.step(
        STEP_S,
        StepperDemand::Position {
            microsteps: i64::MAX,
        },
    );
    s.step(
        STEP_S,
        StepperDemand::PositionIncrements {
            increments: i64::MIN,
            velocity_ff_rpm: 1e30,
        },
    );
    assert!(s.angle().is_finite());
    // Degenerate data give a defined (if useless) motor.
    let mut z = Stepper::new(StepperData {
        full_steps_per_rev: 0,
        microsteps: 0,
        encoder_increments_per_rev: 0,
        rated_current: 0.0,
        resistance: 0.0,
        inductance: 0.0,
        rotor_inertia: 0.0,
        load_inertia: 0.0,
        ..StepperData::default()
    });
    for _ in 0..100 {
        z.step(STEP_S, StepperDemand::Position { microsteps: 7 });
    }
    assert!(z.angle().is_finite());
}

// ---- SINC scaling (vector catalogue §2.5) -------------------------------------------------------

/// FHPP-SC-01: PNU 600 = −7, PNU 601 = 01h → 1 SINC = 0.1 µm, 10 000 SINC = 1 mm.
#[test]
fn fhpp_sc_01() {
    // PNU 600 = −7, PNU 601 = 01h (metre): 1 SINC = 1·10⁻⁷ m = 0.1 µm; 10 000 SINC = 1 mm.
    assert_eq!(sinc_to_si(1, -7, 0x01), Some(1e-7));
    assert_eq!(sinc_to_si(10_000, -7, 0x01), Some(1e-3));
    assert_eq!(sinc_to_unit(10_000, -7), 0.001);
    assert_eq!(si_to_sinc(1e-3, -7, 0x01), Some(10_000));
    assert_eq!(si_to_sinc(0.1e-6, -7, 0x01), Some(1));
    assert_eq!(unit_to_sinc(0.001, -7), 10_000);
}

/// FHPP-SC-02: comparator −50 mm … −40 mm with PNU 600 = −7 → FFF85EE0h … FFF9E580h.
#[test]
fn fhpp_sc_02() {
    // Position comparator −50 mm ≤ x ≤ −40 mm with PNU 600 = −7:
    // min = −500 000 SINC (FFF85EE0h), max = −400 000 SINC (FFF9E580h).
    let min = si_to_sinc(-0.050, -7, 0x01).unwrap();
    let max = si_to_sinc(-0.040, -7, 0x01).unwrap();
    assert_eq!(min, -500_000);
    assert_eq!(max, -400_000);
    assert_eq!(min as i32 as u32, 0xFFF8_5EE0);
    assert_eq!(max as i32 as u32, 0xFFF9_E580);
    assert_eq!(sinc_to_si(min, -7, 0x01), Some(-0.05));
}

/// FHPP-SC-03: PNU 601 = 00h, 01h, 41h, F0h, F6h → user, metre, degree, inch, revolution.
#[test]
fn fhpp_sc_03() {
    // PNU 601 = 00h, 01h, 41h, F0h, F6h → undefined/user, metre, degree, inch, revolution.
    let codes = [0x00, 0x01, 0x41, 0xF0, 0xF6];
    let units = [
        SincUnit::Undefined,
        SincUnit::Metre,
        SincUnit::Degree,
        SincUnit::Inch,
        SincUnit::Revolution,
    ];
    for (&c, &u) in codes.iter().zip(&units) {
        assert_eq!(SincUnit::from_pnu601(c), Some(u));
        assert_eq!(u.pnu601(), c);
    }
    assert_eq!(SincUnit::from_pnu601(0x02), None);
    // Undefined has no SI size; the others convert.
    assert_eq!(sinc_to_si(1, 0, 0x00), None);
    assert_eq!(si_to_sinc(1.0, 0, 0x00), None);
    assert_eq!(sinc_to_si(1, 0, 0x02), None);
    assert_eq!(sinc_to_si(3600, -1, 0x41), Some(TAU)); // 360.0° with 1/10° SINC
    assert_eq!(si_to_sinc(TAU, -1, 0x41), Some(3600));
    assert_eq!(sinc_to_si(1, 0, 0xF6), Some(TAU));
    assert_eq!(si_to_sinc(0.0254, -3, 0xF0), Some(1000)); // 1 inch in mil
    assert_eq!(sinc_to_unit(5, 3), 5000.0);
    assert_eq!(unit_to_sinc(5000.0, 3), 5);
    assert_eq!(unit_to_sinc(f64::NAN, -7), 0);
}

#[test]
fn extreme_resolutions_do_not_overflow() {
    let mut s = Stepper::new(StepperData {
        full_steps_per_rev: u32::MAX,
        microsteps: u32::MAX,
        encoder_increments_per_rev: 1,
        ..StepperData::default()
    });
    for demand in [
        StepperDemand::Position {
            microsteps: i64::MIN,
        },
        StepperDemand::Position {
            microsteps: i64::MAX,
        },
        StepperDemand::PositionIncrements {
            increments: i64::MIN,
            velocity_ff_rpm: 0.0,
        },
        StepperDemand::PositionIncrements {
            increments: i64::MAX,
            velocity_ff_rpm: 0.0,
        },
    ] {
        s.step(STEP_S, demand);
        let _ = (
            s.lost_steps(),
            s.commanded_increments(),
            s.actual_microsteps(),
        );
    }
    let mut s = Stepper::new(StepperData {
        encoder_increments_per_rev: 1,
        microsteps: 1,
        full_steps_per_rev: 1,
        ..StepperData::default()
    });
    s.step(
        STEP_S,
        StepperDemand::PositionIncrements {
            increments: i64::MIN,
            velocity_ff_rpm: 0.0,
        },
    );
    assert_eq!(s.commanded_microsteps(), i64::MIN);
    s.step(
        STEP_S,
        StepperDemand::Position {
            microsteps: i64::MIN,
        },
    );
    assert_eq!(s.commanded_increments(), i64::MIN);
}

#[test]
fn stiff_data_stays_stable() {
    // ω_n = √(N_r·T_hold/J) = √(50·5/10⁻⁹) = 5·10⁵ rad/s: ω_n·h = 25 at 50 µs, far beyond the
    // explicit limit of 2; the implicit stiffness keeps the rotor on the command.
    let mut s = Stepper::new(StepperData {
        holding_torque: 5.0,
        rotor_inertia: 1e-9,
        load_inertia: 0.0,
        ..StepperData::default()
    });
    for k in 1..=STEPS_PER_S / 10 {
        s.step(
            STEP_S,
            StepperDemand::Position {
                microsteps: k as i64 / 10,
            },
        );
        assert!(s.angle().is_finite());
        assert!(
            s.position_error_full_steps().abs() < 1.0,
            "{}",
            s.position_error_full_steps()
        );
    }
    assert_eq!(s.lost_steps(), 0);
    assert_eq!(s.actual_microsteps(), 200);
}
