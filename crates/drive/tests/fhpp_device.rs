//! The CMMO-ST device (`drive::vendors::festo_cmmo_st::device`): FHPP telegrams in, the stepper plant moving,
//! status telegrams out — the manual's reference values and handshakes end to end.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod fhpp_bench;
use drive::stepper::StepperMode;
use drive::vendors::festo_cmmo_st::device::diag;
use drive::vendors::festo_cmmo_st::fhpp::{Ccon, Cdir, Cpos, OutputData, Scon, Sdir, Spos, State};
use fhpp_bench::{Bench, ENABLED};
use od::ObjectAccess;

const DIRECT: Ccon = Ccon(0x43); // OPM1 + STOP + ENABLE

impl Bench {
    fn pnu_write_i32(&mut self, pnu: u16, sub: u8, v: i32) {
        self.dev
            .write(0x2000 + pnu, sub, &v.to_le_bytes())
            .unwrap_or_else(|e| panic!("PNU {pnu}:{sub}: {e:?}"));
    }
}

#[test]
fn power_on_and_enable_give_the_manuals_status_bytes() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    let i = b.send(OutputData::record(Ccon(0), Cpos(0), 0));
    assert_eq!((i.scon.0, i.spos.0), (0x10, 0x04), "power-on SCON/SPOS");
    let i = b.enable_record();
    assert_eq!((i.scon.0, i.spos.0), (0x13, 0x05), "enabled SCON/SPOS");
    assert!(b.dev.stepper().energised());
    // Direct mode: OPM1 is fed back (0x53).
    let i = b.send(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 0, 0));
    assert_eq!((i.scon.0, i.spos.0), (0x53, 0x05));
    // ENABLE = 0: the stage goes off (T6 / T5), MC stays set.
    let i = b.send(OutputData::record(Ccon(0), Cpos::HALT, 0));
    assert_eq!(i.scon.0 & 0x03, 0);
    b.run(5);
    assert!(!b.dev.stepper().energised());
}

#[test]
fn direct_absolute_move_ends_with_mc_in_the_window() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.enable_record();
    b.home_here();
    // 1 revolution = 36000 SINC (0.01° units, the dictionary's defaults), 50 % of PNU 540.
    let target = 36_000 + 9_000;
    let start = OutputData::direct(DIRECT, Cpos::HALT | Cpos::START, Cdir(0), 50, target);
    let i = b.send(start);
    assert!(
        i.spos.contains(Spos::ACK) && !i.spos.contains(Spos::MC),
        "{i:?}"
    );
    b.run(20);
    let i = b.input();
    assert!(i.spos.contains(Spos::MOV), "moving: {i:?}");
    // START away: ACK falls, the task carries on.
    let i = b.send(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 50, target));
    assert!(!i.spos.contains(Spos::ACK));
    let i = b.until(5000, |i| i.spos.contains(Spos::MC));
    let window = 180; // PNU 1022
    assert!(
        (i.actual2 - target).abs() <= window,
        "actual {} target {target}",
        i.actual2
    );
    assert!(!i.spos.contains(Spos::MOV) && !i.spos.contains(Spos::FOLERR));
    assert_eq!(
        b.dev.read_u32(0x2000 + 1041, 1).map(|v| v as i32),
        Some(i.actual2)
    );
}

#[test]
fn a_move_before_homing_is_refused_with_28h() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.enable_record();
    b.send(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 50, 0));
    b.send(OutputData::direct(
        DIRECT,
        Cpos::HALT | Cpos::START,
        Cdir(0),
        50,
        1000,
    ));
    let i = b.until(50, |i| i.scon.contains(Scon::FAULT));
    assert!(i.scon.contains(Scon::FAULT));
    assert_eq!(b.dev.fault_number(), diag::HOMING_REQUIRED);
}

