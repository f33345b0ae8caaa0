//! The Festo CMMO-ST as one device: its FHPP parameters (the `cmmo-st` object dictionary,
//! PNU n = object 0x2000 + n), the FHPP state machine ([`Fhpp`]), the record list, a motion
//! executor for every [`MotionCommand`] and the stepper plant ([`Stepper`]) behind it.
//!
//! The runtime feeds the output telegram with [`FhppDevice::set_outputs`] (8 or 16 bytes, as
//! Modbus / IO-Link / I-Port deliver it), steps the device with [`FhppDevice::step`] on its
//! clock (one FHPP cycle per millisecond; the stepper integrates in 50 µs sub-steps inside),
//! and reads the input telegram with [`FhppDevice::inputs`]. Front ends see the parameters
//! through [`ObjectAccess`]. Sans-IO, `no_std`, no allocation in `step`, deterministic.
//!
//! # Decisions
//!
//! - **Record list.** Built from PNU 401…442 at construction and rebuilt at the next cycle
//!   after any write to one of those PNUs through [`ObjectAccess`] (so a record changed over
//!   the parameter channel is used by the next start, as the manual's record list is).
//! - **Units.** The trajectory runs in SINC (`f64`) in the raw axis coordinate (encoder based,
//!   no reference). EINC per SINC = (PNU 1001:1 / 1001:2) · (1002:1 / 1002:2) ·
//!   (1005:2 / 1005:3) / (1003:1 / 1003:2) (fhpp §6 inferred formula), PNU 1000 = 0x80 inverts
//!   the sign. With the dictionary's defaults (rotary, 1 SINC = 0.01°, PNU 600 = −2, 601 = 41h,
//!   feed 36000 SINC per revolution, encoder 2000) 1 EINC = 18 SINC.
//! - **Coordinates** (fhpp §5.3): AZ = REF + PNU 1010, PZ = AZ + PNU 500. Every position of the
//!   I/O, PNU 404 and PNU 300 / 1041 is PZ-based: `pz = raw − REF − PNU 1010 − PNU 500`.
//! - **Homing**: method −35 "current position" only: REF := actual position, so the actual
//!   position becomes −(PNU 1010 + PNU 500) (§6.2 step 2 "current position = 0 − offset"); the
//!   optional travel to AZ is not made. Every other method (33/34 index pulse, −17/−18 fixed
//!   stop, 23/27 reference switch) ends with diagnostic 3Bh "homing method invalid" because
//!   the plant has no switches and no index pulse yet.
//! - **Decelerations**: Halt and Stop use the running task's deceleration (record PNU 408,
//!   direct PNU 542, jog PNU 532, homing PNU 1013), QuickStop PNU 1029. When a Stop or
//!   QuickStop has brought the set-point to rest the position controller takes the actual
//!   position as its set-point (a stopped drive holds where it stands), which also ends a
//!   following error left by lost steps, so the fault can be acknowledged.
//! - **MC** (fhpp §5.6): position tasks: the set-point has arrived and the actual position
//!   stays within ±PNU 1022 for PNU 1023 ms; velocity tasks: the ramp is done and the actual
//!   velocity stays within ±PNU 561 for PNU 1023 ms; homing: done; no task: not moving.
//! - **MOV** (SPOS.MOV, "speed ≥ limit value", no PNU names the limit): the set-point is
//!   moving or |actual velocity| > PNU 561 (velocity target window).
//! - **Following error**: |set-point − actual| > window for longer than the timeout: windows
//!   PNU 424 (record), 549 (direct position), 538 (jog, timeout 539), 568 (velocity tasks, on
//!   the velocity difference), timeout PNU 1045. Diagnostic 2Fh with the class and reaction of
//!   PNU 246 / 242 (default F, reaction E).
//! - **Standstill** after MC of a position task: outside ±PNU 1042 around the target for
//!   PNU 1043 ms → SPOS.STILL and warning 37h (PNU 1042 = 0: off).
//! - Direct-mode velocity ramp byte = 0 % uses the base value PNU 560 (a ramp of 0 would
//!   never reach the speed); a position move with 0 % velocity does not move (Tab. 5.17
//!   "0 = no velocity"). Final velocities (PNU 423, 548) are not used: every move ends at rest.
//! - Velocities are limited to PNU 502 (SDIR/RSB.VLIM while limited).
//!
//! # Not modelled yet
//!
//! Force mode (a force task holds position and reports MC at once), record chaining (RCB2,
//! PNU 416, 425, 426 start delay), software limits (PNU 501, diagnostics 11h–14h, 29h/2Ah),
//! jerk limitation, comparators, the parameter channel (FPC input bytes read 0), the
//! diagnostic memory (PNU 200–204), and the rw2 access rule.

use core::time::Duration;

use od::{AbortCode, Entry, Instant, ObjectAccess, ObjectDictionary, Value};

use super::control_bytes::{ControlMode, OutputData};
use super::parameter_channel::{self, ParameterChannel};
use super::record_table::{Comparator, Rcb1, Record, RecordTable, TimeComparator};
use super::state_machine::{
    Ack, Authority, Event, Fault, Fhpp, MotionCommand, MotionStatus, Reaction, RelativeTo,
};
use super::{FHPP_FPC_LEN, FHPP_STD_LEN};
use crate::fhpp::record_table::StartBehaviour;
use crate::stepper::{sinc_to_si, Stepper, StepperData, StepperDemand, StepperMode};
use crate::trajectory::{Limits, Trajectory};

/// Object index of PNU `pnu` (the dictionary's mapping rule).
pub const fn pnu_index(pnu: u16) -> u16 {
    0x2000 + pnu
}

