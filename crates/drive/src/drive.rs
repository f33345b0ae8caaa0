//! The CiA 402 drive: device control, the operating modes and the simulated axis behind one
//! object dictionary. Protocol front ends reach it only through [`ObjectAccess`]; the runtime
//! steps it with [`Drive::step`] on the cell's clock. Stepping never allocates.

use core::time::Duration;

use heapless::Deque;
use od::{AbortCode, DataType, Entry, Instant, ObjectAccess, ObjectDictionary, Value};

use crate::axis::{Axis, Demand};
use crate::control::ControlParams;
use crate::controlword::Controlword;
use crate::device_control::{DeviceControl, Reaction, Rules, State};
use crate::digital_inputs::{Levels, SwitchConfig};
use crate::display::Display;
use crate::factor_group::{FactorGroup, FactorObject, Ratio};
use crate::homing::{Command, HomingError, Search, Sense, Speed};
use crate::interpolated_position::{period_from_60c2, Interpolator, SyncChange};
use crate::messages::{self, Number, Reactions};
use crate::motor::MotorData;
use crate::personality::{self, ErrorReaction, Fault, Personality, Vendor};
use crate::profile_position::{Job, Request, SetPoints};
use crate::smoothing::Smoother;
use crate::statusword::Statusword;
use crate::trajectory::{Limits, Trajectory};
use crate::travel::{Inputs, TravelSettings};

pub mod diagnostics;
mod feed_constant;
mod homing_run;
pub mod named_switches;
pub(crate) mod object_writes;
mod plant;
pub mod plant_supervision;
mod publish;
mod target_limits;
mod velocity_mode;
pub use plant::StepperPlant;

/// Operating modes (6060h / 6061h values).
pub mod mode {
    pub const PROFILE_POSITION: i8 = 1;
    /// Velocity mode VL (CiA 402 §10).
    pub const VELOCITY: i8 = 2;
    pub const PROFILE_VELOCITY: i8 = 3;
    pub const PROFILE_TORQUE: i8 = 4;
    pub const HOMING: i8 = 6;
    pub const INTERPOLATED_POSITION: i8 = 7;
    /// EtherCAT only on the CMMP-AS (6060h value range).
    pub const CYCLIC_SYNCHRONOUS_POSITION: i8 = 8;
    /// 6061h while a mode change is in progress (CMMP-AS §7.1).
    pub const CHANGING: i8 = -1;
}

/// The CMMP-AS's diagnostic messages (its personality's error table).
pub use crate::personality::cmmp_as::diag;

/// Settings of the simulation that no object holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveSettings {
    pub motor: MotorData,
    /// How long a mode change takes; 6061h reads −1 meanwhile (CMMP-AS §7.1 "may briefly
    /// show −1"). 0 switches at the next cycle and keeps showing the old mode until then
    /// (python-canopen's BaseNode402 cannot decode −1); a longer value reproduces slow drives.
    pub mode_change_time: Duration,
    /// The hardware enables (DIN4 output stage, DIN5 controller enable) transition 2 needs.
    /// False also for a Nanotec that "accepts no motion commands" (NT-NODE-07: switch =
    /// node + 128 with no bit-rate code in 2005h; `canopen::rotary_switches`).
    pub enables_present: bool,
    /// A holding brake is fitted: it holds the shaft while the output stage is off.
    pub brake_fitted: bool,
    /// The drive is reached over EtherCAT: cyclic synchronous position (6060h = 8) is
    /// available (CMMP-AS 6060h: "8 CSP, EtherCAT only").
    pub ethercat: bool,
    /// The axis travel: limit switches, home switch, index pulse, hard stops.
    pub travel: TravelSettings,
    /// The hybrid stepper motor of a stepper personality (Nanotec); `None`: the
    /// personality's plant with its defaults (the servo motor for the CMMP-AS).
    pub stepper: Option<crate::stepper::StepperData>,
    /// A brushless motor with Hall sensors is connected to the stepper personality (Nanotec
    /// 2004h:07 = 1 / 2 drives it; `crate::bldc`); `None`: the stepper.
    pub bldc: Option<crate::bldc::BldcData>,
    /// The longest distance one homing search step may travel, increments (0: no limit);
    /// beyond it homing ends with 11-6 "end of search distance". Default 128 revolutions,
    /// more than the default travel.
    pub homing_max_distance: i64,
}

impl Default for DriveSettings {
    fn default() -> Self {
        DriveSettings {
            motor: MotorData::default(),
            mode_change_time: Duration::ZERO,
            enables_present: true,
            brake_fitted: true,
            ethercat: false,
            travel: TravelSettings::default(),
            stepper: None,
            bldc: None,
            homing_max_distance: 128 * 65536,
        }
    }
}

/// What the drive reports to its communication side (EMCY).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveEvent {
    Error {
        code: u16,
        register: u8,
    },
    Cleared {
        code: u16,
    },
    /// The drive asks to be restarted as at power-on (Kinco EA00 / tn00 = 2 / 3): the
    /// runtime reloads the stored set and boots the drive's nodes.
    Reboot,
}

/// min⁻¹ per increment/s (for the personality modules).
pub(crate) const RPM_PER_INCREMENT_S: f64 = RPM_PER_INC_S;

/// A deceleration that stops within one cycle, increments/s² ("abruptly").
const ABRUPT_STOP: f64 = 1e15;

/// Increments per second per internal velocity unit (1/4096 min⁻¹): 65536 / 60 / 4096.
const INC_S_PER_VEL: f64 = 65536.0 / 60.0 / 4096.0;
/// Increments per second² per internal acceleration unit (1/256 min⁻¹/s): 65536 / 60 / 256.
const INC_S2_PER_ACC: f64 = 65536.0 / 60.0 / 256.0;
/// min⁻¹ per increment/s.
const RPM_PER_INC_S: f64 = 60.0 / 65536.0;

/// Parameters the device logic reads every cycle: looked up in the dictionary once, so a
/// cycle never searches the object table. Sorted by (index, sub) (for the reader, and
/// `kinco_io` counts on the order of 2010h); [`param_slot`] finds a key through
/// [`PARAM_HASH`].
const PARAMS: [(u16, u8); 81] = [
    (0x2001, 0),
    (0x2004, 1),
    (0x2004, 7),
    (0x2004, 8),
    (0x2004, 0x0C),
    (0x2004, 0x0D),
    (0x2004, 0x0E),
    (0x2005, 1),
    (0x2006, 0),
    (0x2007, 1),
    (0x2007, 2),
    (0x2007, 3),
    (0x200A, 0),
    (0x200A, 1),
    (0x200B, 0),
    // Kinco 2010h: DIN polarity, simulate and the seven function codes (in input order, one
    // after the other: `din_function_code` counts on it), read every cycle.
    (0x2010, 1),
    (0x2010, 2),
    (0x2010, 3),
    (0x2010, 4),
    (0x2010, 5),
    (0x2010, 6),
    (0x2010, 7),
    (0x2010, 8),
    (0x2010, 9),
    (0x2011, 0),
    (0x2020, 0),
    (0x2045, 0),
    (0x2090, 1),
    (0x2090, 2),
    (0x2090, 3),
    (0x2090, 4),
    (0x2090, 5),
    (0x6065, 0),
    (0x6066, 0),
    (0x6067, 0),
    (0x6068, 0),
    (0x606D, 0),
    (0x606E, 0),
    (0x606F, 0),
    (0x6070, 0),
    (0x6071, 0),
    (0x6072, 0),
    (0x607A, 0),
    (0x607B, 1),
    (0x607B, 2),
    (0x607C, 0),
    (0x607D, 1),
    (0x607D, 2),
    (0x607E, 0),
    (0x607F, 0),
    (0x6080, 0),
    (0x6081, 0),
    (0x6082, 0),
    (0x6083, 0),
    (0x6084, 0),
    (0x6085, 0),
    (0x6086, 0),
    (0x6087, 0),
    (0x608F, 1),
    (0x608F, 2),
    (0x6098, 0),
    (0x6099, 1),
    (0x6099, 2),
    (0x609A, 0),
    (0x60C1, 1),
    (0x60FE, 1),
    (0x60FE, 2),
    (0x6510, 0x10),
    (0x6510, 0x11),
    (0x6510, 0x12),
    (0x6510, 0x13),
    (0x6510, 0x14),
    (0x6510, 0x15),
    (0x6510, 0x18),
    (0x6510, 0x22),
    (0x6510, 0x2F),
    (0x6510, 0x32),
    (0x6510, 0x36),
    (0x6510, 0x37),
    (0x6510, 0x38),
    (0x6510, 0xF0),
];

// The binary search needs the table sorted, without duplicates (checked when compiling).
const _: () = {
    let mut i = 1;
    while i < PARAMS.len() {
        let (a, b) = (PARAMS[i - 1], PARAMS[i]);
        assert!(a.0 < b.0 || (a.0 == b.0 && a.1 < b.1), "PARAMS unsorted");
        i += 1;
    }
};

/// `(index, sub)` as one key.
#[inline(always)]
const fn param_key(index: u16, sub: u8) -> u32 {
    (index as u32) << 8 | sub as u32
}

/// Buckets of [`PARAM_HASH`] (a power of two, at least twice the table: a lookup probes one
/// or two buckets).
const PARAM_BUCKETS: usize = 256;

