//! The Festo CMMO-ST as one device: its FHPP parameters (the `cmmo-st` object dictionary,
//! PNU n = object 0x2000 + n), the FHPP state machine ([`Fhpp`]), the record list, a motion
//! executor for every [`MotionCommand`] and the stepper plant ([`Stepper`]) behind it.
//!
//! The runtime feeds the output telegram with [`FhppDevice::set_outputs`] (8 or 16 bytes, as
//! Modbus / IO-Link / I-Port deliver it), steps the device with [`FhppDevice::step`] on its
//! clock (one FHPP cycle per millisecond; the stepper integrates in sub-steps inside it),
//! and reads the input telegram with [`FhppDevice::inputs`]. Front ends see the parameters
//! through [`ObjectAccess`]. Sans-IO, `no_std`, no allocation in `step`, deterministic.
//!
//! The parts, each an `impl` block of its own with its decisions: `cycle.rs` (the FHPP
//! cycle), `motion_commands.rs` (starting a task), `motion.rs` (the running task and its
//! monitoring), `homing_run.rs`, `coordinates.rs` and `faults.rs` (diagnostics and the memory).
//!
//! # Decisions
//!
//! - **Units.** The trajectory runs in SINC (`f64`) in the raw axis coordinate (encoder based,
//!   no reference). EINC per SINC = (PNU 1001:1 / 1001:2) · (1002:1 / 1002:2) ·
//!   (1005:2 / 1005:3) / (1003:1 / 1003:2) (fhpp §6 inferred formula), PNU 1000 = 0x80 inverts
//!   the sign. With the dictionary's defaults (rotary, 1 SINC = 0.01°, PNU 600 = −2, 601 = 41h,
//!   feed 36000 SINC per revolution, encoder 2000) 1 EINC = 18 SINC.
//! - **Parameter channel** ([`super::fhpp::parameter_channel`]): bytes 9…16 of a 16-byte telegram,
//!   one job per cycle through this device's own [`ObjectAccess`]; PNU 127 saves to and loads
//!   from the permanent memory, which also holds the parameter file.
//!
//! # Not modelled
//!
//! The torque limits (PNU 418, 512, 581), jerk limitation, final velocities, the causes the
//! plant cannot produce (temperatures, voltages, I²t, encoder: inject them with
//! [`FhppDevice::fault`]), and the rw2 access rule outside PNU 242 / 246 and the parameter
//! channel (other writers through [`ObjectAccess`] are not checked). Homing: limit switches
//! (CiA 402 methods 1…14, 17…30 other than 23 / 27 are not in Tab. 6.2), the NC/NO setting
//! and the digital input of the reference switch as a PNU (it is read from the mechanics
//! directly), and the cell file / `drivetwin run` options for [`FhppSettings::mechanics`].

use core::time::Duration;

use od::{AbortCode, DataType, Entry, Instant, ObjectAccess, ObjectDictionary, Value};

use super::axis_mechanics::AxisMechanics;
use super::diagnostic_memory::{self, DiagnosticMemory, EventType};
use super::diagnostics::{self, Class, Diagnostic};
use super::fhpp::control_bytes::{ControlMode, OutputData};
use super::fhpp::parameter_channel::{self, ParameterChannel};
use super::fhpp::parameter_file::{FormatError, PermanentMemory};
use super::fhpp::record_table::StartBehaviour;
use super::fhpp::record_table::{ChainCondition, Comparators, Rcb1, Record, RecordTable};
use super::fhpp::state_machine::{
    Ack, Authority, Event, Fault, Fhpp, MotionCommand, MotionStatus, RelativeTo,
};
use super::fhpp::{FHPP_FPC_LEN, FHPP_STD_LEN};
use super::homing::{self, Method, Target};
use super::seven_segment::SevenSegment;
use crate::controlword::ConfirmedWrites;
use crate::published::Published;
use crate::stepper::{sinc_to_si, Stepper, StepperData, StepperDemand, StepperMode};
use crate::trajectory::{Limits, Trajectory};

mod coordinates;
mod cycle;
mod external_load;
mod faults;
mod homing_run;
mod motion;
mod motion_commands;