/// Diagnostic numbers this device raises (App. D).
pub mod diag {
    /// 28h homing required.
    pub const HOMING_REQUIRED: u8 = 0x28;
    /// 2Fh following error.
    pub const FOLLOWING_ERROR: u8 = 0x2F;
    /// 37h standstill monitoring.
    pub const STANDSTILL: u8 = 0x37;
    /// 3Bh homing method invalid.
    pub const HOMING_METHOD_INVALID: u8 = 0x3B;
    /// 3Fh record invalid.
    pub const RECORD_INVALID: u8 = 0x3F;
    /// 47h Modbus connection with master control.
    pub const MODBUS_WITH_CONTROL: u8 = 0x47;
    /// 48h Modbus connection without master control.
    pub const MODBUS_WITHOUT_CONTROL: u8 = 0x48;
}

/// The "Ack" column of App. D for a diagnostic number: "Reset" = not by RESET,
/// "AfterCause" = once the cause is gone, "Imm" = at once.
pub const fn ack_type(code: u8) -> Ack {
    match code {
        0x01 | 0x02 | 0x06 | 0x09 | 0x0C | 0x0D | 0x18 | 0x23 | 0x4D => Ack::NotAckable,
        0x0E | 0x15 | 0x16 | 0x17 | 0x1A | 0x1B | 0x2F | 0x34 | 0x38 | 0x45 | 0x46 | 0x4E => {
            Ack::AfterCause
        }
        _ => Ack::Immediately,
    }
}

/// Settings of the simulation that no PNU holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FhppSettings {
    /// Motor, load and controller data of the stepper.
    pub stepper: StepperData,
    /// Closed loop (the CMMO-ST with its encoder, the default) or open loop.
    pub mode: StepperMode,
    /// FHPP cycle (1 ms).
    pub cycle: Duration,
}

impl Default for FhppSettings {
    fn default() -> Self {
        FhppSettings {
            stepper: StepperData::default(),
            mode: StepperMode::ClosedLoop,
            cycle: Duration::from_millis(1),
        }
    }
}

/// The output image had neither 8 nor 16 bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BadLength(pub usize);

/// Parameters read every cycle, refreshed from the dictionary after a write.
#[derive(Debug, Clone, Copy, Default)]
struct Params {
    einc_per_sinc: f64,
    polarity: f64,
    project_zero: i64,
    az_offset: i64,
    max_velocity: f64,
    jog_slow: f64,
    jog_fast: f64,
    jog_accel: f64,
    jog_time_ms: u64,
    jog_fe_window: f64,
    jog_fe_time_ms: u64,
    direct_accel: f64,
    direct_decel: f64,
    direct_fe_window: f64,
    velocity_target_window: f64,
    velocity_fe_window: f64,
    stroke_velocity: f64,
    target_window: f64,
    target_window_ms: u64,
    standstill_window: f64,
    standstill_ms: u64,
    fe_timeout_ms: u64,
    quick_stop: f64,
    homing_method: i64,
    homing_accel: f64,
    base_acceleration: f64,
    base_force_ma: f64,
}

/// What the executor is doing to the set-point.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Motion {
    /// Hold the set-point.
    Hold,
    /// Position move to `target` (raw SINC).
    Position { target: f64, lim: Limits },
    /// Velocity ramp to `target` SINC/s; `stroke`: limit of travel from `start`.
    Velocity {
        target: f64,
        accel: f64,
        decel: f64,
        start: f64,
        stroke: Option<f64>,
    },
    /// Jog since cycle `since`.
    Jog { positive: bool, since: u64 },
    /// Brake to rest; `resync`: then take the actual position as the set-point.
    Braking { decel: f64, resync: bool },
}

/// Which MC condition the current task has.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Task {
    None,
    Position {
        target: f64,
    },
    Velocity {
        target: f64,
    },
    Homing {
        done: bool,
    },
    /// Force task (not modelled): complete at once.
    Force,
}

/// A position task interrupted by HALT (SA3), continued by START.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pending {
    target: f64,
    lim: Limits,
}

/// The CMMO-ST: dictionary, FHPP state machine, record list, motion and stepper plant.
pub struct FhppDevice<S> {
    od: ObjectDictionary<S>,
    settings: FhppSettings,
    fhpp: Fhpp,
    records: RecordTable,
    records_dirty: bool,
    params: Params,
    params_dirty: bool,
    stepper: Stepper,
    outputs: OutputData,
    fpc_out: [u8; 8],
    fpc_in: [u8; 8],
    /// The EFPC server and the permanent memory (App. C, PNU 127).
    fpc: ParameterChannel,
    inputs: [u8; FHPP_STD_LEN],
    status: MotionStatus,
    next: Option<Instant>,
    /// Cycles run so far (the device's millisecond clock for its timers).
    cycles: u64,
    // ---- motion ----
    stage_on: bool,
    traj: Trajectory,
    motion: Motion,
    task: Task,
    pending: Option<Pending>,
    /// Deceleration of the running task (Halt, Stop).
    task_decel: f64,
    fe_window: f64,
    fe_time_ms: u64,
    fe_velocity: bool,
    velocity_limited: bool,
    stroke_reached: bool,
    last_target: f64,
    /// Raw SINC position of REF; `None` until homed.
    reference: Option<f64>,
    window_since: Option<u64>,
    mc: bool,
    fe_since: Option<u64>,
    following_error: bool,
    /// Target of the last completed position task (standstill monitoring).
    standstill_target: Option<f64>,
    still_since: Option<u64>,
    standstill_error: bool,
    /// Warnings present, bit n = diagnostic n.
    warnings: u128,
    /// Injected faults still present.
    injected: u128,
}

