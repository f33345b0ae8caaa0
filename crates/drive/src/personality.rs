//! A CiA 402 personality: what one vendor's drive is, as data the engine in
//! [`crate::drive`] reads, and the hooks it calls where a table cannot say it ([`Vendor`]).
//! The tables are the manuals' tables (modes, option codes, error numbers with their EMCY
//! codes and error-register bits, homing methods, brake delays, the plant's messages); each
//! vendor's tables and hooks live in its folder under [`crate::vendors`].

use crate::control::ControlParams;
use crate::controlword::Controlword;
use crate::device_control::State;
use crate::digital_inputs::InputWiring;
use crate::drive::diagnostics::emcy_code;
use crate::drive::named_switches::{NamedSwitch, SwitchInput};
use crate::drive::object_writes::Hook;
use crate::drive::refusal::{Refusal, Request};
use crate::drive::Drive;
use crate::factor_group::{FactorGroup, FactorObject};
use crate::homing::{HomingError, Method};
use crate::statusword::Statusword;
use crate::travel::Inputs;

/// The following error of a logic cycle as `publish` finds it, for the vendor's
/// [`Vendor::following_error`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FollowingError {
    /// Actual − demand position, increments.
    pub increments: i64,
    /// The window 6065h in increments.
    pub window: i64,
    /// `increments` in user units (60F4h).
    pub user: i32,
}

/// What one vendor's drive does where its manual departs from CiA 402: the engine calls these
/// hooks at the points where the manuals differ, each with CiA 402's behaviour as its
/// default. The vendor type is also the vendor's own state ([`Drive`]'s `vendor` field).
/// Static dispatch: the engine is generic over its vendor.
pub trait Vendor: Sized {
    /// The engine gives the manufacturer-specific objects it knows (the area 2000h–5FFFh of
    /// CiA 301 §7.4.1 and the drive data 6510h) the meaning the vendors' manuals give them.
    /// `false`, CiA 402's default: the engine reads and writes none of them, so a device
    /// file with other objects at those indices keeps its own meanings.
    const MANUFACTURER_OBJECTS: bool = false;

    /// The vendor's objects its hooks read or write every cycle, `(index, sub)`: the engine
    /// looks them up in the dictionary once, beside CiA 402's, and finds a literal key's
    /// slot when compiling. CiA 402's default: none.
    const CACHED_OBJECTS: &'static [(u16, u8)] = &[];

    /// The personality of a drive over `desc` and the vendor's state at power-on.
    fn for_device(desc: &'static od::DeviceDescription) -> (&'static Personality, Self);