/// Object index of PNU `pnu` (the dictionary's mapping rule).
pub const fn pnu_index(pnu: u16) -> u16 {
    0x2000 + pnu
}

/// Names of the diagnostic numbers the twin raises (App. D; the full list is
/// [`super::diagnostics::table`]).
pub use super::diagnostics::code as diag;

/// Settings of the simulation that no PNU holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FhppSettings {
    /// Motor, load and controller data of the stepper.
    pub stepper: StepperData,
    /// Closed loop (the CMMO-ST with its encoder, the default) or open loop.
    pub mode: StepperMode,
    /// FHPP cycle (1 ms).
    pub cycle: Duration,
    /// End stops, reference switch and index pulse around the motor (homing).
    pub mechanics: AxisMechanics,
    /// Open loop: a switch search (methods 23 / 27) not done after this long ends with 3Ah
    /// "homing timeout". The manual names no time and no PNU for it; 20 s is 5 revolutions
    /// at the default search velocity, more than the default stroke.
    pub homing_timeout: Duration,
}

impl Default for FhppSettings {
    fn default() -> Self {
        FhppSettings {
            stepper: StepperData::default(),
            mode: StepperMode::ClosedLoop,
            cycle: Duration::from_millis(1),
            mechanics: AxisMechanics::default(),
            homing_timeout: Duration::from_secs(20),
        }
    }
}

/// A diagnostic number App. D does not assign.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnknownDiagnostic(pub u8);

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
    /// PNU 1012:1…3: search, drive (to AZ), crawl velocity.
    homing_search: f64,
    homing_drive: f64,
    homing_crawl: f64,
    /// PNU 1015 in ‰ of PNU 555 (the current limit while homing).
    homing_torque: f64,
    /// PNU 1016 / 1017: block detection.
    block_velocity: f64,
    block_ms: u64,
    base_acceleration: f64,
    base_force_ma: f64,
    force_stroke: f64,
    force_window: f64,
    direct_comparators: Comparators,
    /// PNU 501:1 / 501:2, relative to AZ; both 0 = no software limits.
    soft_lower: i64,
    soft_upper: i64,
    /// PNU 1024:6, the time constant filtering the motor speed, seconds.
    velocity_filter_s: f64,
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
    /// Force control (§6.6): the set-point moves towards the force direction at up to `vmax`
    /// while the force is below `target` ‰ and backs off above it, so the position
    /// controller builds the force against whatever stops the axis. Decision: the plant has
    /// a position / current-vector interface only, so force control is this outer loop on the
    /// position set-point (a free axis runs at `vmax` to the stroke limit, as the manual's
    /// "missing workpiece" case does).
    Force {
        target: f64,
        vmax: f64,
        accel: f64,
        start: f64,
        stroke: Option<f64>,
    },
    /// Jog since cycle `since`.
    Jog { positive: bool, since: u64 },
    /// Brake to rest; `resync`: then take the actual position as the set-point.
    Braking { decel: f64, resync: bool },
    /// A homing run (§6.2) searching for REF or travelling to AZ.
    Homing(Homing),
}

/// A homing run in progress.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Homing {
    method: Method,
    phase: HomingPhase,
    /// Direction of travel in raw SINC (±1).
    dir: f64,
    /// Shaft angle at the last cycle (rad), for the index and switch edges.
    angle: f64,
    /// Shaft angle where the phase began (rad).
    phase_start: f64,
    /// Cycle the run started (3Ah).
    started: u64,
    /// Since when the axis stands while the set-point moves (block detection).
    stall_since: Option<u64>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum HomingPhase {
    /// Towards the method's target at the search velocity PNU 1012:1.
    Search,
    /// Off the reference switch at the crawl velocity PNU 1012:3 until its edge.
    LeaveSwitch,
    /// Closed loop: on at the crawl velocity to the first index pulse behind the switch edge
    /// at `edge` rad.
    IndexAfterSwitch { edge: f64 },
    /// REF found (raw SINC `reference`): to AZ = REF + PNU 1010 at PNU 1012:2.
    ToZero { target: f64, reference: f64 },
}

