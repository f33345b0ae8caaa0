//! CMMO-ST diagnostics end to end (manual §7, App. D, PNU 200…246): the App. D table against
//! the device file, error management, every class and reaction path, acknowledge types, the
//! diagnostic memory, record chaining (§6.5.3, the §8.3 example) and the software limits.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod fhpp_bench;
use drive::stepper::StepperMode;
use drive::vendors::festo_cmmo_st::device::diag;
use drive::vendors::festo_cmmo_st::diagnostics::{self, Class};
use drive::vendors::festo_cmmo_st::fhpp::{
    Ack, Ccon, Cdir, Cpos, InputData, OutputData, Reaction, Rsb, Scon, Spos,
};
use drive::vendors::festo_cmmo_st::seven_segment::SevenSegment;
use fhpp_bench::{Bench, ENABLED};
use od::{AbortCode, ObjectAccess};

const DIRECT: Ccon = Ccon(0x43); // OPM1 + STOP + ENABLE
/// CDIR velocity mode (COM2) without stroke monitoring (XLIM).
const VELOCITY: Cdir = Cdir(0x24);

fn pnu(n: u16) -> u16 {
    0x2000 + n
}

impl Bench {
    fn new() -> Self {
        Self::with_mode(StepperMode::ClosedLoop)
    }

    /// Enabled, referenced, record selection.
    fn ready() -> Self {
        let mut b = Bench::new();
        b.enable_record();
        b.home_here();
        b
    }

    fn w16(&mut self, p: u16, sub: u8, v: u16) -> Result<(), AbortCode> {
        self.dev.write(pnu(p), sub, &v.to_le_bytes())
    }

    fn w32(&mut self, p: u16, sub: u8, v: i32) {
        self.dev
            .write(pnu(p), sub, &v.to_le_bytes())
            .unwrap_or_else(|e| panic!("PNU {p}:{sub}: {e:?}"));
    }

    fn w8(&mut self, p: u16, sub: u8, v: u8) {
        self.dev
            .write(pnu(p), sub, &[v])
            .unwrap_or_else(|e| panic!("PNU {p}:{sub}: {e:?}"));
    }

    fn r8(&self, p: u16, sub: u8) -> u8 {
        self.dev.read_u8(pnu(p), sub).unwrap()
    }

    fn r16(&self, p: u16, sub: u8) -> u16 {
        self.dev.read_u16(pnu(p), sub).unwrap()
    }

    fn r32(&self, p: u16, sub: u8) -> u32 {
        self.dev.read_u32(pnu(p), sub).unwrap()
    }

    /// Diagnostic memory entry `sub` (1 = newest) as (PNU 200, 201, 202).
    fn memory(&self, sub: u8) -> (u8, u16, u32) {
        (self.r8(200, sub), self.r16(201, sub), self.r32(202, sub))
    }

    /// Starts a direct velocity task at `v` SINC/s with the ramp 10 % of PNU 560
    /// (360000 SINC/s², a tenth of the Quick-Stop deceleration PNU 1029) and lets it get going.
    fn spin(&mut self, v: i32) {
        self.send(OutputData::direct(DIRECT, Cpos::HALT, VELOCITY, 10, v));
        let i = self.send(OutputData::direct(
            DIRECT,
            Cpos::HALT | Cpos::START,
            VELOCITY,
            10,
            v,
        ));
        assert!(i.spos.contains(Spos::ACK), "velocity start: {i:?}");
        self.send(OutputData::direct(DIRECT, Cpos::HALT, VELOCITY, 10, v));
        self.until(500, |i| i.spos.contains(Spos::MC));
    }

    /// CCON.RESET rising edge with `ccon`, then RESET away again.
    fn reset(&mut self, ccon: Ccon) -> InputData {
        self.send(OutputData::record(ccon, Cpos::HALT, 0));
        self.send(OutputData::record(ccon | Ccon::RESET, Cpos::HALT, 0));
        self.send(OutputData::record(ccon, Cpos::HALT, 0))
    }
}

// ---- the table --------------------------------------------------------------------------

#[test]
fn app_d_table_matches_the_error_management_defaults_of_the_device_file() {
    let b = Bench::new();
    for sub in 1u8..=255 {
        let d = diagnostics::code_of_subindex(sub).and_then(|c| diagnostics::lookup(c.into()));
        let want = match d {
            Some(d) => (
                d.permissible_reactions(),
                d.permissible_handling(),
                d.default_reaction(),
                d.default_handling(),
            ),
            None => (0xFFFF, 0xFFFF, 0, 0),
        };
        let got = (
            b.r16(234, sub),
            b.r16(238, sub),
            b.r16(242, sub),
            b.r16(246, sub),
        );
        assert_eq!(got, want, "PNU 234/238/242/246 sub {sub}");
    }
    assert_eq!(diagnostics::all().count(), 57);
    // FHPP-FPC-10 (fhpp §8.1 example 2): 0x0037 = A, B, C, E, F (11h…14h, sub = n + 1).
    assert_eq!(b.r16(234, 0x12), 0x0037);
}

