//! The Kinco CD3 / FD3 in the CiA 402 engine (the CD3 / FD3 user manual): what
//! [`KINCO`](super::KINCO)'s tables cannot say. The motor of the motor-data objects 6410h, the
//! units, the statusword, the error words Error_State / Error_State2 with their masks and the
//! following-error limit, the object rules (6065h from 2FF0h:0E, the DIN-owned controlword and
//! mode) and the velocity and torque modes −3, 3, 4.
//!
//! Units. The manual defines no internal units; the sibling FD manuals
//! give them \[EXT\] with the encoder resolution: velocities in DEC = rpm × 512 × resolution /
//! 1875, accelerations in DEC = rps/s × 65536 × resolution / 4 000 000.
//! Decision: the twin's Kinco has the 2500-line (10 000 increments per revolution) encoder
//! of the Kinco AS motors (Encoder_Out_Res 2340h:0F = 10 000 by default): positions in those
//! increments, velocities and accelerations in the DEC of that resolution. The factors to the
//! engine's units (65 536 per revolution, 1/4096 min⁻¹, 1/256 min⁻¹/s) are then exact
//! ratios: 4096/625, 3/2 and 375/4. Din_Speed, Max_Speed_RPM 6080h and Jog_RPM stay in rpm,
//! as printed.

use od::{AbortCode, ObjectAccess};

use super::{slot, DinFunction, ErrorWord};
use crate::axis::{Axis, Demand};
use crate::control::ControlParams;
use crate::controlword::Controlword;
use crate::device_control::State;
use crate::drive::named_switches::{NamedSwitch, SwitchInput};
use crate::drive::object_writes::Hook;
use crate::drive::refusal::{Refusal, Request};
use crate::drive::{mode, Drive, RPM_PER_INCREMENT_S};
use crate::factor_group::{FactorGroup, Ratio};
use crate::motor::MotorData;
use crate::personality::{ErrorReaction, Personality, Vendor};
use crate::statusword::Statusword;
use crate::trajectory::Trajectory;
use crate::travel::Inputs;

/// The factor group of the units above (see the module doc).
pub(crate) const FACTOR_GROUP: FactorGroup = FactorGroup {
    position: Ratio::new(4096, 625),
    velocity: Ratio::new(3, 2),
    acceleration: Ratio::new(375, 4),
    polarity: 0,
};

/// The Kinco: what it keeps beside the CiA 402 engine's state.
#[derive(Debug, Clone, Default)]
pub struct Kinco {
    /// The inputs at the last cycle (their edges), the Start Homing return, Kvi Off.
    pub(crate) din: super::io::DinMemory,
    /// The simulated pulse input of mode −4.
    pub(crate) pulse: super::pulse::PulseInput,
    /// The error history (the last 8 errors).
    pub(crate) history: heapless::Deque<u16, 8>,
    /// The position table and its flow.
    pub(crate) table: super::table::TableRun,
    /// The simulated analog inputs.
    pub(crate) analog: super::analog::AnalogInputs,
    /// An auto-tuning run.
    pub(crate) tuning: super::tuning::TuningRun,
    /// Jog (F006): the direction and the mode to return to.
    pub(crate) jog: Option<(i8, i8)>,
    /// Warning_Word 2680h as injected.
    pub(crate) warnings: u16,
    /// The LED panel (kinco_panel.rs).
    pub(crate) panel: super::panel::Panel,
    /// The position limits after homing (kinco_limits.rs).
    pub(crate) limits: super::limits::LimitState,
}

impl Vendor for Kinco {
    const MANUFACTURER_OBJECTS: bool = true;