/// CMMO-ST 2Eh: an index pulse closer to the switch edge than this (fraction of a revolution,
/// either side) gives no reproducible REF. The manual names no distance; decision: 5 %.
const MIN_INDEX_DISTANCE: f64 = 0.05;

/// Output telegrams that may wait for their cycle ([`FhppDevice::set_outputs`]).
pub const TELEGRAM_QUEUE: usize = 16;

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
    /// Force task: MC once the actual force stays within ±PNU 552 of `target` ‰.
    Force {
        target: f64,
    },
    /// Record `number` waits for its start delay (PNU 426) until cycle `until`.
    Delayed {
        number: u8,
        mode: ControlMode,
        until: u64,
    },
}

/// The running record of record selection, watched for its switching condition (RCB2).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Chain {
    record: u8,
}

/// PNU 312 bits: the comparator outputs (Tab. B.41).
const CMP_POSITION: u8 = 0x01;
const CMP_VELOCITY: u8 = 0x02;
const CMP_FORCE: u8 = 0x04;
const CMP_TIME: u8 = 0x08;

/// A position task interrupted by HALT (SA3), continued by START.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pending {
    target: f64,
    lim: Limits,
}

/// The CMMO-ST: dictionary, FHPP state machine, record list, motion and stepper plant.
#[derive(Clone)]
pub struct FhppDevice<S> {
    od: ObjectDictionary<S>,
    settings: FhppSettings,
    fhpp: Fhpp,
    records: RecordTable,
    /// The records to read again from their PNUs at the next cycle (bit n − 1: record n): a
    /// write to one record PNU reads that record, not the table.
    records_dirty: u64,
    params: Params,
    params_dirty: bool,
    stepper: Stepper,
    /// The output telegram last set (what a read-back of the outputs shows).
    outputs: OutputData,
    /// The telegrams set since the cycle last took one, oldest first ([`FhppDevice::set_outputs`]).
    telegrams: ConfirmedWrites<OutputData, TELEGRAM_QUEUE>,
    /// The telegram the state machine runs on this cycle.
    applied: OutputData,
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
    /// The motor speed as the controller measures it, EINC/s (`coordinates.rs`).
    velocity_readout: crate::measured_velocity::MeasuredVelocity,
    /// Warnings present, bit n = diagnostic n.
    warnings: u128,
    /// Warnings raised by a single event (a refused start): they show until the next start.
    once_warnings: u128,
    /// Injected faults still present.
    injected: u128,
    /// The output stage's temperature and the encoder, and what their supervision raised
    /// ([`super::plant_supervision`]).
    pub(super) plant_watch: crate::drive::plant_supervision::PlantWatch,
    /// Faults present at the end of the last cycle (PNU 220; new ones are logged).
    faults_present: u128,
    /// Warnings already logged (a new warning bit is logged once).
    warnings_logged: u128,
    /// The active fault of the last cycle (its end is logged).
    last_fault: Option<u8>,
    memory: DiagnosticMemory,
    memory_dirty: bool,
    /// The entries [`Self::publish`] wrote in the last cycle, in call order: it writes the
    /// same ones every cycle, so it looks each up once, and the values it wrote there. A
    /// store into `od` between two cycles' writes forgets the values
    /// ([`crate::published::Published::begin`]).
    published: PublishedEntries,
    /// App. D's following error (2Fh), looked up once: the monitoring asks for its class
    /// every cycle.
    following_error_diagnostic: Option<Diagnostic>,
    /// Its PNU 246 and 242 entries (class and reaction).
    following_error_entries: (Option<&'static Entry>, Option<&'static Entry>),
    // ---- record chaining, software limits ----
    chain: Option<Chain>,
    /// Whose comparators PNU 312 shows in record selection (the last record started).
    comparator_record: Option<u8>,
    /// Since when each of position / velocity / force is inside its window.
    comparator_since: [Option<u64>; 3],
    /// PNU 312.
    comparator_outputs: u8,
    /// Cycle the current task started (time comparator).
    task_started: u64,
    /// Software limit passed (11h / 12h): that direction is locked (13h / 14h).
    locked_positive: bool,
    locked_negative: bool,
    /// The reference switch input held at this level (a load model's light barrier, an
    /// importer's input), in place of the cam of [`AxisMechanics::reference_switch`].
    reference_forced: Option<bool>,
}