#[test]
fn pnu_242_and_246_accept_only_what_234_and_238_permit() {
    let mut b = Bench::new();
    let fe = diagnostics::subindex(diag::FOLLOWING_ERROR);
    assert_eq!(fe, 48, "FHPP-FPC-13 (fhpp §8.4): 2Fh at subindex 48");
    // 2Fh: B, C, E, F permitted.
    assert_eq!(b.w16(242, fe, 0x0004), Ok(()));
    assert_eq!(b.r16(242, fe), 0x0004);
    assert_eq!(b.w16(242, fe, 0x0001), Err(AbortCode::INVALID_VALUE), "A");
    assert_eq!(b.w16(242, fe, 0x0006), Err(AbortCode::INVALID_VALUE), "two");
    // 2Fh F/W/I: W, I allowed; reserved bits refused.
    assert_eq!(b.w16(246, fe, 0x0080), Ok(()));
    assert_eq!(b.w16(246, fe, 0x00C0), Ok(()));
    assert_eq!(b.w16(246, fe, 0x00A1), Err(AbortCode::INVALID_VALUE));
    // 01h software error: F only, always logged: nothing to change.
    assert_eq!(b.w16(246, 2, 0x0080), Err(AbortCode::INVALID_VALUE));
    assert_eq!(b.w16(242, 2, 0x0002), Err(AbortCode::INVALID_VALUE));
    assert_eq!(b.w16(246, 2, 0x00A0), Ok(()), "its factory value");
    // Unassigned 03h.
    assert_eq!(b.w16(242, 4, 0x0010), Err(AbortCode::INVALID_VALUE));
    // rw2: not with the output stage on.
    b.enable_record();
    assert_eq!(b.w16(242, fe, 0x0010), Err(AbortCode::DEVICE_STATE));
    // PNU 234 / 238 are read only.
    assert!(b.w16(234, fe, 0x0001).is_err());
}

// ---- classes and reactions ------------------------------------------------------------

#[test]
fn reaction_a_switches_the_output_stage_off_at_once() {
    let mut b = Bench::new();
    b.w16(242, diagnostics::subindex(0x11), 0x0001).unwrap();
    b.enable_record();
    b.home_here();
    b.spin(36_000);
    b.dev.fault(diag::SOFTWARE_LIMIT_POSITIVE);
    b.run(3);
    let i = b.input();
    assert!(i.spos.contains(Spos::MOV), "coasting: {i:?}");
    let i = b.until(2000, |i| {
        i.scon.contains(Scon::FAULT) && !i.spos.contains(Spos::MOV)
    });
    assert!(!i.scon.contains(Scon::ENABLED), "{i:?}");
    assert!(!b.dev.stepper().energised());
    assert_eq!(b.dev.fault_number(), 0x11);
}

#[test]
fn quick_stop_is_faster_than_the_deceleration_ramp_and_e_f_keep_the_stage_on() {
    let stop_ms = |reaction: u16| {
        let mut b = Bench::new();
        b.w16(242, diagnostics::subindex(0x47), reaction).unwrap();
        b.enable_record();
        b.home_here();
        b.spin(36_000);
        let t0 = b.t_ms;
        b.dev.fault(diag::MODBUS_WITH_CONTROL);
        let i = b.until(2000, |i| {
            i.scon.contains(Scon::FAULT) && !i.spos.contains(Spos::MOV)
        });
        (b.t_ms - t0, i)
    };
    let (e_ms, e) = stop_ms(0x0010); // E: Quick-Stop ramp PNU 1029, stage on
    let (f_ms, f) = stop_ms(0x0020); // F: the task's deceleration, stage on
    let (b_ms, b) = stop_ms(0x0002); // B: Quick-Stop ramp, stage off
    let (c_ms, c) = stop_ms(0x0004); // C: the task's deceleration, stage off
                                     // 36000 SINC/s: the Quick-Stop ramp (3.6e6 SINC/s²) stops in 10 ms, the task's ramp
                                     // (3.6e5 SINC/s²) in 100 ms.
    assert!(e.scon.contains(Scon::ENABLED) && f.scon.contains(Scon::ENABLED));
    assert!(!b.scon.contains(Scon::ENABLED) && !c.scon.contains(Scon::ENABLED));
    assert!(e_ms < 40 && b_ms < 40, "E {e_ms} B {b_ms}");
    assert!(f_ms > 90 && c_ms > 90, "F {f_ms} C {c_ms}");
}

#[test]
fn reactions_d_and_g_finish_the_record_before_the_fault_state() {
    // D: then the output stage goes off; G: it stays on.
    for (reaction, stage_on) in [(0x0008, false), (0x0040, true)] {
        finish_the_record(reaction, stage_on);
    }
}

fn finish_the_record(reaction: u16, stage_on: bool) {
    let mut b = Bench::new();
    b.w16(242, diagnostics::subindex(0x47), reaction).unwrap();
    b.enable_record();
    b.home_here();
    // Record 1: 9000 SINC at 36000 SINC/s (0.25 s).
    b.w32(404, 1, 9_000);
    b.send(OutputData::record(ENABLED, Cpos::HALT, 1));
    b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::START, 1));
    b.run(30);
    b.dev.fault(diag::MODBUS_WITH_CONTROL);
    b.run(3);
    let i = b.input();
    assert!(
        i.scon.contains(Scon::FAULT) && i.spos.contains(Spos::MOV),
        "{i:?}"
    );
    let i = b.until(2000, |i| !i.spos.contains(Spos::MOV));
    assert!(
        (i.actual2 - 9_000).abs() <= 180,
        "ran to the target: {}",
        i.actual2
    );
    b.run(20);
    let i = b.input();
    assert_eq!(i.scon.contains(Scon::ENABLED), stage_on, "{i:?}");
}

