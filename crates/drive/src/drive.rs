//! The CiA 402 drive: device control, the operating modes and the simulated axis behind one
//! object dictionary. Protocol front ends reach it only through [`ObjectAccess`]; the runtime
//! steps it with [`Drive::step`] on the cell's clock. Stepping never allocates.

use core::time::Duration;

use heapless::Deque;
use od::{AbortCode, DataType, Entry, Instant, ObjectAccess, ObjectDictionary, Value};

use crate::axis::{Axis, Demand};
use crate::control::ControlParams;
use crate::device_control::{DeviceControl, Reaction, State};
use crate::digital_inputs::{Levels, SwitchConfig};
use crate::display::Display;
use crate::factor_group::{FactorGroup, FactorObject, Ratio};
use crate::homing::{Command, HomingError, Search, Sense, Speed};
use crate::interpolated_position::{period_from_60c2, Interpolator, SyncChange};
use crate::messages::{self, reaction, Number, Reactions};
use crate::motor::MotorData;
use crate::profile_position::{Job, Request, SetPoints};
use crate::smoothing::Smoother;
use crate::trajectory::{Limits, Trajectory};
use crate::travel::{Inputs, TravelSettings};

mod object_writes;

/// Operating modes (6060h / 6061h values).
pub mod mode {
    pub const PROFILE_POSITION: i8 = 1;
    pub const PROFILE_VELOCITY: i8 = 3;
    pub const PROFILE_TORQUE: i8 = 4;
    pub const HOMING: i8 = 6;
    pub const INTERPOLATED_POSITION: i8 = 7;
    /// EtherCAT only on the CMMP-AS (6060h value range).
    pub const CYCLIC_SYNCHRONOUS_POSITION: i8 = 8;
    /// 6061h while a mode change is in progress (CMMP-AS §7.1).
    pub const CHANGING: i8 = -1;
}

/// CMMP-AS diagnostic messages the drive raises, with their CiA 402 EMCY codes (ch. B.2).
pub mod diag {
    /// 02-0 DC-link undervoltage (below 6510h:36 with 6510h:37 = 1).
    pub const DC_LINK_UNDERVOLTAGE: u16 = 0x3220;
    /// 17-0 following error: the hard limit 6510h:22 was exceeded.
    pub const FOLLOWING_ERROR: u16 = 0x8611;
    /// 31-0 I²t motor (with 6510h:38 = 1).
    pub const I2T_MOTOR: u16 = 0x2312;
    /// 34-0 no fieldbus synchronisation: IP mode activated off the SYNC grid.
    pub const NO_FIELDBUS_SYNC: u16 = 0x8780;
    /// 34-1 fieldbus synchronisation error: the SYNC grid lost while interpolating.
    pub const FIELDBUS_SYNC_ERROR: u16 = 0x8781;
    /// 43-0 limit switch: negative set-point blocked (the negative hardware limit switch).
    pub const LIMIT_SWITCH_NEGATIVE: u16 = 0x8081;
    /// 43-1 limit switch: positive set-point blocked.
    pub const LIMIT_SWITCH_POSITIVE: u16 = 0x8082;
}

/// Settings of the simulation that no object holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveSettings {
    pub motor: MotorData,
    /// How long a mode change takes; 6061h reads −1 meanwhile (CMMP-AS §7.1 "may briefly
    /// show −1"). 0 switches at the next cycle and keeps showing the old mode until then
    /// (python-canopen's BaseNode402 cannot decode −1); a longer value reproduces slow drives.
    pub mode_change_time: Duration,
    /// The hardware enables (DIN4 output stage, DIN5 controller enable) transition 2 needs.
    pub enables_present: bool,
    /// A holding brake is fitted: it holds the shaft while the output stage is off.
    pub brake_fitted: bool,
    /// The drive is reached over EtherCAT: cyclic synchronous position (6060h = 8) is
    /// available (CMMP-AS 6060h: "8 CSP, EtherCAT only").
    pub ethercat: bool,
    /// The axis travel: limit switches, home switch, index pulse, hard stops.
    pub travel: TravelSettings,
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
            homing_max_distance: 128 * 65536,
        }
    }
}

/// What the drive reports to its communication side (EMCY).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveEvent {
    Error { code: u16, register: u8 },
    Cleared { code: u16 },
}

/// Increments per second per internal velocity unit (1/4096 min⁻¹): 65536 / 60 / 4096.
const INC_S_PER_VEL: f64 = 65536.0 / 60.0 / 4096.0;
/// Increments per second² per internal acceleration unit (1/256 min⁻¹/s): 65536 / 60 / 256.
const INC_S2_PER_ACC: f64 = 65536.0 / 60.0 / 256.0;
/// min⁻¹ per increment/s.
const RPM_PER_INC_S: f64 = 60.0 / 65536.0;

/// Parameters the device logic reads every cycle: looked up in the dictionary once, so a
/// cycle never searches the object table.
const PARAMS: [(u16, u8); 43] = [
    (0x2005, 1),
    (0x2045, 0),
    (0x200A, 1),
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
    (0x6072, 0),
    (0x607A, 0),
    (0x607C, 0),
    (0x6080, 0),
    (0x6081, 0),
    (0x6082, 0),
    (0x6083, 0),
    (0x6084, 0),
    (0x6085, 0),
    (0x6087, 0),
    (0x6098, 0),
    (0x6099, 1),
    (0x6099, 2),
    (0x609A, 0),
    (0x60FE, 1),
    (0x60FE, 2),
    (0x6510, 0x10),
    (0x6510, 0x11),
    (0x6510, 0x12),
    (0x6510, 0x13),
    (0x6510, 0x14),
    (0x6510, 0x18),
    (0x6510, 0x22),
    (0x6510, 0x36),
    (0x6510, 0x37),
    (0x6510, 0x38),
    (0x6510, 0xF0),
];