#[test]
fn record_move_uses_the_record_list() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    // Record 3: absolute, position mode, −18000 SINC (half a revolution back).
    b.pnu_write_i32(404, 3, -18_000);
    b.enable_record();
    b.home_here();
    b.send(OutputData::record(ENABLED, Cpos::HALT, 3));
    assert_eq!(b.input().record_number(), 0, "previous record until start");
    let i = b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::START, 3));
    assert!(i.spos.contains(Spos::ACK));
    assert_eq!(i.record_number(), 3);
    b.send(OutputData::record(ENABLED, Cpos::HALT, 3));
    let i = b.until(5000, |i| i.spos.contains(Spos::MC));
    assert!((i.actual2 + 18_000).abs() <= 180, "actual {}", i.actual2);
}

/// A record PNU written while the device runs: that record is read again at the next cycle
/// (only that one: the others keep what the table held), and a start goes to the new target.
#[test]
fn a_record_written_while_running_is_read_again() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.enable_record();
    b.home_here();
    let other = b.dev.records().get(4).map(|r| r.target);
    b.pnu_write_i32(404, 3, 9_000);
    b.pnu_write_i32(406, 3, 20_000);
    b.run(1);
    let r3 = b.dev.records().get(3).copied();
    assert_eq!(r3.map(|r| (r.target, r.velocity)), Some((9_000, 20_000)));
    assert_eq!(b.dev.records().get(4).map(|r| r.target), other);
    b.send(OutputData::record(ENABLED, Cpos::HALT, 3));
    b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::START, 3));
    b.send(OutputData::record(ENABLED, Cpos::HALT, 3));
    let i = b.until(5000, |i| i.spos.contains(Spos::MC));
    assert!((i.actual2 - 9_000).abs() <= 180, "actual {}", i.actual2);
}

/// FHPP-ST-14, FHPP-ST-15, FHPP-ST-16, FHPP-ST-17 end to end: JOGP rising moves towards increasing
/// actual values and keeps moving while the bit is held (level-controlled); JOGP falling stops
/// the axis; JOGN moves back the same way and stops when it falls.
#[test]
fn jog_moves_while_held_and_stops_on_release() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.enable_record();
    let i = b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::JOGP, 0));
    assert!(i.spos.contains(Spos::ACK) && !i.spos.contains(Spos::MC));
    b.run(500);
    let i = b.input();
    assert!(i.spos.contains(Spos::MOV));
    let p1 = i.actual2;
    assert!(p1 > 500, "jogged positive: {p1}");
    let i = b.send(OutputData::record(ENABLED, Cpos::HALT, 0));
    assert!(!i.spos.contains(Spos::ACK));
    let i = b.until(2000, |i| i.spos.contains(Spos::MC));
    assert!(!i.spos.contains(Spos::MOV));
    b.run(50);
    let p2 = b.input().actual2;
    b.run(100);
    assert!((b.input().actual2 - p2).abs() <= 18, "stands still");
    // Negative jog goes back.
    b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::JOGN, 0));
    b.run(300);
    let p3 = b.input().actual2;
    assert!(p3 < p2);
    b.run(200);
    let i = b.input();
    assert!(i.actual2 < p3, "still moving while JOGN is held");
    assert!(i.spos.contains(Spos::MOV) && !i.spos.contains(Spos::MC));
    b.send(OutputData::record(ENABLED, Cpos::HALT, 0));
    let i = b.until(2000, |i| i.spos.contains(Spos::MC));
    assert!(!i.spos.contains(Spos::MOV));
    b.run(50);
    let p4 = b.input().actual2;
    b.run(100);
    assert!((b.input().actual2 - p4).abs() <= 18, "stands still");
}