#[test]
fn reaction_e_stops_short_of_the_target() {
    let mut b = Bench::ready();
    b.w32(404, 1, 9_000);
    b.send(OutputData::record(ENABLED, Cpos::HALT, 1));
    b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::START, 1));
    b.run(30);
    b.dev.fault(diag::MODBUS_WITH_CONTROL); // factory reaction E
    let i = b.until(2000, |i| {
        i.scon.contains(Scon::FAULT) && !i.spos.contains(Spos::MOV) && i.spos.contains(Spos::MC)
    });
    assert!(i.actual2 < 8_000, "stopped early: {}", i.actual2);
    assert!(i.scon.contains(Scon::ENABLED));
}

#[test]
fn warning_class_sets_warn_and_pnu_221_and_clears_with_its_cause() {
    let mut b = Bench::new();
    let sub = diagnostics::subindex(diag::LOAD_VOLTAGE_LOW);
    b.w16(246, sub, 0x0080).unwrap(); // 1Bh as a warning (the manual's advice)
    assert_eq!(
        b.dev.diagnostic_class(diag::LOAD_VOLTAGE_LOW),
        Some(Class::Warning)
    );
    b.enable_record();
    b.dev.fault(diag::LOAD_VOLTAGE_LOW);
    b.run(2);
    let i = b.input();
    // FHPP-CB-06: SCON.WARN.
    assert!(
        i.scon.contains(Scon::WARN) && !i.scon.contains(Scon::FAULT),
        "{i:?}"
    );
    // PNU 221 sub 1, bit 27.
    assert_eq!(b.r32(221, 1), 1 << 0x1B);
    assert_eq!(b.r32(220, 1), 0);
    assert_eq!(b.memory(1).0, 0x05, "warning entry");
    assert_eq!(b.memory(1).1, 0x1B);
    b.dev.clear_fault(diag::LOAD_VOLTAGE_LOW);
    b.run(2);
    assert!(!b.input().scon.contains(Scon::WARN));
    assert_eq!(b.r32(221, 1), 0);
}

#[test]
fn information_class_only_writes_the_memory() {
    let mut b = Bench::new();
    let sub = diagnostics::subindex(diag::FOLLOWING_ERROR);
    b.w16(246, sub, 0x00C0).unwrap();
    b.enable_record();
    b.dev.fault(diag::FOLLOWING_ERROR);
    b.run(2);
    let i = b.input();
    assert!(!i.scon.contains(Scon::WARN) && !i.scon.contains(Scon::FAULT));
    assert_eq!(b.memory(1).0, 0x09);
    assert_eq!(b.memory(1).1, 0x2F);
    // Not logged with PNU 246 bit 7 = 0.
    let mut b = Bench::new();
    b.w16(246, sub, 0x0040).unwrap();
    b.dev.fault(diag::FOLLOWING_ERROR);
    b.run(2);
    assert_eq!(b.r8(204, 4), 1, "only the start-up event");
}

/// FHPP-FPC-13: diagnostic 2Fh → PNU 220 subindex 2 bit 15, PNU 242 / 246 subindex 48.
#[test]
fn following_error_fault_shows_in_220_sub_2_bit_15() {
    let mut b = Bench::ready();
    b.dev.fault(diag::FOLLOWING_ERROR);
    b.run(2);
    // FHPP-FPC-13 (fhpp §8.4): 2Fh → PNU 220 sub 2, bit 47 − 32 = 15.
    assert_eq!(b.r32(220, 2), 1 << 15);
    assert_eq!(b.r16(205, 1), 0x2F);
    assert_eq!(b.r8(230, 1), 1, "after the cause");
    // FHPP-FPC-13 (corrected): the arrays run to subindex 32 (numbers 992…1023), not 4.
    for p in [220, 221] {
        assert_eq!(b.dev.read_u32(pnu(p), 32), Some(0), "PNU {p}:32");
        assert_eq!(b.dev.read_u32(pnu(p), 33), None, "PNU {p}:33");
    }
    // PNU 242 / 246 for 2Fh at subindex 2Fh + 1 = 48.
    assert_eq!(
        b.r16(242, 48),
        diagnostics::lookup(0x2F).unwrap().default_reaction()
    );
}

// ---- acknowledge types --------------------------------------------------------------------