/// Entries the drive reads or writes every cycle, looked up once.
#[derive(Debug, Clone, Copy, Default)]
struct Hot {
    controlword: Option<&'static Entry>,
    statusword: Option<&'static Entry>,
    mode_display: Option<&'static Entry>,
    position_internal: Option<&'static Entry>,
    position_actual: Option<&'static Entry>,
    position_demand: Option<&'static Entry>,
    velocity_actual: Option<&'static Entry>,
    velocity_demand: Option<&'static Entry>,
    current_actual: Option<&'static Entry>,
    torque_actual: Option<&'static Entry>,
    torque_demand: Option<&'static Entry>,
    following_error_actual: Option<&'static Entry>,
    control_effort: Option<&'static Entry>,
    manufacturer_status: Option<&'static Entry>,
    target_velocity: Option<&'static Entry>,
    target_torque: Option<&'static Entry>,
    digital_inputs: Option<&'static Entry>,
}

pub struct Drive<S> {
    od: ObjectDictionary<S>,
    settings: DriveSettings,
    dc: DeviceControl,
    axis: Axis,
    fg: FactorGroup,
    hot: Hot,
    params: [Option<&'static Entry>; PARAMS.len()],
    /// Current-controller cycle and how many of them make one logic (position-loop) cycle.
    cycle: Duration,
    logic_every: u32,
    next_cycle: Option<Instant>,
    cycles: u64,
    now: Instant,
    /// Added to the encoder to give 6063h (2030h set_position_absolute, homing).
    position_offset: i64,
    mode: i8,
    mode_pending: Option<(i8, Instant)>,
    traj: Trajectory,
    /// Jerk-free profile (6086h = 2): the set-points through a moving average.
    smoother: Smoother,
    /// The position set-point the axis follows (after smoothing), increments.
    demand_position: f64,
    setpoints: SetPoints,
    demand: Demand,
    /// When the CSP set-point last changed.
    csp_changed_at: Option<Instant>,
    /// Interpolated position mode and its SYNC grid.
    ip: Interpolator,
    /// Quick stop, disable operation or fault reaction ramp in progress.
    stopping: bool,
    halted: bool,
    velocity_set: f64,
    torque_set: f64,
    target_reached: bool,
    window_since: Option<Instant>,
    following_error: bool,
    fe_since: Option<Instant>,
    speed_zero: bool,
    over_threshold_since: Option<Instant>,
    homing_attained: bool,
    homing_error: bool,
    referenced: bool,
    homing: HomingRun,
    homing_started: Instant,
    /// The fault reaction brakes for a limit switch: with 6510h:15, not 6085h.
    limit_stop: bool,
    /// Controlword edges latched at the write, so a short pulse is never missed.
    cw_rising: u16,
    last_cw: u16,
    brake_engaged: bool,
    /// The output stage goes off / the set-point is released when the brake delay ends.
    power_off_at: Option<Instant>,
    release_at: Option<Instant>,
    /// Errors reported and not yet acknowledged.
    faults: heapless::Vec<u16, 8>,
    /// Causes still present (injected faults until cleared): they block the fault reset.
    causes: heapless::Vec<u16, 8>,
    events: Deque<DriveEvent, 16>,
    params_dirty: bool,
    /// Digital inputs driven from outside ([`Drive::force_inputs`]).
    forced_mask: u16,
    forced_levels: u16,
    /// Error management 2100h: the reaction per main error number.
    reactions: Reactions,
    /// The last warning and whether it is still active (200Fh).
    warning: Option<(Number, bool)>,
    /// The safety module reports safe standstill (2000h:01 bit 8).
    safe_standstill: bool,
    /// The DC-link voltage the supply gives, mV; `None`: the nominal 6510h:33.
    dc_link_mv: Option<u32>,
    /// The diagnostic memory: messages with their additional information, oldest first.
    memory: Deque<MemoryEntry, 16>,
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
fn decode_i64(e: &Entry, raw: &[u8]) -> i64 {
    let mut u = 0u64;
    for (i, b) in raw.iter().take(8).enumerate() {
        u |= u64::from(*b) << (8 * i);
    }
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
    /// A drive at power-on over `od` (holding defaults, commissioning and stored values).
    pub fn new(mut od: ObjectDictionary<S>, settings: DriveSettings) -> Self {
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
            od,
            settings,
            dc: DeviceControl::default(),
            axis,
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
            setpoints: SetPoints::default(),
            demand: Demand::Off,
            csp_changed_at: None,
            ip: Interpolator::new(DEFAULT_IP_PERIOD),
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
            limit_stop: false,
            cw_rising: 0,
            last_cw: 0,
            brake_engaged: true,
            power_off_at: None,
            release_at: None,
            faults: heapless::Vec::new(),
            causes: heapless::Vec::new(),
            events: Deque::new(),
            params_dirty: false,
            forced_mask: 0,
            forced_levels: 0,
            reactions: Reactions::default(),
            warning: None,
            safe_standstill: false,
            dc_link_mv: None,
            memory: Deque::new(),
        };
        d.following_error_reaction();
        d.reload_factor_group();
        d.ip.reset(interpolation_period(&d.od));
        d.axis.hold_brake(d.settings.brake_fitted);
        d.place_hard_stops();
        d.mode = d
            .read(d.hot.mode_display)
            .clamp(i8::MIN as i64, i8::MAX as i64) as i8;
        // CMMP-AS §5.4 (CMMP-SDO-16): enable_logic is set to 2 ("DINs + CAN") whenever CANopen
        // is active, also after a reset.
        let _ = d.od.set_value(0x6510, 0x10, Value::Unsigned(2));
        if d.settings.ethercat {
            // CiA 402 6502h bit 7: CSP.
            let modes = d.od.get_unsigned(0x6502, 0).unwrap_or(0) | 0x80;
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
            self.raise(diag::FIELDBUS_SYNC_ERROR, 0x11, false);
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
        let _ = self.od.set_value(0x6510, 0x10, Value::Unsigned(2));
        // The reaction table is not part of the stored set: defaults again.
        self.reactions = Reactions::default();
        self.following_error_reaction();
    }

    fn reload_factor_group(&mut self) {
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
    }

    /// A diagnostic message with the reaction 2100h sets for its main number (CMMP-AS §5.18):
    /// none / buffer entry change nothing, a warning shows in 200Fh, the display and
    /// statusword bit 7, a stopping reaction reports the error (EMCY) and stops. A code
    /// missing from [`messages::MESSAGES`] stops; `critical` ones switch the output stage off
    /// at once.
    fn raise(&mut self, code: u16, register: u8, critical: bool) {
        self.raise_with_info(code, register, critical, 0);
    }

    /// [`Drive::raise`] with the message's additional information for the diagnostic
    /// memory.
    fn raise_with_info(&mut self, code: u16, register: u8, critical: bool, info: u32) {
        let message = messages::by_code(code);
        if let Some(m) = message {
            // Every reaction but "no action" makes an entry, once per occurrence: an error
            // until it is acknowledged, a warning while active, a plain entry while it is
            // the newest one.
            let logged = match self.reactions.get(m.number.main).unwrap_or(0) {
                reaction::NONE => true,
                reaction::BUFFER_ENTRY => self.memory.back().is_some_and(|e| e.code == code),
                reaction::WARNING => self.warning == Some((m.number, true)),
                _ => self.faults.contains(&code),
            };
            if !logged {
                if self.memory.is_full() {
                    self.memory.pop_front();
                }
                let _ = self.memory.push_back(MemoryEntry {
                    number: m.number,
                    code,
                    info,
                });
            }
        }
        let r = message
            .and_then(|m| self.reactions.get(m.number.main))
            .unwrap_or(if critical {
                reaction::OUTPUT_STAGE_OFF
            } else {
                reaction::CONTROLLER_ENABLE_OFF
            });
        match (r, message) {
            (reaction::NONE | reaction::BUFFER_ENTRY, _) => return,
            (reaction::WARNING, Some(m)) => {
                self.set_warning(m.number, true);
                return;
            }
            _ => {}
        }
        if !self.faults.contains(&code) {
            let _ = self.faults.push(code);
            self.push_event(DriveEvent::Error { code, register });
        }
        let r = match r {
            reaction::OUTPUT_STAGE_OFF => self.dc.fault_immediate(),
            reaction::BRAKE_MAX_CURRENT => {
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

    /// 200Fh last_warning_code and statusword bit 7 (CMMP-AS §5.18).
    fn set_warning(&mut self, number: Number, active: bool) {
        if self.warning == Some((number, active)) {
            return;
        }
        self.warning = Some((number, active));
        let code = messages::warning_code(number, active);
        let _ = self.od.write_internal(0x200F, 0, &code.to_le_bytes());
    }

    /// Ends the warning `number` if it is the active one (its cause is gone; the CMMP-AS
    /// resets warnings itself).
    fn end_warning(&mut self, number: Number) {
        if self.warning == Some((number, true)) {
            self.set_warning(number, false);
        }
    }

    /// 6510h:22 > 0 sets the reaction of error 17 to output stage off, 0 to no action
    /// (cmmp-as-2 §5.7); 2100h can change it afterwards.
    fn following_error_reaction(&mut self) {
        let r = if self.value(0x6510, 0x22) > 0 {
            reaction::OUTPUT_STAGE_OFF
        } else {
            reaction::NONE
        };
        let _ = self.reactions.set(17, r);
        self.show_reaction();
    }

    /// 2100h:02 shows the reaction of the main number selected in 2100h:01.
    fn show_reaction(&mut self) {
        let main = self.od.get_unsigned(0x2100, 1).unwrap_or(1) as u8;
        if let Some(r) = self.reactions.get(main) {
            let _ = self.od.write_internal(0x2100, 2, &[r]);
        }
    }

    /// What the 7-segment display shows (App. B): the oldest error, else the warning, else
    /// "H" for safe standstill, else "A" while 6510h:C0 commissioning_state is 0.
    pub fn display(&self) -> Display {
        let error = self
            .faults
            .iter()
            .find_map(|c| messages::by_code(*c))
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
        let enabled = self.value(0x6510, 0x37) == 1;
        let min = self.value(0x6510, 0x36);
        let low = self.dc_link_mv.filter(|mv| enabled && i64::from(*mv) < min);
        if let Some(mv) = low {
            if !self.causes.contains(&diag::DC_LINK_UNDERVOLTAGE) {
                let _ = self.causes.push(diag::DC_LINK_UNDERVOLTAGE);
            }
            let info = messages::undervoltage_info(self.dc.state() as u16, mv);
            self.raise_with_info(diag::DC_LINK_UNDERVOLTAGE, 0x04, false, info);
        } else if let Some(i) = self
            .causes
            .iter()
            .position(|c| *c == diag::DC_LINK_UNDERVOLTAGE)
        {
            self.causes.remove(i);
        }
    }

    /// CMMP-AS 31-0 I²t motor (§5.5, 6510h:38 iit_error_enable = 1): the motor I²t at 100 %
    /// is an error, not only the limitation to the rated current; the cause stays until the
    /// I²t has fallen below the release threshold.
    fn supervise_i2t(&mut self) {
        let over = self.value(0x6510, 0x38) == 1 && self.axis.i2t_limit_active();
        self.cause(diag::I2T_MOTOR, over, 0x02);
    }

    /// Keeps `code` as a cause while `present` and raises it (with `register`); a cause that
    /// went lets the fault reset acknowledge the error.
    fn cause(&mut self, code: u16, present: bool, register: u8) {
        let at = self.causes.iter().position(|c| *c == code);
        match (present, at) {
            (true, None) => {
                let _ = self.causes.push(code);
                self.raise(code, register, false);
            }
            (true, Some(_)) => self.raise(code, register, false),
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

    fn push_event(&mut self, e: DriveEvent) {
        if self.events.is_full() {
            self.events.pop_front();
        }
        let _ = self.events.push_back(e);
    }

    fn read(&self, e: Option<&'static Entry>) -> i64 {
        e.map(|e| decode_i64(e, self.od.raw(e))).unwrap_or(0)
    }

    fn value(&self, index: u16, sub: u8) -> i64 {
        if let Some(pos) = PARAMS.iter().position(|k| *k == (index, sub)) {
            return self.read(self.params.get(pos).copied().flatten());
        }
        match self.od.value(index, sub) {
            Some(Value::Signed(s)) => s,
            Some(Value::Unsigned(u)) => u as i64,
            _ => 0,
        }
    }

    /// An INTEGER32 set-point with the other sign (saturating at −2³¹).
    fn negate_stored(&mut self, index: u16) {
        if let Some(Value::Signed(v)) = self.od.value(index, 0) {
            let _ = self.od.set_value(
                index,
                0,
                Value::Signed(v.saturating_neg().min(i64::from(i32::MAX))),
            );
        }
    }

    /// A [`PARAMS`] entry.
    fn param(&self, index: u16, sub: u8) -> Option<&'static Entry> {
        let pos = PARAMS.iter().position(|k| *k == (index, sub))?;
        self.params.get(pos).copied().flatten()
    }

    fn store(&mut self, e: Option<&'static Entry>, v: i64) {
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
            if self.cycles.is_multiple_of(u64::from(self.logic_every)) {
                self.logic();
            }
            self.axis.step(self.demand);
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
            self.axis.set_params(control_params(&self.od));
        }
        self.supervise_dc_link();
        self.supervise_i2t();
        // Device control.
        let cw = self.read(self.hot.controlword) as u16;
        let fault = !self.causes.is_empty();
        // Transition 2 needs both hardware enables (DIN4, DIN5).
        let enables = self.input_levels(self.axis.position_increments()).enables();
        // A fault-reset pulse shorter than a cycle still counts (latched at the write).
        if self.cw_rising & 0x0080 != 0 && cw & 0x0080 == 0 {
            let _ = self.dc.controlword(cw | 0x0080, fault, enables);
        }
        let before = self.dc.state();
        let reaction = self.dc.controlword(cw, fault, enables);
        self.react(reaction);
        if before == State::Fault && self.dc.state() == State::SwitchOnDisabled {
            // Transition 15: the errors are acknowledged (CMMP-AS Tab. 3.8 transition 4).
            while let Some(code) = self.faults.pop() {
                self.push_event(DriveEvent::Cleared { code });
            }
        }
        self.halted = cw & 0x0100 != 0;
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
        self.cw_rising = 0;
        self.publish();
    }

    fn react(&mut self, r: Reaction) {
        match r {
            Reaction::None => {}
            Reaction::Enable => {
                // Brake released with the output stage; the set-point follows after the
                // brake delay (CMMP-AS §5.16).
                self.power_off_at = None;
                self.brake_engaged = false;
                self.axis.hold_brake(false);
                let delay = Duration::from_millis(self.value(0x6510, 0x18).max(0) as u64);
                self.release_at = Some(self.now + delay);
                self.resync_trajectory();
                self.stopping = false;
                self.limit_stop = false;
            }
            Reaction::Coast => {
                // Brake first, output stage off after the brake delay.
                self.setpoints.abort();
                self.stopping = false;
                if self.settings.brake_fitted
                    && !self.brake_engaged
                    && !matches!(self.demand, Demand::Off)
                {
                    self.brake_engaged = true;
                    self.axis.hold_brake(true);
                    let delay = Duration::from_millis(self.value(0x6510, 0x18).max(0) as u64);
                    self.power_off_at = Some(self.now + delay);
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

    fn power_off(&mut self) {
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
            if !manual && shown != data {
                self.store(self.param(0x60FE, 1), shown);
            }
        }
    }

    fn actual_internal(&self) -> i64 {
        self.axis.position_increments() + self.position_offset
    }

    /// The set-point follows the actual position (output stage off, mode change, enable).
    fn resync_trajectory(&mut self) {
        self.traj = Trajectory {
            position: self.actual_internal() as f64,
            velocity: f64::from(self.axis.velocity_rpm()) / RPM_PER_INC_S,
        };
        self.velocity_set = self.traj.velocity;
        self.demand_position = self.traj.position;
        self.smoother.reset(self.traj.position, 1);
    }

    fn accel(&self, index: u16) -> f64 {
        let user = self.value(index, 0).clamp(0, u32::MAX as i64) as u32;
        self.fg.acceleration_to_internal(user) as f64 * INC_S2_PER_ACC
    }

    fn position_demand(&mut self, velocity_ff: f64) {
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
            increments: libm::round(self.demand_position) as i64 - self.position_offset,
            velocity_ff_rpm: (ff * RPM_PER_INC_S) as f32,
        };
    }

    fn motion(&mut self, cw: u16, dt: f64) {
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
            && self.cw_rising & 0x0010 != 0
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
        match self.mode {
            mode::PROFILE_POSITION => self.profile_position(cw, dt),
            mode::PROFILE_VELOCITY => self.profile_velocity(dt),
            mode::PROFILE_TORQUE => self.profile_torque(dt),
            mode::HOMING => self.homing(cw, dt),
            mode::CYCLIC_SYNCHRONOUS_POSITION => self.cyclic_synchronous_position(dt),
            mode::INTERPOLATED_POSITION => self.interpolated_position(cw, dt),
            _ => {
                let decel = self.accel(0x6084);
                self.traj.step_stop(decel, dt);
                self.position_demand(self.traj.velocity);
            }
        }
    }

    fn profile_position(&mut self, cw: u16, dt: f64) {
        let bit4 = cw & 0x0010 != 0 || self.cw_rising & 0x0010 != 0;
        let demand = self.traj.position;
        let fg = self.fg;
        let get = |i: u16| self.value(i, 0);
        // Read the set-point only while bit 4 is high (a rising edge may be taking it).
        let req = bit4.then(|| {
            let user = get(0x607A).clamp(i32::MIN as i64, i32::MAX as i64) as i32;
            let target = fg.position_to_internal(user) as f64;
            let vel = |i| {
                fg.velocity_magnitude_to_internal(get(i).clamp(0, u32::MAX as i64) as u32) as f64
                    * INC_S_PER_VEL
            };
            let acc = |i| {
                fg.acceleration_to_internal(get(i).clamp(0, u32::MAX as i64) as u32) as f64
                    * INC_S2_PER_ACC
            };
            Request {
                target,
                relative: cw & 0x0040 != 0,
                immediately: cw & 0x0020 != 0,
                job: Job {
                    target,
                    velocity: vel(0x6081)
                        .min(f64::from(get(0x6080).max(0) as u32) * 4096.0 * INC_S_PER_VEL),
                    end_velocity: vel(0x6082),
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
        if self.setpoints.update(bit4, demand, request) {
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
            let (acc, dec) = if self.halted {
                (self.accel(0x6084), self.accel(0x6084))
            } else if positive {
                (self.accel2(0x2090, 2), self.accel2(0x2090, 3))
            } else {
                (self.accel2(0x2090, 4), self.accel2(0x2090, 5))
            };
            let mut t = Trajectory {
                position: 0.0,
                velocity: self.velocity_set,
            };
            t.step_velocity(target, acc, dec, dt);
            self.velocity_set = t.velocity;
        } else {
            self.velocity_set = target;
        }
        // The set-point keeps the ramp's speed, so a quick stop brakes from there.
        self.traj = Trajectory {
            position: self.actual_internal() as f64,
            velocity: self.velocity_set,
        };
        self.demand_position = self.traj.position;
        self.demand = Demand::Velocity {
            rpm: (self.velocity_set * RPM_PER_INC_S) as f32,
        };
        // Target reached: |v − target| < 606Dh for 606Eh (CMMP-AS §7.5).
        let v_act = f64::from(self.axis.velocity_internal());
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
    fn interpolated_position(&mut self, cw: u16, dt: f64) {
        let enable = cw & 0x0010 != 0;
        if enable && !self.ip.is_active() {
            if self.ip.is_synchronised() {
                self.ip.activate(self.traj.position, self.now);
            } else if self.cw_rising & 0x0010 != 0 {
                // CMMP-AS 34-0: activation without synchronisation.
                self.raise(diag::NO_FIELDBUS_SYNC, 0x11, false);
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

    fn accel2(&self, index: u16, sub: u8) -> f64 {
        let user = self.value(index, sub).clamp(0, u32::MAX as i64) as u32;
        self.fg.acceleration_to_internal(user) as f64 * INC_S2_PER_ACC
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
            velocity: f64::from(self.axis.velocity_rpm()) / RPM_PER_INC_S,
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

    /// Homing (CMMP-AS §7.2): controlword bit 4 0 → 1 starts the method of 6098h, 1 → 0
    /// aborts it (Tab. 7.2); halt aborts with homing_error (ch. 6). The search of
    /// [`crate::homing`] finds the reference point; then the drive brakes with 609Ah and,
    /// with 6510h:F0 bit 6 homing_to_zero, travels to the zero position.
    fn homing(&mut self, cw: u16, dt: f64) {
        let bit4 = cw & 0x0010 != 0;
        let idle = matches!(self.homing, HomingRun::Idle);
        if self.cw_rising & 0x0010 != 0
            || (bit4 && idle && !self.homing_attained && !self.homing_error)
        {
            self.start_homing();
        } else if !idle && !bit4 {
            // Tab. 7.2: bit 4 1 → 0 aborts homing (neither attained nor error).
            self.homing = HomingRun::Brake {
                then: Then::Nothing,
            };
        } else if !idle && self.halted && !matches!(self.homing, HomingRun::Brake { .. }) {
            // ch. 6: halt aborts homing; homing_error is set.
            self.homing_error = true;
            self.homing = HomingRun::Brake {
                then: Then::Nothing,
            };
        }
        if !matches!(self.homing, HomingRun::Idle) {
            let timeout = self.value(0x2045, 0).max(0) as u64;
            if timeout > 0
                && self.now.saturating_since(self.homing_started) > Duration::from_millis(timeout)
            {
                self.homing_failed(HomingError::Timeout);
            }
        }
        let acc = self.accel(0x609A);
        match self.homing {
            HomingRun::Idle => {
                self.traj.step_stop(acc, dt);
                self.position_demand(self.traj.velocity);
            }
            HomingRun::Search(mut search) => {
                let position = self.axis.position_increments();
                let sense = Sense {
                    position,
                    inputs: self.switch_inputs(position),
                    stalled: self.stalled(),
                };
                let command = search.step(&sense, &self.settings.travel);
                self.homing = HomingRun::Search(search);
                match command {
                    Command::Run {
                        direction,
                        speed,
                        restart,
                    } => {
                        if restart {
                            self.hold_here();
                        }
                        let v = f64::from(direction) * self.homing_speed(speed);
                        self.traj.step_velocity(v, acc, acc, dt);
                        self.position_demand(self.traj.velocity);
                    }
                    Command::Reference { at, stalled } => {
                        if stalled {
                            self.hold_here();
                        }
                        self.set_reference(at);
                        let to_zero = self.value(0x6510, 0xF0) & 0x0040 != 0;
                        self.homing = HomingRun::Brake {
                            then: if to_zero {
                                Then::ToZero
                            } else {
                                Then::Attained
                            },
                        };
                        self.traj.step_stop(acc, dt);
                        self.position_demand(self.traj.velocity);
                    }
                    Command::Failed(e) => {
                        if sense.stalled {
                            self.hold_here();
                        }
                        self.homing_failed(e);
                        self.position_demand(self.traj.velocity);
                    }
                }
            }
            HomingRun::Brake { then } => {
                if self.traj.step_stop(acc, dt) {
                    self.homing = match then {
                        Then::ToZero => HomingRun::ToZero,
                        Then::Attained => {
                            self.homing_done();
                            HomingRun::Idle
                        }
                        Then::Nothing => HomingRun::Idle,
                    };
                }
                self.position_demand(self.traj.velocity);
            }
            HomingRun::ToZero => {
                // 6510h:F0 bit 6: to the zero position at 6099h:01 (cmmp-as-3 §3.2 note).
                let zero = self.fg.position_to_internal(0) as f64;
                let lim = Limits {
                    velocity: self.homing_speed(Speed::Search).max(1.0),
                    acceleration: acc.max(1.0),
                    deceleration: acc.max(1.0),
                };
                let window = self.fg.position_magnitude_to_internal(
                    self.value(0x6067, 0).clamp(0, u32::MAX as i64) as u32,
                );
                // Done when the set-point is there and the axis inside the window 6067h.
                if self.traj.step_to(zero, 0.0, lim, dt)
                    && (self.actual_internal() - libm::round(zero) as i64).abs() <= window
                {
                    self.homing_done();
                    self.homing = HomingRun::Idle;
                }
                self.position_demand(self.traj.velocity);
            }
        }
        self.target_reached = matches!(self.homing, HomingRun::Idle) && self.traj.velocity == 0.0;
    }

    fn start_homing(&mut self) {
        self.homing_attained = false;
        self.homing_error = false;
        self.referenced = false;
        self.homing_started = self.now;
        let method = self.value(0x6098, 0).clamp(i8::MIN as i64, i8::MAX as i64) as i8;
        // Decision: 6510h:F0 bits 0/2 (homing_method_scheme) choose between CiA 402 and a
        // legacy numbering of 32 … 35 that the manual does not print; both use Tab. 7.1's
        // 33/34/35, and 32 (in the printed range, in no table) is refused at the start.
        match Search::start(
            method,
            self.axis.position_increments(),
            self.axis.motor().data().increments_per_rev,
            self.settings.homing_max_distance,
        ) {
            Ok(search) => self.homing = HomingRun::Search(search),
            Err(e) => self.homing_failed(e),
        }
    }

    /// Homing ends with an error: homing_error, the group-11 message, fault reaction.
    fn homing_failed(&mut self, e: HomingError) {
        self.homing = HomingRun::Idle;
        self.homing_error = true;
        self.homing_attained = false;
        self.raise(e.code(), 0x01, false);
    }

    fn homing_done(&mut self) {
        self.homing_attained = true;
        self.homing_error = false;
        self.referenced = true;
    }

    /// The reference point at encoder position `at` gets the value 607Ch home_offset.
    ///
    /// Decision: the manual's Fig. 7.2 calls 607Ch "the offset of the zero position from the
    /// reference point" without a sign convention; as CiA 402 masters expect, the position
    /// at the reference point reads home_offset afterwards (and "zero" lies home_offset
    /// before it).
    fn set_reference(&mut self, at: i64) {
        let home = self
            .value(0x607C, 0)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        let offset = self.fg.position_to_internal(home) - at;
        let shift = (offset - self.position_offset) as f64;
        self.position_offset = offset;
        self.traj.position += shift;
        self.demand_position += shift;
        self.smoother.reset(self.traj.position, 1);
    }

    /// 6099h:01 (search) or :02 (crawl) in increments/s.
    fn homing_speed(&self, speed: Speed) -> f64 {
        let sub = match speed {
            Speed::Search => 1,
            Speed::Crawl => 2,
        };
        let user = self.value(0x6099, sub).clamp(0, u32::MAX as i64) as u32;
        self.fg.velocity_magnitude_to_internal(user) as f64 * INC_S_PER_VEL
    }

    /// The motor stands on a hard stop: the set-point moves on while the actual position
    /// lags by more than the following-error window 6065h (at most a revolution).
    fn stalled(&self) -> bool {
        let window = self
            .fg
            .position_magnitude_to_internal(self.value(0x6065, 0).clamp(0, u32::MAX as i64) as u32)
            .clamp(1, 65536);
        let lag = libm::round(self.demand_position) as i64 - self.actual_internal();
        self.traj.velocity != 0.0 && lag.abs() > window
    }

    /// The set-point jumps to the actual position and stands (after a stall on a stop).
    fn hold_here(&mut self) {
        self.traj = Trajectory::at(self.actual_internal() as f64);
        self.demand_position = self.traj.position;
        self.smoother.reset(self.traj.position, 1);
    }

    /// Mechanical hard stops of the travel into the motor model.
    fn place_hard_stops(&mut self) {
        let t = self.settings.travel;
        let rad = self.axis.motor().rad_per_increment();
        self.axis.motor_mut().set_stops(
            t.negative_stop.map(|p| p as f64 * rad),
            t.positive_stop.map(|p| p as f64 * rad),
        );
    }

    /// Outside homing a limit switch blocks motion towards it (CMMP-AS B.3 43-0/43-1): the
    /// error's fault reaction brakes with 6510h:15 limit_switch_deceleration (§5.14, "limit
    /// switch emergency stop ramp"); motion away stays possible after the fault reset.
    fn supervise_limit_switches(&mut self) {
        let inputs = self.switch_inputs(self.axis.position_increments());
        let v = self.traj.velocity;
        let code = if inputs.negative_limit && v < 0.0 {
            diag::LIMIT_SWITCH_NEGATIVE
        } else if inputs.positive_limit && v > 0.0 {
            diag::LIMIT_SWITCH_POSITIVE
        } else {
            return;
        };
        self.limit_stop = true;
        self.raise(code, 0x01, false);
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

    fn clear_target_reached(&mut self) {
        self.target_reached = false;
        self.window_since = None;
        let sw = self.read(self.hot.statusword) & !0x0400;
        self.store(self.hot.statusword, sw);
    }

    /// Writes the statusword and every actual value.
    fn publish(&mut self) {
        let compat = self.value(0x6510, 0xF0) as u16;
        let state = self.dc.state();
        let mut sw = state.statusword_bits(compat & 0x0080 != 0);
        // Bit 4 voltage enabled: output-stage transistors on (CMMP-AS Tab. 6.7); with
        // 6510h:F0 bit 7 CiA 402 v2.0's "high voltage applied", always true in the twin.
        let power = !matches!(self.demand, Demand::Off);
        if power || compat & 0x0080 != 0 {
            sw |= 0x0010;
        }
        let v_act = i64::from(self.axis.velocity_internal());
        let threshold = self
            .fg
            .velocity_magnitude_to_internal(self.value(0x606F, 0).max(0) as u32);
        // Bit 8: moving when |v| is above velocity_threshold (spec cmmp-as-2 §9.5 reads the
        // manual's "within" as the translation slip it is).
        if v_act.abs() > threshold {
            sw |= 0x0100;
            let since = *self.over_threshold_since.get_or_insert(self.now);
            let time = Duration::from_millis(self.value(0x6070, 0).max(0) as u64);
            if self.now.saturating_since(since) >= time {
                self.speed_zero = false;
            }
        } else {
            self.over_threshold_since = None;
            self.speed_zero = true;
        }
        // Bit 9 remote: enable_logic 2 (DINs + CAN).
        if self.value(0x6510, 0x10) == 2 {
            sw |= 0x0200;
        }
        let in_oe = state == State::OperationEnabled;
        if self.target_reached && in_oe {
            sw |= 0x0400;
        }
        if self.axis.i2t_limit_active() {
            sw |= 0x0800;
        }
        // Following error (PP): |actual − demand| > 6065h for 6066h.
        let demand_pos = libm::round(self.demand_position) as i64;
        let fe = self.actual_internal() - demand_pos;
        let fe_window = self
            .fg
            .position_magnitude_to_internal(self.value(0x6065, 0).clamp(0, u32::MAX as i64) as u32);
        if power && fe.abs() > fe_window {
            let since = *self.fe_since.get_or_insert(self.now);
            let time = Duration::from_millis(self.value(0x6066, 0).max(0) as u64);
            self.following_error = self.now.saturating_since(since) >= time;
        } else {
            self.fe_since = None;
            self.following_error = false;
        }
        // 6510h:22 > 0: hard limit, output stage off and error 17-0.
        let hard = self.value(0x6510, 0x22);
        if power
            && hard > 0
            && fe.abs()
                > self
                    .fg
                    .position_magnitude_to_internal(hard.clamp(0, u32::MAX as i64) as u32)
        {
            // CMMP-AS §5.7: "the output stage switches off at once, the motor coasts" (the
            // reaction 6510h:22 sets; 2100h may make it a warning).
            self.raise(diag::FOLLOWING_ERROR, 0x01, true);
        } else {
            self.end_warning(Number { main: 17, sub: 0 });
        }
        let mode_bits = match self.mode {
            mode::PROFILE_POSITION => {
                (if self.setpoints.acknowledge {
                    0x1000
                } else {
                    0
                }) | (if self.following_error { 0x2000 } else { 0 })
            }
            mode::PROFILE_VELOCITY if self.speed_zero => 0x1000,
            // Bit 12 ip_mode_active, bit 13 following error (CMMP-AS §7.4).
            mode::INTERPOLATED_POSITION => {
                (if self.ip.is_active() { 0x1000 } else { 0 })
                    | (if self.following_error { 0x2000 } else { 0 })
            }
            // CiA 402 CSP: bit 12 "drive follows the command value", bit 13 following error.
            mode::CYCLIC_SYNCHRONOUS_POSITION => {
                (if in_oe { 0x1000 } else { 0 }) | (if self.following_error { 0x2000 } else { 0 })
            }
            mode::HOMING => {
                (if self.homing_attained { 0x1000 } else { 0 })
                    | (if self.homing_error { 0x2000 } else { 0 })
            }
            _ => 0,
        };
        sw |= mode_bits;
        // Bit 14: ((2000h:01 XOR 200Ah:01) AND 2005h:01) ≠ 0 (CMMP-AS §6.1.4).
        let ready = self.faults.is_empty() && !state.power_enabled();
        let msw = u32::from(self.referenced)
            | 0x2 // commutation valid
            | if ready { 0x4 } else { 0 }
            | if self.setpoints.active.is_none() { 0x8 } else { 0 }
            | if self.safe_standstill { 0x100 } else { 0 };
        self.store(self.hot.manufacturer_status, i64::from(msw));
        let invert = self.value(0x200A, 1) as u32;
        let mask = self.value(0x2005, 1) as u32;
        if crate::device_control::manufacturer_bit_14(msw, invert, mask) {
            sw |= 0x4000;
        }
        if self.referenced {
            sw |= 0x8000;
        }
        // Bit 7 warning (CMMP-AS §5.18: "warning on the display and in the statusword").
        if matches!(self.warning, Some((_, true))) {
            sw |= 0x0080;
        }
        self.store(self.hot.statusword, i64::from(sw));
        let position = self.axis.position_increments();
        let inputs = self
            .switch_config()
            .digital_inputs(self.input_levels(position));
        self.store(self.hot.digital_inputs, i64::from(inputs));
        // CMMP-AS §7.4: in IP mode 6061h shows −1 until the drive is on the SYNC grid.
        let display = if self.mode_pending.is_some()
            || (self.mode == mode::INTERPOLATED_POSITION && !self.ip.is_synchronised())
        {
            mode::CHANGING
        } else {
            self.mode
        };
        self.store(self.hot.mode_display, i64::from(display));
        let actual = self.actual_internal();
        self.store(self.hot.position_internal, actual);
        let fg = self.fg;
        self.store(
            self.hot.position_actual,
            i64::from(fg.position_from_internal(actual)),
        );
        self.store(
            self.hot.position_demand,
            i64::from(fg.position_from_internal(demand_pos)),
        );
        self.store(
            self.hot.following_error_actual,
            i64::from(fg.position_from_internal(fe)),
        );
        self.store(
            self.hot.velocity_actual,
            i64::from(fg.velocity_from_internal(v_act)),
        );
        let v_dem = match self.demand {
            Demand::Velocity { rpm } => f64::from(rpm) * 4096.0,
            _ => self.traj.velocity / INC_S_PER_VEL,
        };
        self.store(
            self.hot.velocity_demand,
            i64::from(fg.velocity_from_internal(libm::round(v_dem) as i64)),
        );
        let effort = libm::round(f64::from(self.axis.control_effort_rpm()) * 4096.0) as i64;
        self.store(
            self.hot.control_effort,
            i64::from(fg.velocity_from_internal(effort)),
        );
        self.store(
            self.hot.current_actual,
            i64::from(self.axis.current_permille()),
        );
        self.store(
            self.hot.torque_actual,
            i64::from(self.axis.torque_permille()),
        );
        self.store(
            self.hot.torque_demand,
            i64::from(self.axis.torque_demand_permille()),
        );
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

/// Where a homing run stands.
#[derive(Debug, Clone, Copy, PartialEq)]
enum HomingRun {
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
enum Then {
    Attained,
    ToZero,
    /// Aborted: no bit.
    Nothing,
}