/// FHPP-SC-04: PNU 1000 = 00h leaves the direction unchanged, 80h reverses it: the same
/// positive jog raises the actual position (SINC) either way, but the shaft and the encoder
/// count turn the other way round ("all encoder values inverted").
#[test]
fn pnu_1000_polarity_reverses_the_direction() {
    let mut shaft = Vec::new();
    for polarity in [0x00u8, 0x80] {
        let mut b = Bench::with_mode(StepperMode::ClosedLoop);
        // rw2: written with the output stage off.
        b.dev.write(0x2000 + 1000, 1, &[polarity]).unwrap();
        assert_eq!(b.dev.read_u8(0x2000 + 1000, 1), Some(polarity));
        b.enable_record();
        let (a0, e0) = (
            b.dev.stepper().angle(),
            b.dev.stepper().encoder_increments(),
        );
        b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::JOGP, 0));
        b.run(500);
        let i = b.input();
        assert!(
            i.actual2 > 500,
            "PNU 1000 = {polarity:02X}h: actual {}",
            i.actual2
        );
        let (da, de) = (
            b.dev.stepper().angle() - a0,
            b.dev.stepper().encoder_increments() - e0,
        );
        // The dictionary default feed: 1 EINC = 18 SINC (module doc of the device).
        assert!(
            (de * 18 * if polarity == 0 { 1 } else { -1 } - i64::from(i.actual2)).abs() <= 18,
            "PNU 1000 = {polarity:02X}h: {de} EINC for {} SINC",
            i.actual2
        );
        shaft.push(da);
    }
    assert!(
        shaft[0] > 0.1,
        "00h: the shaft turns positive: {}",
        shaft[0]
    );
    assert!(
        shaft[1] < -0.1,
        "80h: the shaft turns negative: {}",
        shaft[1]
    );
}

#[test]
fn halt_stops_a_position_task_and_start_continues_it() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.enable_record();
    b.home_here();
    let target = 360_000; // 10 revolutions
    b.start(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 100, target));
    b.run(300);
    // HALT = 0: intermediate stop, MC stays 0, SPOS.HALT = 0.
    let i = b.send(OutputData::direct(DIRECT, Cpos(0), Cdir(0), 100, target));
    assert!(!i.spos.contains(Spos::HALT));
    let stopped = b.until(3000, |i| !i.spos.contains(Spos::MOV));
    assert!(!stopped.spos.contains(Spos::MC));
    assert!(
        stopped.actual2 < target - 1000,
        "halted short: {}",
        stopped.actual2
    );
    b.run(100);
    assert!(!b.input().spos.contains(Spos::MC));
    // START with HALT = 1 continues (TA4) to the same target.
    b.start(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 100, target));
    let i = b.until(10_000, |i| i.spos.contains(Spos::MC));
    assert!((i.actual2 - target).abs() <= 180);
}

#[test]
fn injected_fault_and_reset() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.enable_record();
    // 47h (class F, reaction E, acknowledge at once).
    b.dev.fault(diag::MODBUS_WITH_CONTROL);
    let i = b.until(100, |i| i.scon.contains(Scon::FAULT));
    assert_eq!(b.dev.fault_number(), 0x47);
    assert_eq!(b.dev.fhpp().state(), State::Fault);
    assert!(i.spos.contains(Spos::MC));
    assert_eq!(b.dev.read_u16(0x2000 + 205, 1), Some(0x47));
    // RESET rising edge with ENABLE = 1: T10 back to S3/S4 without switching off.
    b.dev.clear_fault(diag::MODBUS_WITH_CONTROL);
    let i = b.send(OutputData::record(Ccon(0x0B), Cpos::HALT, 0));
    assert!(!i.scon.contains(Scon::FAULT), "{i:?}");
    assert!(i.scon.contains(Scon::ENABLED));
    assert!(i.spos.contains(Spos::MC));
    assert_eq!(b.dev.fault_number(), 0);
    assert_eq!(b.dev.read_u16(0x2000 + 205, 1), Some(0xFFFF));
    let i = b.send(OutputData::record(ENABLED, Cpos::HALT, 0));
    assert_eq!((i.scon.0, i.spos.0 & 0x7F), (0x13, 0x05));
}