#[test]
fn after_cause_faults_acknowledge_only_once_the_cause_has_gone() {
    let mut b = Bench::ready();
    b.dev.fault(diag::LOAD_VOLTAGE_HIGH); // 1Ah: F, reaction B, AfterCause
    b.run(50);
    assert_eq!(b.r8(230, 1), 1);
    let i = b.reset(Ccon(0x00));
    assert!(i.scon.contains(Scon::FAULT), "cause present: T11");
    b.dev.clear_fault(diag::LOAD_VOLTAGE_HIGH);
    let i = b.reset(Ccon(0x00));
    assert!(!i.scon.contains(Scon::FAULT), "{i:?}");
    assert_eq!(b.r16(205, 1), 0xFFFF, "FHPP-FPC-08");
    assert_eq!(b.r8(230, 1), 0xFF, "FHPP-FPC-09");
    // Incoming 01h, outgoing 00h in the memory.
    let (gone, incoming) = (b.memory(1), b.memory(2));
    assert_eq!((gone.0, gone.1), (0x00, 0x1A), "outgoing");
    assert_eq!((incoming.0, incoming.1), (0x01, 0x1A), "incoming");
}

#[test]
fn not_ackable_faults_survive_reset() {
    let mut b = Bench::ready();
    b.dev.fault(0x01); // software error: Reset
    b.run(5);
    assert_eq!(b.r8(230, 1), 0);
    b.dev.clear_fault(0x01);
    let i = b.reset(Ccon(0x00));
    assert!(i.scon.contains(Scon::FAULT));
    assert!(!i.scon.contains(Scon::ENABLED), "reaction A");
}

#[test]
fn immediately_ackable_fault_acknowledges_with_the_cause_present() {
    let mut b = Bench::ready();
    b.dev.fault(diag::MODBUS_WITH_CONTROL);
    b.run(50);
    assert_eq!(b.r8(230, 1), 2);
    assert_eq!(b.r32(220, 3), 1 << (0x47 - 64), "PNU 220 sub 3");
    // Reaction E (stage on) is a minor error: T10 with ENABLE = 1.
    let i = b.reset(ENABLED);
    assert!(!i.scon.contains(Scon::FAULT), "{i:?}");
    assert!(i.scon.contains(Scon::ENABLED));
    assert_eq!(b.r32(220, 3), 0, "acknowledged: no longer active");
}

#[test]
fn unknown_numbers_are_refused_by_inject() {
    let mut b = Bench::new();
    assert!(b.dev.inject(0x03).is_err());
    assert_eq!(
        b.dev.inject(diag::MODBUS_WITH_CONTROL),
        Ok(Class::Fault(Reaction::E))
    );
    let d = diagnostics::lookup(0x1A).unwrap();
    assert_eq!(d.ack, Ack::AfterCause);
}

// ---- diagnostic memory --------------------------------------------------------------------

#[test]
fn memory_starts_with_the_start_up_event_and_reads_through_the_dictionary() {
    let b = Bench::new();
    assert_eq!(b.r8(204, 4), 1);
    assert_eq!(b.memory(1), (0x07, 0x3D, 0));
    assert_eq!(b.memory(2), (0x00, 0xFFFF, 0), "empty entries");
    assert_eq!(b.dev.read_u8(pnu(204), 3), None, "204:3 is write only");
}

#[test]
fn memory_keeps_the_newest_200_newest_first_and_clears_on_204_3() {
    let mut b = Bench::new();
    // 210 warnings 48h (Modbus without control), each one a new occurrence.
    for _ in 0..210 {
        b.dev.fault(diag::MODBUS_WITHOUT_CONTROL);
        b.run(1);
        b.dev.clear_fault(diag::MODBUS_WITHOUT_CONTROL);
        b.run(1);
    }
    assert_eq!(b.r8(204, 4), 200);
    let newest = b.memory(1);
    assert_eq!((newest.0, newest.1), (0x05, 0x48));
    // Time stamps fall from sub 1 to sub 200, 2 ms apart (one warning per 2 cycles).
    let stamps: Vec<u32> = (1..=200).map(|s| b.memory(s).2).collect();
    assert!(stamps.windows(2).all(|w| w[0] == w[1] + 2), "{stamps:?}");
    assert_eq!(
        stamps[0],
        2 + 2 * 209,
        "time stamp of the 210th warning (ms at its cycle end)"
    );
    // The start-up event has been overwritten.
    assert!((1..=200).all(|s| b.memory(s).1 == 0x48));
    // Clear: only the new start-up event is left.
    b.w8(204, 3, 1);
    assert_eq!(b.r8(204, 4), 1);
    let (event, number, _) = b.memory(1);
    assert_eq!((event, number), (0x07, 0x3D));
    assert_eq!(b.memory(2).1, 0xFFFF);
    assert!(b.dev.write(pnu(204), 3, &[2]).is_err(), "only 1 clears");
}

// ---- record chaining ----------------------------------------------------------------------

