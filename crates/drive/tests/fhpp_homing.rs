//! CMMO-ST homing (§6.2, Tab. 6.2, PNU 1010…1017): every method of PNU 1011 against the
//! simulated axis mechanics (here end stops at ±1 rev; the default reference switch cam
//! −0.05…+0.05 rev and index pulse at 0.3 rev; 1 rev = 36000 SINC with the dictionary's
//! defaults), the
//! SPOS.ACK / MC / REF handshake and the homing diagnostics 22h, 23h, 24h, 2Eh, 3Ah, 3Bh.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod fhpp_bench;
use core::f64::consts::TAU;
use core::time::Duration;
use fhpp_bench::{Bench, ENABLED};

use drive::stepper::StepperMode;
use drive::vendors::festo_cmmo_st::axis_mechanics::AxisMechanics;
use drive::vendors::festo_cmmo_st::device::FhppSettings;
use drive::vendors::festo_cmmo_st::diagnostics::Class;
use drive::vendors::festo_cmmo_st::fhpp::{Ccon, Cpos, InputData, OutputData, Scon, Spos};
use od::ObjectAccess;

const REV: f64 = 36_000.0; // SINC per motor revolution (PNU 1003 default)

/// The default mechanics with a short stroke: stops at ±1 revolution.
fn axis() -> AxisMechanics {
    AxisMechanics {
        end_stops: Some((-1.0, 1.0)),
        ..AxisMechanics::default()
    }
}

impl Bench {
    fn with(mode: StepperMode, mechanics: AxisMechanics) -> Self {
        let mut b = Bench::with_settings(FhppSettings {
            mode,
            mechanics,
            homing_timeout: Duration::from_secs(6),
            ..FhppSettings::default()
        });
        b.send(OutputData::record(ENABLED, Cpos::HALT, 0));
        b
    }

    fn new(mode: StepperMode) -> Self {
        Self::with(mode, axis())
    }

    fn write(&mut self, pnu: u16, data: &[u8]) {
        self.dev
            .write(0x2000 + pnu, 1, data)
            .unwrap_or_else(|e| panic!("PNU {pnu}: {e:?}"));
    }

    fn method(&mut self, m: i8) {
        self.write(1011, &[m as u8]);
    }

    fn az_offset(&mut self, sinc: i32) {
        self.write(1010, &sinc.to_le_bytes());
    }

    /// CPOS.HOM: ACK rises and MC falls at once, REF is void while the run lasts; HOM away:
    /// ACK falls. Returns the first telegram with MC or FAULT.
    fn home(&mut self, max_ms: u64) -> InputData {
        let i = self.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::HOM, 0));
        assert!(i.spos.contains(Spos::ACK), "ACK on HOM: {i:?}");
        let i = self.send(OutputData::record(ENABLED, Cpos::HALT, 0));
        assert!(!i.spos.contains(Spos::ACK), "ACK falls with HOM: {i:?}");
        self.until(max_ms, |i| {
            i.spos.contains(Spos::MC) || i.scon.contains(Scon::FAULT)
        })
    }

    /// Shaft angle in motor revolutions.
    fn rev(&self) -> f64 {
        self.dev.stepper().angle() / TAU
    }

    /// PZ actual position (SPOS bytes 5…8 in record selection).
    fn position(&self) -> i32 {
        self.dev.motion_status().actual_position
    }
}

fn homed(i: &InputData) {
    assert!(
        i.spos.contains(Spos::MC | Spos::REF) && !i.scon.contains(Scon::FAULT),
        "homed: {i:?}"
    );
}

fn failed(b: &Bench, i: &InputData, code: u8) {
    assert!(i.scon.contains(Scon::FAULT), "fault expected: {i:?}");
    assert_eq!(b.dev.fault_number(), code, "diagnostic");
    assert!(!i.spos.contains(Spos::REF), "not referenced: {i:?}");
}

#[test]
fn fixed_stop_negative_takes_the_stop_as_ref_and_backs_off_to_az() {
    let mut b = Bench::new(StepperMode::ClosedLoop);
    b.method(-17);
    // §6.2.1: back off at least 1 mm from the stop: AZ 0.1 rev (36°) from REF.
    b.az_offset(3600);
    let i = b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::HOM, 0));
    assert!(i.spos.contains(Spos::ACK) && !i.spos.contains(Spos::MC));
    assert!(!i.spos.contains(Spos::REF));
    // At the stop the current rises to the PNU 1015 limit: 500 ‰ of PNU 555 1800 mA.
    let mut peak = 0;
    for _ in 0..10_000 {
        b.run(1);
        peak = peak.max(b.dev.stepper().current_ma());
        if b.input().spos.contains(Spos::MC) {
            break;
        }
    }
    let i = b.input();
    homed(&i);
    assert!(
        (850..=905).contains(&peak),
        "current limit at the stop: {peak} mA"
    );
    // REF = the stop at −1 rev; the drive stands at AZ = REF + 3600 = PZ 0.
    assert!((b.rev() - (-0.9)).abs() < 0.005, "at AZ: {} rev", b.rev());
    assert!(b.position().abs() <= 20, "PZ 0: {}", b.position());
    assert_eq!(
        b.dev.read_u32(0x2000 + 1041, 1).map(|v| v as i32),
        Some(b.position())
    );
}