#[test]
fn open_loop_blocked_load_loses_steps_and_shows_a_following_error() {
    let mut b = Bench::with_mode(StepperMode::OpenLoop);
    b.enable_record();
    b.home_here();
    b.dev.stepper_mut().set_blocked(true);
    let target = 36_000;
    b.send(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 50, target));
    b.send(OutputData::direct(
        DIRECT,
        Cpos::HALT | Cpos::START,
        Cdir(0),
        50,
        target,
    ));
    let mut saw_folerr = false;
    for _ in 0..2000 {
        b.run(1);
        if b.input().spos.contains(Spos::FOLERR) {
            saw_folerr = true;
            break;
        }
    }
    assert!(saw_folerr, "SPOS.FOLERR never set: {:?}", b.input());
    assert!(b.dev.stepper().lost_steps() != 0 || b.input().actual2.abs() < 100);
    let i = b.until(500, |i| i.scon.contains(Scon::FAULT));
    assert!(i.scon.contains(Scon::FAULT));
    assert_eq!(b.dev.fault_number(), diag::FOLLOWING_ERROR);
    // The reaction (E, quick stop, stage on) ends; the set-point holds the actual position,
    // the cause is gone and RESET acknowledges it.
    b.run(200);
    b.dev.stepper_mut().set_blocked(false);
    b.send(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 50, target));
    let i = b.send(OutputData::direct(
        Ccon(0x4B),
        Cpos::HALT,
        Cdir(0),
        50,
        target,
    ));
    assert!(!i.scon.contains(Scon::FAULT), "{i:?}");
    assert!(!i.spos.contains(Spos::FOLERR));
}

#[test]
fn closed_loop_follows_where_open_loop_would_stall() {
    // The same move with a load torque the closed loop can carry: no following error.
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.dev.stepper_mut().set_load_torque(0.2);
    b.enable_record();
    b.home_here();
    let target = 18_000;
    b.send(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 30, target));
    b.send(OutputData::direct(
        DIRECT,
        Cpos::HALT | Cpos::START,
        Cdir(0),
        30,
        target,
    ));
    let i = b.until(5000, |i| {
        i.spos.contains(Spos::MC) || i.spos.contains(Spos::FOLERR)
    });
    assert!(!i.spos.contains(Spos::FOLERR));
    assert!((i.actual2 - target).abs() <= 180);
}

#[test]
fn step_is_deterministic() {
    let run = || {
        let mut b = Bench::with_mode(StepperMode::ClosedLoop);
        b.enable_record();
        b.home_here();
        b.send(OutputData::direct(
            DIRECT,
            Cpos::HALT | Cpos::START,
            Cdir(0),
            70,
            12_345,
        ));
        b.run(700);
        (b.dev.inputs(), b.dev.stepper().angle().to_bits())
    };
    assert_eq!(run(), run());
}

/// Direct force mode (§6.6, CDIR.COM = 01): against a blocked axis the force builds up to
/// the set-point (‰ of PNU 555) and MC follows inside ±PNU 552 for PNU 1023.
#[test]
fn force_task_builds_the_force_against_a_blocked_axis() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.enable_record();
    b.home_here();
    b.dev.stepper_mut().set_blocked(true);
    let force = Cdir(0x02); // COM1: force mode, stroke monitoring on
    let target = 500; // 50 % of PNU 555 = 900 mA
    b.send(OutputData::direct(DIRECT, Cpos::HALT, force, 20, target));
    let i = b.send(OutputData::direct(
        DIRECT,
        Cpos::HALT | Cpos::START,
        force,
        20,
        target,
    ));
    assert!(
        i.spos.contains(Spos::ACK) && !i.spos.contains(Spos::MC),
        "{i:?}"
    );
    b.send(OutputData::direct(DIRECT, Cpos::HALT, force, 20, target));
    let i = b.until(3000, |i| i.spos.contains(Spos::MC));
    // Byte 4: torque in % of PNU 555 (PNU 523:7 factory setting).
    assert!((45..=55).contains(&i.byte4), "force {} %", i.byte4);
    // Settled: 50 % of 1800 mA.
    b.run(500);
    let i = b.input();
    assert!((48..=52).contains(&i.byte4), "force {} %", i.byte4);
    let ma = b.dev.stepper().current_ma();
    assert!((860..=940).contains(&ma), "{ma} mA");
    assert!(i.spos.contains(Spos::MC) && i.actual2.abs() <= 2);
    // PNU 301: actual, set-point, deviation in ‰ of PNU 555.
    let pnu301 = |sub| b.dev.read_u16(0x2000 + 301, sub).map(|v| v as i16);
    assert_eq!(pnu301(2), Some(500));
    let actual = pnu301(1).unwrap();
    assert!((480..=520).contains(&actual), "{actual}");
    assert_eq!(pnu301(3), Some(500 - actual));
    assert!(!i.scon.contains(Scon::FAULT));
}