/// fhpp §8.3 / manual §6.5.3: "after reaching a position, switch to another velocity".
#[test]
fn chaining_on_the_position_comparator_switches_velocity_spec_8_3() {
    let mut b = Bench::ready();
    // Record 1: to 36000 at 18000 SINC/s; RCB2 = 20, next = 2, window 9000…40000.
    b.w32(404, 1, 36_000);
    b.w32(406, 1, 18_000);
    b.w8(402, 1, 20);
    b.w8(416, 1, 2);
    b.w32(430, 1, 9_000);
    b.w32(431, 1, 40_000);
    // Record 2: same target, 72000 SINC/s.
    b.w32(404, 2, 36_000);
    b.w32(406, 2, 72_000);
    b.send(OutputData::record(ENABLED, Cpos::HALT, 1));
    let i = b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::START, 1));
    assert_eq!(i.byte3, 1);
    b.send(OutputData::record(ENABLED, Cpos::HALT, 1));
    b.run(200);
    let i = b.input();
    assert_eq!(
        Rsb(i.byte4) & Rsb::RC1,
        Rsb::EMPTY,
        "not yet: {}",
        i.actual2
    );
    let slow = b.dev.read_u32(pnu(310), 2).unwrap() as i32;
    assert_eq!(slow, 18_000);
    let i = b.until(1000, |i| Rsb(i.byte4).contains(Rsb::RC1));
    assert!(i.actual2 >= 9_000 - 200, "{}", i.actual2);
    assert_eq!(i.byte3, 2, "record feedback follows the chain");
    assert!(!i.spos.contains(Spos::MC));
    b.run(100);
    let fast = b.dev.read_u32(pnu(310), 2).unwrap() as i32;
    assert!(fast > 18_000, "record 2's velocity: {fast}");
    let i = b.until(2000, |i| i.spos.contains(Spos::MC));
    assert!(
        Rsb(i.byte4).contains(Rsb::RC1 | Rsb::RCC),
        "{:?}",
        Rsb(i.byte4)
    );
    assert!((i.actual2 - 36_000).abs() <= 180);
}

#[test]
fn mc_chain_waits_the_start_delay_of_the_next_record_and_pulses_mc() {
    let mut b = Bench::ready();
    b.w32(404, 1, 3_600);
    b.w8(402, 1, 1); // MC
    b.w8(416, 1, 2);
    b.w8(425, 1, 1); // MC pulse at the switch
    b.w32(404, 2, 7_200);
    b.w32(426, 2, 150);
    b.start(OutputData::record(ENABLED, Cpos::HALT, 1));
    // The pulse: one telegram with MC = 1 while the chain goes on.
    let i = b.until(2000, |i| i.spos.contains(Spos::MC));
    assert!(Rsb(i.byte4).contains(Rsb::RC1));
    assert_eq!(i.byte3, 2);
    b.run(1);
    assert!(!b.input().spos.contains(Spos::MC), "MC was a pulse");
    // The switch was two cycles ago: the pulse shows in the telegram after it, and one more
    // cycle has run since.
    let switched = b.t_ms - 2;
    let pos = b.input().actual2;
    b.run(140);
    assert!((b.input().actual2 - pos).abs() <= 180, "waits PNU 426:2");
    let i = b.until(2000, |i| i.spos.contains(Spos::MOV));
    // Motion starts in the 150th cycle after the switch and shows in the next telegram.
    assert!(b.t_ms - switched >= 150, "{} ms {i:?}", b.t_ms - switched);
    assert!(!i.spos.contains(Spos::MC));
    let i = b.until(2000, |i| i.spos.contains(Spos::MC));
    assert!((i.actual2 - 7_200).abs() <= 180);
    assert!(Rsb(i.byte4).contains(Rsb::RCC));
}

#[test]
fn halting_a_chain_leaves_rcc_zero() {
    let mut b = Bench::ready();
    b.w32(404, 1, 3_600);
    b.w8(402, 1, 1);
    b.w8(416, 1, 2);
    b.w32(404, 2, 36_000);
    b.start(OutputData::record(ENABLED, Cpos::HALT, 1));
    b.until(2000, |i| Rsb(i.byte4).contains(Rsb::RC1));
    b.run(50);
    // HALT, then CLEAR: the chain is aborted.
    b.send(OutputData::record(ENABLED, Cpos(0), 1));
    b.run(200);
    b.send(OutputData::record(ENABLED, Cpos::CLEAR, 1));
    let i = b.until(500, |i| i.spos.contains(Spos::MC));
    assert!(!Rsb(i.byte4).contains(Rsb::RCC), "aborted chain");
}

#[test]
fn start_delay_holds_a_started_record() {
    let mut b = Bench::ready();
    b.w32(404, 1, 3_600);
    b.w32(426, 1, 100);
    b.send(OutputData::record(ENABLED, Cpos::HALT, 1));
    let i = b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::START, 1));
    assert!(i.spos.contains(Spos::ACK) && !i.spos.contains(Spos::MC));
    let t0 = b.t_ms;
    b.send(OutputData::record(ENABLED, Cpos::HALT, 1));
    b.until(500, |i| i.spos.contains(Spos::MOV));
    assert!(b.t_ms - t0 >= 95, "{} ms", b.t_ms - t0);
}

#[test]
fn chaining_to_an_invalid_record_raises_3fh() {
    let mut b = Bench::ready();
    b.w32(404, 1, 3_600);
    b.w8(402, 1, 1);
    b.w8(416, 1, 9);
    b.w8(401, 9, 0x06); // COM = 11: invalid record
    b.start(OutputData::record(ENABLED, Cpos::HALT, 1));
    b.until(2000, |i| i.scon.contains(Scon::FAULT));
    assert_eq!(b.dev.fault_number(), diag::RECORD_INVALID);
}