#[test]
fn fixed_stop_positive_with_a_negative_offset() {
    let mut b = Bench::new(StepperMode::ClosedLoop);
    b.method(-18);
    b.az_offset(-3600);
    let i = b.home(10_000);
    homed(&i);
    assert!((b.rev() - 0.9).abs() < 0.005, "at AZ: {} rev", b.rev());
    assert!(b.position().abs() <= 20);
}

#[test]
fn fixed_stop_with_zero_offset_ends_at_the_stop() {
    let mut b = Bench::new(StepperMode::ClosedLoop);
    b.method(-18);
    let i = b.home(10_000);
    homed(&i);
    b.run(200);
    // AZ = REF: the drive holds at the stop (§6.2.1 asks for 1 mm of back-off for this).
    assert!((b.rev() - 1.0).abs() < 0.002, "{} rev", b.rev());
    assert!(b.position().abs() <= 20);
}

#[test]
fn index_pulse_methods_take_the_next_pulse_in_their_direction() {
    // 34: positive, pulse at +0.3 rev = 10800 SINC raw; 33: negative, at −0.7 rev.
    for (method, rev) in [(34i8, 0.3), (33, -0.7)] {
        let mut b = Bench::new(StepperMode::ClosedLoop);
        b.method(method);
        let i = b.home(10_000);
        homed(&i);
        assert!((b.rev() - rev).abs() < 0.002, "{method}: {} rev", b.rev());
        assert!(b.position().abs() <= 20, "{method}: PZ {}", b.position());
        // A move to PZ +9000 lands a quarter revolution on from the pulse.
        let start = OutputData::direct(
            Ccon(0x43),
            Cpos::HALT | Cpos::START,
            Default::default(),
            50,
            9000,
        );
        b.send(start);
        b.until(5000, |i| i.spos.contains(Spos::MC));
        assert!(((b.rev() - rev) * REV - 9000.0).abs() < 30.0, "{method}");
    }
}

#[test]
fn reference_switch_closed_loop_uses_the_index_behind_the_switch_edge() {
    // 23 (CiA 402: positive start): on the switch at power-on, off it negative to the edge
    // at −0.05, on to the index at −0.7. 27: off positive to +0.05, index at +0.3.
    for (method, rev) in [(23i8, -0.7), (27, 0.3)] {
        let mut b = Bench::new(StepperMode::ClosedLoop);
        b.method(method);
        let i = b.home(30_000);
        homed(&i);
        assert!((b.rev() - rev).abs() < 0.002, "{method}: {} rev", b.rev());
    }
}

#[test]
fn reference_switch_searched_from_off_the_switch() {
    // Switch cam at +0.5…+0.6: 23 runs positive onto it, backs off to its lower edge and
    // takes the next index below (+0.3).
    let mech = AxisMechanics {
        reference_switch: Some((0.5, 0.6)),
        ..axis()
    };
    let mut b = Bench::with(StepperMode::ClosedLoop, mech);
    b.method(23);
    let i = b.home(30_000);
    homed(&i);
    assert!((b.rev() - 0.3).abs() < 0.002, "{} rev", b.rev());
}

#[test]
fn reference_switch_open_loop_takes_the_switch_edge() {
    for (method, rev) in [(23i8, -0.05), (27, 0.05)] {
        let mut b = Bench::new(StepperMode::OpenLoop);
        b.method(method);
        let i = b.home(30_000);
        homed(&i);
        assert!((b.rev() - rev).abs() < 0.003, "{method}: {} rev", b.rev());
        assert!(b.position().abs() <= 60, "{method}: PZ {}", b.position());
    }
}

#[test]
fn switch_not_found_before_the_stop_is_22h() {
    let mech = AxisMechanics {
        reference_switch: Some((0.5, 0.6)),
        ..axis()
    };
    let mut b = Bench::with(StepperMode::ClosedLoop, mech);
    b.method(27); // negative: the switch is on the other side
    let i = b.home(20_000);
    failed(&b, &i, 0x22);
    assert!((b.rev() + 1.0).abs() < 0.01, "at the stop: {} rev", b.rev());
}

