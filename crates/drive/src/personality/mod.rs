//! A CiA 402 personality: what one vendor's drive is, as data the engine in
//! [`crate::drive`] reads. The tables are the manuals' tables (modes, option codes, error
//! numbers with their EMCY codes and error-register bits, homing methods); what a table
//! cannot hold (the CMMP-AS's error management 2100h, Nanotec's statusword bits) is an
//! `impl Drive` block in the vendor's module, chosen by [`Vendor`].
//!
//! Decision: the device file names its personality by its `name` ([`for_device`]); a CiA 402
//! device file without a personality of its own runs as the CMMP-AS, as every CiA 402 drive
//! did before the split.

pub mod cmmp_as;
pub mod kinco;
pub(crate) mod kinco_analog;
pub(crate) mod kinco_drive;
pub mod kinco_easy;
pub(crate) mod kinco_io;
pub mod kinco_limits;
pub mod kinco_loops;
pub mod kinco_panel;
pub(crate) mod kinco_pulse;
pub mod kinco_table;
pub mod kinco_tuning;
pub mod nanotec;
pub mod nanotec_units;

use crate::homing::{HomingError, Method};

/// Which vendor module holds the behaviour a table cannot say.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Vendor {
    CmmpAs,
    Nanotec,
    Kinco,
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
    /// encoder increments of 608Fh (Nanotec §6); otherwise the factors 6093h / 6094h / 6097h
    /// (CMMP-AS §5.3).
    pub feed_constant: bool,
    /// Profile Position checks a target against 607Bh (wrap) and 607Dh, and a relative one
    /// for overflow; 6082h is a start speed, bit 9 runs a queued job on the fly (Nanotec
    /// §5.1). Otherwise 6082h is the end velocity of continuous positioning (CMMP-AS).
    pub pp_target_limits: bool,
    /// Interpolated position: the period is the SYNC interval (a PLL), 60C1h:01 needs no
    /// unlocking and the target it shares with 607Ah is the first set-point (Nanotec §5.4);
    /// otherwise 60C2h on a fixed grid with 60C4h:06 (CMMP-AS §7.4).
    pub ip_follows_sync: bool,
    /// 6061h shows −1 in IP until the drive is on the SYNC grid (CMMP-AS §7.4).
    pub ip_changing_until_synchronised: bool,
    /// A quick stop in IP stops without a ramp (Nanotec §5.4).
    pub ip_abrupt_quick_stop: bool,
    /// Homing accelerates with 609Ah only when starting; at the switch the speed changes
    /// at once, at the end the motor stops at once (Nanotec §5.2).
    pub homing_immediate: bool,
    /// The switches are read through 6510h:11 … :14 (CMMP-AS §5.14); otherwise as wired.
    pub switch_polarity_objects: bool,
    /// 60FEh:01 bit 0 is the holding brake (CMMP-AS §5.13).
    pub brake_in_60fe: bool,
    /// An acceleration or deceleration of 0 means no ramp (the set-point steps) instead of
    /// no motion (Kinco: 6083h / 6084h print no default, mode −3 runs without a ramp).
    pub zero_ramp_is_abrupt: bool,
    /// 6044h vl_velocity_actual_value shows a value in closed loop only, 0 in open loop
    /// (Nanotec §6.5: "Nur bei aktiviertem Closed Loop wird ein Wert ausgegeben").
    pub vl_actual_closed_loop_only: bool,
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
    pub vendor: Vendor,
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

/// Every personality.
pub const ALL: [&Personality; 3] = [&cmmp_as::CMMP_AS, &nanotec::NANOTEC, &kinco::KINCO];

/// The personality of the device file `name` (see the module doc for the fallback).
pub fn for_device(name: &str) -> &'static Personality {
    ALL.iter()
        .copied()
        .find(|p| p.devices.contains(&name))
        .unwrap_or(&cmmp_as::CMMP_AS)
}

/// What a reported error does to the drive, as the personality's error management decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorReaction {
    /// Nothing beyond what the vendor module already did (a warning, a log entry).
    Ignore,
    /// An EMCY and nothing else: no fault state (Nanotec §7.1 "–").
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
