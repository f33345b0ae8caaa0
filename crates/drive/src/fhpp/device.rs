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
//! - **Homing** (§6.2, PNU 1010…1017; the methods as data in [`super::homing`], the end
//!   stops, reference switch and index pulse in [`super::axis_mechanics`], set through
//!   [`FhppSettings::mechanics`]): HOM voids the old reference (SPOS.REF = 0, software
//!   limits off) and the method of PNU 1011 runs under the current limit PNU 1015 (‰ of
//!   PNU 555) with the ramps of PNU 1013 and no following-error monitoring:
//!   −35 REF := actual position, no motion; 33 / 34 at the search velocity PNU 1012:1 to the
//!   next index pulse (REF = its latched encoder count; none within 1.05 revolutions or a
//!   stop first: 23h); −17 / −18 at PNU 1012:1 into the stop until the block detection
//!   (current at the PNU 1015 limit and actual velocity < PNU 1016, both for PNU 1017 ms)
//!   takes the actual position as REF; 23 / 27 (CiA 402 numbering, see
//!   [`super::homing::METHODS`]) at PNU 1012:1 onto the switch, back off it at the crawl
//!   velocity PNU 1012:3 to its edge (23: the negative edge, 27: the positive one), REF = the
//!   edge in open loop, the next index pulse behind it in closed loop (closer than 5 % of a
//!   revolution to the edge: 2Eh); a stop before the switch is 22h (closed loop), an
//!   open-loop search longer than [`FhppSettings::homing_timeout`] 3Ah. Tab. 6.2 refusals:
//!   3Bh (unknown number, fixed stop in open loop, switch method without a switch), 24h
//!   (index methods in open loop). Every homing error goes through the one fault path
//!   (`raise_once`, acknowledgeable at once; decision for 23h, whose App. D type is
//!   "software reset": the twin has no software reset and the cause was this run).
//!   Decision on step 3 of §6.2.1 ("optionally travel the AZ offset"): every searching method
//!   travels to AZ = REF + PNU 1010 at the drive velocity PNU 1012:2 (PNU 1015: "the stop is
//!   taken as REF and the drive travels to the axis zero point"), and the run completes (MC,
//!   SPOS.REF) once the axis is inside ±PNU 1022 of AZ for PNU 1023 ms; −35 does not move
//!   (CiA 402 35/37 do not), so the actual position becomes −(PNU 1010 + PNU 500) (§6.2.1
//!   step 2 "current position = 0 − offset"). With PNU 1010 = 0 a fixed-stop run ends at the
//!   stop: §6.2.1 asks for at least 1 mm of back-off through PNU 1010 (or an index method).
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
//!   PNU 246 / 242 (default F, reaction E); as W it clears back inside the window, as I it is
//!   a memory entry per occurrence.
//! - **Standstill** after MC of a position task: outside ±PNU 1042 around the target for
//!   PNU 1043 ms → SPOS.STILL and warning 37h (PNU 1042 = 0: off).
//! - Direct-mode velocity ramp byte = 0 % uses the base value PNU 560 (a ramp of 0 would
//!   never reach the speed); a position move with 0 % velocity does not move (Tab. 5.17
//!   "0 = no velocity"). Final velocities (PNU 423, 548) are not used: every move ends at rest.
//! - Velocities are limited to PNU 502 (SDIR/RSB.VLIM while limited).
//! - **Diagnostics** (§7, App. D): the messages are the table of [`super::diagnostics`]; the
//!   class and reaction of each come from PNU 246 / 242 (subindex = number + 1), whose writes
//!   are checked against PNU 234 / 238 (rw2: output stage off). Errors go to the state
//!   machine (T7, the reaction A…G applied there), warnings to SCON.WARN / PNU 221,
//!   informations to the memory only. PNU 220 shows every fault present, PNU 205 / 230 /
//!   FC 0x07 the active one. A fault that a single event caused (a refused start, a passed
//!   limit) is acknowledgeable at once; an injected one ([`FhppDevice::fault`]) keeps its
//!   App. D acknowledge type and its cause until [`FhppDevice::clear_fault`].
//!   Raised from their simulated causes: 28h, 3Fh, 3Bh (starts), 2Fh, 37h (monitoring),
//!   11h…14h, 29h, 2Ah (software limits), 24h (force or index homing in open loop), 22h,
//!   23h, 2Eh, 3Ah (homing), 40h (teach), 1Bh
//!   ([`FhppDevice::set_load_voltage`]); 47h / 48h come from the Modbus runtime's watchdog.
//! - **Diagnostic memory** ([`super::diagnostic_memory`]): incoming faults (01h), warnings
//!   (05h) and informations (09h) when PNU 246 bit 7 (or App. D "always") says so, the end of
//!   the active fault as 00h, 3Dh at power-on / clear / wrap; time stamps are the device's
//!   cycle clock in ms. Mirrored into PNU 200…204:4 at the end of a cycle that changed it, so
//!   every channel reads it through the dictionary; PNU 204:3 = 1 clears it.
//! - **Comparators** (§6.7.4): every cycle those of the task — the last record started in
//!   record selection (PNU 430…440), PNU 585…595 in direct mode — are evaluated: position on
//!   the PZ actual position, velocity, signed force, time since the task start; window times
//!   PNU 432/435/438 (587/590/593). Result in PNU 312.
//! - **Record chaining** (§6.5.3): after each cycle the running record's RCB2 condition is
//!   checked (MC, or the PNU 312 bit of its comparator). When met, PNU 416 names the next
//!   record; [`Fhpp::record_chained`] updates byte 3, RSB.RC1 and the PNU 425 MC pulse; the
//!   next record starts after its own start delay PNU 426 (also for a START edge).
//! - **Software limits** PNU 501 (relative to AZ, both 0 = off, only while referenced): a
//!   position start with a target behind a limit raises 29h / 2Ah and does not move; a
//!   velocity task whose set-point reaches a limit raises 11h / 12h and locks that direction
//!   (13h / 14h on a start into it) until the set-point is back inside; jog stops at the limit
//!   by itself with its ramp (§6.3 step 4), without an error.
//! - **Parameter channel** ([`super::parameter_channel`]): bytes 9…16 of a 16-byte telegram,
//!   one job per cycle through this device's own [`ObjectAccess`]; PNU 127 saves to and loads
//!   from the permanent memory, which also holds the parameter file.
//! - **Force mode** (§6.6, CDIR.COM = 01 / RCB1 COM = 01; closed loop only, open loop
//!   refuses it with 24h): an outer loop on the position set-point — towards the force's sign
//!   at the velocity limit until the force nears the set-point, then a deviation that makes
//!   the position controller produce that current (see `Motion::Force`). MC once the force
//!   stays within ±PNU 552 for PNU 1023; stroke limit PNU 510 (record PNU 427) from the start
//!   position, then the Quick-Stop ramp and SDIR/RSB.XLIM. Actual force = current / PNU 555.
//!
//! # Not modelled yet
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
use super::control_bytes::{ControlMode, OutputData};
use super::diagnostic_memory::{self, DiagnosticMemory, EventType};
use super::diagnostics::{self, Class, Diagnostic};
use super::homing::{self, Method, Target};
use super::parameter_channel::{self, ParameterChannel};
use super::parameter_file::{FormatError, PermanentMemory};
use super::record_table::{ChainCondition, Comparators, Rcb1, Record, RecordTable};
use super::seven_segment::SevenSegment;
use super::state_machine::{
    Ack, Authority, Event, Fault, Fhpp, MotionCommand, MotionStatus, RelativeTo,
};
use super::{FHPP_FPC_LEN, FHPP_STD_LEN};
use crate::fhpp::record_table::StartBehaviour;
use crate::stepper::{sinc_to_si, Stepper, StepperData, StepperDemand, StepperMode};
use crate::trajectory::{Limits, Trajectory};

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
    /// same ones every cycle, so it looks each up once.
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
}