/// The home bucket of a key (Fibonacci hashing: the key times 2³²/φ, its top 8 bits).
#[inline(always)]
const fn param_bucket(key: u32) -> usize {
    (key.wrapping_mul(0x9E37_79B9) >> 24) as usize & (PARAM_BUCKETS - 1)
}

/// [`PARAMS`] as an open-addressing hash table built when compiling: each bucket holds a
/// slot + 1 (0: empty), collisions go to the next bucket. The parameter reads of a cycle
/// are not all inlined, and a binary search per read cost a third of the Nanotec's cycle.
const PARAM_HASH: [u8; PARAM_BUCKETS] = {
    assert!(PARAMS.len() * 2 <= PARAM_BUCKETS && PARAMS.len() < u8::MAX as usize);
    let mut table = [0u8; PARAM_BUCKETS];
    let mut slot = 0;
    while slot < PARAMS.len() {
        let mut b = param_bucket(param_key(PARAMS[slot].0, PARAMS[slot].1));
        while table[b] != 0 {
            b = (b + 1) & (PARAM_BUCKETS - 1);
        }
        table[b] = slot as u8 + 1;
        slot += 1;
    }
    table
};

/// The slot of `(index, sub)` in [`PARAMS`].
#[inline(always)]
pub(crate) const fn param_slot(index: u16, sub: u8) -> Option<usize> {
    let key = param_key(index, sub);
    let mut b = param_bucket(key);
    // Terminates: the table always has empty buckets.
    loop {
        let s = PARAM_HASH[b];
        if s == 0 {
            return None;
        }
        let (i, u) = PARAMS[s as usize - 1];
        if param_key(i, u) == key {
            return Some(s as usize - 1);
        }
        b = (b + 1) & (PARAM_BUCKETS - 1);
    }
}

/// Entries the drive reads or writes every cycle, looked up once.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Hot {
    pub(crate) controlword: Option<&'static Entry>,
    pub(crate) statusword: Option<&'static Entry>,
    pub(crate) mode_display: Option<&'static Entry>,
    pub(crate) position_internal: Option<&'static Entry>,
    pub(crate) position_actual: Option<&'static Entry>,
    pub(crate) position_demand: Option<&'static Entry>,
    pub(crate) velocity_actual: Option<&'static Entry>,
    pub(crate) velocity_demand: Option<&'static Entry>,
    pub(crate) current_actual: Option<&'static Entry>,
    pub(crate) torque_actual: Option<&'static Entry>,
    pub(crate) torque_demand: Option<&'static Entry>,
    pub(crate) following_error_actual: Option<&'static Entry>,
    pub(crate) control_effort: Option<&'static Entry>,
    pub(crate) manufacturer_status: Option<&'static Entry>,
    pub(crate) target_velocity: Option<&'static Entry>,
    pub(crate) target_torque: Option<&'static Entry>,
    pub(crate) digital_inputs: Option<&'static Entry>,
}

pub struct Drive<S> {
    /// What the drive is: modes, option codes, errors, homing methods, vendor behaviour.
    pub(crate) personality: &'static Personality,
    pub(crate) od: ObjectDictionary<S>,
    pub(crate) settings: DriveSettings,
    pub(crate) dc: DeviceControl,
    pub(crate) axis: Axis,
    /// The stepper plant of a stepper personality; the servo axis is then not stepped.
    pub(crate) stepper: Option<StepperPlant>,
    /// The BLDC connected instead of the stepper: the servo axis, block-commutated.
    pub(crate) bldc: Option<crate::bldc::BldcData>,
    /// The motor type 2004h:07 the output stage runs (taken while it is off).
    pub(crate) motor_type: u8,
    pub(crate) fg: FactorGroup,
    pub(crate) hot: Hot,
    pub(crate) params: [Option<&'static Entry>; PARAMS.len()],
    /// Current-controller cycle and how many of them make one logic (position-loop) cycle.
    pub(crate) cycle: Duration,
    pub(crate) logic_every: u32,
    pub(crate) next_cycle: Option<Instant>,
    pub(crate) cycles: u64,
    pub(crate) now: Instant,
    /// Added to the encoder to give 6063h (2030h set_position_absolute, homing).
    pub(crate) position_offset: i64,
    pub(crate) mode: i8,
    pub(crate) mode_pending: Option<(i8, Instant)>,
    pub(crate) traj: Trajectory,
    /// Jerk-free profile (6086h = 2): the set-points through a moving average.
    pub(crate) smoother: Smoother,
    /// The position set-point the axis follows (after smoothing), increments.
    pub(crate) demand_position: f64,
    pub(crate) setpoints: SetPoints,
    pub(crate) demand: Demand,
    /// When the CSP set-point last changed.
    pub(crate) csp_changed_at: Option<Instant>,
    /// Interpolated position mode and its SYNC grid.
    pub(crate) ip: Interpolator,
    /// Quick stop, disable operation or fault reaction ramp in progress.
    pub(crate) stopping: bool,
    pub(crate) halted: bool,
    pub(crate) velocity_set: f64,
    pub(crate) torque_set: f64,
    pub(crate) target_reached: bool,
    pub(crate) window_since: Option<Instant>,
    pub(crate) following_error: bool,
    pub(crate) fe_since: Option<Instant>,
    pub(crate) speed_zero: bool,
    pub(crate) over_threshold_since: Option<Instant>,
    pub(crate) homing_attained: bool,
    pub(crate) homing_error: bool,
    pub(crate) referenced: bool,
    pub(crate) homing: HomingRun,
    pub(crate) homing_started: Instant,
    /// A homing search is still on its starting ramp (609Ah; Nanotec: only then).
    pub(crate) homing_accelerating: bool,
    /// A homing on block sets the position when the shaft has settled (Nanotec 2004h:05).
    pub(crate) homing_settle: Option<Instant>,
    /// The running homing method takes its reference switch from an object.
    pub(crate) homing_external: Option<personality::ExternalHomeSwitch>,
    /// The fault reaction brakes for a limit switch: with 6510h:15, not 6085h.
    pub(crate) limit_stop: bool,
    /// Controlword edges latched at the write, so a short pulse is never missed.
    pub(crate) cw_rising: Controlword,
    pub(crate) last_cw: Controlword,
    pub(crate) brake_engaged: bool,
    /// The output stage goes off / the set-point is released when the brake delay ends.
    pub(crate) power_off_at: Option<Instant>,
    /// A closed-loop test run in progress (Nanotec 6060h = −1 / −2) and when it ends.
    pub(crate) test_run: Option<(i8, Instant)>,
    /// The short closed-loop test run has aligned the encoder (Nanotec 200Bh found).
    pub(crate) closed_loop_aligned: bool,
    /// The brake opens then (a personality that releases it after the output stage).
    pub(crate) brake_release_at: Option<Instant>,
    pub(crate) release_at: Option<Instant>,
    /// Errors reported and not yet acknowledged.
    pub(crate) faults: heapless::Vec<u16, 8>,
    /// Errors reported by EMCY alone (no fault state), until their cause is gone.
    pub(crate) notices: heapless::Vec<u16, 4>,
    /// Causes still present (injected faults until cleared): they block the fault reset.
    pub(crate) causes: heapless::Vec<u16, 8>,
    pub(crate) events: Deque<DriveEvent, 16>,
    pub(crate) params_dirty: bool,
    /// Digital inputs driven from outside ([`Drive::force_inputs`]).
    pub(crate) forced_mask: u16,
    pub(crate) forced_levels: u16,
    /// Error management 2100h: the reaction per main error number.
    pub(crate) reactions: Reactions,
    /// What only a Kinco keeps (inputs, pulse and analog sources, history, position table,
    /// tuning).
    pub(crate) kinco: personality::kinco_drive::KincoState,
    /// The last warning and whether it is still active (200Fh).
    pub(crate) warning: Option<(Number, bool)>,
    /// Statusword bit 11 internal limit active, set by the mode (Nanotec: a clamped velocity,
    /// a wrapped or refused target).
    pub(crate) internal_limit: bool,
    /// The safety module reports safe standstill (2000h:01 bit 8).
    pub(crate) safe_standstill: bool,
    /// The DC-link voltage the supply gives, mV; `None`: the nominal 6510h:33.
    pub(crate) dc_link_mv: Option<u32>,
    /// The diagnostic memory: messages with their additional information, oldest first.
    pub(crate) memory: Deque<MemoryEntry, 16>,
    /// Messages raised by their number from outside ([`Drive::raise_diagnostic`]), until
    /// cleared.
    pub(crate) injected: heapless::Vec<&'static od::Diagnostic, 16>,
    /// The motor's and the power stage's temperatures, the encoder between the shaft and
    /// the reading, and what the drive's supervision has found in them
    /// ([`plant_supervision`]).
    pub(crate) plant_watch: plant_supervision::PlantWatch,
}

/// One entry of the diagnostic memory (CMMP-AS App. B: "No." and "additional information",
/// read in FCT or through FHPP PNU 203/213).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemoryEntry {
    pub number: Number,
    pub code: u16,
    /// The message's additional information (e.g. 02-0: state number and DC-link voltage).
    pub info: u32,
}