    /// 2010h: DIN polarity, simulate and the seven function codes, the DOUT polarity,
    /// simulate and the five function codes (each in input / output order, one after the
    /// other: `function_codes` counts on it), Zero_Speed_Window and Limit_Function; the
    /// analog filters, selectors and outputs (2502h), the error words (2601h, 2602h), the
    /// display values and the analog offsets and dead bands (2FF0h); PI_Switch 6069h:09;
    /// the display speeds 60F9h:19 / :1A, PI_Pointer 60F9h:28, Pos_Error 60FBh:08 (the
    /// Kinco's sub-indices of CiA 402's objects). Read or written every logic cycle.
    const CACHED_OBJECTS: &'static [(u16, u8)] = &[
        (0x2010, 1),
        (0x2010, 2),
        (0x2010, 3),
        (0x2010, 4),
        (0x2010, 5),
        (0x2010, 6),
        (0x2010, 7),
        (0x2010, 8),
        (0x2010, 9),
        (0x2010, 0x0A),
        (0x2010, 0x0D),
        (0x2010, 0x0E),
        (0x2010, 0x0F),
        (0x2010, 0x10),
        (0x2010, 0x11),
        (0x2010, 0x12),
        (0x2010, 0x13),
        (0x2010, 0x14),
        (0x2010, 0x18),
        (0x2010, 0x19),
        (0x2502, 0x01),
        (0x2502, 0x04),
        (0x2502, 0x07),
        (0x2502, 0x08),
        (0x2502, 0x09),
        (0x2502, 0x0F),
        (0x2502, 0x10),
        (0x2601, 0),
        (0x2602, 0),
        (0x2FF0, 0x14),
        (0x2FF0, 0x16),
        (0x2FF0, 0x17),
        (0x2FF0, 0x18),
        (0x2FF0, 0x1A),
        (0x2FF0, 0x1D),
        (0x2FF0, 0x1E),
        (0x2FF0, 0x1F),
        (0x2FF0, 0x20),
        (0x6069, 0x09),
        (0x60F9, 0x19),
        (0x60F9, 0x1A),
        (0x60F9, 0x28),
        (0x60FB, 0x08),
    ];

    /// The manual is silent on halt in homing; the abort is reported as homing_error, as
    /// the twin has always run it.
    const HALT_IS_HOMING_ERROR: bool = true;

    fn for_device(_desc: &'static od::DeviceDescription) -> (&'static Personality, Self) {
        (&super::KINCO, Kinco::default())
    }

    fn power_on<S: AsRef<[u8]> + AsMut<[u8]>>(d: &mut Drive<S, Self>) {
        d.kinco_power_on();
        d.kinco_panel_power_on();
    }

    /// Fixed units (the module doc), 607Eh the direction.
    fn factor_group<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> Option<FactorGroup> {
        let mut fg = FACTOR_GROUP;
        let invert = d.od().get_unsigned(0x607E, 0).unwrap_or(0) != 0;
        fg.polarity = if invert { 0xC0 } else { 0 };
        Some(fg)
    }

    fn control_params<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> ControlParams {
        d.kinco_control_params()
    }

    /// The DIN functions own the controlword and the mode (L1287); the panel runs.
    fn before_device_control<S: AsRef<[u8]> + AsMut<[u8]>>(d: &mut Drive<S, Self>) {
        d.kinco_din_cycle();
        d.kinco_panel_cycle();
    }

    fn enables<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> bool {
        d.kinco_pre_enable()
    }

    /// The Kinco's own modes (−3, −4, its PP, PV and torque) and the tuning run.
    fn mode_step<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &mut Drive<S, Self>,
        cw: Controlword,
        dt: f64,
    ) -> bool {
        if d.kinco_tuning_active() {
            d.kinco_tuning_step();
            return true;
        }
        match d.mode {
            mode::PROFILE_POSITION => d.kinco_profile_position(cw, dt),
            mode::PROFILE_VELOCITY => d.kinco_velocity(true, dt),
            -3 => d.kinco_velocity(false, dt),
            -4 => d.kinco_pulse_mode(dt),
            mode::PROFILE_TORQUE => d.kinco_torque(dt),
            mode::HOMING => d.homing(cw, dt),
            _ => d.hold(dt),
        }
        d.kinco_velocity_feed_forward();
        true
    }

    fn write_hook<S: AsRef<[u8]> + AsMut<[u8]>>(index: u16, sub: u8) -> Option<Hook<S, Self>> {
        Drive::<S, Self>::kinco_write_hook(index, sub)
    }

    fn refusal<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        request: Request,
    ) -> Option<Refusal> {
        d.kinco_refusal(request)
    }

    fn state_bits<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        state: State,
        power: bool,
        _moving: bool,
    ) -> Statusword {
        d.kinco_state_bits(state, power)
    }

    fn manufacturer_bits<S: AsRef<[u8]> + AsMut<[u8]>>(d: &mut Drive<S, Self>) -> Statusword {
        d.kinco_manufacturer_bits()
    }

    fn following_error<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &mut Drive<S, Self>,
        fe: &crate::personality::FollowingError,
    ) {
        d.kinco_supervise_following_error(fe);
        d.kinco_publish(i64::from(fe.user));
    }

    /// 60FDh stays 0: the inputs show in the Kinco's own objects.
    fn digital_inputs<S: AsRef<[u8]> + AsMut<[u8]>>(d: &mut Drive<S, Self>, _position: i64) -> u32 {
        d.kinco_publish_io();
        0
    }

    fn switches<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>, position: i64) -> Inputs {
        d.kinco_switches(position)
    }

    /// The DIN with the switch's function, its polarity from 2010h:01.
    fn switch_input<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        switch: NamedSwitch,
    ) -> Option<SwitchInput> {
        let function = match switch {
            NamedSwitch::LimitPositive => DinFunction::PositiveLimit,
            NamedSwitch::LimitNegative => DinFunction::NegativeLimit,
            NamedSwitch::Home => DinFunction::HomeSignal,
        };
        let n = d.kinco_din_with(function)?;
        let normal_polarity = d.value(0x2010, 0x01) & (1 << n) != 0;
        // Internal = Real XOR NOT Polarity: a limit is actuated at internal 0, home at 1.
        let internal_actuated = switch == NamedSwitch::Home;
        Some(SwitchInput {
            mask: 1 << n,
            actuated_high: internal_actuated == normal_polarity,
        })
    }

    fn error_reaction<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &mut Drive<S, Self>,
        code: u16,
        _critical: bool,
        _fault: Option<crate::personality::Fault>,
    ) -> ErrorReaction {
        d.kinco_error_reaction(code)
    }

    /// §6.6 Home_Offset_Mode 6099h:05 = 0: "move to the offset point, the actual position is
    /// 0 there"; 1: the home point reads Home_Offset.
    fn homing_to_offset_point<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> bool {
        d.value(0x6099, 0x05) == 0
    }
}