fn get_i64<S: AsRef<[u8]> + AsMut<[u8]>>(od: &ObjectDictionary<S>, pnu: u16, sub: u8) -> i64 {
    match od.value(pnu_index(pnu), sub) {
        Some(Value::Signed(v)) => v,
        Some(Value::Unsigned(v)) => i64::try_from(v).unwrap_or(i64::MAX),
        Some(Value::Bool(b)) => i64::from(b),
        Some(Value::Real(r)) => r as i64,
        None => 0,
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> FhppDevice<S> {
    /// Power-on: S1, not referenced, output stage off, the stepper at rest at angle 0.
    pub fn new(od: ObjectDictionary<S>, settings: FhppSettings) -> Self {
        let mut data = settings.stepper;
        let enc = get_i64(&od, 1001, 1);
        let revs = get_i64(&od, 1001, 2).max(1);
        if enc > 0 {
            data.encoder_increments_per_rev = u32::try_from(enc / revs).unwrap_or(u32::MAX);
        }
        let mut stepper = Stepper::new(data);
        stepper.set_mode(settings.mode);
        let mut dev = FhppDevice {
            od,
            settings,
            fhpp: Fhpp::default(),
            records: RecordTable::default(),
            records_dirty: true,
            params: Params::default(),
            params_dirty: true,
            stepper,
            outputs: OutputData::default(),
            fpc_out: [0; 8],
            fpc_in: [0; 8],
            fpc: ParameterChannel::default(),
            inputs: [0; FHPP_STD_LEN],
            status: MotionStatus::default(),
            next: None,
            cycles: 0,
            stage_on: false,
            traj: Trajectory::default(),
            motion: Motion::Hold,
            task: Task::None,
            pending: None,
            task_decel: 1.0,
            fe_window: 0.0,
            fe_time_ms: 0,
            fe_velocity: false,
            velocity_limited: false,
            stroke_reached: false,
            last_target: 0.0,
            reference: None,
            window_since: None,
            mc: true,
            fe_since: None,
            following_error: false,
            standstill_target: None,
            still_since: None,
            standstill_error: false,
            warnings: 0,
            injected: 0,
        };
        dev.refresh();
        dev.traj = Trajectory::at(dev.raw_actual());
        dev.task_decel = dev.params.direct_decel;
        dev.fe_window = dev.params.direct_fe_window;
        dev.fe_time_ms = dev.params.fe_timeout_ms;
        dev.status = dev.motion_status();
        dev.inputs = dev.fhpp.inputs().to_bytes();
        dev
    }

    // ---- access ------------------------------------------------------------------------

    pub fn od(&self) -> &ObjectDictionary<S> {
        &self.od
    }

    /// The dictionary for the device's own writes; parameters are re-read at the next cycle.
    pub fn od_mut(&mut self) -> &mut ObjectDictionary<S> {
        self.params_dirty = true;
        self.records_dirty = true;
        &mut self.od
    }

    pub fn fhpp(&self) -> &Fhpp {
        &self.fhpp
    }

    pub fn fhpp_mut(&mut self) -> &mut Fhpp {
        &mut self.fhpp
    }

    pub fn records(&self) -> &RecordTable {
        &self.records
    }

    pub fn stepper(&self) -> &Stepper {
        &self.stepper
    }

    /// The plant, e.g. to block the load or add a load torque.
    pub fn stepper_mut(&mut self) -> &mut Stepper {
        &mut self.stepper
    }

    pub fn settings(&self) -> &FhppSettings {
        &self.settings
    }

    /// Open or closed loop (the controller restarts from the present set-point).
    pub fn set_stepper_mode(&mut self, mode: StepperMode) {
        self.settings.mode = mode;
        self.stepper.set_mode(mode);
    }

    /// The motion status fed to the state machine at the next cycle.
    pub fn motion_status(&self) -> MotionStatus {
        let p = &self.params;
        let actual = self.raw_actual();
        let velocity = self.actual_velocity();
        let moving = self.traj.velocity != 0.0 || libm::fabs(velocity) > p.velocity_target_window;
        let motion_complete = match self.task {
            Task::Position { .. } | Task::Velocity { .. } => self.mc,
            Task::Homing { done } => done,
            Task::Force => true,
            Task::None => !moving,
        };
        let fe_fault = self.following_error && self.class_of(diag::FOLLOWING_ERROR).is_some();
        let fault = if fe_fault {
            self.fault_for(diag::FOLLOWING_ERROR)
        } else {
            None
        };
        MotionStatus {
            moving,
            motion_complete,
            following_error: self.following_error,
            standstill_error: self.standstill_error,
            referenced: self.reference.is_some(),
            velocity_limit: self.velocity_limited,
            stroke_limit: self.stroke_reached,
            actual_position: sat_i32(self.to_pz(actual)),
            actual_velocity: sat_i32(velocity),
            actual_force: self.actual_force(),
            warning: self.warnings != 0,
            fault,
        }
    }

    /// The input telegram (SCON, SPOS, bytes 3…8) of the last cycle.
    pub fn inputs(&self) -> [u8; FHPP_STD_LEN] {
        self.inputs
    }

    /// The input telegram with the 8 EFPC bytes (FPCS first) of the last cycle.
    pub fn inputs_fpc(&self) -> [u8; FHPP_FPC_LEN] {
        let mut b = [0u8; FHPP_FPC_LEN];
        b[..8].copy_from_slice(&self.inputs);
        b[8..].copy_from_slice(&self.fpc_in);
        b
    }

    /// The output telegram of the PLC: 8 bytes (FHPP Standard) or 16 (FHPP + FPC). It is
    /// taken at the next cycle.
    pub fn set_outputs(&mut self, image: &[u8]) -> Result<(), BadLength> {
        let (out, fpc) = OutputData::parse(image).ok_or(BadLength(image.len()))?;
        self.outputs = out;
        if let Some(f) = fpc {
            self.fpc_out = f;
        }
        Ok(())
    }

    /// The output telegram last set.
    pub fn outputs(&self) -> OutputData {
        self.outputs
    }

    /// The output EFPC bytes last set.
    pub fn fpc_outputs(&self) -> [u8; 8] {
        self.fpc_out
    }

    /// The parameter channel (its permanent memory holds the parameter file).
    pub fn parameter_channel(&self) -> &ParameterChannel {
        &self.fpc
    }

    /// CMMO-ST App. C: one EFPC exchange per cycle. A parameter job goes through this
    /// device's [`ObjectAccess`], so a written PNU takes effect like any other write.
    fn serve_parameter_channel(&mut self) {
        let ctx = parameter_channel::Context {
            stage_on: self.stage_on,
            authority: self.fhpp.authority(),
            fault: self.fhpp.fault().is_some(),
            now_ms: self.cycles,
        };
        let desc = self.od.description();
        if let Some(job) = self.fpc.receive(&self.fpc_out, &ctx, desc) {
            let result = parameter_channel::execute(job, self, &ctx);
            self.fpc.complete(job, result);
        }
        if let Some(code) = self.fpc.take_diagnostic() {
            self.raise_once(code);
        }
        self.fpc_in = self.fpc.response();
    }

    /// The active fault number (diagnostic), 0 for none: Modbus FC 0x07 (fhpp §9.15).
    pub fn fault_number(&self) -> u8 {
        self.fhpp.fault().map_or(0, |f| f.code)
    }

    /// Actual position in SI units (m or rad) through PNU 600 / 601; `None` for a user unit.
    pub fn actual_position_si(&self) -> Option<f64> {
        let n = get_i64(&self.od, 600, 1) as i8;
        let d = get_i64(&self.od, 601, 1) as u8;
        sinc_to_si(i64::from(self.status.actual_position), n, d)
    }

    // ---- diagnostics -------------------------------------------------------------------

    /// PNU 246 class of diagnostic `code`: `Some(reaction)` for an error (F), `None` for a
    /// warning or an information.
    fn class_of(&self, code: u8) -> Option<Reaction> {
        let sub = code.saturating_add(1);
        let handling = get_i64(&self.od, 246, sub);
        if handling & 0x40 != 0 || handling & 0x20 == 0 {
            return None;
        }
        let bits = get_i64(&self.od, 242, sub) as u16;
        Some(Reaction::from_bit(bits).unwrap_or(Reaction::B))
    }

    fn fault_for(&self, code: u8) -> Option<Fault> {
        self.class_of(code).map(|reaction| Fault {
            code,
            reaction,
            ack: ack_type(code),
        })
    }

    /// Raises diagnostic `code` (fault injection, communication monitoring): an error (per
    /// PNU 246) takes T7 at the next cycle, a warning sets SCON.WARN. The cause counts as
    /// present until [`Self::clear_fault`].
    pub fn fault(&mut self, code: u8) {
        let bit = 1u128 << (code & 0x7F);
        match self.fault_for(code) {
            Some(f) => {
                self.injected |= bit;
                self.fhpp.raise_fault(f);
            }
            None => self.warnings |= bit,
        }
    }

    /// The cause of diagnostic `code` has gone: an error may now be acknowledged, a warning
    /// clears.
    pub fn clear_fault(&mut self, code: u8) {
        let bit = 1u128 << (code & 0x7F);
        self.injected &= !bit;
        self.warnings &= !bit;
        self.fhpp.fault_cause_gone(code);
    }

    /// Raises a diagnostic once (a refused start, a homing error): errors need RESET, a
    /// warning shows until the next start.
    fn raise_once(&mut self, code: u8) {
        match self.fault_for(code) {
            Some(f) => self.fhpp.raise_fault(Fault {
                ack: Ack::Immediately,
                ..f
            }),
            None => self.warnings |= 1u128 << (code & 0x7F),
        }
    }

    // ---- the cycle ---------------------------------------------------------------------

    /// Runs every FHPP cycle due up to `now` (the first call starts the clock); returns when
    /// the next one is due.
    pub fn step(&mut self, now: Instant) -> Option<Instant> {
        let cycle = if self.settings.cycle.is_zero() {
            Duration::from_millis(1)
        } else {
            self.settings.cycle
        };
        let mut next = self.next.unwrap_or(now);
        let mut n = 0;
        while next <= now {
            if n == 1000 {
                // More than a second behind (a stalled host): skip, do not spiral.
                next = now + cycle;
                break;
            }
            self.cycle(cycle.as_secs_f64());
            next = next + cycle;
            n += 1;
        }
        self.next = Some(next);
        self.next
    }

    fn cycle(&mut self, dt: f64) {
        if self.params_dirty {
            self.refresh();
        }
        if self.records_dirty {
            self.rebuild_records();
        }
        let mut events: heapless::Vec<Event, 24> = heapless::Vec::new();
        let status = self.status;
        let input = self.fhpp.cycle(&self.outputs, &self.records, &status, |e| {
            let _ = events.push(e);
        });
        self.inputs = input.to_bytes();
        for e in events {
            match e {
                Event::Motion(m) => self.execute(m),
                Event::Refused(r) => self.raise_once(r.diagnostic()),
                Event::Teach { record, position } => self.teach(record, position),
                Event::Transition(_) => {}
            }
        }
        self.serve_parameter_channel();
        self.advance(dt);
        self.cycles += 1;
        self.status = self.motion_status();
        self.publish();
    }

    fn refresh(&mut self) {
        self.params_dirty = false;
        let od = &self.od;
        let g = |pnu, sub| get_i64(od, pnu, sub);
        let pos = |v: i64| v.max(0) as f64;
        let ratio = |n: i64, d: i64| {
            if n > 0 && d > 0 {
                n as f64 / d as f64
            } else {
                1.0
            }
        };
        let enc = ratio(g(1001, 1), g(1001, 2));
        let gear = ratio(g(1002, 1), g(1002, 2));
        let axis = ratio(g(1005, 2), g(1005, 3));
        let feed = ratio(g(1003, 1), g(1003, 2));
        let old = self.params.einc_per_sinc;
        let einc_per_sinc = enc * gear * axis / feed;
        let acc = |v: i64| pos(v).max(1.0);
        self.params = Params {
            einc_per_sinc,
            polarity: if g(1000, 1) & 0x80 != 0 { -1.0 } else { 1.0 },
            project_zero: g(500, 1),
            az_offset: g(1010, 1),
            max_velocity: pos(g(502, 1)),
            jog_slow: pos(g(530, 1)),
            jog_fast: pos(g(531, 1)),
            jog_accel: acc(g(532, 1)),
            jog_time_ms: g(534, 1).max(0) as u64,
            jog_fe_window: pos(g(538, 1)),
            jog_fe_time_ms: g(539, 1).max(0) as u64,
            direct_accel: acc(g(541, 1)),
            direct_decel: acc(g(542, 1)),
            direct_fe_window: pos(g(549, 1)),
            velocity_target_window: pos(g(561, 1)),
            velocity_fe_window: pos(g(568, 1)),
            stroke_velocity: pos(g(566, 1)),
            target_window: pos(g(1022, 1)),
            target_window_ms: g(1023, 1).max(0) as u64,
            standstill_window: pos(g(1042, 1)),
            standstill_ms: g(1043, 1).max(0) as u64,
            fe_timeout_ms: g(1045, 1).max(0) as u64,
            quick_stop: acc(g(1029, 1)),
            homing_method: g(1011, 1),
            homing_accel: acc(g(1013, 1)),
            base_acceleration: pos(g(560, 1)),
            base_force_ma: pos(g(555, 1)),
        };
        let cfg = self.fhpp.config_mut();
        cfg.base_velocity = u32::try_from(g(540, 1).max(0)).unwrap_or(u32::MAX);
        cfg.base_acceleration = u32::try_from(g(560, 1).max(0)).unwrap_or(u32::MAX);
        cfg.start_condition =
            StartBehaviour::from_bits(g(583, 1) as u8).unwrap_or(StartBehaviour::Ignore);
        cfg.relative_to_actual = g(524, 1) & 1 != 0;
        cfg.teach_record = g(400, 1).clamp(0, 255) as u8;
        cfg.force_actual1_torque = g(523, 7) != 0;
        cfg.force_actual2_torque = g(523, 8) != 0;
        if old != 0.0 && old != einc_per_sinc {
            // A new scaling: the set-point follows the actual position in the new unit.
            self.traj = Trajectory::at(self.raw_actual());
            self.motion = Motion::Hold;
        }
    }

    fn rebuild_records(&mut self) {
        self.records_dirty = false;
        let od = &self.od;
        for n in 1u8..=64 {
            let g = |pnu| get_i64(od, pnu, n);
            let Some(r) = self.records.get_mut(n) else {
                continue;
            };
            *r = Record {
                rcb1: Rcb1(g(401) as u8),
                rcb2: g(402) as u8,
                target: g(404) as i32,
                velocity: g(406) as i32,
                acceleration: g(407) as i32,
                deceleration: g(408) as i32,
                jerk_acceleration: g(409) as u32,
                load: g(410) as u32,
                following_record: g(416) as u8,
                jerk_deceleration: g(417) as u32,
                torque_limit: g(418) as i16,
                rcb3: g(421) as u8,
                final_velocity: g(423) as i32,
                max_deviation: g(424) as i32,
                mc_on_continuation: g(425) as u8,
                start_delay_ms: g(426) as u32,
                stroke_limit: g(427) as i32,
                torque_feed_forward: g(428) as u16,
                position_comparator: Comparator {
                    min: g(430) as i32,
                    max: g(431) as i32,
                    window_time_ms: g(432) as u16,
                },
                velocity_comparator: Comparator {
                    min: g(433) as i32,
                    max: g(434) as i32,
                    window_time_ms: g(435) as u16,
                },
                force_comparator: Comparator {
                    min: g(436) as i16,
                    max: g(437) as i16,
                    window_time_ms: g(438) as u16,
                },
                time_comparator: TimeComparator {
                    min_ms: g(439) as u32,
                    max_ms: g(440) as u32,
                },
                setpoint_velocity: g(441) as i32,
                setpoint_force: g(442) as i16,
            };
        }
    }

    // ---- coordinates -------------------------------------------------------------------

    /// Actual position, raw SINC (encoder based).
    fn raw_actual(&self) -> f64 {
        let k = self.params.einc_per_sinc;
        if k <= 0.0 {
            return 0.0;
        }
        self.stepper.encoder_increments() as f64 / k * self.params.polarity
    }

    /// Actual velocity, SINC/s (as the controller's encoder observer sees it).
    fn actual_velocity(&self) -> f64 {
        let k = self.params.einc_per_sinc;
        if k <= 0.0 {
            return 0.0;
        }
        let inc_rev = f64::from(self.stepper.data().encoder_increments_per_rev.max(1));
        let v = f64::from(self.stepper.estimated_velocity_rpm()) / 60.0 * inc_rev / k;
        // Quantisation noise of the observer at rest is not motion.
        libm::round(v) * self.params.polarity
    }

    /// Actual current in ‰ of PNU 555 (the force actual value).
    fn actual_force(&self) -> i32 {
        if self.params.base_force_ma <= 0.0 {
            return 0;
        }
        let ma = self.stepper.current_ma() as f64;
        sat_i32(ma * 1000.0 / self.params.base_force_ma)
    }

    fn zero(&self) -> f64 {
        self.reference.unwrap_or(0.0) + (self.params.az_offset + self.params.project_zero) as f64
    }

    fn to_pz(&self, raw: f64) -> f64 {
        raw - self.zero()
    }

    fn pz_to_raw(&self, pz: f64) -> f64 {
        pz + self.zero()
    }

    fn clamp_velocity(&mut self, v: f64) -> f64 {
        let max = self.params.max_velocity;
        if max > 0.0 && v > max {
            self.velocity_limited = true;
            max
        } else {
            self.velocity_limited = false;
            v
        }
    }

    // ---- motion commands ---------------------------------------------------------------

    fn start_task(&mut self, task: Task) {
        self.task = task;
        self.mc = false;
        self.window_since = None;
        self.standstill_target = None;
        self.still_since = None;
        self.standstill_error = false;
        self.stroke_reached = false;
        self.warnings &= !(1u128 << diag::STANDSTILL);
        self.warnings &= !(1u128 << diag::HOMING_REQUIRED);
        self.warnings &= !(1u128 << diag::RECORD_INVALID);
    }

    fn start_position(&mut self, target: f64, velocity: f64, accel: f64, decel: f64, fe: f64) {
        let velocity = self.clamp_velocity(velocity);
        let lim = Limits {
            velocity,
            acceleration: accel.max(1.0),
            deceleration: decel.max(1.0),
        };
        self.start_task(Task::Position { target });
        self.motion = Motion::Position { target, lim };
        self.pending = Some(Pending { target, lim });
        self.task_decel = lim.deceleration;
        self.fe_window = fe;
        self.fe_time_ms = self.params.fe_timeout_ms;
        self.fe_velocity = false;
        self.last_target = target;
    }

    fn start_velocity(&mut self, target: f64, accel: f64, decel: f64, stroke: Option<f64>) {
        let mag = self.clamp_velocity(libm::fabs(target));
        let target = if target < 0.0 { -mag } else { mag };
        self.start_task(Task::Velocity { target });
        self.motion = Motion::Velocity {
            target,
            accel: accel.max(1.0),
            decel: decel.max(1.0),
            start: self.traj.position,
            stroke,
        };
        self.pending = None;
        self.task_decel = decel.max(1.0);
        self.fe_window = self.params.velocity_fe_window;
        self.fe_time_ms = self.params.fe_timeout_ms;
        self.fe_velocity = true;
    }

    fn brake(&mut self, decel: f64, resync: bool) {
        self.motion = Motion::Braking {
            decel: decel.max(1.0),
            resync,
        };
    }

    fn resync(&mut self) {
        self.traj = Trajectory::at(self.raw_actual());
        self.fe_since = None;
        self.following_error = false;
    }

    fn execute(&mut self, cmd: MotionCommand) {
        let p = self.params;
        match cmd {
            MotionCommand::Enable => {
                self.stage_on = true;
                self.resync();
                self.motion = Motion::Hold;
                self.task = Task::None;
                self.pending = None;
            }
            MotionCommand::Disable => {
                self.stage_on = false;
                self.motion = Motion::Hold;
                self.task = Task::None;
                self.pending = None;
                self.standstill_target = None;
            }
            MotionCommand::ManualBrake { .. } => {} // no holding brake fitted
            MotionCommand::Home => {
                self.start_task(Task::Homing { done: false });
                self.pending = None;
                self.task_decel = p.homing_accel;
                if p.homing_method == -35 {
                    // Current position: REF = here; the task completes at the next cycle.
                    self.reference = Some(self.raw_actual());
                    self.traj = Trajectory {
                        position: self.traj.position,
                        velocity: 0.0,
                    };
                    self.motion = Motion::Hold;
                    self.task = Task::Homing { done: true };
                } else {
                    self.task = Task::None;
                    self.raise_once(diag::HOMING_METHOD_INVALID);
                }
            }
            MotionCommand::MoveAbsolute {
                target, velocity, ..
            } => {
                let t = self.pz_to_raw(f64::from(target));
                self.start_position(
                    t,
                    f64::from(velocity),
                    p.direct_accel,
                    p.direct_decel,
                    p.direct_fe_window,
                );
            }
            MotionCommand::MoveRelative {
                distance,
                velocity,
                reference,
                ..
            } => {
                let base = match reference {
                    RelativeTo::ActualPosition => self.raw_actual(),
                    RelativeTo::LastSetpoint => self.last_target,
                };
                self.start_position(
                    base + f64::from(distance),
                    f64::from(velocity),
                    p.direct_accel,
                    p.direct_decel,
                    p.direct_fe_window,
                );
            }
            MotionCommand::Velocity {
                velocity,
                ramp,
                stroke_monitoring,
                ..
            } => {
                let ramp = if ramp == 0 {
                    p.base_acceleration
                } else {
                    f64::from(ramp)
                };
                let stroke = stroke_monitoring.then_some(p.stroke_velocity);
                self.start_velocity(f64::from(velocity), ramp, ramp, stroke);
            }
            MotionCommand::Force { .. } => {
                // Not modelled: hold position, complete at once.
                self.start_task(Task::Force);
                self.motion = Motion::Hold;
                self.pending = None;
            }
            MotionCommand::Record { number, mode } => self.start_record(number, mode),
            MotionCommand::Jog { positive } => {
                self.start_task(Task::None);
                self.pending = None;
                self.motion = Motion::Jog {
                    positive,
                    since: self.cycles,
                };
                self.task_decel = p.jog_accel;
                self.fe_window = p.jog_fe_window;
                self.fe_time_ms = p.jog_fe_time_ms;
                self.fe_velocity = false;
            }
            MotionCommand::Halt => {
                let position_task = matches!(self.task, Task::Position { .. });
                if !position_task {
                    self.task = Task::None;
                    self.pending = None;
                }
                self.brake(self.task_decel, false);
            }
            MotionCommand::Continue => {
                if let Some(pd) = self.pending {
                    self.start_task(Task::Position { target: pd.target });
                    self.motion = Motion::Position {
                        target: pd.target,
                        lim: pd.lim,
                    };
                }
            }
            MotionCommand::Clear => {
                self.pending = None;
                self.task = Task::None;
                if !matches!(self.motion, Motion::Braking { .. }) {
                    self.brake(self.task_decel, false);
                }
            }
            MotionCommand::Stop => {
                self.task = Task::None;
                self.pending = None;
                self.brake(self.task_decel, true);
            }
            MotionCommand::QuickStop => {
                self.task = Task::None;
                self.pending = None;
                self.brake(p.quick_stop, true);
            }
        }
    }

    fn start_record(&mut self, number: u8, mode: ControlMode) {
        let Some(r) = self.records.get(number).copied() else {
            self.raise_once(diag::RECORD_INVALID);
            return;
        };
        let p = self.params;
        let accel = f64::from(r.acceleration.max(0));
        let decel = f64::from(r.deceleration.max(0));
        let accel = if accel > 0.0 { accel } else { p.direct_accel };
        let decel = if decel > 0.0 { decel } else { p.direct_decel };
        match mode {
            ControlMode::Position => {
                let target = if r.rcb1.contains(Rcb1::ABS) {
                    let base = if r.rcb1.contains(Rcb1::REL) {
                        self.raw_actual()
                    } else {
                        self.last_target
                    };
                    base + f64::from(r.target)
                } else {
                    self.pz_to_raw(f64::from(r.target))
                };
                self.start_position(
                    target,
                    f64::from(r.velocity.unsigned_abs()),
                    accel,
                    decel,
                    f64::from(r.max_deviation.max(0)),
                );
            }
            ControlMode::Velocity => {
                let stroke =
                    (!r.rcb1.contains(Rcb1::XLIM)).then_some(f64::from(r.stroke_limit.max(0)));
                self.start_velocity(f64::from(r.setpoint_velocity), accel, decel, stroke);
                self.fe_window = f64::from(r.max_deviation.max(0));
            }
            ControlMode::Force => {
                self.start_task(Task::Force);
                self.motion = Motion::Hold;
                self.pending = None;
            }
        }
    }

    /// TEACH falling edge: the actual position into the target of PNU 520 (§6.4).
    fn teach(&mut self, record: u8, position: i32) {
        let target = get_i64(&self.od, 520, 1);
        let raw = self.pz_to_raw(f64::from(position));
        let (pnu, sub, value) = match target {
            1 => (404, record, i64::from(position)),
            // AZ := here: AZ = REF + PNU 1010.
            2 => (1010, 1, (raw - self.reference.unwrap_or(0.0)) as i64),
            // PZ := here: PZ = AZ + PNU 500.
            3 => {
                let az = self.reference.unwrap_or(0.0) + self.params.az_offset as f64;
                (500, 1, (raw - az) as i64)
            }
            4 | 5 => {
                let az = self.reference.unwrap_or(0.0) + self.params.az_offset as f64;
                (501, (target - 3) as u8, (raw - az) as i64)
            }
            6 => (430, record, i64::from(position)),
            7 => (431, record, i64::from(position)),
            _ => return,
        };
        let _ = self.od.set_value(pnu_index(pnu), sub, Value::Signed(value));
        self.params_dirty = true;
        self.records_dirty = true;
    }

    // ---- motion and plant --------------------------------------------------------------

    fn advance(&mut self, dt: f64) {
        let p = self.params;
        if !self.stage_on {
            self.stepper.step(dt, StepperDemand::Off);
            self.traj = Trajectory::at(self.raw_actual());
            self.following_error = false;
            self.fe_since = None;
            return;
        }
        match self.motion {
            Motion::Hold => {}
            Motion::Position { target, lim } => {
                if self.traj.step_to(target, 0.0, lim, dt) {
                    self.motion = Motion::Hold;
                }
            }
            Motion::Velocity {
                target,
                accel,
                decel,
                start,
                stroke,
            } => {
                self.traj.step_velocity(target, accel, decel, dt);
                if let Some(limit) = stroke {
                    if libm::fabs(self.traj.position - start) >= limit {
                        // Stroke limit: Quick-Stop ramp, then hold position-controlled.
                        self.stroke_reached = true;
                        self.task = Task::None;
                        self.brake(p.quick_stop, false);
                    }
                }
            }
            Motion::Jog { positive, since } => {
                let slow = self.cycles.saturating_sub(since) < p.jog_time_ms;
                let v = if slow { p.jog_slow } else { p.jog_fast };
                let v = self.clamp_velocity(v);
                let v = if positive { v } else { -v };
                self.traj.step_velocity(v, p.jog_accel, p.jog_accel, dt);
            }
            Motion::Braking { decel, resync } => {
                if self.traj.step_stop(decel, dt) {
                    self.motion = Motion::Hold;
                    if resync {
                        self.resync();
                    }
                }
            }
        }
        let k = p.einc_per_sinc * p.polarity;
        let increments = libm::round(self.traj.position * k) as i64;
        let inc_rev = f64::from(self.stepper.data().encoder_increments_per_rev.max(1));
        let rpm = self.traj.velocity * k / inc_rev * 60.0;
        self.stepper.step(
            dt,
            StepperDemand::PositionIncrements {
                increments,
                velocity_ff_rpm: rpm as f32,
            },
        );
        self.monitor();
    }

    /// MC window, following error, standstill (§6.7).
    fn monitor(&mut self) {
        let p = self.params;
        let now = self.cycles;
        let actual = self.raw_actual();
        let velocity = self.actual_velocity();
        let held = |since: &mut Option<u64>, inside: bool, ms: u64| -> bool {
            if !inside {
                *since = None;
                return false;
            }
            let t0 = *since.get_or_insert(now);
            now.saturating_sub(t0) >= ms
        };
        match self.task {
            Task::Position { target } if !self.mc => {
                let arrived = self.motion == Motion::Hold && self.traj.position == target;
                let inside = arrived && libm::fabs(actual - target) <= p.target_window;
                if held(&mut self.window_since, inside, p.target_window_ms) {
                    self.mc = true;
                    self.standstill_target = Some(target);
                }
            }
            Task::Velocity { target } if !self.mc => {
                let ramped = self.traj.velocity == target;
                let inside = ramped && libm::fabs(velocity - target) <= p.velocity_target_window;
                if held(&mut self.window_since, inside, p.target_window_ms) {
                    self.mc = true;
                }
            }
            _ => {}
        }
        // Following error against the theoretical trajectory.
        let deviation = if self.fe_velocity {
            libm::fabs(self.traj.velocity - velocity)
        } else {
            libm::fabs(self.traj.position - actual)
        };
        let over = self.fe_window > 0.0 && deviation > self.fe_window;
        let fe_time = self.fe_time_ms;
        self.following_error = held(&mut self.fe_since, over, fe_time);
        if self.following_error && self.class_of(diag::FOLLOWING_ERROR).is_none() {
            self.warnings |= 1u128 << diag::FOLLOWING_ERROR;
        } else {
            self.warnings &= !(1u128 << diag::FOLLOWING_ERROR);
        }
        // Standstill monitoring after MC of a position task.
        if let Some(target) = self.standstill_target {
            let outside =
                p.standstill_window > 0.0 && libm::fabs(actual - target) > p.standstill_window;
            let mut since = self.still_since;
            if held(&mut since, outside, p.standstill_ms) {
                self.standstill_error = true;
                self.warnings |= 1u128 << diag::STANDSTILL;
            } else if !outside {
                self.standstill_error = false;
                self.warnings &= !(1u128 << diag::STANDSTILL);
            }
            self.still_since = since;
        }
    }

    /// Actual values into their PNUs (300, 310, 320, 321, 1040, 1041, 1059, 205, 230, 220,
    /// 221, 400:2).
    fn publish(&mut self) {
        let s = self.status;
        let setpoint = sat_i32(self.to_pz(self.traj.position));
        let fe = sat_i32(self.traj.position - self.raw_actual());
        let setpoint_v = sat_i32(self.traj.velocity);
        let inp = self.inputs;
        let out = self.outputs.to_bytes();
        let fault = self.fhpp.fault();
        let ack = match fault {
            None => 0xFF,
            Some(f) => match f.ack {
                Ack::NotAckable => 0,
                Ack::AfterCause => 1,
                Ack::Immediately => 2,
            },
        };
        let record = inp[2];
        let last_target = sat_i32(self.to_pz(self.last_target));
        let current = self.stepper.current_ma();
        let od = &mut self.od;
        let mut set = |pnu: u16, sub: u8, v: Value| {
            let _ = od.set_value(pnu_index(pnu), sub, v);
        };
        set(300, 1, Value::Signed(s.actual_position.into()));
        set(300, 2, Value::Signed(setpoint.into()));
        set(300, 3, Value::Signed(fe.into()));
        set(310, 1, Value::Signed(s.actual_velocity.into()));
        set(310, 2, Value::Signed(setpoint_v.into()));
        set(
            310,
            3,
            Value::Signed(i64::from(setpoint_v) - i64::from(s.actual_velocity)),
        );
        set(1040, 1, Value::Signed(last_target.into()));
        set(1041, 1, Value::Signed(s.actual_position.into()));
        set(1059, 1, Value::Signed(current.into()));
        set(
            320,
            1,
            Value::Unsigned(u32::from_be_bytes([inp[0], inp[1], inp[2], inp[3]]).into()),
        );
        set(
            320,
            2,
            Value::Signed(i32::from_be_bytes([inp[4], inp[5], inp[6], inp[7]]).into()),
        );
        set(
            321,
            1,
            Value::Unsigned(u32::from_be_bytes([out[0], out[1], out[2], out[3]]).into()),
        );
        set(
            321,
            2,
            Value::Signed(i32::from_be_bytes([out[4], out[5], out[6], out[7]]).into()),
        );
        set(
            205,
            1,
            Value::Unsigned(fault.map_or(0xFFFF, |f| u64::from(f.code))),
        );
        set(230, 1, Value::Unsigned(ack));
        set(400, 2, Value::Unsigned(record.into()));
        let faults = fault.map_or(0u128, |f| 1u128 << (f.code & 0x7F));
        for (i, sub) in (1u8..=4).enumerate() {
            let shift = 32 * i as u32;
            set(220, sub, Value::Unsigned(((faults >> shift) as u32).into()));
            set(
                221,
                sub,
                Value::Unsigned(((self.warnings >> shift) as u32).into()),
            );
        }
    }
}

fn sat_i32(v: f64) -> i32 {
    let r = libm::round(v);
    if r >= i32::MAX as f64 {
        i32::MAX
    } else if r <= i32::MIN as f64 {
        i32::MIN
    } else {
        r as i32
    }
}

/// Record PNUs 401…442.
fn is_record_pnu(index: u16) -> bool {
    (pnu_index(401)..=pnu_index(442)).contains(&index)
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> ObjectAccess for FhppDevice<S> {
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode> {
        self.od.entry(index, sub)
    }

    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        if index == pnu_index(125) && sub == 1 {
            let b = buf.first_mut().ok_or(AbortCode::OUT_OF_MEMORY)?;
            *b = self.fhpp.control_logic();
            return Ok(1);
        }
        self.od.read(index, sub, buf)
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        if index == pnu_index(125) && sub == 1 {
            // PNU 125: the fieldbus takes control back (not from FCT).
            let v = match data {
                [v] => *v,
                [] => return Err(AbortCode::LENGTH_TOO_LOW),
                _ => return Err(AbortCode::LENGTH_TOO_HIGH),
            };
            return self
                .fhpp
                .write_control_logic(v)
                .map_err(|_| AbortCode::DEVICE_STATE);
        }
        self.od.write(index, sub, data)?;
        self.params_dirty = true;
        if is_record_pnu(index) {
            self.records_dirty = true;
        }
        if index == pnu_index(127) {
            // PNU 127 data memory control: save, delete, reload (parameter_file.rs).
            let reloaded = self
                .fpc
                .memory_mut()
                .command(sub, &mut self.od)
                .map_err(|_| AbortCode::CANNOT_STORE)?;
            self.records_dirty |= reloaded;
        }
        Ok(())
    }

    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.write_internal(index, sub, data)?;
        self.params_dirty = true;
        if is_record_pnu(index) {
            self.records_dirty = true;
        }
        Ok(())
    }
}

/// Whether the fieldbus holds device control (the 47h / 48h choice of the watchdog).
impl<S> FhppDevice<S> {
    pub fn fieldbus_has_control(&self) -> bool {
        self.fhpp.authority() == Authority::Fieldbus
    }
}
