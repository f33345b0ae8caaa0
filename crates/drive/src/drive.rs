//! The CiA 402 drive: device control, the operating modes and the simulated axis behind one
//! object dictionary. Protocol front ends reach it only through [`ObjectAccess`]; the runtime
//! steps it with [`Drive::step`] on the cell's clock. Stepping never allocates.

use core::time::Duration;

use heapless::Deque;
use od::{AbortCode, DataType, Entry, Instant, ObjectAccess, ObjectDictionary, Value};

use crate::axis::{Axis, Demand};
use crate::control::ControlParams;
use crate::controlword::{Controlword, ControlwordQueue};
use crate::device_control::{DeviceControl, Reaction, Rules, State};
use crate::digital_inputs::Levels;
use crate::factor_group::{FactorGroup, FactorObject, Ratio};
use crate::homing::{Command, HomingError, Search, Sense, Speed};
use crate::interpolated_position::{Interpolator, SyncChange};
use crate::motor::MotorData;
use crate::personality::{self, ErrorReaction, Fault, Personality, PowerStageObjects, Vendor};
use crate::profile_position::{Job, Request, SetPoints};
use crate::smoothing::Smoother;
use crate::statusword::Statusword;
use crate::trajectory::{Limits, Trajectory};
use crate::travel::{Inputs, TravelSettings};

mod brake;
pub mod diagnostics;
mod digital_io;
pub mod external_load;
mod faults;
mod feed_constant;
mod homing_run;
pub mod named_switches;
pub mod object_writes;
pub use object_writes::Hook;
mod plant;
pub mod plant_supervision;
mod position_modes;
mod power_supervision;
mod profile_torque;
mod profile_velocity;
pub(crate) mod publish;
pub mod refusal;
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

/// Settings of the simulation that no object holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveSettings {
    pub motor: MotorData,
    /// How long a mode change takes; 6061h reads −1 meanwhile (CMMP-AS §7.1 "may briefly
    /// show −1"). 0 switches at the next cycle and keeps showing the old mode until then
    /// (python-canopen's BaseNode402 cannot decode −1); a longer value reproduces slow drives.
    pub mode_change_time: Duration,
    /// The hardware enables transition 2 needs (on the vendor's wiring: the CMMP-AS's DIN4
    /// output stage and DIN5 controller enable).
    /// False also for a Nanotec that "accepts no motion commands" (NT-NODE-07: switch =
    /// node + 128 with no bit-rate code in 2005h; `drive::vendors::nanotec::rotary_switches`).
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

/// The CiA 402 objects the engine reads every cycle: looked up in the dictionary once, so a
/// cycle never searches the object table ([`Params`]).
const CIA402_PARAMS: &[(u16, u8)] = &[
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
];

// CiA 402's list holds no manufacturer object (checked when compiling): those are the
// vendors' (`Vendor`'s `CACHED_OBJECTS`).
const _: () = {
    let mut rest: &[(u16, u8)] = CIA402_PARAMS;
    while let [(index, _), tail @ ..] = rest {
        assert!(
            !manufacturer_object(*index),
            "a vendor's object in CIA402_PARAMS"
        );
        rest = tail;
    }
};

/// Slots of a drive's parameter cache: CiA 402's objects and its vendor's at most (below
/// half of [`PARAM_BUCKETS`], so a lookup probes one or two buckets).
pub(crate) const PARAM_SLOTS: usize = 127;

/// The parameters a drive of vendor `V` reads every cycle: [`CIA402_PARAMS`] and the
/// vendor's ([`Vendor`](crate::personality::Vendor)'s `CACHED_OBJECTS`), merged
/// when compiling, sorted by (index, sub) (for the reader, and the Kinco's `function_codes`
/// counts on the order of 2010h); [`param_slot`] finds a key through the hash table.
pub(crate) struct Params<V>(core::marker::PhantomData<V>);

impl<V: Vendor> Params<V> {
    /// How many keys the cache holds.
    pub(crate) const LEN: usize =
        crate::object_keys::merged_len(CIA402_PARAMS, &[V::CACHED_OBJECTS]);

    /// The keys, slot by slot (the first [`Params::LEN`]).
    pub(crate) const KEYS: [(u16, u8); PARAM_SLOTS] =
        crate::object_keys::merged(CIA402_PARAMS, &[V::CACHED_OBJECTS]);