    /// At power-on and after a reload (the objects the drive sets itself).
    fn power_on<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &mut Drive<S, Self>) {}

    /// Fixed units instead of the factor group 6093h / 6094h / 6097h; `None`: the factor
    /// group objects (or the feed constant, [`Capabilities::feed_constant`]).
    fn factor_group<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &Drive<S, Self>) -> Option<FactorGroup> {
        None
    }

    /// The controller parameters as the drive's objects give them, read again after a
    /// write to one of them. CiA 402's default: the motor data, the power stage and the
    /// display filter the engine knows, with the gains of [`Vendor`]'s `control_parameter_sets`.
    fn control_params<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> ControlParams {
        crate::drive::control_params_of::<S, Self>(d.od())
    }

    /// The controllers' gains from CiA 402's parameter sets 60F6h (current), 60F9h
    /// (velocity) and 60FBh (position), whose sub-indices the profile leaves to the
    /// manufacturer: `params` (what the engine read of the other objects) with the vendor's
    /// reading of them. Also at power-on, before the vendor's state exists (hence the
    /// dictionary, not the drive). CiA 402's default (Decision: a foreign drive's
    /// sub-indices are in units the twin does not know): `params` as they are, the engine's
    /// standard gains ([`ControlParams::default`], tuned for the default servo motor).
    fn control_parameter_sets<S: AsRef<[u8]> + AsMut<[u8]>>(
        _od: &od::ObjectDictionary<S>,
        params: ControlParams,
    ) -> ControlParams {
        params
    }

    /// Each logic cycle before device control: inputs that own the controlword or the mode.
    fn before_device_control<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &mut Drive<S, Self>) {}

    /// The hardware enables transition 2 needs are present (CiA 402 §6.3.1: the drive's own
    /// condition for READY TO SWITCH ON). CiA 402's default: the inputs of
    /// [`Vendor`]'s `INPUT_WIRING` `enables` are HIGH.
    fn enables<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> bool {
        Self::INPUT_WIRING.enables(d.input_levels(d.plant_position()))
    }

    /// Runs the mode of this cycle where the vendor's own rules drive it; `false`: the
    /// engine's CiA 402 modes.
    fn mode_step<S: AsRef<[u8]> + AsMut<[u8]>>(
        _d: &mut Drive<S, Self>,
        _cw: Controlword,
        _dt: f64,
    ) -> bool {
        false
    }

    /// The vendor's handler of a write to `index:sub`; `None`: the engine's (CiA 402).
    fn write_hook<S: AsRef<[u8]> + AsMut<[u8]>>(_index: u16, _sub: u8) -> Option<Hook<S, Self>> {
        None
    }

    /// What the vendor refuses beyond the engine's rules.
    fn refusal<S: AsRef<[u8]> + AsMut<[u8]>>(
        _d: &Drive<S, Self>,
        _request: Request,
    ) -> Option<Refusal> {
        None
    }

    /// Statusword bits 0–6, 8 and 9: CiA 402 §6.3.2 (bit 4 voltage enabled with the output
    /// stage, bit 9 remote).
    fn state_bits<S: AsRef<[u8]> + AsMut<[u8]>>(
        _d: &Drive<S, Self>,
        state: State,
        power: bool,
        _moving: bool,
    ) -> Statusword {
        Statusword(state.statusword_bits(true))
            | Statusword::VOLTAGE_ENABLED.when(power)
            | Statusword::REMOTE
    }

    /// The profile velocity ramp (acceleration, deceleration, increments/s²) towards a
    /// target on the `positive` side (`None`: the set-point jumps to the target). CiA 402
    /// §6.5: 6083h profile acceleration and 6084h profile deceleration.
    fn profile_velocity_ramp<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        _positive: bool,
    ) -> Option<(f64, f64)> {
        Some((d.accel(0x6083), d.accel(0x6084)))
    }

    /// Statusword bits 14 and 15 (manufacturer specific) and what goes with them.
    fn manufacturer_bits<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &mut Drive<S, Self>) -> Statusword {
        Statusword::EMPTY
    }

    /// After the following error is known each cycle.
    fn following_error<S: AsRef<[u8]> + AsMut<[u8]>>(
        _d: &mut Drive<S, Self>,
        _fe: &FollowingError,
    ) {
    }

    /// Which of the drive's inputs the simulated axis's switches and hardware enables are
    /// wired to (bit n = input n of [`Drive::force_inputs`]). CiA 402 names no input
    /// terminals; its default, [`InputWiring::CIA402`], numbers the inputs as the 60FDh bits
    /// they show.
    const INPUT_WIRING: InputWiring = InputWiring::CIA402;

    /// 60FDh digital_inputs at `position`. CiA 402's default (§6.6.4): bit 0 negative limit,
    /// 1 positive limit, 2 home switch, 3 interlock (a hardware enable missing), as
    /// [`Vendor`]'s `switches` reads them; no manufacturer bits (16 … 31).
    fn digital_inputs<S: AsRef<[u8]> + AsMut<[u8]>>(d: &mut Drive<S, Self>, position: i64) -> u32 {
        Self::INPUT_WIRING.digital_inputs(d.input_levels(position))
    }

    /// The limit and home switches as the drive reads them at `position` (polarity, which
    /// input is which). CiA 402's default: as wired, every switch normally open (the
    /// profile's homing methods name the switch, 60FDh shows it).
    fn switches<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>, position: i64) -> Inputs {
        Self::INPUT_WIRING.switches(d.input_levels(position))
    }

    /// The input carrying `switch` (`None`: no input has its function). CiA 402's default:
    /// the input [`Vendor`]'s `INPUT_WIRING` names, actuated HIGH.
    fn switch_input<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        switch: NamedSwitch,
    ) -> Option<SwitchInput> {
        d.wired_switch_input(switch)
    }

    /// What error `code` does (`critical`: switch the output stage off without a reaction
    /// of its own); `fault`: the condition the engine detected, `None` for an error raised
    /// from outside. CiA 402 §6.3.1: the fault reaction (605Eh fault_reaction_option_code),
    /// the output stage off for a critical one.
    fn error_reaction<S: AsRef<[u8]> + AsMut<[u8]>>(
        _d: &mut Drive<S, Self>,
        _code: u16,
        critical: bool,
        _fault: Option<Fault>,
    ) -> ErrorReaction {
        if critical {
            ErrorReaction::OutputStageOff
        } else {
            ErrorReaction::QuickStop
        }
    }

    /// What diagnostic message `row` does when raised (`by_number`: from outside by its
    /// number, not by the drive's own supervision).
    fn message_reaction<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &mut Drive<S, Self>,
        row: &'static od::Diagnostic,
        _by_number: bool,
    ) -> ErrorReaction {
        let critical = row.reaction == od::Reaction::PsOff;
        Self::error_reaction(d, emcy_code(row), critical, None)
    }

    /// The cause of error `code` has gone (a cleared fault injection): what the vendor's
    /// error management ends with it beyond the engine's EMCY "error reset".
    fn error_cleared<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &mut Drive<S, Self>, _code: u16) {}

    /// The cause of diagnostic message `row` has gone (cleared by its number, or the drive's
    /// own supervision no longer finds it).
    fn message_cleared<S: AsRef<[u8]> + AsMut<[u8]>>(
        _d: &mut Drive<S, Self>,
        _row: &'static od::Diagnostic,
    ) {
    }

    /// The warning the vendor's error management shows, as a row of the device's diagnostic
    /// table: it sets statusword bit 7 warning (CiA 402 §6.3.2) and the row is active.
    /// `None`, CiA 402's default: the engine reports every error as an EMCY, none as a warning.
    fn active_warning<S: AsRef<[u8]> + AsMut<[u8]>>(
        _d: &Drive<S, Self>,
    ) -> Option<&'static od::Diagnostic> {
        None
    }

    /// Homing ends at the offset point: the home point reads −607Ch and the drive travels to
    /// where the position is 0.
    fn homing_to_offset_point<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &Drive<S, Self>) -> bool {
        false
    }

    /// The deceleration, increments/s², of the stop a limit switch starts and of a fault
    /// reaction that brakes with maximum current. CiA 402's default: 6085h
    /// quick_stop_deceleration.
    fn emergency_deceleration<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> f64 {
        d.accel(0x6085)
    }

    /// After the reference point the drive travels to the position 0 (at 6099h:01 search
    /// speed) before homing is attained. `false`, CiA 402's default: homing ends at the
    /// reference point, which then reads 607Ch home_offset.
    fn homing_to_zero<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &Drive<S, Self>) -> bool {
        false
    }

    /// How long homing may run before it fails ([`HomingError::Timeout`]). `None`, CiA 402's
    /// default: the profile names no homing timeout.
    fn homing_timeout<S: AsRef<[u8]> + AsMut<[u8]>>(
        _d: &Drive<S, Self>,
    ) -> Option<core::time::Duration> {
        None
    }

    /// How long a homing on a hard stop lets the shaft settle before the position where it
    /// stands is the reference (with [`Capabilities::homing_immediate`]). CiA 402's default:
    /// at once.
    fn homing_block_settle<S: AsRef<[u8]> + AsMut<[u8]>>(
        _d: &Drive<S, Self>,
    ) -> core::time::Duration {
        core::time::Duration::ZERO
    }

    /// Halt (controlword bit 8) during homing aborts it with statusword bit 13
    /// homing_error. `false`, CiA 402's default: halt interrupts homing, which reads as
    /// "interrupted or not started" (bits 13, 12 and 10 = 0, 0, 1 once stopped), not as an
    /// error.
    const HALT_IS_HOMING_ERROR: bool = false;

    /// Where the drive shows its power stage among the manufacturer's objects (the drive data
    /// 6510h CiA 402 leaves to the manufacturer): the DC link beside 6079h, the peak current
    /// and the controllers' cycle times. `None`, CiA 402's default: 6079h
    /// dc_link_circuit_voltage alone shows the supply, and the power stage has the engine's
    /// defaults ([`ControlParams::default`]).
    const POWER_STAGE_OBJECTS: Option<PowerStageObjects> = None;

    /// Where the drive shows its actual speed through a display filter beside 606Ch
    /// velocity_actual_value. `None`, CiA 402's default: the profile has no display value;
    /// the filter keeps [`ControlParams::default`]'s time and nothing shows it.
    const VELOCITY_DISPLAY_OBJECTS: Option<VelocityDisplayObjects> = None;

    /// The DC-link voltage in mV below which the drive reports its
    /// [`Fault::DcLinkUndervoltage`], where the drive is set to supervise it. `None`, CiA
    /// 402's default: the profile names no threshold object (its object 6079h
    /// dc_link_circuit_voltage only shows the voltage), so the drive raises no undervoltage
    /// error of its own.
    fn dc_link_undervoltage_mv<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &Drive<S, Self>) -> Option<i64> {
        None
    }

    /// The motor's I²t at 100 % is an error ([`Fault::I2tMotor`]), not only the limitation
    /// to the rated current. `false`, CiA 402's default: the drive limits the current to
    /// 6075h motor_rated_current and reports nothing (the profile's current objects 6073h
    /// max_current and 6075h are limits; it names no I²t error).
    fn i2t_is_error<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &Drive<S, Self>) -> bool {
        false
    }

    /// The interpolation period 60C2h gives (ip_time_units, ip_time_index); `None`: outside
    /// what the drive takes, which runs at the default 1 ms. CiA 402's default: units ×
    /// 10^index s, any period the twin can hold.
    fn ip_period(units: u8, index: i8) -> Option<core::time::Duration> {
        crate::interpolated_position::period_of_60c2(units, index)
    }

    /// Whether 60C1h interpolation_data_record takes set-points when the interpolator starts
    /// (power-on, reset). CiA 402's default: as 60C4h:06 buffer_clear says (1: access
    /// enabled), open where the drive has no 60C4h:06 to open it with.
    fn ip_buffer_open_at_reset<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> bool {
        d.od().get_unsigned(0x60C4, 6).is_none_or(|v| v == 1)
    }

    /// The stepper plant runs closed loop (the encoder closes the loops; no step is lost
    /// below the peak torque), read each logic cycle. `false`, CiA 402's default: the
    /// profile has no object that closes a stepper's loop, so the stepper runs open loop.
    fn stepper_closed_loop<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &Drive<S, Self>) -> bool {
        false
    }

    /// Where the drive shows that its stepper plant runs closed loop (1) or open loop (0),
    /// `(index, sub)`; the engine writes it each logic cycle and reads it for the personality's
    /// [`Capabilities::vl_actual_closed_loop_only`]. `None`, CiA 402's default: no object shows it.
    const CLOSED_LOOP_OBJECT: Option<(u16, u8)> = None;

    /// The motor a stepper personality's output stage drives ([`PlantMotor`]), taken while
    /// the output stage is off. CiA 402's default: the stepper.
    fn plant_motor<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &Drive<S, Self>) -> PlantMotor {
        PlantMotor::Stepper
    }

    /// The BLDC's commutation and current limits when a stepper personality drives one
    /// ([`BldcSettings`]). CiA 402's default: [`BldcSettings::default`].
    fn bldc_settings<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &Drive<S, Self>) -> BldcSettings {
        BldcSettings::default()
    }

    /// The quotient numerator / divisor a factor of 6093h / 6094h / 6097h may not exceed
    /// (checked on write; a stored set beyond it falls back to the defaults). `None`, CiA
    /// 402's default: the profile's objects 6093h position_factor, 6094h
    /// velocity_encoder_factor and 6097h acceleration_factor are two UNSIGNED32 each with no
    /// bound on their quotient; a zero numerator or divisor stays refused (no inverse).
    fn factor_limit(_object: FactorObject) -> Option<u32> {
        None
    }
}