/// Encoder increments per revolution of the twin's Kinco motor (module doc).
pub const INCREMENTS_PER_REV: i64 = 10_000;

/// Statusword bits 0–6 of each state: CiA 402's (the manual defines none, §4.1).
const STATE_BITS: [(State, u16); 8] = [
    (State::NotReadyToSwitchOn, 0x0000),
    (State::SwitchOnDisabled, 0x0040),
    (State::ReadyToSwitchOn, 0x0021),
    (State::SwitchedOn, 0x0023),
    (State::OperationEnabled, 0x0027),
    (State::QuickStopActive, 0x0007),
    (State::FaultReactionActive, 0x000F),
    (State::Fault, 0x0008),
];

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Kinco> {
    /// At power-on (and after a reload): Max_Following_Error 6065h = 100 × 2FF0h:0E
    /// (§6 item 3), a holding brake where Addition_Device 6410h:17 bit 0 says the motor has
    /// one; at power-on the motor of the motor-data objects 6410h.
    pub(crate) fn kinco_power_on(&mut self) {
        self.kinco_set_following_error_limit();
        let brake = self.value(0x6410, 0x17) & 1 != 0;
        if self.settings.brake_fitted != brake {
            self.settings.brake_fitted = brake;
            self.brake_engaged = brake;
            self.axis.hold_brake(brake);
        }
        if self.cycles == 0 {
            if self.settings.motor == MotorData::default() {
                self.settings.motor = self.kinco_motor();
            }
            self.axis = Axis::new(self.settings.motor, self.kinco_control_params());
            self.axis.hold_brake(brake);
        }
    }

    /// The motor of 6410h (§6 item 10 units): Kt 6410h:0F in 0.01 N·m/A, J :10 in
    /// 0.01 kg·cm², the I²t current :09 (the rated current) and Imax_Motor :0B in 0.0707 A,
    /// the maximum speed Max_Speed_RPM 6080h. Friction and brake as the engine's servo motor.
    ///
    /// Decision: the winding (R 6410h:0D, L :0C) stays the engine's servo motor's; its
    /// current controller is tuned for that winding, and the Kinco loop objects that would
    /// retune it are not the engine's (see [`Drive::kinco_control_params`]): with 2 Ω / 4 mH
    /// the current loop rings.
    fn kinco_motor(&self) -> MotorData {
        let d = MotorData::default();
        let or = |v: i64, scale: f64, dflt: f64| if v > 0 { v as f64 * scale } else { dflt };
        MotorData {
            torque_constant: or(self.value(0x6410, 0x0F), 0.01, d.torque_constant),
            inertia: or(self.value(0x6410, 0x10), 1e-6, d.inertia),
            rated_current: or(self.value(0x6410, 0x09), 0.0707, d.rated_current),
            peak_current: or(self.value(0x6410, 0x0B), 0.0707, d.peak_current),
            max_speed_rpm: or(self.value(0x6080, 0), 1.0, d.max_speed_rpm),
            ..d
        }
    }

    /// The controller parameters: the engine's servo controller for the motor above (its
    /// current loop, currents from the motor data, the speed limit from 6080h), with the
    /// velocity and position loops of the Kinco loop objects of the active gain set
    /// (`kinco_loops.rs`, §5.5.4, ch. 7).
    pub(crate) fn kinco_control_params(&self) -> ControlParams {
        let m = self.settings.motor;
        let d = ControlParams::default();
        let rated_ma = (m.rated_current * 1000.0) as u32;
        let peak_ma = (m.peak_current * 1000.0) as u32;
        let base = ControlParams {
            motor_rated_current_ma: rated_ma,
            max_current_permille: (peak_ma * 1000 / rated_ma.max(1)).min(u32::from(u16::MAX))
                as u16,
            peak_current_ma: peak_ma,
            max_motor_speed_rpm: self.value(0x6080, 0).clamp(1, 32768) as u32,
            // The analog max torque (kinco_analog.rs) in the velocity and position loops.
            limit_current_ma: self.vendor.analog.max_current_ma,
            ..d
        };
        self.kinco_loop_params(base)
    }

    fn kinco_set_following_error_limit(&mut self) {
        let limit = super::max_following_error(self.value(0x2FF0, 0x0E).clamp(0, 0xFFFF) as u16);
        let _ = self.od.write_internal(0x6065, 0, &limit.to_le_bytes());
    }

    /// The objects whose Kinco rules do more than store a value.
    pub(crate) fn kinco_write_hook(index: u16, sub: u8) -> Option<Hook<S, Kinco>> {
        Some(match (index, sub) {
            (0x6040, 0x00) => Self::kinco_write_controlword,
            (0x6060, 0x00) => Self::kinco_write_mode,
            (0x2FF0, 0x0E) => Self::kinco_write_max_following_error_16,
            (0x607E, 0x00) => Self::kinco_write_invert_dir,
            (0x60F9, 0x28) => Self::kinco_write_pi_pointer,
            (0x3040, 0x01) => Self::kinco_write_tuning_method,
            (0x2340, _) | (0x60F9, 0x01 | 0x02 | 0x07) | (0x60FB, 0x01) | (0x2FF0, 0x19) => {
                Self::kinco_write_gain
            }
            (0x2FF0, 0x0A) => Self::kinco_write_velocity_bw,
            (0x2FF0, 0x01 | 0x03) => Self::kinco_write_store,
            (0x3041, 0x03) => Self::kinco_write_easy_settings,
            (0x3040, 0x08 | 0x0B) => Self::kinco_write_stiffness,
            _ => return None,
        })
    }

    /// 6040h: "the DIN function has the highest priority: the object can no longer be changed
    /// by hand once a DIN has it, e.g. with Enable configured the controlword cannot be
    /// changed" (L1287, KINCO-CW-06).
    ///
    /// Decision: the write is refused with 0800 0021h (local control), so a master learns why
    /// nothing happens; the manual does not say whether it is refused or ignored.
    fn kinco_write_controlword(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        if self.kinco_refusal(Request::Write { index, sub }).is_some() {
            return Err(AbortCode::LOCAL_CONTROL);
        }
        self.write_controlword(index, sub, data)
    }

    /// 6060h: owned by the Operation Mode Sel DIN as 6040h is by Enable (L1287).
    fn kinco_write_mode(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.write_mode_unless(index, sub, data, |d, m| {
            d.kinco_refusal(Request::Mode(m))
                .map(|_| AbortCode::LOCAL_CONTROL)
        })
    }

    /// PI_Pointer 60F9h:28: owned by the Gain Switch inputs where one is configured (L1287);
    /// otherwise the set the master chooses.
    fn kinco_write_pi_pointer(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        if self.kinco_refusal(Request::Write { index, sub }).is_some() {
            return Err(AbortCode::LOCAL_CONTROL);
        }
        self.kinco_write_gain(index, sub, data)
    }

    /// 2FF0h:0E Max_Following_Error_16: 6065h = 100 × it (§6 item 3, KINCO-SC-09).
    fn kinco_write_max_following_error_16(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        self.kinco_set_following_error_limit();
        Ok(())
    }

    /// Statusword (§4.1: CiA 402's; bit 15 "reference found" of the sibling FD manuals,
    /// [`super::HOME_FOUND`]): bit 4 voltage enabled while the output stage is on. Decision:
    /// bit 9 remote stays 0 (the manual names no remote condition).
    pub(crate) fn kinco_state_bits(&self, state: State, power: bool) -> Statusword {
        let bits = STATE_BITS
            .iter()
            .find(|(s, _)| *s == state)
            .map_or(0, |(_, b)| *b);
        Statusword(bits) | Statusword::VOLTAGE_ENABLED.when(power)
    }

    /// Bit 15: the reference is found; bit 7 (CiA 402 warning) while Warning_Word 2680h is
    /// not 0.
    pub(crate) fn kinco_manufacturer_bits(&self) -> Statusword {
        super::HOME_FOUND.when(self.referenced)
            | Statusword::WARNING.when(self.vendor.warnings != 0)
    }

    /// Warning_Word 2680h (§7: bit 0 battery low, bit 1 mixed warning, bit 2 encoder busy)
    /// from outside (a test, a fault injection): the drive goes on; the Enc Warning output
    /// (8002h) and statusword bit 7 show it. Decision: the twin's encoder has no battery, so
    /// the warnings are injected only; bit 7 is CiA 402's warning bit.
    pub fn set_warnings(&mut self, bits: u16) {
        self.vendor.warnings = bits & 0x0007;
        let e = self.od.description().entry(0x2680, 0);
        self.store(e, i64::from(self.vendor.warnings));
    }

    /// The reaction to an error: none where its bit is masked out (Error_Mask 2605h:01,
    /// Error_Mask2 2605h:04: "bit = 0: the error is ignored", §7); else the output stage goes
    /// off (the motor coasts, the brake closes).
    ///
    /// Decision: the manual lists no reactions; a Kinco drive disables on every error it
    /// shows (ch. 8: "the drive stops and shows the code"), so every error is a fault with
    /// the output stage off.
    pub(crate) fn kinco_error_reaction(&mut self, code: u16) -> ErrorReaction {
        if let Some((word, bit)) = self.kinco_error_bit(code) {
            let mask = match word {
                ErrorWord::State => self.value(0x2605, 0x01),
                ErrorWord::State2 => self.value(0x2605, 0x04),
            };
            if mask & (1 << bit) == 0 {
                return ErrorReaction::Ignore;
            }
            if !self.faults.contains(&code) {
                self.kinco_record_error(code, word, bit);
            }
        }
        ErrorReaction::OutputStageOff
    }

    /// The error history (§7: "the last 8 errors"): an error goes in where its bit is set
    /// in Store_Mask_ON 2605h:02 / Store_Mask_ON2 :05 while the drive is enabled, in
    /// Store_Mask_OFF :03 / Store_Mask_OFF2 :06 while it is not.
    ///
    /// Decision: this part prints no object for the history (the panel and KincoServo show
    /// it); the twin keeps it and gives it through [`Drive::error_history`].
    fn kinco_record_error(&mut self, code: u16, word: ErrorWord, bit: u8) {
        let enabled = self.dc.state() == State::OperationEnabled;
        let sub = match (word, enabled) {
            (ErrorWord::State, true) => 0x02,
            (ErrorWord::State, false) => 0x03,
            (ErrorWord::State2, true) => 0x05,
            (ErrorWord::State2, false) => 0x06,
        };
        if self.value(0x2605, sub) & (1 << bit) != 0 {
            if self.vendor.history.is_full() {
                self.vendor.history.pop_front();
            }
            let _ = self.vendor.history.push_back(code);
        }
    }

    /// The error word and bit of `code`: a row raised by its number first (Error_State bits 1
    /// and 14 share 7331h), else the first row with the code.
    pub(crate) fn kinco_error_bit(&self, code: u16) -> Option<(ErrorWord, u8)> {
        self.injected
            .iter()
            .filter_map(|d| super::KincoError::of(d))
            .find(|e| e.emcy == Some(code))
            .map(|e| (e.word, e.bit))
            .or_else(|| error_bit(code))
    }

    /// The panel's alarm code (ch. 8): the oldest error's bit value (`002.0`); an Error_State2
    /// error shows as Error_State bit 0, `000.1` (SET then opens d1.16). `None` without error.
    pub fn kinco_led(&self) -> Option<[u8; 5]> {
        self.faults
            .iter()
            .find_map(|c| self.kinco_error_bit(*c))
            .map(|(word, bit)| match word {
                ErrorWord::State => super::led_code(bit),
                ErrorWord::State2 => super::led_code(0),
            })
    }

    /// The error history, the oldest of the last 8 first (EMCY codes; Kinco §7).
    pub fn error_history(&self) -> impl Iterator<Item = u16> + '_ {
        self.vendor.history.iter().copied()
    }

    /// The error words of the errors raised and not yet reset: Error_State 2601h (bit 0 for
    /// any Error_State2 bit) and Error_State2 2602h (§7, KINCO-DIAG-01/06); the following
    /// error Pos_Error 60FBh:08 and Real_Speed_RPM 2FF0h:14 (filtered for the display).
    pub(crate) fn kinco_publish(&mut self, following_error: i64) {
        self.kinco_publish_analog();
        let (mut state, mut state2) = (0u16, 0u16);
        for code in self.faults.iter() {
            match self.kinco_error_bit(*code) {
                Some((ErrorWord::State, bit)) => state |= 1 << bit,
                Some((ErrorWord::State2, bit)) => state2 |= 1 << bit,
                None => {}
            }
        }
        if state2 != 0 {
            state |= 1;
        }
        let display_rpm = f64::from(self.axis.velocity_display_rpm());
        // `rounding::round_i64` is `libm::round(v) as i64` bit for bit, without libm's
        // software path.
        let round = crate::rounding::round_i64;
        let i16_range = |v: f64| round(v).clamp(i16::MIN.into(), i16::MAX.into());
        // The entries by literal keys: their parameter slots are found when compiling.
        for (n, (e, v)) in (slot::ERROR_STATE..).zip([
            (self.kinco_entry(0x2601, 0), i64::from(state)),
            (self.kinco_entry(0x2602, 0), i64::from(state2)),
            (self.kinco_entry(0x60FB, 0x08), following_error),
            // Decision: the display values d1.25 (rpm) and d1.26 (0.01 rpm, printed range
            // "−10~10"; held within its 16 bits) are the speed through the engine's display
            // filter (20 ms), so that they do not flicker with the loop's ripple.
            (self.kinco_entry(0x2FF0, 0x14), round(display_rpm)),
            (
                self.kinco_entry(0x60F9, 0x19),
                i16_range(display_rpm * 100.0),
            ),
            // Speed_1ms (Tab. 6-2): the speed feedback (606Ch's) in whole increments per ms.
            (
                self.kinco_entry(0x60F9, 0x1A),
                (f64::from(self.axis.velocity_rpm()) * INCREMENTS_PER_REV as f64 / 60_000.0) as i64,
            ),
            // d1.29 I_q_Arms, 0.1 Arms: the measured current, as 6078h.
            (
                self.kinco_entry(0x2FF0, 0x18),
                i16_range(f64::from(self.axis.current_ma()) / 100.0),
            ),
        ]) {
            self.publish_store(n, e, v);
        }
    }

    /// Modes 3 (ramped with Profile_Acc / Profile_Dec 6083h / 6084h) and −3 (no ramp, §5.2):
    /// the speed Target_Speed 60FFh, or `Din_Speed[x]` (rpm) where a Din Vel Index function is
    /// on a DIN (§6.2.2), or the analog input Analog_Speed_Con names (§6.2.1); the Invert Direction DIN turns it round; Max_Speed_RPM 6080h
    /// limits it; a limit switch blocks its direction.
    pub(crate) fn kinco_velocity(&mut self, ramped: bool, dt: f64) {
        let rpm_max = self.value(0x6080, 0).max(0) as f64;
        if let Some((direction, _)) = self.vendor.jog {
            // Jog (§4, F006): Jog_RPM 2FF0h:23, "independent of other settings", the limit
            // switches not active.
            let rpm = f64::from(direction.signum()) * self.value(0x2FF0, 0x23) as f64;
            self.command_velocity(rpm.clamp(-rpm_max, rpm_max) / RPM_PER_INCREMENT_S, None, dt);
            return;
        }
        let mut rpm = match self.kinco_din_speed_rpm().or(self.kinco_analog_speed_rpm()) {
            Some(rpm) => f64::from(rpm),
            None => {
                let user = self
                    .read(self.hot.target_velocity)
                    .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
                self.fg.velocity_to_internal(user) as f64 / 4096.0
            }
        };
        if self.kinco_din_active(DinFunction::InvertDirection) {
            rpm = -rpm;
        }
        rpm = rpm.clamp(-rpm_max, rpm_max);
        let (negative_blocked, positive_blocked) = self.kinco_limits_active();
        if (rpm < 0.0 && negative_blocked) || (rpm > 0.0 && positive_blocked) || self.halted {
            rpm = 0.0;
        }
        let target = rpm / RPM_PER_INCREMENT_S;
        if ramped || self.halted {
            let ramp = if self.halted {
                (self.accel(0x6084), self.accel(0x6084))
            } else {
                (self.accel(0x6083), self.accel(0x6084))
            };
            self.command_velocity(target, Some(ramp), dt);
        } else {
            self.command_velocity(target, None, dt);
        }
        // Speed Reached (Tab. 5-3): |speed error| < Target_Speed_Window 60F9h:0A (DEC).
        let window = self.fg.velocity_magnitude_to_internal(
            self.value(0x60F9, 0x0A).clamp(0, u32::MAX as i64) as u32,
        ) as f64
            / 4096.0;
        // Decision: on the display-filtered speed (as Real_Speed_RPM), not on the loop's
        // ripple of a fraction of an rpm.
        let error = f64::from(self.axis.velocity_display_rpm()) - rpm;
        self.target_reached = self.velocity_set == target && error.abs() <= window.max(1.0);
    }

    /// Jog (the panel's F006, §4): `direction` > 0 turns at +Jog_RPM 2FF0h:23, < 0 at
    /// −Jog_RPM, in mode −3 without the limit switches; 0 ends it and the mode before it
    /// returns. Decision: jog moves an enabled drive only (the panel's own enable is the
    /// panel's business).
    pub fn jog(&mut self, direction: i8) {
        match (direction, self.vendor.jog) {
            (0, Some((_, previous))) => {
                self.vendor.jog = None;
                let _ = self.write_mode(0x6060, 0, &[previous as u8]);
            }
            (0, None) => {}
            (d, Some((_, previous))) => self.vendor.jog = Some((d, previous)),
            (d, None) => {
                self.vendor.jog = Some((d, self.mode));
                let _ = self.write_mode(0x6060, 0, &[(-3i8) as u8]);
            }
        }
    }

    /// Mode 4 (§5.3): Target_Torque 6071h in % of the rated torque (the motor's rated
    /// current), the speed held to Max_Speed 607Fh (DEC; 0: Max_Speed_RPM 6080h) by taking
    /// the torque back over the last 5 % below it (Decision: the manual does not say how
    /// Speed_Limit_Factor 60F6h:03 shapes the limit); Invert Direction turns it round.
    pub(crate) fn kinco_torque(&mut self, _dt: f64) {
        let rpm = f64::from(self.plant_velocity_rpm());
        // AIN torque (§6.3): mN·m over the rated torque (Kt × rated current), in %.
        let rated_nm = self.settings.motor.torque_constant * self.settings.motor.rated_current;
        let mut percent = match self.kinco_analog_torque_mnm() {
            Some(mnm) if rated_nm > 0.0 => mnm as f64 / 10.0 / rated_nm,
            _ => self.read(self.hot.target_torque) as f64,
        };
        if self.kinco_din_active(DinFunction::InvertDirection) {
            percent = -percent;
        }
        if self.halted {
            percent = 0.0;
        }
        let mut current_a = self
            .axis
            .params()
            .current_for_torque_permille(percent.clamp(-300.0, 300.0) * 10.0);
        if let Some(max) = self.kinco_analog_max_current_a() {
            // The analog max torque (§6.3, kinco_analog.rs).
            current_a = current_a.clamp(-max, max);
        }
        let max_dec = self.value(0x607F, 0).clamp(0, u32::MAX as i64) as u32;
        let limit = if max_dec == 0 {
            self.value(0x6080, 0).max(0) as f64
        } else {
            self.fg.velocity_magnitude_to_internal(max_dec) as f64 / 4096.0
        };
        let along = rpm * current_a.signum();
        let band = 0.05 * limit + 1.0;
        let factor = ((limit - along) / band).clamp(0.0, 1.0);
        let (negative_blocked, positive_blocked) = self.kinco_limits_active();
        let blocked =
            (current_a < 0.0 && negative_blocked) || (current_a > 0.0 && positive_blocked);
        let current = if blocked { 0.0 } else { current_a * factor };
        self.demand = Demand::Torque {
            current_a: current as f32,
        };
        self.target_reached = factor >= 1.0;
        self.traj = Trajectory {
            position: self.actual_internal() as f64,
            velocity: rpm / RPM_PER_INCREMENT_S,
        };
        self.demand_position = self.traj.position;
    }

    /// Mode 1 (§5.4) is CiA 402's profile position (2Fh → 3Fh absolute, 4Fh → 5Fh relative,
    /// the set-point on the rising edge of bit 4, bit 5 change immediately); a limit switch
    /// ahead stops the move with Profile_Dec 6084h and drops the job.
    pub(crate) fn kinco_profile_position(&mut self, cw: Controlword, dt: f64) {
        let (negative_blocked, positive_blocked) = self.kinco_limits_active();
        let v = self.traj.velocity;
        if (negative_blocked && v < 0.0) || (positive_blocked && v > 0.0) {
            self.setpoints.abort();
            let decel = self.accel(0x6084);
            self.traj.step_stop(decel, dt);
            self.position_demand(self.traj.velocity);
            self.kinco_table_abort();
            return;
        }
        if self.kinco_table_cycle(dt) {
            return;
        }
        self.profile_position(cw, dt);
    }

    /// 607Eh Invert_Dir (0: CCW positive, 1: CW positive): positions and speeds turn round.
    fn kinco_write_invert_dir(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        self.reload_factor_group();
        Ok(())
    }

    /// The following error beyond Max_Following_Error 6065h is Error_State bit 9 (8611h,
    /// §5.4, KINCO-DIAG-03), in every mode that controls the position.
    pub(crate) fn kinco_supervise_following_error(
        &mut self,
        following_error: &crate::personality::FollowingError,
    ) {
        let position_controlled = matches!(self.demand, Demand::Position { .. });
        if position_controlled && following_error.increments.abs() > following_error.window {
            self.raise_fault(super::Fault::FollowingError);
        }
    }
}

/// The error word and bit of an EMCY code; Error_State bit 14 shares 7331h with bit 1 and
/// is the answer only when raised by its number (see [`super::errors`]).
pub(crate) fn error_bit(code: u16) -> Option<(ErrorWord, u8)> {
    super::errors()
        .find(|e| e.emcy == Some(code))
        .map(|e| (e.word, e.bit))
}
