//! The Festo CMMP-AS (its CiA 402 manual, Russian edition, and the English edition's
//! appendix): its modes, option codes, homing methods (Tab. 7.1) and error numbers as tables,
//! and as behaviour the error management 2100h (§5.18, [`error_management`]) with the messages
//! of App. B ([`messages`]), warnings, the diagnostic memory and the 7-segment display
//! ([`display`]), the statusword's manufacturer bits (§6.1.4: bit 8 moving, bit 9 from
//! enable_logic, bit 14 from 2000h/200Ah/2005h, bit 15 referenced), the compatibility settings
//! 6510h:F0 and the object rules of its manual.

pub mod ci_terminal;
pub mod control_params;
pub mod digital_inputs;
pub mod display;
pub mod error_management;
pub mod factor_limit;
pub mod homing_methods;
pub mod interpolation_period;
pub mod messages;

use od::{AbortCode, ObjectAccess, Value};

use crate::control::ControlParams;
use crate::controlword::Controlword;
use crate::device_control::State;
use crate::digital_inputs::InputWiring;
use crate::drive::diagnostics::emcy_code;
use crate::drive::named_switches::{NamedSwitch, SwitchInput};
use crate::drive::object_writes::Hook;
use crate::drive::refusal::{Refusal, Request};
use crate::drive::Drive;
use crate::factor_group::FactorObject;
use crate::homing::HomingError;
use crate::personality::{
    Capabilities, ErrorReaction, ErrorSpec, Fault, HardwareEnable, ModeSpec, OptionCode,
    Personality, PowerStageObjects, VelocityDisplayObjects, Vendor,
};
use crate::statusword::Statusword;
use crate::travel::Inputs;
use digital_inputs::SwitchConfig;
use error_management::ErrorManagement;
use homing_methods::METHODS;

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

const fn mode(mode: i8, bit: u8, ethercat_only: bool) -> ModeSpec {
    ModeSpec {
        mode,
        bit: Some(bit),
        ethercat_only,
    }
}

const fn fixed(index: u16, value: i16) -> OptionCode {
    OptionCode {
        index,
        value,
        fixed: true,
    }
}

const fn error(fault: Fault, code: u16, register: u8, critical: bool) -> ErrorSpec {
    ErrorSpec {
        fault,
        code,
        register,
        critical,
    }
}

/// The CMMP-AS.
pub const CMMP_AS: Personality = Personality {
    devices: &["cmmp-as"],
    // §7.1 6060h: 1, 3, 4, 6, 7 over CANopen; 8 CSP over EtherCAT only.
    modes: &[
        mode(1, 0, false),
        mode(3, 2, false),
        mode(4, 3, false),
        mode(6, 5, false),
        mode(7, 6, false),
        mode(8, 7, true),
    ],
    // §6.1.6: every option code has one value only; the reactions are set per error in 2100h.
    option_codes: &[
        fixed(crate::personality::QUICK_STOP_OPTION, 2),
        fixed(crate::personality::SHUTDOWN_OPTION, 0),
        fixed(crate::personality::DISABLE_OPERATION_OPTION, -1),
        fixed(crate::personality::FAULT_REACTION_OPTION, 0),
    ],
    // Tab. 6.2: 0Fh in READY TO SWITCH ON runs transitions 3 and 4.
    enable_from_ready: true,
    errors: &[
        error(
            Fault::DcLinkUndervoltage,
            diag::DC_LINK_UNDERVOLTAGE,
            0x04,
            false,
        ),
        error(Fault::FollowingError, diag::FOLLOWING_ERROR, 0x01, true),
        error(Fault::I2tMotor, diag::I2T_MOTOR, 0x02, false),
        error(Fault::NoFieldbusSync, diag::NO_FIELDBUS_SYNC, 0x11, false),
        error(
            Fault::FieldbusSyncError,
            diag::FIELDBUS_SYNC_ERROR,
            0x11,
            false,
        ),
        error(
            Fault::LimitSwitchNegative,
            diag::LIMIT_SWITCH_NEGATIVE,
            0x01,
            false,
        ),
        error(
            Fault::LimitSwitchPositive,
            diag::LIMIT_SWITCH_POSITIVE,
            0x01,
            false,
        ),
        // B.2 11-0 … 11-6: 8A80h … 8A86h.
        error(Fault::Homing(HomingError::Start), 0x8A80, 0x01, false),
        error(Fault::Homing(HomingError::Aborted), 0x8A81, 0x01, false),
        error(Fault::Homing(HomingError::NoIndex), 0x8A82, 0x01, false),
        error(Fault::Homing(HomingError::Timeout), 0x8A83, 0x01, false),
        error(Fault::Homing(HomingError::LimitSwitch), 0x8A84, 0x01, false),
        error(
            Fault::Homing(HomingError::FollowingError),
            0x8A85,
            0x01,
            false,
        ),
        error(
            Fault::Homing(HomingError::SearchDistance),
            0x8A86,
            0x01,
            false,
        ),
    ],
    stepper_plant: false,
    pp_overwrite_queued: false,
    capabilities: Capabilities {
        feed_constant: false,
        pp_target_limits: false,
        ip_follows_sync: false,
        ip_changing_until_synchronised: true,
        ip_abrupt_quick_stop: false,
        homing_immediate: false,
        brake_in_60fe: true,
        zero_ramp_is_abrupt: false,
        vl_actual_closed_loop_only: false,
        internal_position_in_user_units: false,
    },
    homing_methods: &METHODS,
    external_home_switch: None,
    hardware_enable: Some(HardwareEnable {
        what: "DIN4 output-stage enable and DIN5 controller enable",
        effect: "the drive stays in SWITCH ON DISABLED",
        rule: "CMMP-AS §6.1.3 Tab. 6.4 transition 2: SWITCH ON DISABLED → READY TO SWITCH ON \
            needs output-stage enable and controller enable present, plus Shutdown",
    }),
};