/// The objects a vendor shows its power stage in, each `(index, sub)` of an unsigned value
/// ([`Vendor`]'s `POWER_STAGE_OBJECTS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PowerStageObjects {
    /// The nominal DC-link voltage, mV: what the supply gives while no other voltage is set.
    pub nominal_dc_link_voltage: (u16, u8),
    /// The DC-link voltage the drive measures, mV, written with 6079h.
    pub actual_dc_link_voltage: (u16, u8),
    /// The device's peak current, mA.
    pub peak_current: (u16, u8),
    /// The cycle times of the current, velocity and position controllers, µs.
    pub cycle_times: [(u16, u8); 3],
}

/// The motor a stepper personality's output stage drives ([`Vendor`]'s `plant_motor`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlantMotor {
    /// The hybrid stepper (micro-stepping, or closed loop).
    #[default]
    Stepper,
    /// A BLDC commutated from its Hall sensors alone: the position counts Hall edges.
    BldcHall,
    /// A BLDC with its quadrature encoder.
    BldcEncoder,
}

impl PlantMotor {
    /// The motor type as a number: 0 the stepper, 1 BLDC on Hall sensors, 2 BLDC with encoder.
    pub const fn code(self) -> u8 {
        match self {
            PlantMotor::Stepper => 0,
            PlantMotor::BldcHall => 1,
            PlantMotor::BldcEncoder => 2,
        }
    }
}

