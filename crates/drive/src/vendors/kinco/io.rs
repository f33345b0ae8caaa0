//! Kinco digital inputs and outputs (§5.5, Tab. 5-2 / 6-1, Tab. 5-3 / 6-2): seven DINs and five
//! DOUTs, each with its function codes, polarity and simulation.
//!
//! The manual's rules:
//! - inputs: `Internal = (Real OR Simulate) XOR (NOT Polarity)`, Din_Polarity 2010h:01,
//!   Din_Real 2010h:0A; a function is active while an input that has it is;
//! - outputs: `Real = (Function_Status OR Simulate) XOR (NOT Polarity)`, the status the OR of
//!   the output's functions, Dout_Polarity 2010h:0D, Dout_Real 2010h:14;
//! - a DIN function owns the object it sets (Enable the controlword, Operation Mode Sel the
//!   mode, L1287): Enable 1 → controlword := Din_Controlword 2020h:0F, 0 → 06h; Reset Errors
//!   on its rising edge; Activate Command drives bit 4; Quick Stop the quick-stop command;
//!   the limit switches are normally closed (0 = that direction blocked); Pre Enable 0 refuses
//!   the enable with "External enable"; Motor Error raises "Motor Temperature"; Din Vel Index
//!   selects `Din_Speed[x]` in the velocity modes; Fast_Capture latches 6063h on the first edge.
//!
//! Decisions:
//! - the simulation objects are not printed in this part; the sibling FD manuals' Din_Simulate
//!   2010h:02 and Dout_Simulate 2010h:0E are taken (the extract's §5.11, EXT);
//! - the twin has no cabinet: the travel's switches are wired to the inputs whose function
//!   names them (P limit± as normally closed contacts, the home switch normally open);
//!   [`Drive::force_inputs`] bit n − 1 drives DINn's wire;
//! - the owning functions act when their input changes (and at power-on), so after a Quick
//!   Stop input the Enable input is toggled again, as the manual says;
//! - Ready is "no error and not switch-on disabled" (the manual: "ready to switch on"),
//!   Motor Brake is "brake released".

use super::hooks::Kinco;
use super::{din_has, selected_index, DinFunction, DoutFunction, DOUT_FUNCTIONS};
use crate::axis::Demand;
use crate::controlword::Controlword;
use crate::device_control::State;
use crate::drive::refusal::{Refusal, Request};
use crate::drive::{mode, Drive, HomingRun};
use crate::travel::Inputs;
use od::ObjectAccess;

/// DIN1 … DIN7.
pub const DINS: u8 = 7;
/// OUT1 … OUT5.
pub const DOUTS: u8 = 5;

/// Motor Temperature (Error_State bit 13), raised by the Motor Error DIN.
const MOTOR_TEMPERATURE: u16 = 0x4310;
/// External enable (Error_State2 bit 8), an enable without Pre Enable.
const EXTERNAL_ENABLE: u16 = 0x5443;

/// L1287: "the DIN function has the highest priority".
const DIN_PRIORITY: &str = "Kinco FD/CD §5.5 (L1287): the DIN function has the highest \
    priority; an object a DIN function sets can no longer be changed by hand, e.g. with Enable \
    configured the controlword cannot be changed";

/// Tab. 6-1 (8200h) and Tab. 5-8 bit 8.
const PRE_ENABLE: &str = "Kinco FD/CD Tab. 6-1 (8200h Pre Enable): 0 = the drive cannot be \
    enabled; an enable then raises \"External enable\" (5443h, Tab. 5-8 bit 8)";

/// The input functions that own an object, with the manual's name (Tab. 6-1).
const OWNERS: [(DinFunction, &str, u16, u8); 4] = [
    (DinFunction::Enable, "Enable", 0x6040, 0x00),
    (
        DinFunction::OperationModeSel,
        "Operation Mode Sel",
        0x6060,
        0x00,
    ),
    (DinFunction::GainSwitch0, "Gain Switch0", 0x60F9, 0x28),
    (DinFunction::GainSwitch1, "Gain Switch1", 0x60F9, 0x28),
];