/// The CMMP-AS: its error management 2100h, statusword and write rules, and the state of its
/// error management (the reactions, the warning, the diagnostic memory).
#[derive(Debug, Clone, Default)]
pub struct CmmpAs {
    pub(crate) errors: ErrorManagement,
    /// 2000h:01 manufacturer_statusword_1, written every logic cycle (§6.1.4).
    manufacturer_status: Option<&'static od::Entry>,
}

impl Vendor for CmmpAs {
    const MANUFACTURER_OBJECTS: bool = true;

    /// 2005h:01 / 200Ah:01 (statusword bit 14's mask and inversion), 2045h (the brake's
    /// switch-off delay), 2090h:01 … :05 (the profile velocity ramps) and the drive data
    /// 6510h the hooks read each cycle: the remote bit :10, the switch set-up :11 … :14, the
    /// emergency ramp :15, the brake delay :18, the following-error reaction :22, the
    /// temperature limits :2F / :32, the under-voltage supervision :36 … :38, the
    /// compatibility word :F0.
    const CACHED_OBJECTS: &'static [(u16, u8)] = &[
        (0x2005, 1),
        (0x200A, 1),
        (0x2045, 0),
        (0x2090, 1),
        (0x2090, 2),
        (0x2090, 3),
        (0x2090, 4),
        (0x2090, 5),
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

    /// Ch. 6: halt aborts homing and sets homing_error (statusword bit 13).
    const HALT_IS_HOMING_ERROR: bool = true;

    /// The drive data 6510h: :33 nominal_dc_link_circuit_voltage, :34
    /// actual_dc_link_circuit_voltage, :41 peak_current (the bound of 6073h max_current), :B0
    /// … :B2 the cycle times of the current, velocity and position controllers (§5.17).
    /// §7.5.2: 2074h velocity_actual_value_filtered, the actual speed through the filter of
    /// 2073h velocity_display_filter_time (µs, 20 ms by default), "for display only".
    const VELOCITY_DISPLAY_OBJECTS: Option<VelocityDisplayObjects> = Some(VelocityDisplayObjects {
        filter_time: (0x2073, 0),
        value: (0x2074, 0),
    });

    const POWER_STAGE_OBJECTS: Option<PowerStageObjects> = Some(PowerStageObjects {
        nominal_dc_link_voltage: (0x6510, 0x33),
        actual_dc_link_voltage: (0x6510, 0x34),
        peak_current: (0x6510, 0x41),
        cycle_times: [(0x6510, 0xB0), (0x6510, 0xB1), (0x6510, 0xB2)],
    });