/// A BLDC's commutation and current limits on a stepper personality ([`Vendor`]'s `bldc_settings`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BldcSettings {
    /// The commutation mode [`crate::bldc::BldcData::torque_factor`] takes.
    pub commutation: u32,
    /// The continuous current, % of the motor's rated current (1 … 100).
    pub current_percent: f64,
    /// The peak current, % of the rated current; at or below `current_percent`: no peak.
    pub peak_percent: f64,
    /// How long the peak current may flow, ms (the axis's I²t time).
    pub peak_time_ms: u16,
}

impl Default for BldcSettings {
    /// The rated current, no peak, commutation mode 0.
    fn default() -> Self {
        BldcSettings {
            commutation: 0,
            current_percent: 100.0,
            peak_percent: 0.0,
            peak_time_ms: 0,
        }
    }
}

/// The objects of a speed shown through a display filter
/// ([`Vendor`]'s `VELOCITY_DISPLAY_OBJECTS`), each `(index, sub)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VelocityDisplayObjects {
    /// The display filter's time constant, µs (unsigned).
    pub filter_time: (u16, u8),
    /// The filtered speed, in the velocity unit of 606Ch.
    pub value: (u16, u8),
}

/// One operating mode: its 6060h value and its 6502h bit (CiA 402 §6.4.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModeSpec {
    pub mode: i8,
    /// The bit of 6502h supported_drive_modes; `None` for manufacturer modes (< 0).
    pub bit: Option<u8>,
    /// Only reachable over EtherCAT (CMMP-AS 6060h = 8).
    pub ethercat_only: bool,
}