// ---- software limits ----------------------------------------------------------------------

fn limited() -> Bench {
    let mut b = Bench::new();
    b.w32(501, 1, -18_000);
    b.w32(501, 2, 18_000);
    b.enable_record();
    b.home_here();
    b
}

#[test]
fn a_target_behind_a_software_limit_is_refused_with_29h_2ah() {
    let mut b = limited();
    for (target, code) in [(20_000, 0x2A), (-20_000, 0x29)] {
        b.start(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 50, target));
        let i = b.until(200, |i| i.scon.contains(Scon::FAULT));
        assert_eq!(b.dev.fault_number(), code);
        assert!(i.actual2.abs() <= 180, "no motion: {}", i.actual2);
        let i = b.reset(DIRECT);
        assert!(!i.scon.contains(Scon::FAULT), "immediately ackable");
    }
    // Inside: it moves.
    b.send(OutputData::direct(
        DIRECT,
        Cpos::HALT | Cpos::START,
        Cdir(0),
        50,
        9_000,
    ));
    b.send(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 50, 9_000));
    let i = b.until(2000, |i| i.spos.contains(Spos::MC) && i.actual2 > 8_800);
    assert!(!i.scon.contains(Scon::FAULT));
}

#[test]
fn a_velocity_task_into_the_limit_raises_11h_and_locks_the_direction() {
    let mut b = limited();
    b.start(OutputData::direct(DIRECT, Cpos::HALT, VELOCITY, 0, 36_000));
    let i = b.until(2000, |i| i.scon.contains(Scon::FAULT));
    assert_eq!(b.dev.fault_number(), diag::SOFTWARE_LIMIT_POSITIVE);
    b.until(500, |i| !i.spos.contains(Spos::MOV));
    // The reported speed follows MOV within its filter (PNU 1024:6, 20 ms).
    b.run(100);
    let i2 = b.input();
    assert!(i.actual2 >= 17_000 && i2.actual2 < 19_000, "{}", i2.actual2);
    b.reset(DIRECT);
    // Positive again: 13h.
    b.send(OutputData::direct(
        DIRECT,
        Cpos::HALT | Cpos::START,
        VELOCITY,
        0,
        36_000,
    ));
    b.send(OutputData::direct(DIRECT, Cpos::HALT, VELOCITY, 0, 36_000));
    b.until(200, |i| i.scon.contains(Scon::FAULT));
    assert_eq!(b.dev.fault_number(), diag::POSITIVE_DIRECTION_LOCKED);
    b.reset(DIRECT);
    // Back out negative: allowed.
    b.send(OutputData::direct(
        DIRECT,
        Cpos::HALT | Cpos::START,
        Cdir(0),
        50,
        0,
    ));
    b.send(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 50, 0));
    let i = b.until(2000, |i| i.spos.contains(Spos::MC) && i.actual2.abs() < 200);
    assert!(!i.scon.contains(Scon::FAULT));
}

#[test]
fn jog_stops_at_the_software_limit_without_a_fault() {
    let mut b = limited();
    b.w32(530, 1, 36_000); // fast enough to reach the limit soon
    b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::JOGP, 0));
    b.run(1500);
    let i = b.input();
    assert!(!i.scon.contains(Scon::FAULT), "{i:?}");
    assert!(
        i.actual2 <= 18_000 + 180 && i.actual2 >= 17_000,
        "{}",
        i.actual2
    );
    assert!(!i.spos.contains(Spos::MOV));
}

#[test]
fn force_task_in_open_loop_raises_24h() {
    let mut b = Bench::with_mode(StepperMode::OpenLoop);
    b.enable_record();
    b.home_here();
    let force = Cdir(0x02);
    b.send(OutputData::direct(DIRECT, Cpos::HALT, force, 50, 100));
    b.send(OutputData::direct(
        DIRECT,
        Cpos::HALT | Cpos::START,
        force,
        50,
        100,
    ));
    b.until(100, |i| i.scon.contains(Scon::FAULT));
    assert_eq!(b.dev.fault_number(), diag::NOT_IN_OPEN_LOOP);
}

// ---- comparators (PNU 312) ----------------------------------------------------------------

/// Direct mode uses PNU 585…595 (§6.7.4): the position comparator is on while the actual
/// position is in [min, max] for the window time; the time comparator counts from the start.
#[test]
fn direct_comparators_show_in_pnu_312() {
    let mut b = Bench::ready();
    b.w32(585, 1, 9_000);
    b.w32(586, 1, 18_000);
    b.dev.write(pnu(587), 1, &5u16.to_le_bytes()).unwrap();
    b.w32(594, 1, 100);
    b.w32(595, 1, 200);
    b.start(OutputData::direct(DIRECT, Cpos::HALT, Cdir(0), 10, 36_000));
    let t0 = b.t_ms;
    let mut seen = 0u8;
    let mut time_on = None;
    let mut inside_ms = 0;
    for _ in 0..3000 {
        b.run(1);
        let out = b.r8(312, 1);
        let pz = b.input().actual2;
        if out & 0x01 != 0 {
            assert!((9_000..=18_200).contains(&pz), "position bit at {pz}");
            inside_ms += 1;
        }
        if out & 0x08 != 0 && time_on.is_none() {
            time_on = Some(b.t_ms - t0);
        }
        seen |= out;
    }
    assert_eq!(
        seen & 0x09,
        0x09,
        "position and time comparators: {seen:#04x}"
    );
    assert!(inside_ms > 100, "{inside_ms} ms inside");
    let t = time_on.unwrap();
    // t0 is taken 3 cycles after the START edge was seen.
    assert!((96..=100).contains(&t), "time comparator from {t} ms");
    assert_eq!(b.r8(312, 1) & 0x09, 0, "past both windows");
}