/// Entries written every cycle, remembered by their place in the sequence of writes, with
/// the value each was last given ([`crate::published::Published`]): a write of the value the
/// entry already holds is skipped. Most actual values stand for many cycles (the fault
/// words, the I/O data, a force at 0).
#[derive(Debug, Clone, Copy, Default)]
struct PublishedEntries {
    entries: [(u16, u8, Option<&'static Entry>); 32],
    values: Published<Written, 32>,
}

/// An integer value as written: equal ones store the same bytes (or are refused again).
/// Reals are not remembered (0.0 and −0.0 compare equal with other bits).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
enum Written {
    #[default]
    None,
    Signed(i64),
    Unsigned(u64),
}

impl PublishedEntries {
    /// `od.set_value(index, sub, v)`, the `n`-th write of the cycle: the entry of the last
    /// cycle's `n`-th write if that was the same object, else looked up (and remembered).
    /// Inlined at each write: the value's kind is then known there and the branch on the
    /// entry's type is a branch of that write alone (one shared branch over 28 writes of
    /// five types was mispredicted).
    #[inline(always)]
    fn set<S: AsRef<[u8]> + AsMut<[u8]>>(
        &mut self,
        od: &mut ObjectDictionary<S>,
        n: usize,
        index: u16,
        sub: u8,
        v: Value,
    ) {
        // `publish` makes the same writes in the same order every cycle (none of them
        // conditional), so a known slot's object is this one.
        let written = match v {
            Value::Signed(x) => Written::Signed(x),
            Value::Unsigned(x) => Written::Unsigned(x),
            _ => Written::None,
        };
        if written != Written::None && self.values.unchanged(n, written) {
            debug_assert!(self
                .entries
                .get(n)
                .is_some_and(|s| s.0 == index && s.1 == sub && s.2.is_some()));
            return;
        }
        let e = match self.entries.get_mut(n) {
            Some((i, s, e)) if *i == index && *s == sub && e.is_some() => *e,
            Some(slot) => {
                *slot = (index, sub, od.description().entry(index, sub));
                slot.2
            }
            None => od.description().entry(index, sub),
        };
        let Some(e) = e else {
            self.values.unknown(n);
            return;
        };
        if written == Written::None {
            self.values.unknown(n);
        }
        // As `ObjectDictionary::set_value`: a value the type cannot hold is not stored. The
        // integers the actual values are, without the general encoding (`Value::encode`'s
        // i128 range checks): the same bytes, the same refusals.
        let b;
        let bytes: &[u8] = match (e.data_type, v) {
            (DataType::Integer32, Value::Signed(x)) => match i32::try_from(x) {
                Ok(x) => {
                    b = x.to_le_bytes();
                    &b
                }
                Err(_) => return,
            },
            (DataType::Unsigned32, Value::Unsigned(x)) => match u32::try_from(x) {
                Ok(x) => {
                    b = x.to_le_bytes();
                    &b
                }
                Err(_) => return,
            },
            (DataType::Integer16, Value::Signed(x)) => match i16::try_from(x) {
                Ok(x) => return od.store(e, &x.to_le_bytes()),
                Err(_) => return,
            },
            (DataType::Unsigned16, Value::Unsigned(x)) => match u16::try_from(x) {
                Ok(x) => return od.store(e, &x.to_le_bytes()),
                Err(_) => return,
            },
            (DataType::Unsigned8, Value::Unsigned(x)) => match u8::try_from(x) {
                Ok(x) => return od.store(e, &[x]),
                Err(_) => return,
            },
            _ => {
                let mut g = [0u8; 8];
                if let Some(len) = v.encode(e.data_type, &mut g) {
                    od.store(e, g.get(..len).unwrap_or(&[]));
                }
                return;
            }
        };
        od.store(e, bytes);
    }
}

fn get_i64<S: AsRef<[u8]> + AsMut<[u8]>>(od: &ObjectDictionary<S>, pnu: u16, sub: u8) -> i64 {
    as_i64(od.value(pnu_index(pnu), sub))
}

/// `as_i64(Value::decode(e.data_type, raw))`, the 8- and 16-bit integers without the
/// general decoding (the diagnostics' class and reaction PNUs, read every cycle).
#[inline]
fn entry_i64(e: &Entry, raw: &[u8]) -> i64 {
    match (e.data_type, raw) {
        (DataType::Unsigned8, [b]) => i64::from(*b),
        (DataType::Unsigned16, [a, b]) => i64::from(u16::from_le_bytes([*a, *b])),
        (DataType::Integer8, [b]) => i64::from(*b as i8),
        (DataType::Integer16, [a, b]) => i64::from(i16::from_le_bytes([*a, *b])),
        _ => as_i64(Value::decode(e.data_type, raw)),
    }
}

/// A PNU value as [`get_i64`] reads it.
fn as_i64(v: Option<Value>) -> i64 {
    match v {
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
        let following_error_entries = {
            let sub = diagnostics::subindex(diag::FOLLOWING_ERROR);
            let desc = od.description();
            (
                desc.entry(pnu_index(246), sub),
                desc.entry(pnu_index(242), sub),
            )
        };
        stepper.set_end_stops(settings.mechanics.stops_rad());
        let records = RecordTable::new(od.description().fhpp.map_or(0, |f| f.records));
        let mut dev = FhppDevice {
            od,
            settings,
            fhpp: Fhpp::default(),
            records,
            records_dirty: ALL_RECORDS,
            params: Params::default(),
            params_dirty: true,
            stepper,
            outputs: OutputData::default(),
            telegrams: ConfirmedWrites::default(),
            applied: OutputData::default(),
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
            velocity_readout: Default::default(),
            warnings: 0,
            once_warnings: 0,
            injected: 0,
            plant_watch: Default::default(),
            faults_present: 0,
            warnings_logged: 0,
            last_fault: None,
            memory: DiagnosticMemory::power_on(0),
            memory_dirty: true,
            published: PublishedEntries::default(),
            following_error_diagnostic: diagnostics::lookup(diag::FOLLOWING_ERROR.into()),
            following_error_entries,
            chain: None,
            comparator_record: None,
            comparator_since: [None; 3],
            comparator_outputs: 0,
            task_started: 0,
            locked_positive: false,
            locked_negative: false,
            reference_forced: None,
        };
        dev.refresh();
        dev.traj = Trajectory::at(dev.raw_actual());
        dev.task_decel = dev.params.direct_decel;
        dev.fe_window = dev.params.direct_fe_window;
        dev.fe_time_ms = dev.params.fe_timeout_ms;
        dev.status = dev.motion_status();
        dev.inputs = dev.fhpp.inputs().to_bytes();
        dev.mirror_memory();
        dev
    }

    // ---- access ------------------------------------------------------------------------

    pub fn od(&self) -> &ObjectDictionary<S> {
        &self.od
    }

    /// The dictionary for the device's own writes; parameters are re-read at the next cycle.
    pub fn od_mut(&mut self) -> &mut ObjectDictionary<S> {
        self.params_dirty = true;
        self.records_dirty = ALL_RECORDS;
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
            Task::Force { .. } => self.mc,
            Task::Delayed { .. } => false,
            Task::None => !moving,
        };
        let fault = if self.following_error {
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
            actual_velocity: sat_i32(self.reported_velocity()),
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
    ///
    /// **Decision** (DESIGN "a confirmed write has been taken"): every telegram set is seen by
    /// the state machine for at least one cycle, in the order set, so an edge (START, RESET,
    /// ENABLE) a PLC writes and takes back before the next cycle still counts, as it does on
    /// the device, whose Modbus answer comes after the telegram was taken. Telegrams set
    /// faster than the cycle wait their turn (the twin is then slower than the bus, never
    /// faster); more than [`TELEGRAM_QUEUE`] waiting drop the oldest.
    pub fn set_outputs(&mut self, image: &[u8]) -> Result<(), BadLength> {
        let (out, fpc) = OutputData::parse(image).ok_or(BadLength(image.len()))?;
        self.telegrams.push(out, self.outputs);
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

    /// The permanent memory (PNU 127), e.g. for a host that keeps it on disk: its
    /// [`generation`](PermanentMemory::generation) changes with every save, download and
    /// delete.
    pub fn permanent_memory(&self) -> &PermanentMemory {
        self.fpc.memory()
    }

    /// Power-on with a permanent memory that holds `file` (kept by the host across restarts):
    /// the stored values become active, as at the CMMO-ST's own power-on. A file that is no
    /// parameter file of this device changes nothing and is refused.
    pub fn power_on_from_memory(&mut self, file: &[u8]) -> Result<(), FormatError> {
        self.fpc.memory_mut().power_on_from(&mut self.od, file)?;
        self.records_dirty = ALL_RECORDS;
        Ok(())
    }

    /// CMMO-ST App. C: one EFPC exchange per cycle. A parameter job goes through this
    /// device's [`ObjectAccess`], so a written PNU takes effect like any other write.
    fn serve_parameter_channel(&mut self) {
        let ctx = parameter_channel::Context {
            stage_on: self.stage_on,
            authority: self.fhpp.authority(),
            fault: self.fhpp.fault().is_some(),
            now_ms: self.cycles,
            stage_off_pnus: self.od.description().fhpp.map_or(&[], |f| f.stage_off_pnus),
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
}

/// Braking distance from `v` at `decel`, plus one cycle of travel (so the ramp starts in time).
fn stop_room(v: f64, decel: f64, dt: f64) -> f64 {
    let v = libm::fabs(v);
    v * v / (2.0 * decel.max(1.0)) + v * dt
}

fn sat_i32(v: f64) -> i32 {
    // `round_i64` is libm's round for |v| < 2⁵² and saturates (NaN → 0) beyond: clamped to
    // i32 it is `round(v)` saturated at the i32 edges, without the ±0 and the float compares.
    crate::rounding::round_i64(v).clamp(i32::MIN.into(), i32::MAX.into()) as i32
}

/// Record PNUs 401…442.
fn is_record_pnu(index: u16) -> bool {
    (pnu_index(401)..=pnu_index(442)).contains(&index)
}

/// Every record of the table (1…64) in [`FhppDevice::records_dirty`].
const ALL_RECORDS: u64 = u64::MAX;

/// Record `sub`'s bit in [`FhppDevice::records_dirty`] (none for a sub-index that is no
/// record, 0 or above 64).
fn record_bit(sub: u8) -> u64 {
    sub.checked_sub(1)
        .and_then(|n| 1u64.checked_shl(u32::from(n)))
        .unwrap_or(0)
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
        self.check_error_management(index, sub, data, true)?;
        self.od.write(index, sub, data)?;
        self.after_write(index, sub);
        if index == pnu_index(127) {
            // PNU 127 data memory control: save, delete, reload (parameter_file.rs).
            let reloaded = self
                .fpc
                .memory_mut()
                .command(sub, &mut self.od)
                .map_err(|_| AbortCode::CANNOT_STORE)?;
            if reloaded {
                self.records_dirty = ALL_RECORDS;
            }
        }
        Ok(())
    }

    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.check_error_management(index, sub, data, false)?;
        self.od.write_internal(index, sub, data)?;
        self.after_write(index, sub);
        Ok(())
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> FhppDevice<S> {
    fn after_write(&mut self, index: u16, sub: u8) {
        self.params_dirty = true;
        if is_record_pnu(index) {
            self.records_dirty |= record_bit(sub);
        }
        if index == pnu_index(204) && sub == 3 {
            // PNU 204:3 = 1 (the dictionary admits 1 only): clear the diagnostic memory.
            self.clear_memory();
        }
    }
}

/// Whether the fieldbus holds device control (the 47h / 48h choice of the watchdog).
impl<S> FhppDevice<S> {
    pub fn fieldbus_has_control(&self) -> bool {
        self.fhpp.authority() == Authority::Fieldbus
    }
}