/// An option code 605Ah–605Eh (CiA 402 §6.3.4–6.3.8) and its value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OptionCode {
    pub index: u16,
    pub value: i16,
    /// The manual allows this value only.
    pub fixed: bool,
}

/// 605Ah quick_stop_option_code.
pub const QUICK_STOP_OPTION: u16 = 0x605A;
/// 605Bh shutdown_option_code.
pub const SHUTDOWN_OPTION: u16 = 0x605B;
/// 605Ch disable_operation_option_code.
pub const DISABLE_OPERATION_OPTION: u16 = 0x605C;
/// 605Dh halt_option_code.
pub const HALT_OPTION: u16 = 0x605D;
/// 605Eh fault_reaction_option_code.
pub const FAULT_REACTION_OPTION: u16 = 0x605E;

/// A condition the engine detects; the personality names its error (if the drive has one).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    DcLinkUndervoltage,
    FollowingError,
    I2tMotor,
    /// Interpolation started off the SYNC grid.
    NoFieldbusSync,
    /// The SYNC grid lost while interpolating.
    FieldbusSyncError,
    LimitSwitchNegative,
    LimitSwitchPositive,
    Homing(HomingError),
    /// A PP target beyond the software position limits 607Dh.
    SoftwareLimit,
    /// A relative PP target that overflows the position range.
    PositionOverflow,
    /// The pulse input faster than the drive counts (Kinco Frequency_Check 2508h:08).
    Overfrequency,
}