/// RCB2 = 23: the time comparator of record 1 (PNU 439/440) switches to record 2 after
/// PNU 439 ms of record 1.
#[test]
fn chaining_on_the_time_comparator() {
    let mut b = Bench::ready();
    b.w32(404, 1, 36_000);
    b.w32(406, 1, 9_000);
    b.w8(402, 1, 23);
    b.w8(416, 1, 2);
    b.w32(439, 1, 150);
    b.w32(440, 1, 10_000);
    b.w32(404, 2, -3_600);
    b.send(OutputData::record(ENABLED, Cpos::HALT, 1));
    b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::START, 1));
    let t0 = b.t_ms - 2;
    b.send(OutputData::record(ENABLED, Cpos::HALT, 1));
    let i = b.until(1000, |i| Rsb(i.byte4).contains(Rsb::RC1));
    let t = b.t_ms - t0;
    assert!((150..=156).contains(&t), "switched after {t} ms");
    assert_eq!(i.byte3, 2);
    let i = b.until(3000, |i| i.spos.contains(Spos::MC));
    assert!(
        (i.actual2 + 3_600).abs() <= 180,
        "record 2's target: {}",
        i.actual2
    );
    assert!(Rsb(i.byte4).contains(Rsb::RCC));
}

/// Load voltage off: SCON.VLOAD = 0, 1Bh (F, reaction A: the output stage goes off); back on,
/// RESET acknowledges it and the drive can be enabled again.
#[test]
fn load_voltage_off_raises_1bh() {
    let mut b = Bench::ready();
    b.dev.set_load_voltage(false);
    let i = b.until(100, |i| i.scon.contains(Scon::FAULT));
    assert!(
        !i.scon.contains(Scon::VLOAD) && !i.scon.contains(Scon::ENABLED),
        "{i:?}"
    );
    assert_eq!(b.dev.fault_number(), diag::LOAD_VOLTAGE_LOW);
    let i = b.reset(Ccon(0x00));
    assert!(i.scon.contains(Scon::FAULT), "cause present");
    b.dev.set_load_voltage(true);
    let i = b.reset(Ccon(0x00));
    assert!(
        !i.scon.contains(Scon::FAULT) && i.scon.contains(Scon::VLOAD),
        "{i:?}"
    );
    let i = b.enable_record();
    assert!(i.scon.contains(Scon::ENABLED));
}

/// Teach into a relative record: 40h "last teaching not successful" (a warning by default),
/// the record keeps its target; a successful teach clears it.
#[test]
fn teach_into_a_relative_record_warns_40h() {
    let mut b = Bench::ready();
    b.w8(401, 3, 0x01); // record 3: relative
    b.w32(404, 3, 1234);
    b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::TEACH, 3));
    let i = b.send(OutputData::record(ENABLED, Cpos::HALT, 3));
    assert!(i.scon.contains(Scon::WARN), "{i:?}");
    assert_eq!(b.r32(221, 3), 1 << (0x40 - 64));
    assert_eq!(b.r32(404, 3), 1234);
    // Record 4 is absolute: taught, the warning goes.
    b.send(OutputData::record(ENABLED, Cpos::HALT | Cpos::TEACH, 4));
    let i = b.send(OutputData::record(ENABLED, Cpos::HALT, 4));
    assert!(!i.scon.contains(Scon::WARN), "{i:?}");
    assert_eq!(b.r32(404, 4) as i32, i.actual2);
}

// ---- spec vectors FHPP-DIAG-01 … FHPP-DIAG-04 -------------------------------------------------

/// FHPP-DIAG-01: the Modbus timeout diagnostics by their factory class: 47h "with master
/// control" is an error (F: SCON.FAULT, PNU 205 = 47h), 48h "without master control" a
/// warning (SCON.WARN, PNU 221 sub 3 bit 8, no fault). Which one the timeout raises is the
/// Modbus server's choice (`drivetwin::vendors::festo_cmmo_st::modbus_server`, tested there).
#[test]
fn fhpp_diag_01_modbus_timeout_47h_is_an_error_48h_a_warning() {
    let mut b = Bench::ready();
    assert!(matches!(
        b.dev.diagnostic_class(diag::MODBUS_WITH_CONTROL),
        Some(Class::Fault(_))
    ));
    assert_eq!(
        b.dev.diagnostic_class(diag::MODBUS_WITHOUT_CONTROL),
        Some(Class::Warning)
    );
    b.dev.fault(diag::MODBUS_WITHOUT_CONTROL);
    b.run(2);
    let i = b.input();
    assert!(
        i.scon.contains(Scon::WARN) && !i.scon.contains(Scon::FAULT),
        "{i:?}"
    );
    assert_eq!(b.r32(221, 3), 1 << (0x48 - 64));
    assert_eq!(b.r16(205, 1), 0xFFFF, "a warning is no fault");
    b.dev.clear_fault(diag::MODBUS_WITHOUT_CONTROL);
    b.dev.fault(diag::MODBUS_WITH_CONTROL);
    b.run(2);
    let i = b.input();
    assert!(i.scon.contains(Scon::FAULT), "{i:?}");
    assert!(!i.scon.contains(Scon::WARN), "48h cleared with its cause");
    assert_eq!(b.r16(205, 1), 0x47);
    assert_eq!(b.dev.fault_number(), 0x47);
}