/// What the inputs were at the last cycle (for their edges).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct DinMemory {
    /// Internal levels, bit n − 1 = DINn; `None` before the first cycle.
    pub(crate) internal: Option<u8>,
    /// A homing the Start Homing input started, and the mode to return to.
    pub(crate) homing_return: Option<i8>,
    /// The Kvi Off input is active (the controller runs without the velocity integral).
    pub(crate) kvi_off: bool,
}

// `din_function_code` reads DINn_Function from slot `param_slot(2010h:03) + n` of the
// drive's PARAMS: the seven keys 2010h:03 … :09 must stay in consecutive slots there.
const _: () = {
    let first = match crate::drive::param_slot(0x2010, 0x03) {
        Some(s) => s,
        None => panic!("2010h:03 is not in PARAMS"),
    };
    let mut n = 0;
    while n < DINS {
        match crate::drive::param_slot(0x2010, 0x03 + n) {
            Some(s) if s == first + n as usize => {}
            _ => panic!("DINx_Function not in consecutive PARAMS slots"),
        }
        n += 1;
    }
};

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Kinco> {
    /// DINn_Function (2010h:03 + n), read through its resolved entry (every logic cycle
    /// asks for each input several times; the slots are consecutive, checked above).
    fn din_function_code(&self, n: u8) -> u16 {
        let first = crate::drive::param_slot(0x2010, 0x03).unwrap_or(usize::MAX);
        let entry = (n < DINS)
            .then(|| self.params.get(first.wrapping_add(usize::from(n))))
            .flatten()
            .copied()
            .flatten();
        self.read(entry).clamp(0, 0xFFFF) as u16
    }

    /// Din_Real: the wires at `position` (see the module doc), forced inputs over them.
    pub(crate) fn kinco_din_real(&self, position: i64) -> u8 {
        let switches = self.settings.travel.inputs(position);
        let wired = (0..DINS).fold(0u8, |acc, n| {
            let code = self.din_function_code(n);
            let level = (din_has(code, DinFunction::PositiveLimit) && !switches.positive_limit)
                || (din_has(code, DinFunction::NegativeLimit) && !switches.negative_limit)
                || (din_has(code, DinFunction::HomeSignal) && switches.home);
            acc | (u8::from(level) << n)
        });
        let mask = self.forced_mask as u8;
        ((wired & !mask) | (self.forced_levels as u8 & mask)) & 0x7F
    }

    /// The internal levels: `(Real OR Simulate) XOR (NOT Polarity)`.
    pub(crate) fn kinco_din_internal(&self, position: i64) -> u8 {
        let simulate = self.value(0x2010, 0x02) as u8;
        let polarity = self.value(0x2010, 0x01) as u8;
        ((self.kinco_din_real(position) | simulate) ^ !polarity) & 0x7F
    }

    /// The first input (0 = DIN1) that has `function`.
    pub(crate) fn kinco_din_with(&self, function: DinFunction) -> Option<u8> {
        (0..DINS).find(|n| din_has(self.din_function_code(*n), function))
    }

    /// Whether an input has `function`.
    pub(crate) fn kinco_din_configured(&self, function: DinFunction) -> bool {
        (0..DINS).any(|n| din_has(self.din_function_code(n), function))
    }

    fn din_level(&self, internal: u8, function: DinFunction) -> Option<bool> {
        din_level_of(&self.din_codes(), internal, function)
    }

    /// DIN1…DIN7's function codes, read once for the many questions of one cycle.
    fn din_codes(&self) -> [u16; DINS as usize] {
        core::array::from_fn(|n| self.din_function_code(n as u8))
    }

    /// The internal levels of this logic cycle (read once by [`Drive::kinco_din_cycle`]).
    fn din_now(&self) -> u8 {
        self.vendor
            .din
            .internal
            .unwrap_or_else(|| self.kinco_din_internal(self.plant_position()))
    }

    /// Whether `function` is active now (an input that has it is active).
    pub(crate) fn kinco_din_active(&self, function: DinFunction) -> bool {
        self.din_level(self.din_now(), function).unwrap_or(false)
    }

    /// The limit switches at `position` (negative, positive): a configured P limit input
    /// that is 0 blocks its direction.
    pub(crate) fn kinco_limits_at(&self, position: i64) -> (bool, bool) {
        let internal = self.kinco_din_internal(position);
        (
            self.din_level(internal, DinFunction::NegativeLimit) == Some(false),
            self.din_level(internal, DinFunction::PositiveLimit) == Some(false),
        )
    }

    /// The directions blocked now (negative, positive): a limit switch or a position limit
    /// after homing (kinco_limits.rs).
    pub(crate) fn kinco_limits_active(&self) -> (bool, bool) {
        let internal = self.din_now();
        let (below, above) = self.kinco_position_limits_blocking();
        (
            self.din_level(internal, DinFunction::NegativeLimit) == Some(false) || below,
            self.din_level(internal, DinFunction::PositiveLimit) == Some(false) || above,
        )
    }

    /// The switches as homing reads them.
    pub(crate) fn kinco_switches(&self, position: i64) -> Inputs {
        let (negative_limit, positive_limit) = self.kinco_limits_at(position);
        let internal = self.kinco_din_internal(position);
        Inputs {
            negative_limit,
            positive_limit,
            home: self.din_level(internal, DinFunction::HomeSignal) == Some(true),
        }
    }

    /// `Din_Speed[x]` in rpm where a Din Vel Index function is on an input (§6.2.2,
    /// KINCO-SC-03): x = Index0 + 2·Index1 + 4·Index2, an index no input has counts 0.
    pub(crate) fn kinco_din_speed_rpm(&self) -> Option<i32> {
        let internal = self.din_now();
        let bits = [
            DinFunction::DinVelIndex0,
            DinFunction::DinVelIndex1,
            DinFunction::DinVelIndex2,
        ]
        .map(|f| self.din_level(internal, f));
        if bits.iter().all(Option::is_none) {
            return None;
        }
        let x = selected_index(&bits);
        let sub = if x < 4 { 0x09 + x } else { 0x18 + x - 4 };
        Some(
            self.value(0x2020, sub)
                .clamp(i32::MIN as i64, i32::MAX as i64) as i32,
        )
    }

    /// The input that owns object `index:sub` (L1287), as a refusal.
    fn kinco_owner(&self, index: u16, sub: u8) -> Option<Refusal> {
        OWNERS
            .iter()
            .filter(|(_, _, i, s)| (*i, *s) == (index, sub))
            .find_map(|&(f, name, _, _)| {
                let n = self.kinco_din_with(f)?;
                Some(Refusal::InputOwns {
                    input: n + 1,
                    function: name,
                    function_object: (0x2010, 0x03 + n),
                    index,
                    sub,
                    rule: DIN_PRIORITY,
                })
            })
    }

    /// What the Kinco's input functions refuse: the objects they own (6040h, 6060h,
    /// PI_Pointer 60F9h:28, which PI_Switch 6069h:09 = 1 owns as well), an enable without
    /// Pre Enable. The write hooks of `kinco_drive.rs` refuse by the same rules.
    pub(crate) fn kinco_refusal(&self, request: Request) -> Option<Refusal> {
        match request {
            Request::Enable => self.kinco_owner(0x6040, 0).or_else(|| {
                let n = self.kinco_din_with(DinFunction::PreEnable)?;
                (!self.kinco_pre_enable()).then_some(Refusal::InputInactive {
                    input: n + 1,
                    function: "Pre Enable",
                    rule: PRE_ENABLE,
                })
            }),
            Request::Mode(_) => self.kinco_owner(0x6060, 0),
            Request::Write { index, sub } => {
                self.kinco_owner(index, sub).or_else(|| match (index, sub) {
                    (0x60F9, 0x28) if self.value(0x6069, 0x09) == 1 => Some(Refusal::State {
                        reason: "PI_Switch 6069h:09 = 1 switches the gain set itself",
                        rule: "Kinco FD/CD §5.5.4: PI_Pointer is set by the Gain Switch \
                            inputs, else by PI_Switch (6069h:09 = 1), else by hand",
                    }),
                    (0x3040, 0x01) if self.value(0x3041, 0x05) != 1 => Some(Refusal::State {
                        reason: "a tuning run needs WriteFUN_CTL 3041h:05 = 1",
                        rule: "Kinco FD/CD §7.1: over communication, WriteFUN_CTL 3041h:05 \
                            must be 1 before a tuning run starts",
                    }),
                    _ => None,
                })
            }
        }
    }

    /// Transition 2 / 3 may happen: no Pre Enable input, or it is active.
    pub(crate) fn kinco_pre_enable(&self) -> bool {
        let internal = self.din_now();
        self.din_level(internal, DinFunction::PreEnable) != Some(false)
    }

    /// One logic cycle of the input functions, before the controlword is read.
    pub(crate) fn kinco_din_cycle(&mut self) {
        let position = self.plant_position();
        let now = self.kinco_din_internal(position);
        let before = self.vendor.din.internal;
        self.vendor.din.internal = Some(now);
        // The functions are the inputs' until the next SDO write, never changed by this cycle.
        let codes = self.din_codes();
        let level = |_: &Self, f| din_level_of(&codes, now, f);
        let changed = |_: &Self, f| {
            let was = before.and_then(|b| din_level_of(&codes, b, f));
            let is = din_level_of(&codes, now, f);
            (is.is_some() && is != was).then_some(is == Some(true))
        };
        let rising = |d: &Self, f| changed(d, f) == Some(true) && before.is_some();
        if let Some(active) = changed(self, DinFunction::OperationModeSel) {
            let sub = if active { 0x0E } else { 0x0D };
            let m = self.value(0x2020, sub) as i8;
            let _ = self.write_mode(0x6060, 0, &[m as u8]);
        }
        if let Some(active) = changed(self, DinFunction::Enable) {
            let cw = if active {
                self.value(0x2020, 0x0F) as u16
            } else {
                0x0006
            };
            self.kinco_set_controlword(cw);
        }
        if let Some(active) = changed(self, DinFunction::ActivateCommand) {
            let cw = Controlword(self.read(self.hot.controlword) as u16);
            let cw = if active {
                cw | Controlword::NEW_SET_POINT
            } else {
                cw.difference(Controlword::NEW_SET_POINT)
            };
            self.kinco_set_controlword(cw.bits());
        }
        if rising(self, DinFunction::QuickStop) {
            // CiA 402 quick stop: bit 1 set, bit 2 clear.
            let cw = self.read(self.hot.controlword) as u16;
            self.kinco_set_controlword((cw & !0x0004) | 0x0002);
        }
        if rising(self, DinFunction::StartHoming) && self.dc.state() == State::OperationEnabled {
            self.vendor.din.homing_return = Some(self.mode);
            let _ = self.write_mode(0x6060, 0, &[mode::HOMING as u8]);
            let cw = Controlword(self.read(self.hot.controlword) as u16);
            self.kinco_set_controlword((cw | Controlword::HOMING_START).bits());
        }
        self.kinco_homing_return();
        // The position table (§6.4.1): its edges for the next mode-1 cycle; an error, another
        // mode or the enable gone end the flow at once.
        self.vendor.table.start_edge |= rising(self, DinFunction::StartPosTable);
        self.vendor.table.abort_edge |= rising(self, DinFunction::AbortPosTable)
            || !self.kinco_din_configured(DinFunction::StartPosTable);
        self.vendor.table.cond1_rising |= rising(self, DinFunction::PosTableCond1);
        if self.mode != mode::PROFILE_POSITION
            || self.dc.state() != State::OperationEnabled
            || !self.faults.is_empty()
        {
            self.kinco_table_abort();
            self.vendor.table.start_edge = false;
            self.vendor.table.abort_edge = false;
        }
        if rising(self, DinFunction::ResetErrors) {
            self.cw_rising |= Controlword::FAULT_RESET;
        }
        self.kinco_gain_switching(now);
        let motor_error = level(self, DinFunction::MotorError) == Some(true);
        self.cause(
            MOTOR_TEMPERATURE,
            motor_error,
            super::error_register(MOTOR_TEMPERATURE),
        );
        let cw = Controlword(self.read(self.hot.controlword) as u16);
        let enabling = cw.contains(Controlword::ENABLE_OPERATION_CMD);
        let refused = level(self, DinFunction::PreEnable) == Some(false)
            && enabling
            && self.dc.state() != State::Fault;
        if refused && !self.faults.contains(&EXTERNAL_ENABLE) {
            self.raise(
                EXTERNAL_ENABLE,
                super::error_register(EXTERNAL_ENABLE),
                true,
            );
        }
        self.kinco_capture(before, now, position);
        self.kinco_position_limits_cycle();
    }

    /// Gain switching (§5.5.4), in the manual's order: the Gain Switch inputs (PI_Pointer =
    /// BCD(GS1:GS0), an input not configured counts 0); else with PI_Switch 6069h:09 = 1 set 0
    /// while the motor turns and set 1 once Pos Reached or Zero Speed holds; else the
    /// PI_Pointer written. Kvi Off turns the velocity integral off.
    fn kinco_gain_switching(&mut self, internal: u8) {
        let bits = [DinFunction::GainSwitch0, DinFunction::GainSwitch1]
            .map(|f| self.din_level(internal, f));
        let pointer = if bits.iter().any(Option::is_some) {
            Some(i64::from(selected_index(&bits)))
        } else if self.value(0x6069, 0x09) == 1 {
            let settled = self.dout_function(DoutFunction::PosReached)
                || self.dout_function(DoutFunction::ZeroSpeed);
            Some(i64::from(settled))
        } else {
            None
        };
        if let Some(p) = pointer.filter(|p| *p != self.value(0x60F9, 0x28)) {
            let e = self.od.description().entry(0x60F9, 0x28);
            self.store(e, p);
            self.params_dirty = true;
        }
        let kvi_off = self.din_level(internal, DinFunction::KviOff) == Some(true);
        if kvi_off != self.vendor.din.kvi_off {
            self.vendor.din.kvi_off = kvi_off;
            self.params_dirty = true;
        }
    }

    /// "After homing started by the input the drive returns to the previous mode" (Tab.
    /// 5-2): once the homing has ended (attained or failed), the mode and bit 4 go back.
    fn kinco_homing_return(&mut self) {
        let Some(previous) = self.vendor.din.homing_return else {
            return;
        };
        let ended = matches!(self.homing, HomingRun::Idle)
            && (self.homing_attained || self.homing_error)
            && self.mode_pending.is_none();
        if ended || self.dc.state() != State::OperationEnabled {
            self.vendor.din.homing_return = None;
            let _ = self.write_mode(0x6060, 0, &[previous as u8]);
            let cw = Controlword(self.read(self.hot.controlword) as u16);
            self.kinco_set_controlword(cw.difference(Controlword::HOMING_START).bits());
        }
    }

    /// Fast capture (§5.5.5): the first edge of Fast_Capture1 / 2 sets its
    /// flag 2010h:20 … :23 and latches Pos_Actual 6063h into 2010h:24 … :27; later edges are
    /// ignored until the flag is written back to 0.
    fn kinco_capture(&mut self, before: Option<u8>, now: u8, _position: i64) {
        let Some(before) = before else { return };
        for (function, flag) in [
            (DinFunction::FastCapture1, 0x20u8),
            (DinFunction::FastCapture2, 0x22u8),
        ] {
            let (Some(was), Some(is)) = (
                self.din_level(before, function),
                self.din_level(now, function),
            ) else {
                continue;
            };
            if was == is {
                continue;
            }
            let flag = if is { flag } else { flag + 1 };
            if self.value(0x2010, flag) == 0 {
                let pos = self.value(0x6063, 0);
                let d = self.od.description();
                let (f, p) = (d.entry(0x2010, flag), d.entry(0x2010, flag + 4));
                self.store(f, 1);
                self.store(p, pos);
            }
        }
    }

    /// A controlword an input function sets, with the edges a bus write would latch.
    pub(crate) fn kinco_set_controlword(&mut self, cw: u16) {
        let _ = self.od.write_internal(0x6040, 0, &cw.to_le_bytes());
        self.take_controlword(Controlword(cw));
    }

    /// The status of one DOUT function (Tab. 5-3).
    fn dout_function(&self, f: DoutFunction) -> bool {
        let state = self.dc.state();
        let power = !matches!(self.demand, Demand::Off);
        let (negative, positive) = self.kinco_limits_active();
        match f {
            DoutFunction::Ready => {
                self.faults.is_empty()
                    && matches!(
                        state,
                        State::ReadyToSwitchOn | State::SwitchedOn | State::OperationEnabled
                    )
            }
            DoutFunction::Error => matches!(state, State::Fault | State::FaultReactionActive),
            DoutFunction::PosReached => {
                self.mode == mode::PROFILE_POSITION
                    && self.target_reached
                    && state == State::OperationEnabled
            }
            DoutFunction::ZeroSpeed => {
                // Speed_1ms (whole inc/ms) against Zero_Speed_Window 2010h:18 (inc/ms).
                let inc_per_ms = f64::from(self.plant_velocity_rpm())
                    * super::hooks::INCREMENTS_PER_REV as f64
                    / 60_000.0;
                (inc_per_ms as i64).abs() <= self.value(0x2010, 0x18).max(0)
            }
            DoutFunction::MotorBrake => power && !self.brake_engaged,
            DoutFunction::SpeedReached => {
                matches!(self.mode, mode::PROFILE_VELOCITY | -3)
                    && self.target_reached
                    && state == State::OperationEnabled
            }
            DoutFunction::SpeedLimit => {
                self.mode == mode::PROFILE_TORQUE
                    && !self.target_reached
                    && state == State::OperationEnabled
            }
            DoutFunction::DriverEnable => state == State::OperationEnabled,
            DoutFunction::PositionLimit => negative || positive,
            DoutFunction::HomeFound => self.referenced,
            DoutFunction::PosTableActive => self.kinco_table_active(),
            DoutFunction::EncWarning => self.vendor.warnings != 0,
            DoutFunction::EncIndex => false,
        }
    }

    /// The function status of OUTn (the OR of its functions).
    fn dout_status(&self, n: u8) -> bool {
        let code = self.value(0x2010, 0x0F + n).clamp(0, 0xFFFF) as u16;
        DOUT_FUNCTIONS.iter().any(|&(c, f)| {
            let has = if c & 0x8000 == 0 {
                code & 0x8000 == 0 && code & c == c
            } else {
                code == c
            };
            has && self.dout_function(f)
        })
    }

    /// Dout_Real 2010h:14, bit n − 1 = OUTn: `(status OR Simulate) XOR (NOT Polarity)`.
    pub fn kinco_dout_real(&self) -> u8 {
        let status = (0..DOUTS).fold(0u8, |acc, n| acc | (u8::from(self.dout_status(n)) << n));
        let simulate = self.value(0x2010, 0x0E) as u8;
        let polarity = self.value(0x2010, 0x0D) as u8;
        ((status | simulate) ^ !polarity) & 0x1F
    }

    /// Din_Real 2010h:0A and Dout_Real 2010h:14.
    pub(crate) fn kinco_publish_io(&mut self) {
        let din = self.kinco_din_real(self.plant_position());
        let dout = self.kinco_dout_real();
        // Resolved once at power-on (the engine's parameter slots): this runs every cycle.
        let entry = |sub| {
            crate::drive::param_slot(0x2010, sub)
                .and_then(|slot| self.params.get(slot).copied().flatten())
        };
        let (a, b) = (entry(0x0A), entry(0x14));
        self.store(a, i64::from(din));
        self.store(b, i64::from(dout));
    }
}

/// The level of `function` from the internal levels `internal` and the inputs' function codes:
/// `None` if no input has it, else whether any input that has it is active.
fn din_level_of(codes: &[u16; DINS as usize], internal: u8, function: DinFunction) -> Option<bool> {
    let mut any = false;
    let mut active = false;
    for (n, code) in codes.iter().enumerate() {
        if din_has(*code, function) {
            any = true;
            active |= internal & (1 << n) != 0;
        }
    }
    any.then_some(active)
}