/// One row of a personality's error table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ErrorSpec {
    pub fault: Fault,
    /// The EMCY error code (bytes 0–1 of the EMCY frame, 603Fh).
    pub code: u16,
    /// The error register 1001h bits it sets.
    pub register: u8,
    /// Output stage off at once (no fault-reaction ramp) where no reaction table says
    /// otherwise.
    pub critical: bool,
}

/// Where the engine's CiA 402 behaviour differs between drives, as switches: what one
/// manual's table or rule turns on, another drive can turn on by data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Capabilities {
    /// Positions from the feed constant 6092h and the gear ratio 6091h, 6063h in the
    /// encoder increments of 608Fh (Nanotec §1.2); otherwise the factors 6093h / 6094h / 6097h
    /// (CMMP-AS §5.3).
    pub feed_constant: bool,
    /// Profile Position checks a target against 607Bh (wrap) and 607Dh, and a relative one
    /// for overflow; 6082h is a start speed, bit 9 runs a queued job on the fly (Nanotec
    /// §5.1). Otherwise 6082h is the end velocity of continuous positioning (CMMP-AS).
    pub pp_target_limits: bool,
    /// Interpolated position: the period is the SYNC interval (a PLL), 60C1h:01 needs no
    /// unlocking and the target it shares with 607Ah is the first set-point (Nanotec ch. 7);
    /// otherwise 60C2h on a fixed grid with 60C4h:06 (CMMP-AS §7.4).
    pub ip_follows_sync: bool,
    /// 6061h shows −1 in IP until the drive is on the SYNC grid (CMMP-AS §7.4).
    pub ip_changing_until_synchronised: bool,
    /// A quick stop in IP stops without a ramp (Nanotec §7.3).
    pub ip_abrupt_quick_stop: bool,
    /// Homing accelerates with 609Ah only when starting; at the switch the speed changes
    /// at once, at the end the motor stops at once (Nanotec ch. 5).
    pub homing_immediate: bool,
    /// 60FEh:01 bit 0 is the holding brake (CMMP-AS §5.13).
    pub brake_in_60fe: bool,
    /// An acceleration or deceleration of 0 means no ramp (the set-point steps) instead of
    /// no motion (Kinco: 6083h / 6084h print no default, mode −3 runs without a ramp).
    pub zero_ramp_is_abrupt: bool,
    /// 6044h vl_velocity_actual_value shows a value in closed loop only, 0 in open loop
    /// (Nanotec §6.5: "Nur bei aktiviertem Closed Loop wird ein Wert ausgegeben").
    pub vl_actual_closed_loop_only: bool,
    /// 6063h position_actual_value* is in the user's position units, as 6064h (a drive
    /// with fixed units); otherwise in the engine's internal increments.
    pub internal_position_in_user_units: bool,
}