/// A numeric entry's value as `i64`, without going through `Value` (this runs several times
/// per control cycle).
#[inline(always)]
fn decode_i64(e: &Entry, raw: &[u8]) -> i64 {
    // The fixed-size integers by their type (one dispatch, one load); anything else, or a
    // value of another length, as the general decoding below has it.
    let fast = match e.data_type {
        DataType::Integer8 => le::<1>(raw).map(|b| i64::from(i8::from_le_bytes(b))),
        DataType::Boolean | DataType::Unsigned8 => le::<1>(raw).map(|b| i64::from(b[0])),
        DataType::Integer16 => le::<2>(raw).map(|b| i64::from(i16::from_le_bytes(b))),
        DataType::Unsigned16 => le::<2>(raw).map(|b| i64::from(u16::from_le_bytes(b))),
        DataType::Integer32 => le::<4>(raw).map(|b| i64::from(i32::from_le_bytes(b))),
        DataType::Unsigned32 => le::<4>(raw).map(|b| i64::from(u32::from_le_bytes(b))),
        _ => None,
    };
    match fast {
        Some(v) => v,
        None => decode_i64_general(e, raw),
    }
}

/// `raw` as an array of exactly `N` bytes.
#[inline(always)]
fn le<const N: usize>(raw: &[u8]) -> Option<[u8; N]> {
    raw.try_into().ok()
}