#[test]
fn open_loop_switch_search_times_out_with_3ah() {
    let mech = AxisMechanics {
        reference_switch: Some((0.5, 0.6)),
        ..axis()
    };
    let mut b = Bench::with(StepperMode::OpenLoop, mech);
    b.method(27);
    let t0 = b.t_ms;
    let i = b.home(20_000);
    failed(&b, &i, 0x3A);
    // The open-loop motor ran into the stop (losing steps there, nothing noticed it) until
    // the search time (6 s in this bench) was up.
    assert!(b.t_ms - t0 >= 6000, "after {} ms", b.t_ms - t0);
    assert!((b.rev() + 1.0).abs() < 0.03, "at the stop: {} rev", b.rev());
}

#[test]
fn no_index_pulse_is_23h() {
    // An endless axis whose encoder has no index track.
    let mech = AxisMechanics {
        index_pulse: None,
        end_stops: None,
        ..axis()
    };
    let mut b = Bench::with(StepperMode::ClosedLoop, mech);
    b.method(34);
    let i = b.home(20_000);
    failed(&b, &i, 0x23);
    // Searched a full revolution (and the 5 % margin) in vain.
    assert!(b.rev() > 1.05, "{} rev", b.rev());
}

#[test]
fn index_too_close_to_the_switch_edge_is_2eh() {
    // Lower switch edge at 0.31 rev, the index below it at 0.30: 1 % of a revolution.
    let mech = AxisMechanics {
        reference_switch: Some((0.31, 0.6)),
        ..axis()
    };
    let mut b = Bench::with(StepperMode::ClosedLoop, mech);
    b.method(23);
    let i = b.home(30_000);
    failed(&b, &i, 0x2E);
}

/// HOM with a method Tab. 6.2 refuses: the start is answered by the diagnostic, nothing moves.
fn refused(b: &mut Bench) -> InputData {
    b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::HOM, 0));
    b.send(OutputData::record(ENABLED, Cpos::HALT, 0));
    b.run(20);
    assert!(b.rev().abs() < 0.001, "no motion: {} rev", b.rev());
    b.input()
}

#[test]
fn methods_tab_6_2_refuses_are_3bh_or_24h() {
    // Fixed stop in open loop: 3Bh (App. D's example).
    let mut b = Bench::new(StepperMode::OpenLoop);
    b.method(-17);
    let i = refused(&mut b);
    failed(&b, &i, 0x3B);
    // Not in Tab. 6.2 at all.
    let mut b = Bench::new(StepperMode::ClosedLoop);
    b.method(1);
    let i = refused(&mut b);
    failed(&b, &i, 0x3B);
    // A switch method without a switch wired.
    let mech = AxisMechanics {
        reference_switch: None,
        ..axis()
    };
    let mut b = Bench::with(StepperMode::ClosedLoop, mech);
    b.method(23);
    let i = refused(&mut b);
    failed(&b, &i, 0x3B);
    // The index methods need the closed-loop encoder function: 24h (its class per PNU 246).
    let mut b = Bench::new(StepperMode::OpenLoop);
    b.method(34);
    let i = refused(&mut b);
    match b.dev.diagnostic_class(0x24) {
        Some(Class::Fault(_)) => failed(&b, &i, 0x24),
        _ => assert!(i.scon.contains(Scon::WARN) && !i.spos.contains(Spos::REF)),
    }
}

#[test]
fn current_position_method_does_not_move() {
    let mut b = Bench::new(StepperMode::ClosedLoop);
    b.az_offset(1000);
    let i = b.home(100);
    homed(&i);
    assert!(b.rev().abs() < 0.001);
    assert_eq!(b.position(), -1000, "§6.2.1 step 2: 0 − offset");
}

#[test]
fn software_limits_are_off_while_homing_and_back_after() {
    let mut b = Bench::new(StepperMode::ClosedLoop);
    homed(&b.home(100)); // −35 first: referenced, limits ±1000 SINC active
    b.write(501, &(-1000i32).to_le_bytes());
    b.dev
        .write(0x2000 + 501, 2, &1000i32.to_le_bytes())
        .unwrap();
    b.method(-18);
    b.az_offset(-3600);
    let i = b.home(10_000);
    homed(&i);
    // Far outside the old limits (the new AZ carries them along).
    assert!((b.rev() - 0.9).abs() < 0.005, "{} rev", b.rev());
    // Active again: a target 2000 SINC beyond AZ is refused with 2Ah.
    let start = OutputData::direct(
        Ccon(0x43),
        Cpos::HALT | Cpos::START,
        Default::default(),
        50,
        2000,
    );
    b.send(OutputData::direct(
        Ccon(0x43),
        Cpos::HALT,
        Default::default(),
        50,
        2000,
    ));
    b.send(start);
    let i = b.until(50, |i| i.scon.contains(Scon::FAULT));
    assert_eq!(b.dev.fault_number(), 0x2A, "{i:?}");
}