/// A reference switch a master supplies through an object (an RPDO from an external I/O
/// node): bit `bit_number(index:bit_sub)` of `index:value_sub`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExternalHomeSwitch {
    pub index: u16,
    pub bit_sub: u8,
    pub value_sub: u8,
    /// The homing methods that use it instead of the wired switch.
    pub methods: &'static [i8],
}

/// A CiA 402 personality.
#[derive(Debug)]
pub struct Personality {
    /// The device files (`[device] name`) it serves.
    pub devices: &'static [&'static str],
    /// The modes 6060h accepts.
    pub modes: &'static [ModeSpec],
    pub option_codes: &'static [OptionCode],
    /// Controlword 0Fh in READY TO SWITCH ON enables operation at once (transitions 3 + 4).
    pub enable_from_ready: bool,
    pub errors: &'static [ErrorSpec],
    /// The plant is a hybrid stepper motor ([`crate::stepper`]), not the servo motor.
    pub stepper_plant: bool,
    /// Profile Position: a new set-point while one is queued replaces the queued one.
    pub pp_overwrite_queued: bool,
    pub capabilities: Capabilities,
    /// The homing methods 6098h selects.
    pub homing_methods: &'static [Method],
    pub external_home_switch: Option<ExternalHomeSwitch>,
    /// What stands for the hardware enables transition 2 needs
    /// ([`crate::drive::DriveSettings::enables_present`]); `None`: the drive has none (its
    /// enables are input functions, [`crate::drive::refusal`]).
    pub hardware_enable: Option<HardwareEnable>,
}

/// The hardware enables of a drive, as its manual names them: what is missing while
/// [`crate::drive::DriveSettings::enables_present`] is false (or the inputs are forced low),
/// what that does, and the rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HardwareEnable {
    pub what: &'static str,
    pub effect: &'static str,
    pub rule: &'static str,
}

impl Personality {
    /// Whether 6060h accepts `mode` (`ethercat`: the drive is reached over EtherCAT).
    pub fn accepts_mode(&self, mode: i8, ethercat: bool) -> bool {
        self.modes
            .iter()
            .any(|m| m.mode == mode && (ethercat || !m.ethercat_only))
    }

    /// 6502h supported_drive_modes.
    pub fn supported_drive_modes(&self, ethercat: bool) -> u32 {
        self.modes
            .iter()
            .filter(|m| ethercat || !m.ethercat_only)
            .filter_map(|m| m.bit)
            .fold(0, |acc, b| acc | 1u32 << b)
    }

    /// The value of option code `index`, `default` where the personality has none (CiA 402's
    /// defaults).
    pub fn option_code(&self, index: u16, default: i16) -> i16 {
        self.option_codes
            .iter()
            .find(|o| o.index == index)
            .map_or(default, |o| o.value)
    }

    /// The error the drive reports for `fault`; `None`: this drive does not detect it.
    pub fn error(&self, fault: Fault) -> Option<&'static ErrorSpec> {
        self.errors.iter().find(|e| e.fault == fault)
    }

    pub fn homing_method(&self, method: i8) -> bool {
        self.homing_methods.iter().any(|(m, _)| *m == method)
    }
}

/// What a reported error does to the drive, as the personality's error management decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorReaction {
    /// Nothing beyond what the vendor module already did (a warning, a log entry).
    Ignore,
    /// An EMCY and nothing else: no fault state ("–" in the Nanotec reaction table, the extract's
    /// §7.1).
    MessageOnly,
    /// An EMCY and a quick stop (the state machine's, not a fault).
    QuickStopNoFault,
    /// FAULT REACTION ACTIVE with the quick-stop ramp, then FAULT.
    QuickStop,
    /// FAULT REACTION ACTIVE braking at the current limit, then FAULT.
    BrakeMaxCurrent,
    /// FAULT at once, the output stage off (the motor coasts).
    OutputStageOff,
}