fn decode_i64_general(e: &Entry, raw: &[u8]) -> i64 {
    let u = match *raw {
        [a] => u64::from(a),
        [a, b] => u64::from(u16::from_le_bytes([a, b])),
        [a, b, c, d] => u64::from(u32::from_le_bytes([a, b, c, d])),
        [a, b, c, d, e, f, g, h] => u64::from_le_bytes([a, b, c, d, e, f, g, h]),
        _ => {
            let mut u = 0u64;
            for (i, b) in raw.iter().take(8).enumerate() {
                u |= u64::from(*b) << (8 * i);
            }
            u
        }
    };
    match e.data_type {
        DataType::Integer8 => i64::from(u as u8 as i8),
        DataType::Integer16 => i64::from(u as u16 as i16),
        DataType::Integer32 => i64::from(u as u32 as i32),
        DataType::Real32 => f32::from_bits(u as u32) as i64,
        DataType::Real64 => f64::from_bits(u) as i64,
        _ => u as i64,
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S> {
    /// A drive at power-on over `od` (holding defaults, commissioning and stored values),
    /// with the personality its device file names ([`personality::for_device`]).
    pub fn new(od: ObjectDictionary<S>, settings: DriveSettings) -> Self {
        let personality = personality::for_device(od.description().name);
        Self::with_personality(od, settings, personality)
    }

    /// A drive at power-on over `od` with `personality`.
    pub fn with_personality(
        mut od: ObjectDictionary<S>,
        settings: DriveSettings,
        personality: &'static Personality,
    ) -> Self {
        publish_supply(&mut od, None);
        let desc = od.description();
        let e = |i, s| desc.entry(i, s);
        let hot = Hot {
            controlword: e(0x6040, 0),
            statusword: e(0x6041, 0),
            mode_display: e(0x6061, 0),
            position_internal: e(0x6063, 0),
            position_actual: e(0x6064, 0),
            position_demand: e(0x6062, 0),
            velocity_actual: e(0x606C, 0),
            velocity_demand: e(0x606B, 0),
            current_actual: e(0x6078, 0),
            torque_actual: e(0x6077, 0),
            torque_demand: e(0x6074, 0),
            following_error_actual: e(0x60F4, 0),
            control_effort: e(0x60FA, 0),
            manufacturer_status: e(0x2000, 1),
            target_velocity: e(0x60FF, 0),
            target_torque: e(0x6071, 0),
            digital_inputs: e(0x60FD, 0),
        };
        let mut param_entries = [None; PARAMS.len()];
        for (slot, (i, s)) in param_entries.iter_mut().zip(PARAMS.iter()) {
            *slot = desc.entry(*i, *s);
        }
        let params = control_params(&od);
        let axis = Axis::new(settings.motor, params);
        let cycle = Duration::from_micros(u64::from(params.cycletime_current_us.max(1)));
        let logic_every = axis.gains().pos_every.max(1);
        let mut d = Drive {
            personality,
            od,
            settings,
            dc: DeviceControl::with_rules(Rules {
                enable_from_ready: personality.enable_from_ready,
                quick_stop_option: personality.option_code(personality::QUICK_STOP_OPTION, 2),
            }),
            axis,
            stepper: ((personality.stepper_plant && settings.bldc.is_none())
                || settings.stepper.is_some())
            .then(|| {
                StepperPlant::new(crate::stepper::Stepper::new(
                    settings.stepper.unwrap_or_default(),
                ))
            }),
            bldc: settings.bldc.filter(|_| personality.stepper_plant),
            motor_type: 0,
            fg: FactorGroup::default(),
            hot,
            params: param_entries,
            cycle,
            logic_every,
            next_cycle: None,
            cycles: 0,
            now: Instant::ZERO,
            position_offset: 0,
            mode: 0,
            mode_pending: None,
            traj: Trajectory::default(),
            smoother: Smoother::default(),
            demand_position: 0.0,
            setpoints: SetPoints::overwriting(personality.pp_overwrite_queued),
            demand: Demand::Off,
            csp_changed_at: None,
            ip: if personality.capabilities.ip_follows_sync {
                Interpolator::following_sync()
            } else {
                Interpolator::new(DEFAULT_IP_PERIOD)
            },
            stopping: false,
            halted: false,
            velocity_set: 0.0,
            torque_set: 0.0,
            target_reached: false,
            window_since: None,
            following_error: false,
            fe_since: None,
            speed_zero: true,
            over_threshold_since: None,
            homing_attained: false,
            homing_error: false,
            referenced: false,
            homing: HomingRun::Idle,
            homing_started: Instant::ZERO,
            homing_accelerating: false,
            homing_settle: None,
            homing_external: None,
            limit_stop: false,
            cw_rising: Controlword::EMPTY,
            last_cw: Controlword::EMPTY,
            brake_engaged: true,
            power_off_at: None,
            brake_release_at: None,
            test_run: None,
            closed_loop_aligned: false,
            release_at: None,
            faults: heapless::Vec::new(),
            notices: heapless::Vec::new(),
            causes: heapless::Vec::new(),
            events: Deque::new(),
            params_dirty: false,
            forced_mask: 0,
            forced_levels: 0,
            reactions: Reactions::default(),
            kinco: Default::default(),
            warning: None,
            internal_limit: false,
            safe_standstill: false,
            dc_link_mv: None,
            memory: Deque::new(),
            injected: heapless::Vec::new(),
            plant_watch: plant_supervision::PlantWatch::default(),
        };
        d.vendor_power_on();
        d.reload_factor_group();
        d.ip.reset(interpolation_period(&d.od));
        d.axis.hold_brake(d.settings.brake_fitted);
        d.place_hard_stops();
        d.mode = d
            .read(d.hot.mode_display)
            .clamp(i8::MIN as i64, i8::MAX as i64) as i8;
        if d.settings.ethercat {
            // CiA 402 6502h: the modes reached over EtherCAT only (CMMP-AS: bit 7 CSP).
            let modes = d.od.get_unsigned(0x6502, 0).unwrap_or(0)
                | u64::from(d.personality.supported_drive_modes(true));
            let _ = d.od.set_value(0x6502, 0, Value::Unsigned(modes));
        }
        d.dc.initialised();
        d.publish();
        d
    }

    pub fn od(&self) -> &ObjectDictionary<S> {
        &self.od
    }
    pub fn od_mut(&mut self) -> &mut ObjectDictionary<S> {
        &mut self.od
    }
    /// A SYNC at `now` (a CANopen SYNC, an EtherCAT SYNC0 event, or in EtherCAT free run the
    /// frame): the time base of interpolated position mode. Step the drive to `now` first.
    pub fn sync(&mut self, now: Instant) {
        let change = self.ip.sync(now);
        self.ip_sync_change(change);
    }

    /// The interpolation period in force (60C2h as read at power-on or the last reset): the
    /// cycle a SYNC or SYNC0 grid must keep.
    pub fn interpolation_period(&self) -> Duration {
        self.ip.period()
    }

    /// Interpolated position: synchronised to the SYNC grid (6061h may show 7).
    pub fn ip_synchronised(&self) -> bool {
        self.ip.is_synchronised()
    }

    fn ip_sync_change(&mut self, change: SyncChange) {
        if let SyncChange::Lost { while_active: true } = change {
            // CMMP-AS 34-1: the SYNC grid was lost while interpolating.
            self.raise_fault(Fault::FieldbusSyncError);
        }
    }

    /// The error codes raised and not yet acknowledged, oldest first.
    pub fn errors(&self) -> &[u16] {
        &self.faults
    }

    pub fn state(&self) -> State {
        self.dc.state()
    }
    pub fn axis(&self) -> &Axis {
        &self.axis
    }
    pub fn axis_mut(&mut self) -> &mut Axis {
        &mut self.axis
    }
    pub fn factor_group(&self) -> &FactorGroup {
        &self.fg
    }
    /// What the axis is asked for this cycle.
    pub fn demand(&self) -> Demand {
        self.demand
    }
    pub fn take_event(&mut self) -> Option<DriveEvent> {
        self.events.pop_front()
    }

    /// The dictionary's values changed behind the drive's back (restore, reload after a
    /// reset): re-read what the drive caches.
    pub fn reload(&mut self) {
        publish_supply(&mut self.od, self.dc_link_mv);
        self.reload_factor_group();
        // 60C2h takes effect after save and reset (CMMP-AS §7.4.1).
        self.ip.reset(interpolation_period(&self.od));
        self.params_dirty = true;
        // The reaction table is not part of the stored set: defaults again.
        self.reactions = Reactions::default();
        self.vendor_power_on();
    }

    /// What the personality sets at power-on and after a reload.
    fn vendor_power_on(&mut self) {
        match self.personality.vendor {
            Vendor::CmmpAs => {
                self.following_error_reaction();
                self.cmmp_power_on();
            }
            Vendor::Nanotec => self.nanotec_power_on(),
            Vendor::Kinco => {
                self.kinco_power_on();
                self.kinco_panel_power_on();
            }
        }
    }

    pub(crate) fn reload_factor_group(&mut self) {
        if self.personality.capabilities.feed_constant {
            self.fg = self.feed_constant_factor_group();
            return;
        }
        if self.personality.vendor == Vendor::Kinco {
            // Kinco: fixed units (personality/kinco_drive.rs), 607Eh the direction.
            let mut fg = personality::kinco_drive::FACTOR_GROUP;
            let invert = self.od.get_unsigned(0x607E, 0).unwrap_or(0) != 0;
            fg.polarity = if invert { 0xC0 } else { 0 };
            self.fg = fg;
            return;
        }
        let ratio = |od: &ObjectDictionary<S>, index: u16, dflt: Ratio| Ratio {
            numerator: od
                .get_unsigned(index, 1)
                .map(|v| v as u32)
                .unwrap_or(dflt.numerator),
            divisor: od
                .get_unsigned(index, 2)
                .map(|v| v as u32)
                .unwrap_or(dflt.divisor),
        };
        let d = FactorGroup::default();
        let fg = FactorGroup {
            position: ratio(&self.od, 0x6093, d.position),
            velocity: ratio(&self.od, 0x6094, d.velocity),
            acceleration: ratio(&self.od, 0x6097, d.acceleration),
            polarity: self.od.get_unsigned(0x607E, 0).unwrap_or(0) as u8,
        };
        // A stored set that breaks the rules falls back to the defaults rather than dividing
        // by zero.
        self.fg = if fg.validate().is_ok() { fg } else { d };
    }

    /// Raises a fault from outside (fault injection, a test): EMCY, fault reaction (quick-stop
    /// ramp), FAULT.
    /// The cause stays until [`Drive::clear_fault`].
    pub fn inject_fault(&mut self, code: u16, register: u8) {
        if !self.causes.contains(&code) {
            let _ = self.causes.push(code);
        }
        self.raise(code, register, false);
    }

    /// Removes an injected fault's cause; a fault reset then acknowledges the error.
    pub fn clear_fault(&mut self, code: u16) {
        if let Some(i) = self.causes.iter().position(|c| *c == code) {
            self.causes.remove(i);
        }
        if let Some(m) = messages::by_code(code) {
            self.end_warning(m.number);
        }
        self.clear_notice(code);
    }

    /// Reports the error `code` with the reaction the personality's error management gives
    /// it (CMMP-AS: 2100h; Nanotec: the reaction table of §7.1); `critical` errors without a
    /// reaction of their own switch the output stage off at once.
    pub(crate) fn raise(&mut self, code: u16, register: u8, critical: bool) {
        self.raise_with_info(code, register, critical, 0);
    }

    /// [`Drive::raise`] with the message's additional information for the diagnostic
    /// memory.
    pub(crate) fn raise_with_info(&mut self, code: u16, register: u8, critical: bool, info: u32) {
        let reaction = match self.personality.vendor {
            Vendor::CmmpAs => self.cmmp_error_reaction(code, critical, info),
            Vendor::Nanotec => self.nanotec_error_reaction(code, critical),
            Vendor::Kinco => self.kinco_error_reaction(code),
        };
        self.report_error(code, register, reaction);
    }

    /// Raises the personality's error for `fault`; `false` where the drive has none.
    pub(crate) fn raise_fault(&mut self, fault: Fault) -> bool {
        match self.personality.error(fault) {
            Some(e) => {
                self.raise(e.code, e.register, e.critical);
                true
            }
            None => false,
        }
    }

    /// The error's EMCY and the device control's fault reaction.
    pub(crate) fn report_error(&mut self, code: u16, register: u8, reaction: ErrorReaction) {
        match reaction {
            ErrorReaction::Ignore => return,
            ErrorReaction::MessageOnly | ErrorReaction::QuickStopNoFault => {
                if !self.notices.contains(&code) && self.notices.push(code).is_ok() {
                    self.push_event(DriveEvent::Error { code, register });
                }
                if reaction == ErrorReaction::QuickStopNoFault {
                    let r = self.dc.quick_stop();
                    self.react(r);
                }
                return;
            }
            _ => {}
        }
        if !self.faults.contains(&code) {
            let _ = self.faults.push(code);
            self.push_event(DriveEvent::Error { code, register });
        }
        let r = match reaction {
            ErrorReaction::OutputStageOff => self.dc.fault_immediate(),
            ErrorReaction::BrakeMaxCurrent => {
                // Decision: "brake with maximum current" uses the emergency ramp 6510h:15
                // (the limit-switch deceleration, 2 000 000 min⁻¹/s by default), which the
                // current limit caps.
                self.limit_stop = true;
                self.dc.fault()
            }
            _ => self.dc.fault(),
        };
        self.react(r);
    }

    /// A message-only error (EMCY without a fault) is over: the EMCY "error reset".
    pub(crate) fn clear_notice(&mut self, code: u16) {
        if let Some(i) = self.notices.iter().position(|c| *c == code) {
            self.notices.remove(i);
            self.push_event(DriveEvent::Cleared { code });
        }
    }

    /// The highest speed a profile may ask for, increments/s: 6080h max_motor_speed where
    /// the drive has it, else the controller's limit.
    pub(crate) fn max_motor_speed(&self) -> f64 {
        let rpm = match self.param(0x6080, 0) {
            Some(_) => self.value(0x6080, 0).max(0) as f64,
            None => f64::from(self.axis.params().max_motor_speed_rpm),
        };
        rpm * 4096.0 * INC_S_PER_VEL
    }

    /// What the 7-segment display shows (App. B): the oldest error, else the warning, else
    /// "H" for safe standstill, else "A" while 6510h:C0 commissioning_state is 0.
    pub fn display(&self) -> Display {
        let error = self
            .faults
            .iter()
            .find_map(|c| self.message_of(*c))
            .map(|m| m.number);
        let warning = self.warning.filter(|(_, a)| *a).map(|(n, _)| n);
        let commissioning = self.od.get_unsigned(0x6510, 0xC0).unwrap_or(0) as u32;
        Display::select(error, warning, self.safe_standstill, commissioning)
    }

    /// The diagnostic memory, oldest entry first.
    pub fn diagnostic_memory(&self) -> impl Iterator<Item = &MemoryEntry> {
        self.memory.iter()
    }

    /// The supply: the DC-link voltage in mV (`None`: the nominal 6510h:33). It shows in
    /// 6510h:34 and 6079h, limits the current controller's output voltage, and below
    /// 6510h:36 with 6510h:37 = 1 it is error 02-0.
    pub fn set_dc_link_voltage(&mut self, mv: Option<u32>) {
        self.dc_link_mv = mv;
        publish_supply(&mut self.od, mv);
        self.params_dirty = true;
    }

    /// CMMP-AS 02-0 DC-link undervoltage (6510h:36 min_dc_link_circuit_voltage, 6510h:37
    /// enable_dc_link_undervoltage_error); the cause stays while the voltage is low.
    fn supervise_dc_link(&mut self) {
        let Some(e) = self.personality.error(Fault::DcLinkUndervoltage) else {
            return;
        };
        let enabled = self.value(0x6510, 0x37) == 1;
        let min = self.value(0x6510, 0x36);
        let low = self.dc_link_mv.filter(|mv| enabled && i64::from(*mv) < min);
        if let Some(mv) = low {
            if !self.causes.contains(&e.code) {
                let _ = self.causes.push(e.code);
            }
            let info = messages::undervoltage_info(self.dc.state() as u16, mv);
            self.raise_with_info(e.code, e.register, e.critical, info);
        } else if let Some(i) = self.causes.iter().position(|c| *c == e.code) {
            if !self.injected_code(e.code) {
                self.causes.remove(i);
            }
        }
    }

    /// CMMP-AS 31-0 I²t motor (§5.5, 6510h:38 iit_error_enable = 1): the motor I²t at 100 %
    /// is an error, not only the limitation to the rated current; the cause stays until the
    /// I²t has fallen below the release threshold.
    fn supervise_i2t(&mut self) {
        let over = self.value(0x6510, 0x38) == 1 && self.axis.i2t_limit_active();
        if let Some(e) = self.personality.error(Fault::I2tMotor) {
            self.cause(e.code, over, e.register);
        }
    }

    /// Keeps `code` as a cause while `present` and raises it (with `register`); a cause that
    /// went lets the fault reset acknowledge the error.
    pub(crate) fn cause(&mut self, code: u16, present: bool, register: u8) {
        let at = self.causes.iter().position(|c| *c == code);
        match (present, at) {
            (true, None) => {
                let _ = self.causes.push(code);
                self.raise(code, register, false);
            }
            (true, Some(_)) => self.raise(code, register, false),
            // A message raised by its number stays until it is cleared.
            (false, Some(_)) if self.injected_code(code) => {}
            (false, Some(i)) => {
                self.causes.remove(i);
            }
            (false, None) => {}
        }
    }

    /// The safety module (CAMC-G-S1) reports safe standstill or not: 2000h:01 bit 8 and
    /// the "H" of the display.
    pub fn set_safe_standstill(&mut self, on: bool) {
        self.safe_standstill = on;
    }

    pub(crate) fn push_event(&mut self, e: DriveEvent) {
        if self.events.is_full() {
            self.events.pop_front();
        }
        let _ = self.events.push_back(e);
    }

    #[inline(always)]
    pub(crate) fn read(&self, e: Option<&'static Entry>) -> i64 {
        e.map(|e| decode_i64(e, self.od.raw(e))).unwrap_or(0)
    }

    #[inline]
    pub(crate) fn value(&self, index: u16, sub: u8) -> i64 {
        if let Some(pos) = param_slot(index, sub) {
            return self.read(self.params.get(pos).copied().flatten());
        }
        match self.od.value(index, sub) {
            Some(Value::Signed(s)) => s,
            Some(Value::Unsigned(u)) => u as i64,
            _ => 0,
        }
    }

    /// An INTEGER32 set-point with the other sign (saturating at −2³¹).
    pub(crate) fn negate_stored(&mut self, index: u16) {
        if let Some(Value::Signed(v)) = self.od.value(index, 0) {
            let _ = self.od.set_value(
                index,
                0,
                Value::Signed(v.saturating_neg().min(i64::from(i32::MAX))),
            );
        }
    }

    /// A [`PARAMS`] entry.
    #[inline]
    pub(crate) fn param(&self, index: u16, sub: u8) -> Option<&'static Entry> {
        let pos = param_slot(index, sub)?;
        self.params.get(pos).copied().flatten()
    }

    pub(crate) fn store(&mut self, e: Option<&'static Entry>, v: i64) {
        if let Some(e) = e {
            let b = v.to_le_bytes();
            self.od.store(e, b.get(..e.capacity as usize).unwrap_or(&b));
        }
    }

    /// Runs every control cycle due up to `now`; returns when the next one is due.
    pub fn step(&mut self, now: Instant) -> Option<Instant> {
        let mut next = *self.next_cycle.get_or_insert(now);
        while next <= now {
            self.now = next;
            let every = u64::from(self.logic_every);
            // A mask where it can (4 by default): a 64-bit division per cycle is a tenth of
            // the cycle's budget.
            let due = if every.is_power_of_two() {
                self.cycles & (every - 1) == 0
            } else {
                self.cycles.is_multiple_of(every)
            };
            if due {
                self.logic();
            }
            self.plant_step();
            self.cycles += 1;
            next = next + self.cycle;
        }
        self.next_cycle = Some(next);
        Some(next)
    }

    /// One position-loop cycle of device logic: controlword, state machine, mode, windows,
    /// statusword and actual values.
    fn logic(&mut self) {
        let dt = self.cycle.as_secs_f64() * f64::from(self.logic_every);
        if self.params_dirty {
            self.params_dirty = false;
            let params = match self.personality.vendor {
                Vendor::Kinco => self.kinco_control_params(),
                _ => control_params(&self.od),
            };
            self.axis.set_params(params);
        }
        if self.personality.vendor == Vendor::Kinco {
            // The DIN functions own the controlword and the mode (Kinco L1287).
            self.kinco_din_cycle();
            self.kinco_panel_cycle();
        }
        self.stepper_mode();
        self.supervise_dc_link();
        self.supervise_i2t();
        self.supervise_plant(dt);
        // Device control.
        let cw = Controlword(self.read(self.hot.controlword) as u16);
        let fault = !self.causes.is_empty();
        // Transition 2 needs both hardware enables (DIN4, DIN5).
        let enables = match self.personality.vendor {
            Vendor::Kinco => self.kinco_pre_enable(),
            _ => self.input_levels(self.plant_position()).enables(),
        };
        let before = self.dc.state();
        // A fault-reset pulse shorter than a cycle still counts (latched at the write); so
        // does a rising edge written within one cycle after the bit was seen set (0080h,
        // 0000h, 0080h between two steps): the device control sees the low level first.
        if self.cw_rising.contains(Controlword::FAULT_RESET) {
            let other = if cw.contains(Controlword::FAULT_RESET) {
                cw.difference(Controlword::FAULT_RESET)
            } else {
                cw | Controlword::FAULT_RESET
            };
            let _ = self.dc.controlword(other.bits(), fault, enables);
        }
        let reaction = self.dc.controlword(cw.bits(), fault, enables);
        self.react(reaction);
        if before == State::Fault && self.dc.state() == State::SwitchOnDisabled {
            // Transition 15: the errors are acknowledged (CMMP-AS Tab. 3.8 transition 4).
            while let Some(code) = self.faults.pop() {
                self.push_event(DriveEvent::Cleared { code });
            }
        }
        self.halted = cw.contains(Controlword::HALT);
        // Mode change (6061h shows −1 meanwhile).
        if let Some((m, at)) = self.mode_pending {
            if self.now >= at {
                self.mode_pending = None;
                self.mode = m;
                self.setpoints.abort();
                self.resync_trajectory();
            }
        }
        self.motion(cw, dt);
        self.brake_timers();
        self.cw_rising = Controlword::EMPTY;
        self.publish();
    }

    fn react(&mut self, r: Reaction) {
        match r {
            Reaction::None => {}
            Reaction::Enable => {
                // Brake released with the output stage (CMMP-AS) or after the personality's
                // delay; the set-point follows after the brake delay (CMMP-AS §5.16).
                self.power_off_at = None;
                let delays = self.brake_delays();
                if delays.release.is_zero() {
                    self.brake_engaged = false;
                    self.axis.hold_brake(false);
                } else {
                    self.brake_release_at = Some(self.now + delays.release);
                }
                self.release_at = Some(self.now + delays.motion);
                self.resync_trajectory();
                self.stopping = false;
                self.limit_stop = false;
            }
            Reaction::Coast => {
                // Brake first, output stage off after the brake delay.
                self.brake_release_at = None;
                self.setpoints.abort();
                self.stopping = false;
                if self.settings.brake_fitted
                    && !self.brake_engaged
                    && !matches!(self.demand, Demand::Off)
                {
                    self.brake_engaged = true;
                    self.axis.hold_brake(true);
                    self.power_off_at = Some(self.now + self.brake_delays().engage);
                } else {
                    self.power_off();
                }
            }
            Reaction::QuickStopRamp => {
                self.setpoints.abort();
                self.stopping = true;
            }
        }
    }

    /// The personality's brake timing: CMMP-AS §5.16 one delay 6510h:18 (brake open at once,
    /// the set-point after it; output stage off after it); Nanotec §5.8 2007h:01 power on →
    /// brake off, :02 brake off → operational, :03 brake on → power off.
    fn brake_delays(&self) -> BrakeDelays {
        let ms = |i: u16, s: u8| Duration::from_millis(self.value(i, s).max(0) as u64);
        match self.personality.vendor {
            Vendor::CmmpAs => BrakeDelays {
                release: Duration::ZERO,
                motion: ms(0x6510, 0x18),
                engage: ms(0x6510, 0x18),
            },
            Vendor::Nanotec => BrakeDelays {
                release: ms(0x2007, 1),
                motion: ms(0x2007, 1) + ms(0x2007, 2),
                engage: ms(0x2007, 3),
            },
            // Kinco 6410h:12 Brake_Delay: "with a brake the drive keeps running until the
            // brake is closed"; Decision: the set-point waits as long after the enable.
            // Without a brake (6410h:17 bit 0 clear) nothing waits.
            Vendor::Kinco if !self.settings.brake_fitted => BrakeDelays {
                release: Duration::ZERO,
                motion: Duration::ZERO,
                engage: Duration::ZERO,
            },
            Vendor::Kinco => BrakeDelays {
                release: Duration::ZERO,
                motion: ms(0x6410, 0x12),
                engage: ms(0x6410, 0x12),
            },
        }
    }

    /// A brake delay is running (Nanotec §5.8: mode changes wait for it).
    pub(crate) fn brake_wait(&self) -> bool {
        self.power_off_at.is_some() || self.release_at.is_some_and(|t| self.now < t)
    }

    pub(crate) fn power_off(&mut self) {
        self.power_off_at = None;
        self.demand = Demand::Off;
        if self.settings.brake_fitted {
            self.brake_engaged = true;
            self.axis.hold_brake(true);
        }
    }

    fn brake_timers(&mut self) {
        if self.power_off_at.is_some_and(|t| self.now >= t) {
            self.power_off();
        }
        if self.brake_release_at.is_some_and(|t| self.now >= t) {
            self.brake_release_at = None;
            self.brake_engaged = false;
        }
        // CMMP-AS §5.13/5.16: with 60FEh:02 bit 0 set the host works the brake through
        // 60FEh:01 bit 0 (1 = brake applied, CiA 402 "set brake"); otherwise it follows the
        // output stage.
        if self.settings.brake_fitted {
            let manual = self.value(0x60FE, 2) & 1 != 0;
            let engaged = if manual {
                self.value(0x60FE, 1) & 1 != 0
            } else {
                self.brake_engaged
            };
            if self.axis.motor().brake() != engaged {
                self.axis.hold_brake(engaged);
            }
            // Without host control 60FEh:01 bit 0 reads the brake's state ("depends on the
            // state of the brake", L4203–4215).
            let data = self.value(0x60FE, 1);
            let shown = (data & !1) | i64::from(engaged);
            if !manual && shown != data && self.personality.capabilities.brake_in_60fe {
                self.store(self.param(0x60FE, 1), shown);
            }
        }
    }

    pub(crate) fn actual_internal(&self) -> i64 {
        self.plant_position() + self.position_offset
    }

    /// The set-point follows the actual position (output stage off, mode change, enable).
    pub(crate) fn resync_trajectory(&mut self) {
        self.traj = Trajectory {
            position: self.actual_internal() as f64,
            velocity: f64::from(self.plant_velocity_rpm()) / RPM_PER_INC_S,
        };
        self.velocity_set = self.traj.velocity;
        self.demand_position = self.traj.position;
        self.smoother.reset(self.traj.position, 1);
    }

    pub(crate) fn accel(&self, index: u16) -> f64 {
        let user = self.value(index, 0).clamp(0, u32::MAX as i64) as u32;
        self.ramp(self.fg.acceleration_to_internal(user) as f64 * INC_S2_PER_ACC)
    }

    pub(crate) fn position_demand(&mut self, velocity_ff: f64) {
        let previous = self.demand_position;
        self.demand_position = self.smoother.push(self.traj.position);
        // With smoothing the feed-forward is the smoothed set-point's own speed.
        let ff = if self.smoother.window() > 1 {
            let dt = self.cycle.as_secs_f64() * f64::from(self.logic_every);
            (self.demand_position - previous) / dt
        } else {
            velocity_ff
        };
        self.demand = Demand::Position {
            increments: crate::rounding::round(self.demand_position) as i64 - self.position_offset,
            velocity_ff_rpm: (ff * RPM_PER_INC_S) as f32,
        };
    }

    fn motion(&mut self, cw: Controlword, dt: f64) {
        let state = self.dc.state();
        let change = self.ip.check(self.now);
        self.ip_sync_change(change);
        if self.ip.is_active()
            && (state != State::OperationEnabled || self.mode != mode::INTERPOLATED_POSITION)
        {
            // CMMP-AS §7.4.3: an error ends interpolation; it needs a new synchronisation.
            self.ip.interrupt();
        }
        if !matches!(self.homing, HomingRun::Idle)
            && (state != State::OperationEnabled || self.mode != mode::HOMING)
        {
            // Homing ends with the enable or the mode (B.3 11-1 "enable removed"); the bit
            // only: an error that caused it has its own message.
            self.homing = HomingRun::Idle;
            self.homing_error = true;
        }
        if self.mode == mode::HOMING
            && self.cw_rising.contains(Controlword::HOMING_START)
            && !matches!(
                state,
                State::OperationEnabled | State::Fault | State::FaultReactionActive
            )
        {
            // B.3 11-0: homing started without the controller enable.
            self.homing_failed(HomingError::Start);
            return;
        }
        if !state.power_enabled() {
            if self.power_off_at.is_none() {
                self.demand = Demand::Off;
            }
            self.resync_trajectory();
            self.target_reached = false;
            return;
        }
        if self.release_at.is_some_and(|t| self.now < t) {
            // Brake still opening: hold.
            self.position_demand(0.0);
            return;
        }
        self.release_at = None;
        if self.stopping || matches!(state, State::QuickStopActive | State::FaultReactionActive) {
            // Quick stop / disable operation / fault reaction: 6085h ramp, then the state
            // machine moves on (transitions 12, 14) or holds (SWITCHED ON).
            let decel = if self.limit_stop {
                self.accel2(0x6510, 0x15)
            } else if let Some(ramp) = self.vl_ramp(0x604A).filter(|_| self.mode == mode::VELOCITY)
            {
                // VL brakes with its own quick-stop ramp 604Ah (Nanotec §4.2).
                ramp
            } else if self.personality.capabilities.ip_abrupt_quick_stop
                && self.mode == mode::INTERPOLATED_POSITION
            {
                // Nanotec §5.4: in IP a quick stop stops the motor abruptly, without a ramp.
                ABRUPT_STOP
            } else {
                self.accel(0x6085)
            };
            let stopped = self.traj.step_stop(decel, dt);
            self.position_demand(self.traj.velocity);
            if stopped {
                self.stopping = false;
                self.limit_stop = false;
                let r = self.dc.stopped();
                self.react(r);
            }
            return;
        }
        if state != State::OperationEnabled || self.mode_pending.is_some() {
            // SWITCHED ON, or a mode change in progress: hold the position.
            let decel = self.accel(0x6084);
            self.traj.step_stop(decel, dt);
            self.position_demand(self.traj.velocity);
            return;
        }
        if self.mode != mode::HOMING {
            self.supervise_limit_switches();
            if self.dc.state() != State::OperationEnabled {
                return;
            }
        }
        if self.personality.vendor == Vendor::Kinco {
            if self.kinco_tuning_active() {
                self.kinco_tuning_step();
                return;
            }
            match self.mode {
                mode::PROFILE_POSITION => self.kinco_profile_position(cw, dt),
                mode::PROFILE_VELOCITY => self.kinco_velocity(true, dt),
                -3 => self.kinco_velocity(false, dt),
                -4 => self.kinco_pulse_mode(dt),
                mode::PROFILE_TORQUE => self.kinco_torque(dt),
                mode::HOMING => self.homing(cw, dt),
                _ => self.hold(dt),
            }
            self.kinco_velocity_feed_forward();
            return;
        }
        match self.mode {
            mode::PROFILE_POSITION => self.profile_position(cw, dt),
            mode::PROFILE_VELOCITY => self.profile_velocity(dt),
            mode::VELOCITY => self.velocity_mode(dt),
            mode::PROFILE_TORQUE if self.personality.vendor == Vendor::Nanotec => {
                self.nanotec_torque(dt)
            }
            mode::PROFILE_TORQUE => self.profile_torque(dt),
            mode::HOMING => self.homing(cw, dt),
            mode::CYCLIC_SYNCHRONOUS_POSITION => self.cyclic_synchronous_position(dt),
            mode::INTERPOLATED_POSITION => self.interpolated_position(cw, dt),
            m if m < 0 && self.personality.vendor == Vendor::Nanotec => {
                self.nanotec_test_run(cw, dt)
            }
            _ => self.hold(dt),
        }
    }

    /// No mode that moves: the set-point brakes with 6084h and stands.
    pub(crate) fn hold(&mut self, dt: f64) {
        let decel = self.accel(0x6084);
        self.traj.step_stop(decel, dt);
        self.position_demand(self.traj.velocity);
    }

    pub(crate) fn profile_position(&mut self, cw: Controlword, dt: f64) {
        let bit4 = cw.contains(Controlword::NEW_SET_POINT)
            || self.cw_rising.contains(Controlword::NEW_SET_POINT);
        let demand = self.traj.position;
        let fg = self.fg;
        let max_speed = self.max_motor_speed();
        let target_limits = self.personality.capabilities.pp_target_limits;
        let abrupt_zero = self.personality.capabilities.zero_ramp_is_abrupt;
        // Nanotec §5.1: range-limit wrap, software limits and relative overflow checked before
        // the set-point is taken; a refused one becomes a job that stays where it is.
        let checked = (bit4 && target_limits).then(|| self.check_target(cw));
        let get = |i: u16| self.value(i, 0);
        // Read the set-point only while bit 4 is high (a rising edge may be taking it).
        let req = bit4.then(|| {
            let user = get(0x607A).clamp(i32::MIN as i64, i32::MAX as i64) as i32;
            let (user, relative) = match checked {
                Some(Ok(absolute)) => (absolute, false),
                Some(Err(_)) => (0, true),
                None => (user, cw.contains(Controlword::RELATIVE)),
            };
            let target = fg.position_to_internal(user) as f64;
            let vel = |i| {
                fg.velocity_magnitude_to_internal(get(i).clamp(0, u32::MAX as i64) as u32) as f64
                    * INC_S_PER_VEL
            };
            let acc = |i| match fg.acceleration_to_internal(get(i).clamp(0, u32::MAX as i64) as u32)
            {
                0 if abrupt_zero => ABRUPT_STOP,
                a => a as f64 * INC_S2_PER_ACC,
            };
            Request {
                target,
                relative,
                immediately: cw.contains(Controlword::CHANGE_SET_IMMEDIATELY),
                job: Job {
                    target,
                    velocity: vel(0x6081).min(max_speed),
                    // Nanotec §5.1: 6082h is the start / stop speed of the ramp, not an
                    // end velocity; bit 9 decides whether a queued job follows at speed.
                    end_velocity: if target_limits { 0.0 } else { vel(0x6082) },
                    acceleration: acc(0x6083),
                    deceleration: acc(0x6084),
                },
            }
        });
        let request = move || {
            req.unwrap_or(Request {
                target: demand,
                relative: false,
                immediately: false,
                job: Job {
                    target: demand,
                    velocity: 0.0,
                    end_velocity: 0.0,
                    acceleration: 1.0,
                    deceleration: 1.0,
                },
            })
        };
        // While halted new set-points are still acknowledged but not run (CMMP-AS §6.1.3).
        let accepted = self.setpoints.update(bit4, demand, request);
        if let (true, Some(result)) = (accepted, checked) {
            self.target_taken(result, cw);
        }
        if accepted {
            self.target_reached = false;
            self.window_since = None;
            // 6086h = 2: jerk-free, the acceleration ramps over the window (a quarter of the
            // time to profile velocity, at most the buffer).
            let jerk_free = self.value(0x6086, 0) == 2;
            let window = match (jerk_free, self.setpoints.active) {
                (true, Some(job)) if self.traj.velocity == 0.0 => {
                    let t_acc = job.velocity / job.acceleration.max(1.0);
                    let dt = self.cycle.as_secs_f64() * f64::from(self.logic_every);
                    libm::round(t_acc * 0.5 / dt) as usize
                }
                _ => self.smoother.window(),
            };
            if window != self.smoother.window() && self.smoother.settled(self.traj.position) {
                self.smoother.reset(self.demand_position, window);
            }
        }
        if self.halted {
            // Halt: brake with the profile deceleration; the job is dropped, and target
            // reached is set once standing (CMMP-AS Tab. 6.5).
            let decel = self.accel(0x6084);
            let stopped = self.traj.step_stop(decel, dt);
            self.setpoints.abort();
            self.position_demand(self.traj.velocity);
            if stopped {
                self.target_reached = true;
            }
            return;
        }
        match self.setpoints.active {
            Some(job) => {
                let lim = Limits {
                    velocity: job.velocity.max(1.0),
                    acceleration: job.acceleration.max(1.0),
                    deceleration: job.deceleration.max(1.0),
                };
                let end = self.setpoints.end_velocity();
                if self.traj.step_to(job.target, end, lim, dt) {
                    self.setpoints.finished();
                }
                self.position_demand(self.traj.velocity);
            }
            None => {
                self.position_demand(0.0);
                // Target reached: generator done (smoothing included) and the actual position
                // inside the window for the window time (6067h, 6068h).
                let done = self.smoother.settled(self.traj.position);
                if let Some(target) = self.setpoints.last_target.filter(|_| done) {
                    let window = self.fg.position_magnitude_to_internal(
                        self.value(0x6067, 0).clamp(0, u32::MAX as i64) as u32,
                    );
                    let inside =
                        (self.actual_internal() - libm::round(target) as i64).abs() <= window;
                    let time = Duration::from_millis(self.value(0x6068, 0).max(0) as u64);
                    if inside {
                        let since = *self.window_since.get_or_insert(self.now);
                        if self.now.saturating_since(since) >= time {
                            self.target_reached = true;
                        }
                    } else {
                        self.window_since = None;
                        self.target_reached = false;
                    }
                }
            }
        }
    }

    /// Moves the velocity set-point towards `target` (increments/s), along the ramp
    /// `(acceleration, deceleration)` where one is given, and makes it the cycle's demand. The
    /// position set-point follows the actual position at the set-point's speed, so a quick
    /// stop brakes from there.
    pub(crate) fn command_velocity(&mut self, target: f64, ramp: Option<(f64, f64)>, dt: f64) {
        self.velocity_set = match ramp {
            Some((acc, dec)) => {
                let mut t = Trajectory {
                    position: 0.0,
                    velocity: self.velocity_set,
                };
                t.step_velocity(target, acc, dec, dt);
                t.velocity
            }
            None => target,
        };
        self.traj = Trajectory {
            position: self.actual_internal() as f64,
            velocity: self.velocity_set,
        };
        self.demand_position = self.traj.position;
        self.demand = Demand::Velocity {
            rpm: (self.velocity_set * RPM_PER_INC_S) as f32,
        };
    }

    fn profile_velocity(&mut self, dt: f64) {
        let user = self
            .read(self.hot.target_velocity)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        let max = self.value(0x6080, 0).max(0) as f64 * 4096.0 * INC_S_PER_VEL;
        let mut target =
            (self.fg.velocity_to_internal(user) as f64 * INC_S_PER_VEL).clamp(-max, max);
        if self.halted {
            target = 0.0; // Halt: to zero with the profile deceleration, resumed when cleared.
        }
        let ramps = self.value(0x2090, 1) != 0;
        if ramps || self.halted {
            // 2090h: separate ramps for positive and negative speed (6083h/6084h write them).
            let positive = self.velocity_set >= 0.0 && target >= 0.0;
            let ramp = if self.halted {
                (self.accel(0x6084), self.accel(0x6084))
            } else if positive {
                (self.accel2(0x2090, 2), self.accel2(0x2090, 3))
            } else {
                (self.accel2(0x2090, 4), self.accel2(0x2090, 5))
            };
            self.command_velocity(target, Some(ramp), dt);
        } else {
            self.command_velocity(target, None, dt);
        }
        // Target reached: |v − target| < 606Dh for 606Eh (CMMP-AS §7.5).
        let v_act = f64::from(self.plant_velocity_internal());
        let target_internal = target / INC_S_PER_VEL;
        let window = self
            .fg
            .velocity_magnitude_to_internal(self.value(0x606D, 0).max(0) as u32)
            as f64;
        let time = Duration::from_millis(self.value(0x606E, 0).max(0) as u64);
        if (v_act - target_internal).abs() < window {
            let since = *self.window_since.get_or_insert(self.now);
            self.target_reached = self.now.saturating_since(since) >= time;
        } else {
            self.window_since = None;
            self.target_reached = false;
        }
    }

    /// CSP (CiA 402 §13): the master sends a position every cycle; it is the set-point as it
    /// stands, with the speed between two set-points as feed-forward. The CMMP-AS runs the
    /// interpolator on the frame cycle (CMMP-AS §4: "the EtherCAT cycle equals the
    /// interpolator cycle"), so no further interpolation happens here.
    fn cyclic_synchronous_position(&mut self, dt: f64) {
        let user = self
            .value(0x607A, 0)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        let target = self.fg.position_to_internal(user) as f64;
        if target != self.traj.position {
            // The feed-forward is the speed between the last two set-points, over the time
            // they really came apart (the master's cycle, not ours).
            let elapsed = self
                .csp_changed_at
                .map(|t| self.now.saturating_since(t).as_secs_f64())
                .unwrap_or(dt)
                .max(dt);
            self.traj.velocity = (target - self.traj.position) / elapsed;
            self.traj.position = target;
            self.csp_changed_at = Some(self.now);
        } else if self
            .csp_changed_at
            .is_none_or(|t| self.now.saturating_since(t).as_secs_f64() > 4.0 * dt.max(0.001))
        {
            // Set-points stopped coming: standstill at the last one.
            self.traj.velocity = 0.0;
        }
        let v = self.traj.velocity;
        self.position_demand(v);
        self.target_reached = false;
    }

    /// Interpolated position (CMMP-AS §7.4): with enable_ip_mode (bit 4) on the SYNC grid
    /// the drive takes one set-point of 60C1h:01 per SYNC and moves linearly between them;
    /// without, it holds.
    fn interpolated_position(&mut self, cw: Controlword, dt: f64) {
        let enable = cw.contains(Controlword::ENABLE_IP_MODE);
        if enable && !self.ip.is_active() {
            if self.ip.is_synchronised() {
                // Nanotec §5.4: 60C1h:01 is the target 607Ah shares; what it holds is the
                // first set-point (the manual's warning: write the actual position first).
                let pending = self.personality.capabilities.ip_follows_sync.then(|| {
                    let user = self
                        .value(0x60C1, 1)
                        .clamp(i32::MIN as i64, i32::MAX as i64);
                    self.fg.position_to_internal(user as i32) as f64
                });
                self.ip.activate_with(self.traj.position, self.now, pending);
            } else if self.cw_rising.contains(Controlword::ENABLE_IP_MODE) {
                // CMMP-AS 34-0: activation without synchronisation.
                self.raise_fault(Fault::NoFieldbusSync);
                return;
            }
        } else if !enable && self.ip.is_active() {
            self.ip.deactivate();
        }
        if self.ip.is_engaged() {
            let (position, velocity) = self.ip.demand(self.now);
            self.traj.position = position;
            self.traj.velocity = velocity;
            self.position_demand(velocity);
        } else {
            let decel = self.accel(0x6084);
            self.traj.step_stop(decel, dt);
            self.position_demand(self.traj.velocity);
        }
        self.target_reached = false;
    }

    pub(crate) fn accel2(&self, index: u16, sub: u8) -> f64 {
        let user = self.value(index, sub).clamp(0, u32::MAX as i64) as u32;
        self.ramp(self.fg.acceleration_to_internal(user) as f64 * INC_S2_PER_ACC)
    }

    /// A ramp as the personality reads 0 (no motion, or no ramp: see
    /// [`personality::Capabilities::zero_ramp_is_abrupt`]).
    pub(crate) fn ramp(&self, increments_s2: f64) -> f64 {
        if increments_s2 == 0.0 && self.personality.capabilities.zero_ramp_is_abrupt {
            ABRUPT_STOP
        } else {
            increments_s2
        }
    }

    fn profile_torque(&mut self, dt: f64) {
        let max = self.value(0x6072, 0).max(0) as f64;
        let mut target = (self.read(self.hot.target_torque) as f64).clamp(-max, max);
        if self.halted {
            target = 0.0;
        }
        // 6087h: ‰ of rated torque per second (CMMP-AS §7.7).
        let slope = (self.value(0x6087, 0).max(0) as f64) * dt;
        let d = target - self.torque_set;
        self.torque_set += d.clamp(-slope, slope);
        self.target_reached = self.torque_set == target;
        self.traj = Trajectory {
            position: self.actual_internal() as f64,
            velocity: f64::from(self.plant_velocity_rpm()) / RPM_PER_INC_S,
        };
        self.demand_position = self.traj.position;
        let current = self
            .axis
            .params()
            .current_for_torque_permille(self.torque_set);
        self.demand = Demand::Torque {
            current_a: current as f32,
        };
    }

    /// Mechanical hard stops of the travel into the motor model.
    fn place_hard_stops(&mut self) {
        let t = self.settings.travel;
        let rad = self.axis.motor().rad_per_increment();
        self.axis.motor_mut().set_stops(
            t.negative_stop.map(|p| p as f64 * rad),
            t.positive_stop.map(|p| p as f64 * rad),
        );
        // The stepper plant has the same stops (a shaft angle, 65536 increments a turn).
        if let Some(s) = self.stepper.as_mut() {
            let rad = core::f64::consts::TAU / 65536.0;
            let stops = match (t.negative_stop, t.positive_stop) {
                (None, None) => None,
                (lo, hi) => Some((
                    lo.map_or(f64::MIN, |p| p as f64 * rad),
                    hi.map_or(f64::MAX, |p| p as f64 * rad),
                )),
            };
            s.motor.set_end_stops(stops);
        }
    }

    /// Outside homing a limit switch blocks motion towards it (CMMP-AS B.3 43-0/43-1): the
    /// error's fault reaction brakes with 6510h:15 limit_switch_deceleration (§5.14, "limit
    /// switch emergency stop ramp"); motion away stays possible after the fault reset.
    fn supervise_limit_switches(&mut self) {
        let inputs = self.switch_inputs(self.plant_position());
        let v = self.traj.velocity;
        let fault = if inputs.negative_limit && v < 0.0 {
            Fault::LimitSwitchNegative
        } else if inputs.positive_limit && v > 0.0 {
            Fault::LimitSwitchPositive
        } else {
            return;
        };
        if self.personality.error(fault).is_some() {
            self.limit_stop = true;
            self.raise_fault(fault);
        }
    }

    /// The input levels at `position`: the simulated wiring (travel switches on DIN6, DIN7,
    /// DIN9, enables on DIN4/DIN5) with the forced inputs over it.
    fn input_levels(&self, position: i64) -> Levels {
        Levels::wired(
            self.settings.travel.inputs(position),
            self.settings.enables_present,
        )
        .forced(self.forced_mask, self.forced_levels)
    }

    fn switch_config(&self) -> SwitchConfig {
        if !self.personality.capabilities.switch_polarity_objects {
            // Nanotec §5.2: the methods name the switch type themselves (19/21 normally
            // closed, 20/22 normally open); the simulated switches are read as they are.
            return SwitchConfig::from_objects(1, 0, 0, 1);
        }
        SwitchConfig::from_objects(
            self.value(0x6510, 0x11),
            self.value(0x6510, 0x12),
            self.value(0x6510, 0x13),
            self.value(0x6510, 0x14),
        )
    }

    /// The switches as the drive reads them (CMMP-AS §5.14): 6510h:11 / :14 = 0 (normally
    /// closed) against the normally open switches of the simulation reads them inverted, and
    /// 6510h:12 = 1 swaps the limit-switch inputs DIN6/DIN7 — a wiring set-up the homing
    /// then trips over, as on the real drive.
    fn switch_inputs(&self, position: i64) -> Inputs {
        if self.personality.vendor == Vendor::Kinco {
            return self.kinco_switches(position);
        }
        self.switch_config().switches(self.input_levels(position))
    }

    /// Drives digital inputs from outside (a test, a fault injection): the DINs in `mask`
    /// (bit n = DINn) take the level in `levels`; the others follow the simulated wiring.
    /// Forcing DIN4 or DIN5 LOW removes a hardware enable (CMMP-AS 60FDh bit 3).
    pub fn force_inputs(&mut self, mask: u16, levels: u16) {
        self.forced_mask = mask;
        self.forced_levels = levels;
    }

    /// The output levels the host commands through 60FEh (CMMP-AS §5.13): bit 0 the holding
    /// brake (1 = applied), the other bits of 60FEh:01 where 60FEh:02 puts them under bus
    /// control. Outputs left to their 2420h function are not simulated and read 0.
    pub fn digital_outputs(&self) -> u32 {
        let data = self.value(0x60FE, 1) as u32;
        let mask = self.value(0x60FE, 2) as u32;
        (data & mask & !1) | u32::from(self.axis.motor().brake())
    }

    pub(crate) fn clear_target_reached(&mut self) {
        self.target_reached = false;
        self.window_since = None;
        let sw = self.read(self.hot.statusword) & !i64::from(Statusword::TARGET_REACHED.bits());
        self.store(self.hot.statusword, sw);
    }
}

/// The supply of the twin is ideal: the DC link sits at its nominal voltage (6510h:33 into
/// 6510h:34 and 6079h).
/// 60C2h as the interpolation period; the default 1 ms for a value outside the ranges.
fn interpolation_period<S: AsRef<[u8]> + AsMut<[u8]>>(od: &ObjectDictionary<S>) -> Duration {
    let units = od.get_unsigned(0x60C2, 1).unwrap_or(1);
    let index = match od.value(0x60C2, 2) {
        Some(Value::Signed(v)) => v,
        _ => -3,
    };
    match (u8::try_from(units), i8::try_from(index)) {
        (Ok(u), Ok(i)) => period_from_60c2(u, i).unwrap_or(DEFAULT_IP_PERIOD),
        _ => DEFAULT_IP_PERIOD,
    }
}

/// The interpolation period of the default 60C2h (1 × 10⁻³ s).
const DEFAULT_IP_PERIOD: Duration = Duration::from_millis(1);

fn publish_supply<S: AsRef<[u8]> + AsMut<[u8]>>(od: &mut ObjectDictionary<S>, mv: Option<u32>) {
    let nominal = mv
        .map(u64::from)
        .unwrap_or_else(|| od.get_unsigned(0x6510, 0x33).unwrap_or(325_000));
    let _ = od.set_value(0x6510, 0x34, Value::Unsigned(nominal));
    let _ = od.set_value(0x6079, 0, Value::Unsigned(nominal));
}

/// The controller parameters the dictionary holds (CMMP-AS §5.5–5.8).
pub fn control_params<S: AsRef<[u8]> + AsMut<[u8]>>(od: &ObjectDictionary<S>) -> ControlParams {
    let d = ControlParams::default();
    let u = |i: u16, s: u8, dflt: u64| od.get_unsigned(i, s).unwrap_or(dflt);
    ControlParams {
        motor_rated_current_ma: u(0x6075, 0, d.motor_rated_current_ma.into()) as u32,
        max_current_permille: u(0x6073, 0, d.max_current_permille.into()) as u16,
        iit_time_motor_ms: u(0x6410, 3, d.iit_time_motor_ms.into()) as u16,
        torque_control_gain: u(0x60F6, 1, d.torque_control_gain.into()) as u16,
        torque_control_time_us: u(0x60F6, 2, d.torque_control_time_us.into()) as u16,
        velocity_control_gain: u(0x60F9, 1, d.velocity_control_gain.into()) as u16,
        velocity_control_time_us: u(0x60F9, 2, d.velocity_control_time_us.into()) as u16,
        velocity_control_filter_time_us: u(0x60F9, 4, d.velocity_control_filter_time_us.into())
            as u16,
        velocity_display_filter_time_us: u(0x2073, 0, d.velocity_display_filter_time_us.into())
            as u32,
        position_control_gain: u(0x60FB, 1, d.position_control_gain.into()) as u16,
        position_control_time_us: u(0x60FB, 2, d.position_control_time_us.into()) as u16,
        position_control_v_max_rpm: u(0x60FB, 4, d.position_control_v_max_rpm.into()) as u32,
        position_error_tolerance_window: u(0x60FB, 5, d.position_error_tolerance_window.into())
            as u32,
        max_motor_speed_rpm: u(0x6080, 0, d.max_motor_speed_rpm.into()) as u32,
        limit_current_ma: None,
        nominal_dc_link_voltage_mv: u(0x6510, 0x33, d.nominal_dc_link_voltage_mv.into()) as u32,
        dc_link_voltage_mv: u(0x6510, 0x34, d.dc_link_voltage_mv.into()) as u32,
        peak_current_ma: u(0x6510, 0x41, d.peak_current_ma.into()) as u32,
        cycletime_current_us: u(0x6510, 0xB0, d.cycletime_current_us.into()) as u32,
        cycletime_velocity_us: u(0x6510, 0xB1, d.cycletime_velocity_us.into()) as u32,
        cycletime_position_us: u(0x6510, 0xB2, d.cycletime_position_us.into()) as u32,
        filters: d.filters,
    }
}

/// Objects whose change the controllers must see.
fn is_control_parameter(index: u16) -> bool {
    matches!(
        index,
        0x6073 | 0x6075 | 0x6410 | 0x60F6 | 0x60F9 | 0x60FB | 0x6080 | 0x2073 | 0x6510
    )
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> ObjectAccess for Drive<S> {
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode> {
        self.od.entry(index, sub)
    }

    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        self.od.read(index, sub, buf)
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.write_object(index, sub, data)
    }

    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.write_internal(index, sub, data)
    }
}

/// The brake's delays after the output stage goes on and before it goes off.
#[derive(Debug, Clone, Copy)]
struct BrakeDelays {
    /// Output stage on → brake open.
    release: Duration,
    /// Output stage on → the set-point released (operational).
    motion: Duration,
    /// Brake closed → output stage off.
    engage: Duration,
}

/// Where a homing run stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum HomingRun {
    Idle,
    Search(Search),
    /// Braking with 609Ah, then:
    Brake {
        then: Then,
    },
    /// 6510h:F0 bit 6: travelling to the zero position.
    ToZero,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Then {
    Attained,
    ToZero,
    /// Aborted: no bit.
    Nothing,
}