/// Entries written every cycle, remembered by their place in the sequence of writes.
#[derive(Debug, Clone, Copy, Default)]
struct PublishedEntries([(u16, u8, Option<&'static Entry>); 32]);

impl PublishedEntries {
    /// `od.set_value(index, sub, v)`, the `n`-th write of the cycle: the entry of the last
    /// cycle's `n`-th write if that was the same object, else looked up (and remembered).
    #[inline]
    fn set<S: AsRef<[u8]> + AsMut<[u8]>>(
        &mut self,
        od: &mut ObjectDictionary<S>,
        n: usize,
        index: u16,
        sub: u8,
        v: Value,
    ) {
        let e = match self.0.get_mut(n) {
            Some((i, s, e)) if *i == index && *s == sub && e.is_some() => *e,
            Some(slot) => {
                let e = od.description().entry(index, sub);
                *slot = (index, sub, e);
                e
            }
            None => od.description().entry(index, sub),
        };
        let Some(e) = e else {
            return;
        };
        // As `ObjectDictionary::set_value`: a value the type cannot hold is not stored. The
        // 32-bit integers most actual values are without the general encoding.
        let mut b = [0u8; 8];
        let len = match (e.data_type, v) {
            (DataType::Integer32, Value::Signed(x)) => i32::try_from(x).ok().map(|x| {
                b = i64::from(x).to_le_bytes();
                4
            }),
            (DataType::Unsigned32, Value::Unsigned(x)) => u32::try_from(x).ok().map(|x| {
                b = u64::from(x).to_le_bytes();
                4
            }),
            _ => v.encode(e.data_type, &mut b),
        };
        if let Some(len) = len {
            od.store(e, b.get(..len).unwrap_or(&[]));
        }
    }
}

fn get_i64<S: AsRef<[u8]> + AsMut<[u8]>>(od: &ObjectDictionary<S>, pnu: u16, sub: u8) -> i64 {
    as_i64(od.value(pnu_index(pnu), sub))
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
        let mut dev = FhppDevice {
            od,
            settings,
            fhpp: Fhpp::default(),
            records: RecordTable::default(),
            records_dirty: ALL_RECORDS,
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

    /// The class diagnostic `code` has now: App. D through PNU 246 (class) and 242
    /// (reaction), subindex = number + 1 (fhpp §8.4). `None` for an unassigned number.
    pub fn diagnostic_class(&self, code: u8) -> Option<Class> {
        let d = self.diagnostic(code)?;
        Some(self.class_of(d))
    }

    /// App. D's message `code` (the following error without a search).
    fn diagnostic(&self, code: u8) -> Option<Diagnostic> {
        match self.following_error_diagnostic {
            Some(d) if d.code == code => Some(d),
            _ => diagnostics::lookup(code.into()),
        }
    }

    fn class_of(&self, d: Diagnostic) -> Class {
        let sub = diagnostics::subindex(d.code);
        let (handling, reaction) = match self.following_error_entries {
            (Some(h), Some(r)) if d.code == diag::FOLLOWING_ERROR => {
                let value = |e: &Entry| as_i64(Value::decode(e.data_type, self.od.raw(e))) as u16;
                (value(h), value(r))
            }
            _ => (
                get_i64(&self.od, 246, sub) as u16,
                get_i64(&self.od, 242, sub) as u16,
            ),
        };
        d.class(handling, reaction)
    }

    fn handling(&self, code: u8) -> u16 {
        get_i64(&self.od, 246, diagnostics::subindex(code)) as u16
    }

    fn fault_for(&self, code: u8) -> Option<Fault> {
        let d = self.diagnostic(code)?;
        match self.class_of(d) {
            Class::Fault(reaction) => Some(Fault {
                code,
                reaction,
                ack: d.ack,
            }),
            _ => None,
        }
    }

    /// Raises diagnostic `code` (fault injection, communication monitoring): an error (per
    /// PNU 246) takes T7 at the next cycle with its PNU 242 reaction, a warning sets
    /// SCON.WARN, an information goes to the diagnostic memory only. The cause counts as
    /// present until [`Self::clear_fault`]. Unassigned numbers are ignored (see
    /// [`Self::inject`]).
    pub fn fault(&mut self, code: u8) {
        let _ = self.inject(code);
    }

    /// [`Self::fault`], telling an unassigned number apart.
    pub fn inject(&mut self, code: u8) -> Result<Class, UnknownDiagnostic> {
        let d = diagnostics::lookup(code.into()).ok_or(UnknownDiagnostic(code))?;
        let class = self.class_of(d);
        let bit = 1u128 << (code & 0x7F);
        match class {
            Class::Fault(reaction) => {
                self.injected |= bit;
                self.fhpp.raise_fault(Fault {
                    code,
                    reaction,
                    ack: d.ack,
                });
            }
            Class::Warning => self.warnings |= bit,
            Class::Information | Class::Event => self.log_event(d, class),
        }
        Ok(class)
    }

    /// Raises App. D message `number` as printed ("2Fh") from outside, as [`Self::inject`];
    /// it stays until [`Self::clear_diagnostic`].
    pub fn raise_diagnostic(
        &mut self,
        number: &str,
    ) -> Result<Class, crate::drive::diagnostics::DiagnosticError> {
        let code = diagnostics::number(number)
            .ok_or(crate::drive::diagnostics::DiagnosticError::Unknown)?;
        self.inject(code)
            .map_err(|_| crate::drive::diagnostics::DiagnosticError::Unknown)
    }

    /// Clears App. D message `number` raised by [`Self::raise_diagnostic`]: its cause is gone
    /// (an error may be acknowledged with CCON.RESET, a warning ends).
    pub fn clear_diagnostic(
        &mut self,
        number: &str,
    ) -> Result<(), crate::drive::diagnostics::DiagnosticError> {
        let code = diagnostics::number(number)
            .filter(|c| diagnostics::lookup((*c).into()).is_some())
            .ok_or(crate::drive::diagnostics::DiagnosticError::Unknown)?;
        self.clear_fault(code);
        Ok(())
    }

    /// Whether message `code` is active: the fault shown (PNU 205), a raised cause or a
    /// present warning.
    pub fn diagnostic_active(&self, code: u8) -> bool {
        let bit = 1u128.checked_shl(u32::from(code)).unwrap_or(0);
        self.fhpp.fault().is_some_and(|f| f.code == code)
            || self.injected & bit != 0
            || self.warnings & bit != 0
    }

    /// The load (intermediate circuit) voltage is switched on or off: SCON.VLOAD, the T2
    /// condition, and App. D 1Bh "intermediate circuit voltage too low" while it is off (an
    /// error with reaction A by default, acknowledgeable once the voltage is back; as a
    /// warning it clears by itself).
    pub fn set_load_voltage(&mut self, present: bool) {
        self.fhpp.set_load_voltage(present);
        if present {
            self.clear_fault(diag::LOAD_VOLTAGE_LOW);
        } else {
            self.fault(diag::LOAD_VOLTAGE_LOW);
        }
    }

    /// The cause of diagnostic `code` has gone: an error may now be acknowledged, a warning
    /// clears.
    pub fn clear_fault(&mut self, code: u8) {
        let bit = 1u128 << (code & 0x7F);
        self.injected &= !bit;
        self.warnings &= !bit;
        self.warnings_logged &= !bit;
        self.fhpp.fault_cause_gone(code);
    }

    /// Raises a diagnostic once (a refused start, a homing error, a passed software limit):
    /// an error is acknowledged at once (the cause was the event), a warning shows until the
    /// next start.
    fn raise_once(&mut self, code: u8) {
        let Some(d) = diagnostics::lookup(code.into()) else {
            return;
        };
        let bit = 1u128 << (code & 0x7F);
        match self.class_of(d) {
            Class::Fault(reaction) => self.fhpp.raise_fault(Fault {
                code,
                reaction,
                ack: Ack::Immediately,
            }),
            Class::Warning => {
                self.warnings |= bit;
                self.once_warnings |= bit;
            }
            class => self.log_event(d, class),
        }
    }

    fn clear_warning(&mut self, code: u8) {
        let bit = 1u128 << (code & 0x7F);
        self.warnings &= !bit;
        self.warnings_logged &= !bit;
    }

    /// What the 7-segment display shows (§7.1.2 Tab. 7.3): the active error (PNU 205),
    /// else a present warning (PNU 221), as its hexadecimal code.
    pub fn seven_segment(&self) -> SevenSegment {
        SevenSegment::showing(self.fhpp.fault().map(|f| f.code), self.warnings)
    }

    /// The diagnostic memory (PNU 200…204).
    pub fn diagnostic_memory(&self) -> &DiagnosticMemory {
        &self.memory
    }

    /// The device clock of the time stamps: ms since power-on, wrapping at 2³² (PNU 202).
    fn now_ms(&self) -> u32 {
        self.cycles as u32
    }

    fn log(&mut self, event: EventType, code: u8) {
        let Some(d) = diagnostics::lookup(code.into()) else {
            return;
        };
        if d.logged(self.handling(code)) {
            self.memory.log(event, code.into(), self.now_ms());
            self.memory_dirty = true;
        }
    }

    fn log_event(&mut self, d: Diagnostic, class: Class) {
        let event = match class {
            Class::Fault(_) => EventType::Fault,
            Class::Warning => EventType::Warning,
            Class::Information => EventType::Information,
            Class::Event if d.code == diag::START_UP => EventType::SwitchOn,
            Class::Event => EventType::Information,
        };
        self.log(event, d.code);
    }

    /// Faults present now (PNU 220): the active one, injected ones whose cause is present,
    /// and the following error while it is an error.
    fn current_faults(&self) -> u128 {
        let mut f = self.injected;
        if let Some(a) = self.fhpp.fault() {
            f |= 1u128 << (a.code & 0x7F);
        }
        if self.following_error && self.fault_for(diag::FOLLOWING_ERROR).is_some() {
            f |= 1u128 << diag::FOLLOWING_ERROR;
        }
        f
    }

    /// End of a cycle: new faults and warnings into the memory (incoming, 01h / 05h), the
    /// end of the active fault (acknowledged) as 00h, and the time-stamp wrap.
    fn diagnose(&mut self) {
        self.memory.tick(self.now_ms());
        let faults = self.current_faults();
        let new = faults & !self.faults_present;
        self.faults_present = faults;
        let new_warnings = self.warnings & !self.warnings_logged;
        self.warnings_logged = self.warnings;
        let active = self.fhpp.fault().map(|f| f.code);
        let gone = match (self.last_fault, active) {
            (Some(old), None) => Some(old),
            _ => None,
        };
        self.last_fault = active;
        if let Some(code) = gone {
            // Acknowledged. An "immediately ackable" fault was an event: acknowledging it
            // ends it even if the injected cause was never declared gone.
            if diagnostics::lookup(code.into()).is_some_and(|d| d.ack == Ack::Immediately) {
                self.injected &= !(1u128 << (code & 0x7F));
            }
            self.log(EventType::Gone, code);
        }
        for (mask, event) in [(new, EventType::Fault), (new_warnings, EventType::Warning)] {
            let mut m = mask;
            while m != 0 {
                let code = m.trailing_zeros() as u8;
                m &= m - 1;
                self.log(event, code);
            }
        }
    }

    /// PNU 200…204 from the ring (after a change, once per cycle at most).
    fn mirror_memory(&mut self) {
        self.memory_dirty = false;
        let od = &mut self.od;
        for (n, sub) in (0..diagnostic_memory::CAPACITY).zip(1u8..) {
            let e = self.memory.get(n);
            let vals = [
                (200, e.map_or(0, |e| e.event.value().into())),
                (
                    201,
                    e.map_or(diagnostic_memory::INVALID_NUMBER.into(), |e| {
                        e.number.into()
                    }),
                ),
                (202, e.map_or(0, |e| e.time_ms.into())),
                (203, e.map_or(0, |e| e.info.into())),
            ];
            for (pnu, v) in vals {
                let _ = od.set_value(pnu_index(pnu), sub, Value::Unsigned(v));
            }
        }
        let _ = od.set_value(pnu_index(204), 4, Value::Unsigned(self.memory.len() as u64));
    }

    /// PNU 204:3 = 1: clear the memory (a start-up event is written).
    fn clear_memory(&mut self) {
        self.memory.clear(self.now_ms());
        self.mirror_memory();
    }

    /// PNU 242 / 246 writes: the value must be one App. D allows for that number (PNU 234 /
    /// 238), or its factory value; rw2: only with the output stage off.
    fn check_error_management(
        &self,
        index: u16,
        sub: u8,
        data: &[u8],
        wire: bool,
    ) -> Result<(), AbortCode> {
        let reaction = index == pnu_index(242);
        if !reaction && index != pnu_index(246) {
            return Ok(());
        }
        let &[lo, hi] = data else {
            return Ok(()); // the dictionary answers the length error
        };
        let value = u16::from_le_bytes([lo, hi]);
        let d = diagnostics::code_of_subindex(sub).and_then(|c| diagnostics::lookup(c.into()));
        let factory = d.map_or(0, |d| {
            if reaction {
                d.default_reaction()
            } else {
                d.default_handling()
            }
        });
        let ok = value == factory
            || d.is_some_and(|d| {
                if reaction {
                    d.accepts_reaction(value)
                } else {
                    d.accepts_handling(value)
                }
            });
        if !ok {
            return Err(AbortCode::INVALID_VALUE);
        }
        if wire && self.fhpp.output_stage_on() {
            return Err(AbortCode::DEVICE_STATE);
        }
        Ok(())
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
        if self.records_dirty != 0 {
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
        if let Task::Delayed {
            number,
            mode,
            until,
        } = self.task
        {
            if self.cycles >= until {
                self.begin_record(number, mode);
            }
        }
        self.advance(dt);
        self.supervise_plant(dt);
        self.compare();
        self.check_chain();
        self.cycles += 1;
        self.status = self.motion_status();
        self.diagnose();
        self.publish();
        if self.memory_dirty {
            self.mirror_memory();
        }
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
            homing_search: pos(g(1012, 1)),
            homing_drive: pos(g(1012, 2)),
            homing_crawl: pos(g(1012, 3)),
            homing_torque: pos(g(1015, 1)),
            block_velocity: pos(g(1016, 1)),
            block_ms: g(1017, 1).max(0) as u64,
            base_acceleration: pos(g(560, 1)),
            base_force_ma: pos(g(555, 1)),
            force_stroke: pos(g(510, 1)),
            direct_comparators: Comparators::from_pnus(585, |pnu| g(pnu, 1)),
            force_window: pos(g(552, 1)),
            soft_lower: g(501, 1),
            soft_upper: g(501, 2),
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
        let od = &self.od;
        let mut dirty = core::mem::take(&mut self.records_dirty);
        while dirty != 0 {
            let n = dirty.trailing_zeros() as u8 + 1;
            dirty &= dirty - 1;
            let g = |pnu| get_i64(od, pnu, n);
            let Some(r) = self.records.get_mut(n) else {
                continue;
            };
            *r = Record::from_pnus(g);
        }
    }

    // ---- coordinates -------------------------------------------------------------------

    /// Actual position, raw SINC (encoder based).
    fn raw_actual(&self) -> f64 {
        let k = self.params.einc_per_sinc;
        if k <= 0.0 {
            return 0.0;
        }
        (self.stepper.encoder_increments() + self.plant_watch.encoder.error()) as f64 / k
            * self.params.polarity
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
        crate::rounding::round(v) * self.params.polarity
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
        self.task_started = self.cycles;
        self.mc = false;
        self.window_since = None;
        self.standstill_target = None;
        self.still_since = None;
        self.standstill_error = false;
        self.stroke_reached = false;
        // Warnings of one event (28h, 3Fh, 37h, … as W) clear at the next start (App. D).
        self.warnings &= !self.once_warnings;
        self.warnings_logged &= !self.once_warnings;
        self.once_warnings = 0;
    }

    /// Software limits PNU 501 in raw SINC (lower, upper): relative to AZ, both 0 = off, and
    /// only with a valid reference (§6.2: homing disables them until it has finished).
    fn soft_limits(&self) -> Option<(f64, f64)> {
        let p = &self.params;
        let reference = self.reference?;
        if p.soft_lower == 0 && p.soft_upper == 0 {
            return None;
        }
        let az = reference + p.az_offset as f64;
        Some((az + p.soft_lower as f64, az + p.soft_upper as f64))
    }

    /// Why a move from the set-point towards `target` may not start: 13h / 14h into a
    /// direction locked by a passed limit, 29h / 2Ah for a target behind a limit (App. D).
    fn limit_refusal(&self, target: f64) -> Option<u8> {
        let here = self.traj.position;
        if target > here && self.locked_positive {
            return Some(diag::POSITIVE_DIRECTION_LOCKED);
        }
        if target < here && self.locked_negative {
            return Some(diag::NEGATIVE_DIRECTION_LOCKED);
        }
        let (lo, hi) = self.soft_limits()?;
        if target < lo {
            Some(diag::TARGET_BEHIND_NEGATIVE_LIMIT)
        } else if target > hi {
            Some(diag::TARGET_BEHIND_POSITIVE_LIMIT)
        } else {
            None
        }
    }

    /// A start the limits refuse: no motion, the task ends, the diagnostic is raised.
    fn refuse_start(&mut self, code: u8) {
        self.start_task(Task::None);
        self.pending = None;
        self.chain = None;
        self.raise_once(code);
    }

    /// Software limits while moving (velocity tasks, jog): the set-point reaching a limit
    /// raises 11h / 12h once and locks that direction until the set-point is back inside.
    fn watch_limits(&mut self) {
        let Some((lo, hi)) = self.soft_limits() else {
            self.locked_positive = false;
            self.locked_negative = false;
            return;
        };
        let x = self.traj.position;
        let v = self.traj.velocity;
        if x < hi {
            self.locked_positive = false;
        }
        if x > lo {
            self.locked_negative = false;
        }
        // Position targets were checked at the start and jog stops by itself: the error is
        // for a velocity task (or its braking) that runs into a limit.
        let raise = matches!(
            self.motion,
            Motion::Velocity { .. } | Motion::Braking { .. }
        );
        if x >= hi && v > 0.0 && !self.locked_positive {
            self.locked_positive = true;
            if raise {
                self.raise_once(diag::SOFTWARE_LIMIT_POSITIVE);
            }
        }
        if x <= lo && v < 0.0 && !self.locked_negative {
            self.locked_negative = true;
            if raise {
                self.raise_once(diag::SOFTWARE_LIMIT_NEGATIVE);
            }
        }
    }

    fn start_position(&mut self, target: f64, velocity: f64, accel: f64, decel: f64, fe: f64) {
        if let Some(code) = self.limit_refusal(target) {
            self.refuse_start(code);
            return;
        }
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
        if target > 0.0 && self.locked_positive {
            self.refuse_start(diag::POSITIVE_DIRECTION_LOCKED);
            return;
        }
        if target < 0.0 && self.locked_negative {
            self.refuse_start(diag::NEGATIVE_DIRECTION_LOCKED);
            return;
        }
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
        if !matches!(
            cmd,
            MotionCommand::Record { .. }
                | MotionCommand::Continue
                | MotionCommand::Halt
                | MotionCommand::ManualBrake { .. }
        ) {
            self.chain = None;
        }
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
            MotionCommand::Home => self.start_homing(),
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
            MotionCommand::Force {
                setpoint,
                velocity_limit,
                stroke_monitoring,
                ..
            } => {
                let stroke = stroke_monitoring.then_some(p.force_stroke);
                self.start_force(
                    f64::from(setpoint),
                    f64::from(velocity_limit),
                    p.direct_accel,
                    stroke,
                );
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

    /// A record start (START edge or a chain switch): after its start delay PNU 426 ("the
    /// time counts from the start command", Tab. B.61), at once without one. Decision: the
    /// delay of an MC chain (Tab. 6.9 "PNU 426 as the wait time after MC") is the following
    /// record's own PNU 426, so every record has one delay, however it is started.
    fn start_record(&mut self, number: u8, mode: ControlMode) {
        let Some(r) = self.records.get(number).copied() else {
            self.raise_once(diag::RECORD_INVALID);
            return;
        };
        if r.start_delay_ms > 0 {
            // The axis goes on with what it does (an MC chain stands, a comparator chain
            // keeps the previous profile) until the delay has run out.
            self.start_task(Task::Delayed {
                number,
                mode,
                until: self.cycles + u64::from(r.start_delay_ms),
            });
            self.pending = None;
            self.chain = None;
            return;
        }
        self.begin_record(number, mode);
    }

    fn begin_record(&mut self, number: u8, mode: ControlMode) {
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
                let stroke =
                    (!r.rcb1.contains(Rcb1::XLIM)).then_some(f64::from(r.stroke_limit.max(0)));
                self.start_force(
                    f64::from(r.setpoint_force),
                    f64::from(r.velocity.unsigned_abs()),
                    accel,
                    stroke,
                );
            }
        }
        self.chain = Some(Chain { record: number });
        self.comparator_record = Some(number);
    }

    /// Force task `target` ‰ of PNU 555 (the sign is the direction) with the velocity limit
    /// `vmax` SINC/s (§6.6 force mode). App. D 24h: force control needs the encoder, so open
    /// loop refuses it.
    fn start_force(&mut self, target: f64, vmax: f64, accel: f64, stroke: Option<f64>) {
        if self.settings.mode == StepperMode::OpenLoop {
            self.task = Task::None;
            self.raise_once(diag::NOT_IN_OPEN_LOOP);
            return;
        }
        let vmax = self.clamp_velocity(vmax);
        self.start_task(Task::Force { target });
        self.motion = Motion::Force {
            target,
            vmax,
            accel: accel.max(1.0),
            start: self.traj.position,
            stroke,
        };
        self.pending = None;
        self.task_decel = accel.max(1.0);
        // Tab. B.59: the record's maximum deviation has "no function" for force records.
        self.fe_window = 0.0;
        self.fe_velocity = false;
    }

    /// The actual force in ‰ of PNU 555, positive when it pushes towards `dir` (the current
    /// amplitude with the sign of the torque set-point).
    fn force_along(&self, dir: f64) -> f64 {
        let torque = self.stepper.torque_set() * self.params.polarity;
        let f = f64::from(self.actual_force());
        if torque * dir >= 0.0 {
            f
        } else {
            -f
        }
    }

    /// The comparators of the task (§6.7.4): in record selection those of the last record
    /// started, in direct mode PNU 585…595. A comparator is on while its value is inside
    /// [min, max] for its window time (min > max: never); the time comparator counts from the
    /// task start. Result: PNU 312 and the chaining conditions 20…23.
    fn compare(&mut self) {
        let direct = self.fhpp.operating_mode() == super::OperatingMode::Direct;
        let set = if direct {
            Some(self.params.direct_comparators)
        } else {
            self.comparator_record
                .and_then(|n| self.records.get(n))
                .map(|r| r.comparators)
        };
        let Some(c) = set else {
            self.comparator_outputs = 0;
            self.comparator_since = [None; 3];
            return;
        };
        let now = self.cycles;
        // §6.7.4: the position comparator is absolute (PZ) even for relative records.
        let pz = sat_i32(self.to_pz(self.raw_actual()));
        let v = sat_i32(self.actual_velocity());
        let f = sat_i32(self.force_along(1.0)).clamp(i16::MIN.into(), i16::MAX.into()) as i16;
        let inside = [
            (c.position.contains(pz), c.position.window_time_ms),
            (c.velocity.contains(v), c.velocity.window_time_ms),
            (c.force.contains(f), c.force.window_time_ms),
        ];
        let mut out = 0;
        for ((bit, (inn, ms)), since) in [CMP_POSITION, CMP_VELOCITY, CMP_FORCE]
            .into_iter()
            .zip(inside)
            .zip(self.comparator_since.iter_mut())
        {
            if !inn {
                *since = None;
                continue;
            }
            let t0 = *since.get_or_insert(now);
            if now.saturating_sub(t0) >= u64::from(ms) {
                out |= bit;
            }
        }
        let t = now.saturating_sub(self.task_started);
        if (u64::from(c.time.min_ms)..=u64::from(c.time.max_ms)).contains(&t) {
            out |= CMP_TIME;
        }
        self.comparator_outputs = out;
    }

    /// RCB2 of the running record (§6.5.3 Tab. 6.9): when its switching condition is met,
    /// the record of PNU 416 follows (its own start delay first); PNU 425 pulses MC.
    fn check_chain(&mut self) {
        let Some(chain) = self.chain else {
            return;
        };
        if !self.stage_on || matches!(self.task, Task::Delayed { .. }) {
            return;
        }
        let Some(r) = self.records.get(chain.record).copied() else {
            self.chain = None;
            return;
        };
        let out = self.comparator_outputs;
        let met = match r.chain_condition() {
            None | Some(ChainCondition::None) => false,
            Some(ChainCondition::MotionComplete) => self.mc,
            Some(ChainCondition::PositionComparator) => out & CMP_POSITION != 0,
            Some(ChainCondition::VelocityComparator) => out & CMP_VELOCITY != 0,
            Some(ChainCondition::ForceComparator) => out & CMP_FORCE != 0,
            Some(ChainCondition::TimeComparator) => out & CMP_TIME != 0,
        };
        if !met {
            return;
        }
        let next = r.following_record;
        let Some(mode) = self
            .records
            .get(next)
            .filter(|n| n.is_valid())
            .and_then(|n| n.control_mode())
        else {
            // PNU 416 names no valid record (0 = homing is not a chain target): 3Fh.
            self.chain = None;
            self.raise_once(diag::RECORD_INVALID);
            return;
        };
        if self
            .fhpp
            .record_chained(next, mode, r.mc_on_continuation == 1)
        {
            self.start_record(next, mode);
        } else {
            // The state machine has left the task (halt, stop, fault): the chain ends.
            self.chain = None;
        }
    }

    /// TEACH falling edge: the actual position into the target of PNU 520 (§6.4).
    fn teach(&mut self, record: u8, position: i32) {
        let target = get_i64(&self.od, 520, 1);
        let raw = self.pz_to_raw(f64::from(position));
        let (pnu, sub, value) = match target {
            1 => {
                // App. D 40h: the record must be an absolute position record.
                let absolute_position = self.records.get(record).is_some_and(|r| {
                    r.control_mode() == Some(ControlMode::Position) && !r.rcb1.contains(Rcb1::ABS)
                });
                if !absolute_position {
                    self.raise_once(diag::TEACH_FAILED);
                    return;
                }
                (404, record, i64::from(position))
            }
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
        if is_record_pnu(pnu_index(pnu)) {
            self.records_dirty |= record_bit(sub);
        }
        // A successful teach ends a 40h warning.
        self.clear_warning(diag::TEACH_FAILED);
    }

    // ---- homing (§6.2) -----------------------------------------------------------------

    /// CPOS.HOM (or record 0): the method of PNU 1011 (Tab. 6.2, [`homing::select`]). The
    /// old reference is void from the start (SPOS.REF = 0, software limits off, §6.2.2) until
    /// the run completes.
    fn start_homing(&mut self) {
        let p = self.params;
        self.start_task(Task::Homing { done: false });
        self.pending = None;
        self.task_decel = p.homing_accel;
        let method = match homing::select(
            p.homing_method,
            self.settings.mode,
            self.settings.mechanics.has_switch(),
        ) {
            Ok(m) => m,
            Err(code) => {
                self.task = Task::None;
                self.raise_once(code);
                return;
            }
        };
        self.reference = None;
        if method.target == Target::CurrentPosition {
            // −35 current position: REF = here, the task completes at the next cycle.
            // Decision: no travel to AZ (CiA 402 35/37 do not move); the actual position
            // becomes −(PNU 1010 + PNU 500) (§6.2.1 step 2 "current position = 0 − offset").
            self.reference = Some(self.raw_actual());
            self.traj.velocity = 0.0;
            self.motion = Motion::Hold;
            self.task = Task::Homing { done: true };
            return;
        }
        // Decision: no following-error monitoring while homing (the search runs into a stop
        // on purpose, under the PNU 1015 current limit).
        self.fe_window = 0.0;
        self.fe_since = None;
        self.following_error = false;
        let angle = self.stepper.angle();
        self.motion = Motion::Homing(Homing {
            method,
            phase: HomingPhase::Search,
            dir: f64::from(method.direction),
            angle,
            phase_start: angle,
            started: self.cycles,
            stall_since: None,
        });
    }

    /// Shaft angle (rad) of an index pulse → raw SINC, through the encoder count latched
    /// there (the index sits on a count boundary: rounded, not floored, against the binary
    /// fraction of the angle).
    fn angle_to_raw(&self, angle: f64) -> f64 {
        let k = self.params.einc_per_sinc;
        if k <= 0.0 {
            return 0.0;
        }
        let inc_rev = f64::from(self.stepper.data().encoder_increments_per_rev.max(1));
        libm::round(angle / core::f64::consts::TAU * inc_rev) / k * self.params.polarity
    }

    /// The PNU 1015 current limit of a homing run, A (‰ of PNU 555, at most the motor's).
    fn homing_current_limit(&self) -> f64 {
        let p = &self.params;
        (p.homing_torque * p.base_force_ma / 1e6).min(self.stepper.data().max_current)
    }

    /// Block detection (PNU 1015…1017, Tab. B.131: "if this torque is reached for the time
    /// of PNU 1017 the stop is taken as REF"): the current at the PNU 1015 limit, pushing in
    /// the search direction, while the actual velocity stays below PNU 1016, for PNU 1017 ms.
    /// Closed loop only (it needs the encoder and the current control).
    fn stalled(&self, h: &mut Homing) -> bool {
        let p = &self.params;
        let limit = self.homing_current_limit();
        let pushing = self.stepper.torque_set() * p.polarity * h.dir > 0.0;
        let pressing = limit > 0.0 && pushing && self.stepper.current_a() >= 0.95 * limit;
        let standing = libm::fabs(self.actual_velocity()) < p.block_velocity.max(1.0);
        if self.settings.mode != StepperMode::ClosedLoop || !(standing && pressing) {
            h.stall_since = None;
            return false;
        }
        let t0 = *h.stall_since.get_or_insert(self.cycles);
        self.cycles.saturating_sub(t0) >= p.block_ms
    }

    /// The run ends without a reference: brake at PNU 1013, hold where the axis stands,
    /// raise `code` (its reaction comes from PNU 242 as for every error).
    fn homing_failed(&mut self, code: u8) {
        self.task = Task::None;
        self.fe_window = self.params.direct_fe_window;
        self.brake(self.params.homing_accel, true);
        self.raise_once(code);
    }

    /// REF found at `reference` raw SINC: on to AZ = REF + PNU 1010 (§6.2.1 step 3; PNU 1015
    /// "the stop is taken as REF and the drive travels to the axis zero point").
    fn homing_found(&mut self, h: &mut Homing, reference: f64, at_stop: bool) {
        if at_stop {
            // The set-point ran ahead into the stop: it restarts at the actual position.
            self.resync();
        }
        h.phase = HomingPhase::ToZero {
            target: reference + self.params.az_offset as f64,
            reference,
        };
    }

    /// One cycle of a homing run: the inputs of the last plant step (switch, index pulse,
    /// block detection), then the set-point of the phase.
    fn homing_cycle(&mut self, mut h: Homing, dt: f64) {
        let p = self.params;
        let mech = self.settings.mechanics;
        let angle = self.stepper.angle();
        let shaft_dir = h.dir * p.polarity;
        let moved_on = (angle - h.angle) * shaft_dir > 0.0;
        let index = mech.index_crossed(h.angle, angle).filter(|_| moved_on);
        let travelled = libm::fabs(angle - h.phase_start) / core::f64::consts::TAU;
        let closed = self.settings.mode == StepperMode::ClosedLoop;
        let timed_out = !closed
            && self.cycles.saturating_sub(h.started)
                > self.settings.homing_timeout.as_millis() as u64;
        let stalled = self.stalled(&mut h);
        h.angle = angle;
        let mut failed = None;
        match (h.method.target, h.phase) {
            (_, HomingPhase::ToZero { target, reference }) => {
                let lim = Limits {
                    velocity: self.clamp_velocity(p.homing_drive.max(1.0)),
                    acceleration: p.homing_accel,
                    deceleration: p.homing_accel,
                };
                let arrived = self.traj.step_to(target, 0.0, lim, dt);
                // Done as a position task is (§6.7 MC): inside ±PNU 1022 for PNU 1023 ms.
                let inside = arrived && libm::fabs(self.raw_actual() - target) <= p.target_window;
                let now = self.cycles;
                let since = if inside {
                    *self.window_since.get_or_insert(now)
                } else {
                    self.window_since = None;
                    now
                };
                if inside && now.saturating_sub(since) >= p.target_window_ms {
                    self.reference = Some(reference);
                    self.motion = Motion::Hold;
                    self.task = Task::Homing { done: true };
                    self.fe_window = p.direct_fe_window;
                    return;
                }
            }
            (Target::IndexPulse, _) => {
                if let Some(ix) = index {
                    let r = self.angle_to_raw(ix);
                    self.homing_found(&mut h, r, false);
                } else if travelled > 1.0 + MIN_INDEX_DISTANCE || stalled {
                    // More than a revolution (or a stop) without a pulse.
                    failed = Some(homing::NO_INDEX_PULSE);
                }
            }
            (Target::FixedStop, _) => {
                if stalled {
                    let r = self.raw_actual();
                    self.homing_found(&mut h, r, true);
                }
            }
            (Target::ReferenceSwitch, HomingPhase::Search) => {
                if mech.switch_active(angle) {
                    // CiA 402 23 / 27: on the switch, back off it the other way.
                    h.phase = HomingPhase::LeaveSwitch;
                    h.dir = -h.dir;
                    h.phase_start = angle;
                } else if stalled {
                    failed = Some(homing::SWITCH_NOT_FOUND);
                } else if timed_out {
                    failed = Some(homing::HOMING_TIMEOUT);
                }
            }
            (Target::ReferenceSwitch, HomingPhase::LeaveSwitch) => {
                if !mech.switch_active(angle) {
                    if closed {
                        h.phase = HomingPhase::IndexAfterSwitch { edge: angle };
                        h.phase_start = angle;
                    } else {
                        let r = self.raw_actual();
                        self.homing_found(&mut h, r, false);
                    }
                } else if stalled {
                    failed = Some(homing::SWITCH_NOT_FOUND);
                } else if timed_out {
                    failed = Some(homing::HOMING_TIMEOUT);
                }
            }
            (Target::ReferenceSwitch, HomingPhase::IndexAfterSwitch { edge }) => {
                if let Some(ix) = index {
                    let d = libm::fabs(ix - edge) / core::f64::consts::TAU;
                    if !(MIN_INDEX_DISTANCE..=1.0 - MIN_INDEX_DISTANCE).contains(&d) {
                        failed = Some(homing::INDEX_TOO_CLOSE);
                    } else {
                        let r = self.angle_to_raw(ix);
                        self.homing_found(&mut h, r, false);
                    }
                } else if travelled > 1.0 + MIN_INDEX_DISTANCE || stalled {
                    failed = Some(homing::NO_INDEX_PULSE);
                }
            }
            (Target::CurrentPosition, _) => {}
        }
        if let Some(code) = failed {
            self.homing_failed(code);
            return;
        }
        let v = match h.phase {
            HomingPhase::Search => p.homing_search,
            HomingPhase::LeaveSwitch | HomingPhase::IndexAfterSwitch { .. } => p.homing_crawl,
            HomingPhase::ToZero { .. } => {
                self.motion = Motion::Homing(h);
                return;
            }
        };
        let v = self.clamp_velocity(v.max(1.0));
        self.traj
            .step_velocity(h.dir * v, p.homing_accel, p.homing_accel, dt);
        self.motion = Motion::Homing(h);
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
            Motion::Force {
                target,
                vmax,
                start,
                stroke,
                ..
            } => {
                let dir = if target < 0.0 { -1.0 } else { 1.0 };
                let err = libm::fabs(target) - self.force_along(dir);
                // The position controller integrates a standing deviation into current: a
                // deviation proportional to the force error lets it settle at the target
                // (0.02 rev per 1000 ‰ of error), the set-point moving at most at `vmax`.
                let inc_rev = f64::from(self.stepper.data().encoder_increments_per_rev.max(1));
                let sinc_per_rev = inc_rev / p.einc_per_sinc.max(1e-9);
                let desired = self.raw_actual() + dir * err / 1000.0 * 0.02 * sinc_per_rev;
                // Far from the force (below target − 4 windows: no contact yet) the set-point
                // travels at `vmax`; near it, first order towards `desired` (50 cycles, slow
                // enough for the stiffness of the position controller).
                let w = p.force_window.max(5.0);
                let approach = dir * vmax * ((err - 2.0 * w) / (2.0 * w)).clamp(0.0, 1.0);
                let settle = (desired - self.traj.position) * 0.02;
                let step = (approach * dt + settle).clamp(-vmax * dt, vmax * dt);
                self.traj.position += step;
                self.traj.velocity = if dt > 0.0 { step / dt } else { 0.0 };
                if let Some(limit) = stroke {
                    if libm::fabs(self.traj.position - start) >= limit {
                        // PNU 510 / 427: Quick-Stop ramp, then hold position-controlled.
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
                // §6.3 step 4: referenced, jog stops at the software limit by itself (its
                // ramp planned to end there); it does not leave the limit.
                let stop_at = self
                    .soft_limits()
                    .map(|(lo, hi)| if positive { hi } else { lo });
                let room = stop_at.map(|end| (end - self.traj.position) * v.signum());
                match (stop_at, room) {
                    (_, Some(r)) if r < 0.0 => {
                        // Already beyond the limit: no further in this direction.
                        self.traj.step_stop(p.jog_accel, dt);
                    }
                    (Some(end), Some(r)) if r <= stop_room(self.traj.velocity, p.jog_accel, dt) => {
                        let lim = Limits {
                            velocity: libm::fabs(v).max(libm::fabs(self.traj.velocity)),
                            acceleration: p.jog_accel,
                            deceleration: p.jog_accel,
                        };
                        self.traj.step_to(end, 0.0, lim, dt);
                    }
                    _ => self.traj.step_velocity(v, p.jog_accel, p.jog_accel, dt),
                }
            }
            Motion::Braking { decel, resync } => {
                if self.traj.step_stop(decel, dt) {
                    self.motion = Motion::Hold;
                    if resync {
                        self.resync();
                    }
                }
            }
            Motion::Homing(h) => self.homing_cycle(h, dt),
        }
        // PNU 1015: homing limits the current to its share of PNU 555 (closed loop).
        let homing_limit =
            matches!(self.motion, Motion::Homing(_)).then(|| self.homing_current_limit());
        self.stepper.set_current_limit(homing_limit);
        self.watch_limits();
        let k = p.einc_per_sinc * p.polarity;
        let increments = crate::rounding::round(self.traj.position * k) as i64;
        let inc_rev = f64::from(self.stepper.data().encoder_increments_per_rev.max(1));
        // No speed feed-forward under force control: the force comes from the deviation.
        let ff = if matches!(self.motion, Motion::Force { .. }) {
            0.0
        } else {
            self.traj.velocity
        };
        let rpm = ff * k / inc_rev * 60.0;
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
            Task::Force { target } if !self.mc => {
                let dir = if target < 0.0 { -1.0 } else { 1.0 };
                let inside =
                    libm::fabs(self.force_along(dir) - libm::fabs(target)) <= p.force_window;
                if held(&mut self.window_since, inside, p.target_window_ms) {
                    self.mc = true;
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
        let fe_was = self.following_error;
        self.following_error = held(&mut self.fe_since, over, fe_time);
        // §6.7.2: as a warning it clears once the error is back inside the window; as an
        // information it only goes to the memory (once per occurrence).
        let fe_class = self.diagnostic_class(diag::FOLLOWING_ERROR);
        match fe_class {
            Some(Class::Warning) if self.following_error => {
                self.warnings |= 1u128 << diag::FOLLOWING_ERROR;
            }
            Some(Class::Information) if self.following_error && !fe_was => {
                self.raise_once(diag::FOLLOWING_ERROR);
            }
            _ => self.clear_warning(diag::FOLLOWING_ERROR),
        }
        // Standstill monitoring after MC of a position task.
        if let Some(target) = self.standstill_target {
            let outside =
                p.standstill_window > 0.0 && libm::fabs(actual - target) > p.standstill_window;
            let mut since = self.still_since;
            if held(&mut since, outside, p.standstill_ms) {
                if !self.standstill_error {
                    // 37h is W or I (App. D): a warning until back in the window.
                    self.raise_once(diag::STANDSTILL);
                }
                self.standstill_error = true;
            } else if !outside {
                self.standstill_error = false;
                self.clear_warning(diag::STANDSTILL);
            }
            self.still_since = since;
        }
    }

    /// Actual values into their PNUs (300, 301, 310, 320, 321, 1040, 1041, 1059, 205, 230,
    /// 220, 221, 400:2).
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
        // PNU 301 force values (‰ of PNU 555): the set-point of a force task, else 0.
        let force_set = match self.task {
            Task::Force { target } => target,
            _ => 0.0,
        };
        let dir = if force_set < 0.0 { -1.0 } else { 1.0 };
        let force_act = dir * self.force_along(dir);
        let clamp16 = |v: f64| i64::from(sat_i32(v).clamp(i16::MIN.into(), i16::MAX.into()));
        let force = [
            clamp16(force_act),
            clamp16(force_set),
            clamp16(force_set - force_act),
        ];
        let od = &mut self.od;
        let cache = &mut self.published;
        let mut n = 0;
        let mut set = |pnu: u16, sub: u8, v: Value| {
            cache.set(od, n, pnu_index(pnu), sub, v);
            n += 1;
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
        for (sub, v) in (1u8..).zip(force) {
            set(301, sub, Value::Signed(v));
        }
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
        set(312, 1, Value::Unsigned(self.comparator_outputs.into()));
        let faults = self.faults_present;
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

/// Braking distance from `v` at `decel`, plus one cycle of travel (so the ramp starts in time).
fn stop_room(v: f64, decel: f64, dt: f64) -> f64 {
    let v = libm::fabs(v);
    v * v / (2.0 * decel.max(1.0)) + v * dt
}

fn sat_i32(v: f64) -> i32 {
    let r = crate::rounding::round(v);
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