/// FHPP-DIAG-02 (corrected): "value is out of range" is 4Ch (printed "40h", which is the teach
/// warning): an error (F), acknowledgeable at once, reactions B…G, error management at
/// subindex 4Dh.
#[test]
fn fhpp_diag_02_value_out_of_range_is_4ch() {
    let d = diagnostics::lookup(0x4C).unwrap();
    assert_eq!(d.name, "Value is out of range");
    assert_eq!(d.ack, Ack::Immediately);
    assert_eq!(
        diagnostics::lookup(diag::TEACH_FAILED.into()).map(|d| d.name),
        Some("Last teaching not successful")
    );
    let mut b = Bench::ready();
    assert_eq!(b.r16(234, 0x4D), 0x007E, "B, C, D, E, F, G");
    assert!(matches!(b.dev.inject(0x4C), Ok(Class::Fault(Reaction::E))));
    b.run(50);
    assert!(b.input().scon.contains(Scon::FAULT));
    assert_eq!(b.r16(205, 1), 0x4C);
    assert_eq!(b.r32(220, 3), 1 << (0x4C - 64));
    let i = b.reset(ENABLED);
    assert!(!i.scon.contains(Scon::FAULT), "acknowledged at once: {i:?}");
}

/// FHPP-DIAG-03: the 7-segment display shows the hexadecimal code of an active error ("E2F")
/// or warning ("48"); the error goes first; an information is not shown; nothing once the
/// error is acknowledged and the warning's cause has gone.
#[test]
fn fhpp_diag_03_seven_segment_shows_the_hex_code() {
    let mut b = Bench::ready();
    assert_eq!(b.dev.seven_segment(), SevenSegment::NoMessage);
    b.dev.fault(diag::MODBUS_WITHOUT_CONTROL);
    b.run(2);
    assert_eq!(b.dev.seven_segment(), SevenSegment::Warning(0x48));
    assert_eq!(b.dev.seven_segment().to_string(), "48");
    b.dev.fault(diag::FOLLOWING_ERROR);
    b.run(2);
    assert_eq!(b.dev.seven_segment(), SevenSegment::Error(0x2F));
    assert_eq!(b.dev.seven_segment().to_string(), "E2F");
    b.dev.clear_fault(diag::FOLLOWING_ERROR);
    b.run(50);
    b.reset(ENABLED);
    assert!(!b.input().scon.contains(Scon::FAULT));
    assert_eq!(b.dev.seven_segment().to_string(), "48");
    b.dev.clear_fault(diag::MODBUS_WITHOUT_CONTROL);
    b.run(2);
    assert_eq!(b.dev.seven_segment(), SevenSegment::NoMessage);
    assert_eq!(b.dev.seven_segment().to_string(), "");
    // An information (PNU 246 = C0h, written with the stage off) is not shown (§7.1.2).
    let mut b = Bench::new();
    b.w16(246, diagnostics::subindex(diag::FOLLOWING_ERROR), 0x00C0)
        .unwrap_or_else(|e| panic!("{e:?}"));
    b.enable_record();
    b.dev.fault(diag::FOLLOWING_ERROR);
    b.run(2);
    assert_eq!(b.memory(1).1, 0x2F, "logged");
    assert_eq!(b.dev.seven_segment(), SevenSegment::NoMessage);
}

/// FHPP-DIAG-04: PNU 204:3 := 1 clears the memory and writes the start-up event 3Dh; PNU 204:4
/// then reads 1, also after a second clear right after (the "not twice in a row" rule itself
/// is checked on the ring in `diagnostic_memory`'s unit tests).
#[test]
fn fhpp_diag_04_clear_writes_one_start_up_event() {
    let mut b = Bench::ready();
    b.dev.fault(diag::MODBUS_WITHOUT_CONTROL);
    b.run(2);
    assert!(b.r8(204, 4) >= 2);
    b.w8(204, 3, 1);
    b.run(1);
    assert_eq!(b.r8(204, 4), 1);
    assert_eq!((b.memory(1).0, b.memory(1).1), (0x07, 0x3D));
    b.run(5);
    b.w8(204, 3, 1);
    b.run(1);
    assert_eq!(b.r8(204, 4), 1, "3Dh not twice in a row");
    assert_eq!((b.memory(1).0, b.memory(1).1), (0x07, 0x3D));
    assert_eq!(b.memory(2).1, 0xFFFF);
}