#[test]
fn a_new_homing_run_voids_the_reference_until_it_completes() {
    let mut b = Bench::new(StepperMode::ClosedLoop);
    homed(&b.home(100));
    b.method(-17);
    b.az_offset(3600);
    b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::HOM, 0));
    b.run(200);
    let i = b.input();
    assert!(
        !i.spos.contains(Spos::REF) && !i.spos.contains(Spos::MC),
        "{i:?}"
    );
    let i = b.until(10_000, |i| i.spos.contains(Spos::MC));
    homed(&i);
}

#[test]
fn homing_is_deterministic() {
    let run = || {
        let mut b = Bench::new(StepperMode::ClosedLoop);
        b.method(23);
        b.home(30_000);
        (b.dev.stepper().angle().to_bits(), b.t_ms)
    };
    assert_eq!(run(), run());
}

#[test]
fn fixed_stop_with_the_default_mechanics() {
    // Stops at −3 / +47 rev: −17 finds the negative one after about 12 s.
    let mut b = Bench::with(StepperMode::ClosedLoop, AxisMechanics::default());
    b.method(-17);
    b.az_offset(3600);
    let i = b.home(20_000);
    homed(&i);
    assert!((b.rev() - (-2.9)).abs() < 0.005, "{} rev", b.rev());
}

#[test]
fn record_0_with_start_homes_too() {
    let mut b = Bench::new(StepperMode::ClosedLoop);
    b.method(34);
    let i = b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::START, 0));
    assert!(
        i.spos.contains(Spos::ACK) && !i.spos.contains(Spos::MC),
        "{i:?}"
    );
    b.send(OutputData::record(ENABLED, Cpos::HALT, 0));
    let i = b.until(10_000, |i| i.spos.contains(Spos::MC));
    homed(&i);
    assert_eq!(i.byte3, 0, "record number feedback 0 = homing");
    assert!((b.rev() - 0.3).abs() < 0.002, "{} rev", b.rev());
}

#[test]
fn halt_ends_a_homing_run_without_a_reference() {
    let mut b = Bench::new(StepperMode::ClosedLoop);
    b.method(-17);
    b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::HOM, 0));
    b.run(500);
    let moving_at = b.rev();
    assert!(moving_at < -0.05, "searching: {moving_at} rev");
    // HALT = 0 (active low): the axis brakes at PNU 1013 and stands, not referenced.
    b.send(OutputData::record(ENABLED, Cpos::HOM, 0));
    b.run(500);
    let stood = b.rev();
    b.run(500);
    assert!(
        (b.rev() - stood).abs() < 0.001,
        "stands: {stood} → {}",
        b.rev()
    );
    assert!(stood > -0.9, "did not reach the stop: {stood}");
    assert!(!b.input().spos.contains(Spos::REF));
    // The PNU 1015 current limit belongs to homing only.
    assert!(b.dev.stepper().current_ma() < 900);
}

/// The plant's end stop alone (no homing): an open-loop motor driven past it loses steps,
/// a closed-loop one holds at the stop with its current at the limit.
#[test]
fn end_stop_stalls_the_plant() {
    use drive::stepper::{Stepper, StepperData, StepperDemand};
    for mode in [StepperMode::OpenLoop, StepperMode::ClosedLoop] {
        let mut s = Stepper::new(StepperData::default());
        s.set_mode(mode);
        s.set_end_stops(Some((-TAU, 0.25 * TAU)));
        s.set_current_limit(Some(0.9));
        // Set-point ramps to half a revolution at 0.25 rev/s (1600 micro-steps per rev).
        for ms in 0..3000u32 {
            let micro = (f64::from(ms.min(2000)) * 0.25 * 3200.0 / 1000.0) as i64;
            let inc = (f64::from(ms.min(2000)) * 0.25 * 2000.0 / 1000.0) as i64;
            let demand = match mode {
                StepperMode::OpenLoop => StepperDemand::Position { microsteps: micro },
                StepperMode::ClosedLoop => StepperDemand::PositionIncrements {
                    increments: inc,
                    velocity_ff_rpm: 0.0,
                },
            };
            s.step(1e-3, demand);
            assert!(
                s.angle() <= 0.25 * TAU + 1e-12,
                "{mode:?}: through the stop"
            );
        }
        assert!(
            (s.angle() / TAU - 0.25).abs() < 0.03,
            "{mode:?}: {}",
            s.angle() / TAU
        );
        match mode {
            StepperMode::OpenLoop => assert!(s.lost_steps() >= 40, "{}", s.lost_steps()),
            StepperMode::ClosedLoop => {
                assert_eq!(s.at_end_stop(), Some(true));
                assert!((s.current_a() - 0.9).abs() < 0.05, "{}", s.current_a());
            }
        }
    }
}