    /// [`Params::KEYS`] as an open-addressing hash table built when compiling: each bucket
    /// holds a slot + 1 (0: empty), collisions go to the next bucket. The parameter reads of
    /// a cycle are not all inlined, and a binary search per read cost a third of the
    /// Nanotec's cycle.
    // Evaluated when compiling: `b` is masked to the table's size, `slot` stays below LEN,
    // which `merged` checked against PARAM_SLOTS.
    #[allow(clippy::indexing_slicing)]
    const HASH: [u8; PARAM_BUCKETS] = {
        assert!(Self::LEN <= PARAM_SLOTS && PARAM_SLOTS * 2 <= PARAM_BUCKETS);
        let mut table = [0u8; PARAM_BUCKETS];
        let mut slot = 0;
        while slot < Self::LEN {
            let mut b = param_bucket(param_key(Self::KEYS[slot].0, Self::KEYS[slot].1));
            while table[b] != 0 {
                b = (b + 1) & (PARAM_BUCKETS - 1);
            }
            table[b] = slot as u8 + 1;
            slot += 1;
        }
        table
    };
}

/// An object of the manufacturer area 2000h–5FFFh (CiA 301 §7.4.1) or the drive data 6510h,
/// which CiA 402 leaves to the manufacturer: the engine reads and writes it only for a vendor
/// that gives it a meaning ([`MANUFACTURER_OBJECTS`](Vendor#associatedconstant.MANUFACTURER_OBJECTS)).
pub(crate) const fn manufacturer_object(index: u16) -> bool {
    matches!(index, 0x2000..=0x5FFF | 0x6510)
}

/// `(index, sub)` as one key.
#[inline(always)]
const fn param_key(index: u16, sub: u8) -> u32 {
    (index as u32) << 8 | sub as u32
}

/// Buckets of [`Params`]'s hash table (a power of two, at least twice the table: a lookup probes one
/// or two buckets).
const PARAM_BUCKETS: usize = 256;

/// The home bucket of a key (Fibonacci hashing: the key times 2³²/φ, its top 8 bits).
#[inline(always)]
const fn param_bucket(key: u32) -> usize {
    (key.wrapping_mul(0x9E37_79B9) >> 24) as usize & (PARAM_BUCKETS - 1)
}