    fn for_device(desc: &'static od::DeviceDescription) -> (&'static Personality, Self) {
        let vendor = CmmpAs {
            manufacturer_status: desc.entry(0x2000, 1),
            ..CmmpAs::default()
        };
        (&CMMP_AS, vendor)
    }

    fn power_on<S: AsRef<[u8]> + AsMut<[u8]>>(d: &mut Drive<S, Self>) {
        d.reset_reactions();
        d.cmmp_power_on();
    }

    fn write_hook<S: AsRef<[u8]> + AsMut<[u8]>>(index: u16, sub: u8) -> Option<Hook<S, Self>> {
        Drive::<S, Self>::cmmp_write_hook(index, sub)
    }

    fn refusal<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        request: Request,
    ) -> Option<Refusal> {
        d.cmmp_refusal(request)
    }

    fn state_bits<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        state: State,
        power: bool,
        moving: bool,
    ) -> Statusword {
        d.cmmp_state_bits(state, power, moving)
    }

    fn manufacturer_bits<S: AsRef<[u8]> + AsMut<[u8]>>(d: &mut Drive<S, Self>) -> Statusword {
        d.cmmp_manufacturer_bits()
    }

    /// §7.6: the ramps 2090h (separate for positive and negative speed, 6083h / 6084h write
    /// them) where 2090h:01 enables them; else the set-point jumps to the target.
    fn profile_velocity_ramp<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        positive: bool,
    ) -> Option<(f64, f64)> {
        if d.value(0x2090, 1) == 0 {
            None
        } else if positive {
            Some((d.accel2(0x2090, 2), d.accel2(0x2090, 3)))
        } else {
            Some((d.accel2(0x2090, 4), d.accel2(0x2090, 5)))
        }
    }

    /// 02-0 DC-link undervoltage below 6510h:36 min_dc_link_circuit_voltage where 6510h:37
    /// enable_dc_link_undervoltage_error is 1.
    fn dc_link_undervoltage_mv<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> Option<i64> {
        (d.value(0x6510, 0x37) == 1).then(|| d.value(0x6510, 0x36))
    }

    /// 31-0 I²t motor (§5.5) where 6510h:38 iit_error_enable is 1.
    fn i2t_is_error<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> bool {
        d.value(0x6510, 0x38) == 1
    }

    /// §5.5–5.7: 60F6h, 60F9h and 60FBh as the CMMP-AS's parameter sets
    /// ([`control_params::parameter_sets`]).
    fn control_parameter_sets<S: AsRef<[u8]> + AsMut<[u8]>>(
        od: &od::ObjectDictionary<S>,
        params: ControlParams,
    ) -> ControlParams {
        control_params::parameter_sets(od, params)
    }

    /// §5.13, §5.14: the limit switches on DIN6 / DIN7, the home switch on DIN9, the
    /// output-stage and controller enables on DIN4 / DIN5.
    const INPUT_WIRING: InputWiring = digital_inputs::WIRING;

    /// §5.13: 60FDh with DIN0 … DIN3, DIN8 and DIN9 in bits 24 … 29, the switches as
    /// 6510h:11 … :14 read them.
    fn digital_inputs<S: AsRef<[u8]> + AsMut<[u8]>>(d: &mut Drive<S, Self>, position: i64) -> u32 {
        d.cmmp_switch_config()
            .digital_inputs(d.input_levels(position))
    }

    /// §5.14: the switches as 6510h:11 limit_switch_polarity, :12 limit_switch_selector,
    /// :13 homing_switch_selector and :14 homing_switch_polarity set them.
    fn switches<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>, position: i64) -> Inputs {
        d.cmmp_switch_config().switches(d.input_levels(position))
    }

    /// §5.14: E0 / E1 and the home switch on the inputs 6510h:12 / :13 select, actuated at
    /// the level 6510h:11 / :14 set.
    fn switch_input<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        switch: NamedSwitch,
    ) -> Option<SwitchInput> {
        Some(d.cmmp_switch_config().switch_input(switch))
    }

    /// §5.14: a limit switch (B.3 43-0 / 43-1) stops with 6510h:15
    /// limit_switch_deceleration, the "limit switch emergency stop ramp". Decision: "brake
    /// with maximum current" uses the same ramp (2 000 000 min⁻¹/s by default), which the
    /// current limit caps.
    fn emergency_deceleration<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> f64 {
        d.accel2(0x6510, 0x15)
    }

    /// §7.2: 6510h:F0 bit 6 homing_to_zero: after the reference point the drive travels to
    /// the zero position.
    fn homing_to_zero<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> bool {
        d.value(0x6510, 0xF0) & 0x0040 != 0
    }

    /// §7.2.2: 2045h homing_timeout in ms, 0 off.
    fn homing_timeout<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
    ) -> Option<core::time::Duration> {
        let ms = d.value(0x2045, 0).max(0) as u64;
        (ms > 0).then(|| core::time::Duration::from_millis(ms))
    }

    /// §7.4.2: index −3 with 1…10 ms, index −4 with 10…100 × 0.1 ms.
    fn ip_period(units: u8, index: i8) -> Option<core::time::Duration> {
        interpolation_period::period_from_60c2(units, index)
    }

    /// §7.4.2: 60C1h is locked after power-on until 60C4h:06 buffer_clear = 1 is written.
    fn ip_buffer_open_at_reset<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &Drive<S, Self>) -> bool {
        false
    }

    /// §5.3: 2²⁴ on 6093h and 6094h ([`factor_limit`](factor_limit::factor_limit)).
    fn factor_limit(object: FactorObject) -> Option<u32> {
        factor_limit::factor_limit(object)
    }

    fn error_reaction<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &mut Drive<S, Self>,
        code: u16,
        critical: bool,
        fault: Option<Fault>,
    ) -> ErrorReaction {
        d.cmmp_error_reaction(code, critical, fault)
    }

    /// By its number, so two messages sharing a code keep their own reaction (17-0 and 27-0
    /// are both 8611h).
    fn message_reaction<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &mut Drive<S, Self>,
        row: &'static od::Diagnostic,
        _by_number: bool,
    ) -> ErrorReaction {
        let critical = row.reaction == od::Reaction::PsOff;
        d.numbered_message_reaction(emcy_code(row), messages::message(row), critical, 0)
    }

    /// The warning of the first App. B message with the code ends.
    fn error_cleared<S: AsRef<[u8]> + AsMut<[u8]>>(d: &mut Drive<S, Self>, code: u16) {
        if let Some(m) = messages::by_code(code) {
            d.end_warning(m.number);
        }
    }

    /// The message's warning ends.
    fn message_cleared<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &mut Drive<S, Self>,
        row: &'static od::Diagnostic,
    ) {
        if let Some(m) = messages::message(row) {
            d.end_warning(m.number);
        }
    }

    /// The warning in 200Fh while it is active (§5.18: "warning on the display and in the
    /// statusword").
    fn active_warning<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
    ) -> Option<&'static od::Diagnostic> {
        d.vendor.errors.active_warning().map(|m| m.row)
    }

    /// The hard limit 6510h:22 (the manual's extract, part 2 §5.7): beyond it error 17-0.
    fn following_error<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &mut Drive<S, Self>,
        fe: &crate::personality::FollowingError,
    ) {
        d.supervise_following_error_limit(fe.increments);
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, CmmpAs> {
    /// At power-on and after a reload. §5.4 (CMMP-SDO-16): enable_logic is set to 2 ("DINs +
    /// CAN") whenever CANopen is active, also after a reset.
    pub(crate) fn cmmp_power_on(&mut self) {
        let _ = self.od.set_value(0x6510, 0x10, Value::Unsigned(2));
    }

    /// The switch assignment 6510h:11 … :14 (§5.14).
    pub(crate) fn cmmp_switch_config(&self) -> SwitchConfig {
        SwitchConfig::from_objects(
            self.value(0x6510, 0x11),
            self.value(0x6510, 0x12),
            self.value(0x6510, 0x13),
            self.value(0x6510, 0x14),
        )
    }

    /// The objects whose CMMP-AS rules do more than store a value.
    pub(crate) fn cmmp_write_hook(index: u16, sub: u8) -> Option<Hook<S, CmmpAs>> {
        Some(match (index, sub) {
            (0x1011, _) => Self::write_restore_defaults,
            (0x6510, 0xF0) => Self::write_compatibility,
            (0x2100, 0x01) => Self::write_reaction_group,
            (0x2100, 0x02) => Self::write_reaction,
            (0x6510, 0x22) => Self::write_following_error_reaction,
            (0x6083 | 0x6084, 0x00) => Self::write_profile_ramp,
            (0x60C4, 0x06) => Self::write_buffer_clear,
            (0x60C1, 0x01) => Self::write_ip_set_point,
            // §7.4.1: a new 60C2h takes effect after save and reset.
            (0x60C2, 0x01 | 0x02) => Self::write_plain,
            (0x2030, 0x00) => Self::write_set_position_absolute,
            (0x6098, 0x00) => Self::write_homing_method,
            _ => return None,
        })
    }

    /// Statusword bits 0–6, 8 and 9 (Tab. 6.6, 6.7). 6510h:F0 bit 7 is CiA 402 v2.0's
    /// FAULT (0008h instead of 000Fh) and "high voltage applied" in bit 4.
    pub(crate) fn cmmp_state_bits(&self, state: State, power: bool, moving: bool) -> Statusword {
        let compat = self.value(0x6510, 0xF0) as u16;
        let mut sw = Statusword(state.statusword_bits(compat & 0x0080 != 0));
        // Bit 4 voltage enabled: output-stage transistors on (CMMP-AS Tab. 6.7); with
        // 6510h:F0 bit 7 CiA 402 v2.0's "high voltage applied", always true in the twin.
        sw |= Statusword::VOLTAGE_ENABLED.when(power || compat & 0x0080 != 0);
        // Bit 8: moving when |v| is above velocity_threshold (the manual's "within" is read as
        // the translation slip it is).
        sw |= Statusword::BIT_8.when(moving);
        // Bit 9 remote: enable_logic 2 (DINs + CAN).
        sw |= Statusword::REMOTE.when(self.value(0x6510, 0x10) == 2);
        sw
    }

    /// Bits 14 and 15 and manufacturer_statusword_1 2000h:01. Bit 14: ((2000h:01 XOR
    /// 200Ah:01) AND 2005h:01) ≠ 0 (CMMP-AS §6.1.4); bit 15 referenced.
    pub(crate) fn cmmp_manufacturer_bits(&mut self) -> Statusword {
        let state = self.dc.state();
        let ready = self.faults.is_empty() && !state.power_enabled();
        let msw = u32::from(self.referenced)
            | 0x2 // commutation valid
            | if ready { 0x4 } else { 0 }
            | if self.setpoints.active.is_none() { 0x8 } else { 0 }
            | if self.safe_standstill { 0x100 } else { 0 };
        self.store(self.vendor.manufacturer_status, i64::from(msw));
        let invert = self.value(0x200A, 1) as u32;
        let mask = self.value(0x2005, 1) as u32;
        Statusword::MANUFACTURER_14.when(manufacturer_bit_14(msw, invert, mask))
            | Statusword::MANUFACTURER_15.when(self.referenced)
    }

    /// 6510h:F0h: the compatibility settings.
    fn write_compatibility(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        // CMMP-AS §5.2 (CMMP-SDO-15): bits 0 and 2 (homing method scheme) mirror each other.
        let v = match data {
            [a, b] => u16::from_le_bytes([*a, *b]),
            _ => return self.od.write(index, sub, data),
        };
        let v = if v & 0x0005 != 0 { v | 0x0005 } else { v };
        self.od.write(index, sub, &v.to_le_bytes())
    }

    /// 1011h: restore defaults, not with the output stage on.
    fn write_restore_defaults(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        if self.cmmp_refusal(Request::Write { index, sub }).is_some() {
            self.od.entry(index, sub)?;
            return Err(AbortCode::DEVICE_STATE);
        }
        self.write_plain(index, sub, data)
    }

    /// The objects the CMMP-AS locks in some states (0800 0022h); the write hooks refuse by
    /// these rules.
    pub(crate) fn cmmp_refusal(&self, request: Request) -> Option<Refusal> {
        let Request::Write { index, sub } = request else {
            return None;
        };
        match (index, sub) {
            // CMMP-AS §5.1 (CMMP-SDO-10): defaults only with the output stage off.
            (0x1011, _) if self.dc.state().power_enabled() => Some(Refusal::State {
                reason: "1011h restores the defaults only with the output stage off",
                rule: "CMMP-AS §5.1 (L2364): default values are loaded only while the output \
                    stage is switched off",
            }),
            (0x60C1, 0x01) if !self.ip.is_unlocked() => Some(Refusal::State {
                reason: "60C1h is locked: 60C4h:06 buffer_clear = 1 unlocks it",
                rule: "CMMP-AS §7.4.2 (L6233–6235): with buffer_clear 60C4h:06 = 0 the buffer \
                    is cleared and access to 60C1h is not allowed",
            }),
            (0x6098, 0x00)
                if self.mode == crate::drive::mode::HOMING
                    && self.dc.state() == State::OperationEnabled
                    && self.last_cw.contains(Controlword::HOMING_START) =>
            {
                Some(Refusal::State {
                    reason: "homing is running: the method cannot change",
                    rule: "CMMP-AS §7.2: 6098h is writable only while homing is not active",
                })
            }
            _ => None,
        }
    }

    /// 6083h / 6084h: the profile ramps, also the 2090h ramps.
    fn write_profile_ramp(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        // CMMP-AS §7.6: 6083h/6084h and the 2090h ramps are the same values.
        let (a, b) = if index == 0x6083 { (2, 4) } else { (3, 5) };
        let _ = self.od.write_internal(0x2090, a, data);
        let _ = self.od.write_internal(0x2090, b, data);
        Ok(())
    }

    /// 60C4h:06h: buffer_clear of interpolated position.
    fn write_buffer_clear(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        // buffer_clear: 1 unlocks 60C1h, 0 clears the buffer and locks it (§7.4.2).
        self.od.write(index, sub, data)?;
        self.ip.set_unlocked(data.first() == Some(&1));
        Ok(())
    }

    /// 60C1h:01h: an interpolated-position set-point.
    fn write_ip_set_point(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        // Decision: 60C1h written while locked (60C4h:06 = 0) is refused with the
        // device-state abort; the manual says only "access is not allowed".
        self.od.entry(index, sub)?;
        if self.cmmp_refusal(Request::Write { index, sub }).is_some() {
            return Err(AbortCode::DEVICE_STATE);
        }
        self.od.write(index, sub, data)?;
        let user = self
            .value(0x60C1, 1)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        let increments = self.fg.position_to_internal(user) as f64;
        // 60C1h:02 = 1: a relative distance from the last set-point.
        let target = if self.value(0x60C1, 2) == 1 {
            self.ip.last_set_point() + increments
        } else {
            increments
        };
        self.ip.set_point(target);
        Ok(())
    }

    /// 2030h: set_position_absolute.
    fn write_set_position_absolute(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        // set_position_absolute: the actual position becomes this value, no motion.
        self.od.write(index, sub, data)?;
        let user = self
            .value(0x2030, 0)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        self.position_offset = self.fg.position_to_internal(user) - self.plant_position();
        self.resync_trajectory();
        Ok(())
    }

    /// 6098h: the homing method.
    fn write_homing_method(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        if self.cmmp_refusal(Request::Write { index, sub }).is_some() {
            // CMMP-AS 7.2: the method is writable only while homing is not active.
            return Err(AbortCode::DEVICE_STATE);
        }
        let m = match data {
            [b] => *b as i8,
            _ => return self.od.write(index, sub, data),
        };
        // The printed 6098h range plus −23/−27 of Tab. 7.1 (the manual's extract, part 3 §9); 32 is
        // in the printed range only and fails at the start (see `start_homing`). Beyond
        // −27 … 35 the dictionary's range check answers.
        let listed = m == 32 || self.personality.homing_method(m);
        if !listed && (-27..=35).contains(&m) {
            self.od.entry(index, sub)?;
            return Err(AbortCode::INVALID_VALUE);
        }
        self.od.write(index, sub, data)
    }
}

/// Statusword bit 14, the manufacturer's freely mapped bit (§6.1.5, L5287): set when
/// `((2000h:01 XOR 200Ah:01) AND 2005h:01) ≠ 0`, so any bit of manufacturer_statusword_1 can
/// be shown, inverted or not.
pub const fn manufacturer_bit_14(manufacturer_status: u32, invert: u32, mask: u32) -> bool {
    (manufacturer_status ^ invert) & mask != 0
}