/// A force task without a workpiece runs at its velocity limit to the stroke limit PNU 510,
/// brakes and reports SDIR.XLIM.
#[test]
fn force_task_without_a_workpiece_stops_at_the_stroke_limit() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.enable_record();
    b.home_here();
    b.pnu_write_i32(510, 1, 9_000);
    let force = Cdir(0x02);
    b.start(OutputData::direct(DIRECT, Cpos::HALT, force, 10, 300));
    let i = b.until(3000, |i| Sdir(i.byte3).contains(Sdir::XLIM));
    assert!(i.spos.contains(Spos::MOV));
    let i = b.until(1000, |i| !i.spos.contains(Spos::MOV));
    let pos = b.dev.read_u32(0x2000 + 1041, 1).map(|v| v as i32).unwrap();
    assert!(
        (9_000..10_000).contains(&pos),
        "stopped after 9000 SINC: {pos}"
    );
    assert!(!i.scon.contains(Scon::FAULT));
}

/// A confirmed write has been taken: telegrams a PLC sets faster than the FHPP cycle (each
/// Modbus write answered before the next) are each seen by the state machine, in order. The
/// enable and a record start pulsed within one cycle (START set and taken away before the
/// cycle ran) still start the record; on the device the Modbus answer comes after the
/// telegram was taken.
#[test]
fn telegrams_set_within_one_cycle_are_all_taken_in_order() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.send(OutputData::record(Ccon(0), Cpos(0), 0));
    let set = |b: &mut Bench, out: OutputData| b.dev.set_outputs(&out.to_bytes()).unwrap();
    set(&mut b, OutputData::record(ENABLED, Cpos::HALT, 0));
    set(
        &mut b,
        OutputData::record(ENABLED, Cpos::HALT | Cpos::HOM, 0),
    );
    set(&mut b, OutputData::record(ENABLED, Cpos::HALT, 0));
    let i = b.until(200, |i| i.spos.contains(Spos::MC | Spos::REF));
    assert_eq!(i.scon.0 & 0x03, 0x03, "enabled: {i:?}");
    // Record 1 started by a START pulse shorter than a cycle.
    b.pnu_write_i32(404, 1, 36_000);
    set(
        &mut b,
        OutputData::record(ENABLED, Cpos::HALT | Cpos::START, 1),
    );
    set(&mut b, OutputData::record(ENABLED, Cpos::HALT, 1));
    b.run(30);
    assert!(b.input().spos.contains(Spos::MOV), "{:?}", b.input());
    let i = b.until(5000, |i| i.spos.contains(Spos::MC));
    assert!((i.actual2 - 36_000).abs() <= 180, "{i:?}");
}

/// The actual values are written again after the dictionary was written from outside: a
/// cycle skips a value the entry already holds, so a store through `od_mut` over PNU 205
/// (active fault, FFFFh without one) and PNU 221:1 (warnings) must not stand.
#[test]
fn actual_values_overwritten_from_outside_are_published_again() {
    let mut b = Bench::with_mode(StepperMode::ClosedLoop);
    b.enable_record();
    b.run(5);
    let value = |b: &Bench, pnu: u16, sub: u8| b.dev.od().value(0x2000 + pnu, sub);
    let before = [value(&b, 205, 1), value(&b, 221, 1)];
    assert_eq!(before[0], Some(od::Value::Unsigned(0xFFFF)), "no fault");
    for (pnu, sub) in [(205u16, 1u8), (221, 1)] {
        let e = b.dev.od().description().entry(0x2000 + pnu, sub).unwrap();
        let garbage = [0x5Au8; 8];
        b.dev.od_mut().store(e, &garbage[..e.capacity as usize]);
        assert_ne!(value(&b, pnu, sub), before[usize::from(pnu == 221)]);
    }
    b.run(1);
    assert_eq!([value(&b, 205, 1), value(&b, 221, 1)], before);
}