/// The slot of `(index, sub)` in the parameter cache of a drive of vendor `V` ([`Params`]).
#[inline(always)]
// `b` is masked to the hash table's size; a non-zero bucket holds a slot of KEYS plus one.
#[allow(clippy::indexing_slicing)]
pub(crate) const fn param_slot<V: Vendor>(index: u16, sub: u8) -> Option<usize> {
    let key = param_key(index, sub);
    let mut b = param_bucket(key);
    // Terminates: the table always has empty buckets.
    loop {
        let s = Params::<V>::HASH[b];
        if s == 0 {
            return None;
        }
        let (i, u) = Params::<V>::KEYS[s as usize - 1];
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
    pub(crate) target_velocity: Option<&'static Entry>,
    pub(crate) target_torque: Option<&'static Entry>,
    pub(crate) digital_inputs: Option<&'static Entry>,
    pub(crate) vl_velocity_actual: Option<&'static Entry>,
    /// [`Vendor`]'s `VELOCITY_DISPLAY_OBJECTS`'s value.
    pub(crate) velocity_actual_filtered: Option<&'static Entry>,
}

/// A CiA 402 drive over its object dictionary `S`, generic over its vendor `V`: the
/// behaviour where a vendor's manual departs from CiA 402 ([`Vendor`]) and that vendor's own
/// state.
pub struct Drive<S, V> {
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
    /// The entries of [`Params`]'s keys, slot by slot.
    pub(crate) params: [Option<&'static Entry>; PARAM_SLOTS],
    /// Current-controller cycle and how many of them make one logic (position-loop) cycle.
    pub(crate) cycle: Duration,
    pub(crate) logic_every: u32,
    pub(crate) next_cycle: Option<Instant>,
    pub(crate) cycles: u64,
    /// Counts up as [`Drive::step`] starts and as it returns: the dictionary is written only
    /// between steps (by a master, a console, a restore), never by the cycles themselves, so
    /// what a cycle read of it holds for the rest of the same step (a vendor's caches).
    pub(crate) step_epoch: u64,
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
    /// The encoder's speed as the drive measures it for its readouts (`publish.rs`).
    pub(crate) velocity_readout: crate::measured_velocity::MeasuredVelocity,
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
    /// Halt interrupted homing without an error (CiA 402); bit 4 must fall before a level
    /// starts it again.
    pub(crate) homing_interrupted: bool,
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
    /// Every confirmed controlword since the last logic cycle, for the state machine in order.
    pub(crate) cw_written: ControlwordQueue,
    pub(crate) brake_engaged: bool,
    /// The output stage goes off / the set-point is released when the brake delay ends.
    pub(crate) power_off_at: Option<Instant>,
    /// The brake opens then (a device file whose brake opens after the output stage,
    /// `[device.brake] release`).
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
    /// The values `publish` stored, slot by slot ([`publish::slot`]; a vendor's from
    /// [`publish::slot::VENDOR`]), so that an unchanged one is not stored again.
    pub(crate) published: crate::published::Published<i64, { publish::slot::COUNT }>,
    /// Digital inputs driven from outside ([`Drive::force_inputs`]).
    pub(crate) forced_mask: u16,
    pub(crate) forced_levels: u16,
    /// What only the vendor keeps beside the CiA 402 engine's state.
    pub(crate) vendor: V,
    /// Statusword bit 11 internal limit active, set by the mode (Nanotec: a clamped velocity,
    /// a wrapped or refused target).
    pub(crate) internal_limit: bool,
    /// The safety module reports safe standstill (2000h:01 bit 8).
    pub(crate) safe_standstill: bool,
    /// The DC-link voltage the supply gives, mV; `None`: the nominal 6510h:33.
    pub(crate) dc_link_mv: Option<u32>,
    /// Messages raised by their number from outside ([`Drive::raise_diagnostic`]), until
    /// cleared.
    pub(crate) injected: heapless::Vec<&'static od::Diagnostic, 16>,
    /// The motor's and the power stage's temperatures, the encoder between the shaft and
    /// the reading, and what the drive's supervision has found in them
    /// ([`plant_supervision`]).
    pub(crate) plant_watch: plant_supervision::PlantWatch,
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

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// A drive at power-on over `od` (holding defaults, commissioning and stored values),
    /// with the personality and the state its vendor gives the device file
    /// ([`for_device`](Vendor#tymethod.for_device)).
    pub fn new(od: ObjectDictionary<S>, settings: DriveSettings) -> Self {
        let (personality, vendor) = V::for_device(od.description());
        Self::with_vendor(od, settings, personality, vendor)
    }

    /// A drive at power-on over `od` with `personality` and the vendor's state `vendor`.
    pub fn with_vendor(
        mut od: ObjectDictionary<S>,
        settings: DriveSettings,
        personality: &'static Personality,
        vendor: V,
    ) -> Self {
        publish_supply::<S, V>(&mut od, None);
        let desc = od.description();
        let e = |i: u16, s| {
            if V::MANUFACTURER_OBJECTS || !manufacturer_object(i) {
                desc.entry(i, s)
            } else {
                None
            }
        };
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
            target_velocity: e(0x60FF, 0),
            target_torque: e(0x6071, 0),
            digital_inputs: e(0x60FD, 0),
            vl_velocity_actual: e(0x6044, 0),
            velocity_actual_filtered: V::VELOCITY_DISPLAY_OBJECTS
                .and_then(|o| e(o.value.0, o.value.1)),
        };
        let mut param_entries = [None; PARAM_SLOTS];
        let keys = Params::<V>::KEYS;
        for (slot, (i, s)) in param_entries
            .iter_mut()
            .zip(keys.iter().take(Params::<V>::LEN))
        {
            *slot = e(*i, *s);
        }
        let params = control_params_of::<S, V>(&od);
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
            step_epoch: 0,
            now: Instant::ZERO,
            position_offset: 0,
            mode: 0,
            mode_pending: None,
            traj: Trajectory::default(),
            smoother: Smoother::default(),
            demand_position: 0.0,
            velocity_readout: Default::default(),
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
            homing_interrupted: false,
            referenced: false,
            homing: HomingRun::Idle,
            homing_started: Instant::ZERO,
            homing_accelerating: false,
            homing_settle: None,
            homing_external: None,
            limit_stop: false,
            cw_rising: Controlword::EMPTY,
            last_cw: Controlword::EMPTY,
            cw_written: ControlwordQueue::default(),
            brake_engaged: true,
            power_off_at: None,
            brake_release_at: None,
            release_at: None,
            faults: heapless::Vec::new(),
            notices: heapless::Vec::new(),
            causes: heapless::Vec::new(),
            events: Deque::new(),
            params_dirty: false,
            published: Default::default(),
            forced_mask: 0,
            forced_levels: 0,
            vendor,
            internal_limit: false,
            safe_standstill: false,
            dc_link_mv: None,
            injected: heapless::Vec::new(),
            plant_watch: plant_supervision::PlantWatch::default(),
        };
        d.vendor_power_on();
        d.reload_factor_group();
        d.reset_interpolator();
        d.axis.hold_brake(d.settings.brake_fitted);
        d.place_hard_stops();
        d.mode = d
            .read(d.hot.mode_display)
            .clamp(i8::MIN as i64, i8::MAX as i64) as i8;
        if d.settings.ethercat {
            // CiA 402 6502h: the modes a personality reaches over EtherCAT only join those
            // the device file lists.
            let ethercat_only = d.personality.supported_drive_modes(true)
                & !d.personality.supported_drive_modes(false);
            let modes = d.od.get_unsigned(0x6502, 0).unwrap_or(0) | u64::from(ethercat_only);
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
            // The SYNC grid was lost while interpolating.
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
        publish_supply::<S, V>(&mut self.od, self.dc_link_mv);
        self.reload_factor_group();
        self.reset_interpolator();
        self.params_dirty = true;
        self.vendor_power_on();
    }

    /// The interpolator as at power-on: the period of 60C2h, the buffer open or locked as
    /// the vendor starts it.
    fn reset_interpolator(&mut self) {
        self.ip.reset(interpolation_period::<S, V>(&self.od));
        let open = V::ip_buffer_open_at_reset(self);
        self.ip.set_unlocked(open);
    }

    /// What the personality sets at power-on and after a reload.
    fn vendor_power_on(&mut self) {
        V::power_on(self);
    }

    pub(crate) fn reload_factor_group(&mut self) {
        if self.personality.capabilities.feed_constant {
            self.fg = self.feed_constant_factor_group();
            return;
        }
        if let Some(fg) = V::factor_group(self) {
            // A vendor's fixed units.
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
        self.fg = if fg.validate_within(V::factor_limit).is_ok() {
            fg
        } else {
            d
        };
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
        if let Some(pos) = param_slot::<V>(index, sub) {
            return self.read(self.params.get(pos).copied().flatten());
        }
        if !V::MANUFACTURER_OBJECTS && manufacturer_object(index) {
            return 0;
        }
        match self.od.value(index, sub) {
            Some(Value::Signed(s)) => s,
            Some(Value::Unsigned(u)) => u as i64,
            _ => 0,
        }
    }

    /// The value of an object the device file names for a purpose of the engine's (the
    /// brake's delays, the plant supervision's limits: [`od::BrakeTiming`],
    /// [`od::PlantSupervision`]); 0 where the dictionary has none. Read whatever the vendor:
    /// the file gives the object its meaning, so a manufacturer object is not left alone as
    /// [`Drive::value`] leaves it for a vendor without
    /// [`MANUFACTURER_OBJECTS`](Vendor#associatedconstant.MANUFACTURER_OBJECTS).
    pub(crate) fn described_value(&self, index: u16, sub: u8) -> i64 {
        if let Some(pos) = param_slot::<V>(index, sub) {
            return self.read(self.params.get(pos).copied().flatten());
        }
        match self.od.value(index, sub) {
            Some(Value::Signed(s)) => s,
            Some(Value::Unsigned(u)) => u as i64,
            _ => 0,
        }
    }

    /// [`Drive::value`] inlined at the call site, for the reads of every logic cycle: with a
    /// literal key of [`Params`] the slot is found when compiling and the read is a load and
    /// a decode; any other key takes `value`'s path. (`value` itself stays out of line: the
    /// parameter reads of the rarer paths would make the code grow.)
    #[inline(always)]
    pub(crate) fn cycle_value(&self, index: u16, sub: u8) -> i64 {
        match param_slot::<V>(index, sub) {
            Some(slot) => self.read(self.params.get(slot).copied().flatten()),
            None => self.value(index, sub),
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

    /// A [`Params`] entry.
    #[inline]
    pub(crate) fn param(&self, index: u16, sub: u8) -> Option<&'static Entry> {
        let pos = param_slot::<V>(index, sub)?;
        self.params.get(pos).copied().flatten()
    }

    pub(crate) fn store(&mut self, e: Option<&'static Entry>, v: i64) {
        if let Some(e) = e {
            let b = v.to_le_bytes();
            self.od.store(e, b.get(..e.capacity as usize).unwrap_or(&b));
        }
    }

    /// [`Drive::store`], not made where the entry already holds those bytes: a value a
    /// cycle writes outside `publish` that mostly stands, which would otherwise make every
    /// next `publish` store all its values again ([`crate::published::Published::begin`]).
    pub(crate) fn store_changed(&mut self, e: Option<&'static Entry>, v: i64) {
        if let Some(e) = e {
            let b = v.to_le_bytes();
            let bytes = b.get(..e.capacity as usize).unwrap_or(&b);
            if self.od.raw(e) != bytes {
                self.od.store(e, bytes);
            }
        }
    }

    /// [`Drive::store`] from `publish`, by publishing site `slot` ([`publish::slot`]): not
    /// made if the entry already holds `v` ([`crate::published::Published`]).
    #[inline(always)]
    pub(crate) fn publish_store(&mut self, slot: usize, e: Option<&'static Entry>, v: i64) {
        if !self.published.unchanged(slot, v) {
            self.store(e, v);
        }
    }

    /// Runs every control cycle due up to `now`; returns when the next one is due.
    pub fn step(&mut self, now: Instant) -> Option<Instant> {
        self.step_epoch = self.step_epoch.wrapping_add(1);
        let next = self.step_cycles(now, |_, _| Ok::<(), core::convert::Infallible>(()));
        self.step_epoch = self.step_epoch.wrapping_add(1);
        next.ok()
    }

    /// [`Drive::step`]'s cycles, `before_plant` called at the start of each plant cycle (an
    /// external load's step, [`Drive::step_with_load`]). Its error ends the step at that
    /// cycle, whose plant is not stepped; the next step resumes there.
    pub(crate) fn step_cycles<E>(
        &mut self,
        now: Instant,
        mut before_plant: impl FnMut(&mut Self, Instant) -> Result<(), E>,
    ) -> Result<Instant, E> {
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
            if let Err(e) = before_plant(self, next) {
                self.next_cycle = Some(next);
                return Err(e);
            }
            self.plant_step();
            self.cycles += 1;
            next = next + self.cycle;
        }
        self.next_cycle = Some(next);
        Ok(next)
    }

    /// One position-loop cycle of device logic: controlword, state machine, mode, windows,
    /// statusword and actual values.
    fn logic(&mut self) {
        let dt = self.cycle.as_secs_f64() * f64::from(self.logic_every);
        if self.params_dirty {
            self.params_dirty = false;
            let params = V::control_params(self);
            self.axis.set_params(params);
        }
        V::before_device_control(self);
        self.stepper_mode();
        self.supervise_dc_link();
        self.supervise_i2t();
        self.supervise_plant(dt);
        // Device control.
        let cw = Controlword(self.read(self.hot.controlword) as u16);
        let fault = !self.causes.is_empty();
        // Transition 2 needs the hardware enables.
        let enables = V::enables(self);
        if self.cw_written.is_empty() {
            self.device_control_sampled(cw, fault, enables);
        }
        while let Some(written) = self.cw_written.pop() {
            self.device_control_command(written, fault, enables);
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

    /// The state machine on the controlword as it stands, when no write came since the last
    /// cycle (an input function or the panel set it, or nothing changed).
    fn device_control_sampled(&mut self, cw: Controlword, fault: bool, enables: bool) {
        // A fault-reset pulse shorter than a cycle still counts (latched at the write); so
        // does a rising edge written within one cycle after the bit was seen set (0080h,
        // 0000h, 0080h between two steps): the device control sees the low level first.
        if self.cw_rising.contains(Controlword::FAULT_RESET) {
            let other = if cw.contains(Controlword::FAULT_RESET) {
                cw.difference(Controlword::FAULT_RESET)
            } else {
                cw | Controlword::FAULT_RESET
            };
            self.device_control_command(other.bits(), fault, enables);
        }
        self.device_control_command(cw.bits(), fault, enables);
    }

    /// One controlword through the state machine, with the reaction of its transition.
    fn device_control_command(&mut self, cw: u16, fault: bool, enables: bool) {
        let before = self.dc.state();
        let reaction = self.dc.controlword(cw, fault, enables);
        self.react(reaction);
        if before == State::Fault && self.dc.state() == State::SwitchOnDisabled {
            // CiA 402 §6.3.1 transition 15: the fault reset acknowledges the errors.
            while let Some(code) = self.faults.pop() {
                self.push_event(DriveEvent::Cleared { code });
            }
        }
    }

    fn react(&mut self, r: Reaction) {
        match r {
            Reaction::None => {}
            Reaction::Enable => {
                // Brake released with the output stage (CMMP-AS) or after the device file's
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
                // A limit switch, or braking with maximum current: the vendor's ramp.
                V::emergency_deceleration(self)
            } else if let Some(ramp) = self.vl_ramp(0x604A).filter(|_| self.mode == mode::VELOCITY)
            {
                // VL brakes with its own quick-stop ramp 604Ah (Nanotec §6.1).
                ramp
            } else if self.personality.capabilities.ip_abrupt_quick_stop
                && self.mode == mode::INTERPOLATED_POSITION
            {
                // Nanotec §7.3: in IP a quick stop stops the motor abruptly, without a ramp.
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
        if V::mode_step(self, cw, dt) {
            return;
        }
        match self.mode {
            mode::PROFILE_POSITION => self.profile_position(cw, dt),
            mode::PROFILE_VELOCITY => self.profile_velocity(dt),
            mode::VELOCITY => self.velocity_mode(dt),
            mode::PROFILE_TORQUE => self.profile_torque(dt),
            mode::HOMING => self.homing(cw, dt),
            mode::CYCLIC_SYNCHRONOUS_POSITION => self.cyclic_synchronous_position(dt),
            mode::INTERPOLATED_POSITION => self.interpolated_position(cw, dt),
            _ => self.hold(dt),
        }
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

    pub(crate) fn clear_target_reached(&mut self) {
        self.target_reached = false;
        self.window_since = None;
        let sw = self.read(self.hot.statusword) & !i64::from(Statusword::TARGET_REACHED.bits());
        self.store(self.hot.statusword, sw);
    }
}

/// 60C2h as the interpolation period; the default 1 ms for a value outside the ranges.
pub(crate) fn interpolation_period<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor>(
    od: &ObjectDictionary<S>,
) -> Duration {
    let units = od.get_unsigned(0x60C2, 1).unwrap_or(1);
    let index = match od.value(0x60C2, 2) {
        Some(Value::Signed(v)) => v,
        _ => -3,
    };
    match (u8::try_from(units), i8::try_from(index)) {
        (Ok(u), Ok(i)) => V::ip_period(u, i).unwrap_or(DEFAULT_IP_PERIOD),
        _ => DEFAULT_IP_PERIOD,
    }
}

/// The interpolation period of the default 60C2h (1 × 10⁻³ s).
const DEFAULT_IP_PERIOD: Duration = Duration::from_millis(1);

/// The DC link voltage the drive measures, in 6079h dc_link_circuit_voltage (CiA 402) and
/// where the vendor has one its own object ([`Vendor`]'s `POWER_STAGE_OBJECTS`): `mv`, or
/// without it the nominal voltage (an ideal supply: the vendor's nominal object, else the
/// engine's 325 V).
fn publish_supply<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor>(
    od: &mut ObjectDictionary<S>,
    mv: Option<u32>,
) {
    let objects = V::POWER_STAGE_OBJECTS;
    let stored = || {
        objects.and_then(|o| {
            let (index, sub) = o.nominal_dc_link_voltage;
            od.get_unsigned(index, sub)
        })
    };
    let nominal = mv
        .map(u64::from)
        .unwrap_or_else(|| stored().unwrap_or(325_000));
    if let Some(o) = objects {
        let (index, sub) = o.actual_dc_link_voltage;
        let _ = od.set_value(index, sub, Value::Unsigned(nominal));
    }
    let _ = od.set_value(0x6079, 0, Value::Unsigned(nominal));
}

/// The controller parameters the dictionary holds: motor data (6075h, 6073h, 6410h, 6080h),
/// the vendor's power stage ([`Vendor`]'s `POWER_STAGE_OBJECTS`) and display filter, and the
/// gains of the controllers' parameter sets 60F6h, 60F9h, 60FBh as the vendor reads them
/// ([`Vendor`]'s `control_parameter_sets`; CiA 402 leaves their sub-indices to the
/// manufacturer, so a vendor without a reading keeps the engine's standard gains,
/// [`ControlParams::default`]). The manufacturer-specific objects ([`manufacturer_object`])
/// are read only for a vendor that gives them a meaning (else their defaults).
pub(crate) fn control_params_of<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor>(
    od: &ObjectDictionary<S>,
) -> ControlParams {
    let d = ControlParams::default();
    let u = |i: u16, s: u8, dflt: u64| {
        if V::MANUFACTURER_OBJECTS || !manufacturer_object(i) {
            od.get_unsigned(i, s).unwrap_or(dflt)
        } else {
            dflt
        }
    };
    let power_stage = V::POWER_STAGE_OBJECTS;
    let stage = |pick: fn(&PowerStageObjects) -> (u16, u8), dflt: u32| {
        power_stage.map_or(dflt, |o| {
            let (index, sub) = pick(&o);
            u(index, sub, dflt.into()) as u32
        })
    };
    let params = ControlParams {
        motor_rated_current_ma: u(0x6075, 0, d.motor_rated_current_ma.into()) as u32,
        max_current_permille: u(0x6073, 0, d.max_current_permille.into()) as u16,
        iit_time_motor_ms: u(0x6410, 3, d.iit_time_motor_ms.into()) as u16,
        velocity_display_filter_time_us: V::VELOCITY_DISPLAY_OBJECTS.map_or(
            d.velocity_display_filter_time_us,
            |o| {
                let (index, sub) = o.filter_time;
                u(index, sub, d.velocity_display_filter_time_us.into()) as u32
            },
        ),
        max_motor_speed_rpm: u(0x6080, 0, d.max_motor_speed_rpm.into()) as u32,
        limit_current_ma: None,
        nominal_dc_link_voltage_mv: stage(
            |o| o.nominal_dc_link_voltage,
            d.nominal_dc_link_voltage_mv,
        ),
        dc_link_voltage_mv: stage(|o| o.actual_dc_link_voltage, d.dc_link_voltage_mv),
        peak_current_ma: stage(|o| o.peak_current, d.peak_current_ma),
        cycletime_current_us: stage(|o| o.cycle_times[0], d.cycletime_current_us),
        cycletime_velocity_us: stage(|o| o.cycle_times[1], d.cycletime_velocity_us),
        cycletime_position_us: stage(|o| o.cycle_times[2], d.cycletime_position_us),
        ..d
    };
    V::control_parameter_sets(od, params)
}

/// Objects whose change the controllers must see: CiA 402's (6073h, 6075h, 6410h, the
/// controllers' parameter sets 60F6h, 60F9h, 60FBh that a vendor may read, 6080h), the drive data 6510h (where a
/// vendor keeps its power stage, [`Vendor`]'s `POWER_STAGE_OBJECTS`) and the vendor's display
/// filter ([`Vendor`]'s `VELOCITY_DISPLAY_OBJECTS`).
fn is_control_parameter<V: Vendor>(index: u16) -> bool {
    matches!(
        index,
        0x6073 | 0x6075 | 0x6410 | 0x60F6 | 0x60F9 | 0x60FB | 0x6080 | 0x6510
    ) || V::VELOCITY_DISPLAY_OBJECTS.is_some_and(|o| o.filter_time.0 == index)
}

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> ObjectAccess for Drive<S, V> {
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
