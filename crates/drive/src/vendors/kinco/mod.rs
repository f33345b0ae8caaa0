//! Kinco CD3 / FD3 servo drives (the CD3 / FD3 user manual; its text and its extract are kept
//! beside the project): the tables a Kinco personality reads, before the engine knows the vendor.
//! The manual's tables as data: the modes 6060h takes (Tab. 6-5), the controlword values of
//! Tab. 6-5 (§8.15 of the extract), the Error_State / Error_State2 bits with their LED codes and
//! EMCY codes (Tab. 5-7, 5-8, ch. 8), the DIN and DOUT function codes (Tab. 6-1, 6-2), the BCD
//! selection of DIN speed, gear and gain sets (§5.5.3, §5.5.4, §6.2.2), the analog input's offset
//! and dead band (§6.2.1), the filter formulas and the stiffness table (ch. 7, Tab. 4-5 = 7-2), the
//! inertia ratio and the auto-tuning results (§7.1-7.2).
//!
//! The [`KINCO`] personality points at these tables; the behaviour a table cannot hold is in
//! `kinco_drive.rs` (power-on, statusword, error words, modes −3 / 3 / 4, the following-error
//! limit) and `kinco_io.rs` (the DIN and DOUT functions with their simulation objects).

pub mod dip_switches;
pub mod rs232;
pub mod rtu;

mod analog;
pub mod easy;
mod hooks;
mod io;
pub mod limits;
pub mod loops;
pub mod panel;
mod pulse;
pub mod table;
pub mod tuning;

use crate::controlword::Controlword;
use crate::statusword::Statusword;

/// The Kinco's publishing sites in the engine's `publish` (`Drive::publish_store`): the
/// error words and display values (`kinco_publish`), Din_Real and Dout_Real.
pub(crate) mod slot {
    use crate::drive::publish::slot::{COUNT, VENDOR};

    /// Error_State 2601h, then 2602h, 60FBh:08, 2FF0h:14, 60F9h:19, 60F9h:1A, 2FF0h:18.
    pub(crate) const ERROR_STATE: usize = VENDOR;
    pub(crate) const DIN_REAL: usize = VENDOR + 7;
    pub(crate) const DOUT_REAL: usize = VENDOR + 8;
    const _: () = assert!(DOUT_REAL < COUNT);
}

use crate::homing::Speed::Search as Fast;
use crate::homing::Until::Stop;
use crate::homing::{engine_method, step, Method};
use crate::personality::{Capabilities, ErrorSpec, Fault, ModeSpec, Personality};
pub use hooks::Kinco;

const fn mode(mode: i8, bit: Option<u8>) -> ModeSpec {
    ModeSpec {
        mode,
        bit,
        ethercat_only: false,
    }
}

/// The modes of Tab. 6-5 (L1273): −4 pulse / gear, −3 immediate velocity, 1 profile
/// position, 3 profile velocity, 4 torque, 6 homing; the CiA 402 bits of 6502h for the
/// standard ones (devices/kinco-fd3.toml 6502h = 2Dh).
pub const MODES: [ModeSpec; 6] = [
    mode(-4, None),
    mode(-3, None),
    mode(1, Some(0)),
    mode(3, Some(2)),
    mode(4, Some(3)),
    mode(6, Some(5)),
];

/// The Kinco CD3 / FD3.
///
/// Decisions (the manual defines no state machine of its own):
/// CiA 402's, with 0Fh / 2Fh enabling from READY TO SWITCH ON at once (Tab. 6-5: "06h … 0Fh
/// enable"), no option codes (CiA 402's defaults), the servo motor plant.
pub const KINCO: Personality = Personality {
    devices: &["kinco-fd3", "kinco-cd3"],
    modes: &MODES,
    option_codes: &[],
    enable_from_ready: true,
    errors: &[
        error_spec(Fault::FollowingError, 0x8611),
        error_spec(Fault::Overfrequency, 0x8A80),
    ],
    stepper_plant: false,
    pp_overwrite_queued: false,
    capabilities: Capabilities {
        feed_constant: false,
        pp_target_limits: false,
        ip_follows_sync: false,
        ip_changing_until_synchronised: false,
        ip_abrupt_quick_stop: false,
        homing_immediate: false,
        brake_in_60fe: false,
        zero_ramp_is_abrupt: true,
        vl_actual_closed_loop_only: false,
        internal_position_in_user_units: true,
    },
    homing_methods: &HOMING_METHODS,
    external_home_switch: None,
    // The enables are DIN functions (Enable, Pre Enable: kinco_io.rs).
    hardware_enable: None,
};

/// The 1001h error-register bits of an EMCY code (CiA 301 §7.5.2.2: bit 0 generic always;
/// current 2xxxh bit 1, voltage 3xxxh bit 2, temperature 4xxxh bit 3, communication 81xxh
/// bit 4); the manual gives no register values.
pub const fn error_register(code: u16) -> u8 {
    0x01 | match code >> 12 {
        0x2 => 0x02,
        0x3 => 0x04,
        0x4 => 0x08,
        0x8 if code >> 8 == 0x81 => 0x10,
        _ => 0,
    }
}

const fn error_spec(fault: Fault, code: u16) -> ErrorSpec {
    ErrorSpec {
        fault,
        code,
        register: error_register(code),
        critical: true,
    }
}

/// Tab. 6-19 (§6.6, L1690-1720): the CiA 402 methods the manual lists
/// with rows that survived the OCR and the engine has steps for — 1, 2 (limit switch and
/// index), 7, 11, 23, 27 (limit switch and home switch), 17, 18 (limit switch), 19 … 22 (home
/// switch), 33, 34 (index), 35 (here) — and Kinco's −17 / −18 on the mechanical stop
/// (negative / positive).
///
/// Decision: the rows lost in the OCR (3 … 6, 8 … 10, 12 … 14, 24 … 26, 28 … 30) are not
/// offered; 6098h refuses them rather than guess their figures.
pub const HOMING_METHODS: [Method; 17] = [
    // −18: positive until the mechanical stop; −17: negative (the limit switches ignored).
    (-18, &[step(1, Fast, Stop, false)]),
    (-17, &[step(-1, Fast, Stop, false)]),
    engine_method(1),
    engine_method(2),
    engine_method(7),
    engine_method(11),
    engine_method(17),
    engine_method(18),
    engine_method(19),
    engine_method(20),
    engine_method(21),
    engine_method(22),
    engine_method(23),
    engine_method(27),
    engine_method(33),
    engine_method(34),
    engine_method(35),
];

/// The controlword values of Tab. 6-5 (L1272; the KINCO-CW vectors).
pub mod controlword {
    use super::Controlword;

    /// 06h: disable the controller (Shutdown).
    pub const DISABLE: Controlword = Controlword(0x06);
    /// 0Fh: enable in modes 3, −3, −4, 4 and the position table; from 06h at once.
    pub const ENABLE: Controlword = Controlword(0x0F);
    /// 2Fh: enable with "change set immediately" (the Enable DIN's Din_Controlword default).
    pub const ENABLE_IMMEDIATE: Controlword = Controlword(0x2F);
    /// 2Fh → 3Fh: start an absolute move in mode 1.
    pub const START_ABSOLUTE: Controlword = Controlword(0x3F);
    /// 4Fh: relative, ready to start.
    pub const RELATIVE: Controlword = Controlword(0x4F);
    /// 4Fh → 5Fh: start a relative move in mode 1.
    pub const START_RELATIVE: Controlword = Controlword(0x5F);
    /// 0Fh → 1Fh: start homing in mode 6.
    pub const START_HOMING: Controlword = Controlword(0x1F);
    /// 06h → 86h: reset a fault (rising bit 7).
    pub const FAULT_RESET: Controlword = Controlword(0x86);
}

/// Statusword bit 15: reference found. Decision: from the sibling FD manuals (as the extract
/// notes, §4.1, EXT); this manual defines no statusword bits, so the rest is CiA 402's.
pub const HOME_FOUND: Statusword = Statusword(0x8000);

/// Which error word a bit is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorWord {
    /// Error_State 2601h (d1.15), masked by 2605h:01.
    State,
    /// Error_State2 2602h (d1.16), masked by 2605h:04; shown as Error_State bit 0.
    State2,
}

/// One error of Tab. 5-7 / 5-8.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KincoError {
    pub word: ErrorWord,
    pub bit: u8,
    pub name: &'static str,
    /// The EMCY error code; `None` for Error_State bit 0 (it points at Error_State2).
    pub emcy: Option<u16>,
}

impl KincoError {
    /// The error a `[[diagnostic]]` row names: "Error_State.5", "Error_State2.0".
    pub fn of(row: &'static od::Diagnostic) -> Option<KincoError> {
        let (word, bit) = row.number.split_once('.')?;
        let word = match word {
            "Error_State" => ErrorWord::State,
            "Error_State2" => ErrorWord::State2,
            _ => return None,
        };
        Some(KincoError {
            word,
            bit: bit.parse().ok().filter(|b| *b < 16)?,
            name: row.text,
            emcy: row.code,
        })
    }
}

/// §7 Tab. 5-7 / 5-8 (Tab. 8-1 / 8-2) as the device file gives them (`[[diagnostic]]` of
/// `devices/kinco-fd3.toml`; the CD3's file has the same rows).
///
/// Decision: Error_State bit 14 "Encoder information" keeps the printed 7331h, the code of
/// bit 1 too: nothing says which one is the slip. Error_State2's
/// bits 5-7, 12 and 14 are reserved; bit 15's code is printed "7306" without 0x and read as
/// 7306h. Error_State bit 0 "Extended Error" (no EMCY) is the summary of Error_State2.
pub fn errors() -> impl Iterator<Item = KincoError> {
    devices::KINCO_FD3
        .diagnostics
        .iter()
        .filter_map(KincoError::of)
}

/// The error of bit `bit` in `word`.
pub fn error(word: ErrorWord, bit: u8) -> Option<KincoError> {
    if word == ErrorWord::State && bit == 0 {
        return Some(KincoError {
            word,
            bit,
            name: "Extended Error",
            emcy: None,
        });
    }
    errors().find(|e| e.word == word && e.bit == bit)
}

/// The panel's alarm code of a bit (ch. 8, §4.2): the bit's value in four hex digits with a
/// point before the last, `020.0` for bit 9. Five characters, ASCII.
pub fn led_code(bit: u8) -> [u8; 5] {
    const HEX: &[u8; 16] = b"0123456789ABCDEF";
    let v = 1u16.checked_shl(u32::from(bit)).unwrap_or(0);
    let d = |shift: u16| {
        HEX.get(usize::from((v >> shift) & 0xF))
            .copied()
            .unwrap_or(b'0')
    };
    [d(12), d(8), d(4), b'.', d(0)]
}

/// The panel's code when the stored motor type differs from the connected one (ch. 8, L1950).
pub const LED_MOTOR_TYPE: [u8; 5] = *b"FFF.F";

/// A DIN function of Tab. 6-1 (L886-951).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DinFunction {
    Enable,
    ResetErrors,
    OperationModeSel,
    KviOff,
    PositiveLimit,
    NegativeLimit,
    HomeSignal,
    InvertDirection,
    DinVelIndex0,
    DinVelIndex1,
    QuickStop,
    StartHoming,
    ActivateCommand,
    DinVelIndex2,
    Multifunction0,
    Multifunction1,
    Multifunction2,
    GainSwitch0,
    GainSwitch1,
    MotorError,
    PreEnable,
    FastCapture1,
    FastCapture2,
    PosTableCond0,
    PosTableCond1,
    StartPosTable,
    PosTableIdx0,
    PosTableIdx1,
    PosTableIdx2,
    AbortPosTable,
}

/// Tab. 6-1: function code → function. Codes 0001h-4000h are single bits and combine on one
/// input; 8xxxh and 9xxxh are groups whose low bits select one function.
pub const DIN_FUNCTIONS: [(u16, DinFunction); 30] = [
    (0x0001, DinFunction::Enable),
    (0x0002, DinFunction::ResetErrors),
    (0x0004, DinFunction::OperationModeSel),
    (0x0008, DinFunction::KviOff),
    (0x0010, DinFunction::PositiveLimit),
    (0x0020, DinFunction::NegativeLimit),
    (0x0040, DinFunction::HomeSignal),
    (0x0080, DinFunction::InvertDirection),
    (0x0100, DinFunction::DinVelIndex0),
    (0x0200, DinFunction::DinVelIndex1),
    (0x1000, DinFunction::QuickStop),
    (0x2000, DinFunction::StartHoming),
    (0x4000, DinFunction::ActivateCommand),
    (0x8001, DinFunction::DinVelIndex2),
    (0x8004, DinFunction::Multifunction0),
    (0x8008, DinFunction::Multifunction1),
    (0x8010, DinFunction::Multifunction2),
    (0x8020, DinFunction::GainSwitch0),
    (0x8040, DinFunction::GainSwitch1),
    (0x8100, DinFunction::MotorError),
    (0x8200, DinFunction::PreEnable),
    (0x8400, DinFunction::FastCapture1),
    (0x8800, DinFunction::FastCapture2),
    (0x9001, DinFunction::PosTableCond0),
    (0x9002, DinFunction::PosTableCond1),
    (0x9004, DinFunction::StartPosTable),
    (0x9008, DinFunction::PosTableIdx0),
    (0x9010, DinFunction::PosTableIdx1),
    (0x9020, DinFunction::PosTableIdx2),
    (0x9040, DinFunction::AbortPosTable),
];

/// Whether a DINx_Function value `code` includes `function`. Decision: within a group (the top
/// nibble 0 for the single bits, 8h or 9h for the extended ones) the low 12 bits combine as a
/// mask, as they do for the single-bit codes (Tab. 6-1: "several functions on one input");
/// functions of different groups cannot share an input (the manual does not say how).
pub fn din_has(code: u16, function: DinFunction) -> bool {
    // The table lists the functions in their declaration order (checked below): the row of
    // a function is its discriminant, no search in the logic cycle.
    let Some(&(c, _)) = DIN_FUNCTIONS.get(function as usize) else {
        return false;
    };
    if c & 0x8000 == 0 {
        code & 0x8000 == 0 && code & c == c
    } else {
        code & 0xF000 == c & 0xF000 && code & c & 0x0FFF == c & 0x0FFF
    }
}

// Row n of DIN_FUNCTIONS is the function with discriminant n.
const _: () = {
    let mut rest: &[(u16, DinFunction)] = &DIN_FUNCTIONS;
    let mut i = 0;
    while let [row, tail @ ..] = rest {
        assert!(row.1 as usize == i, "DIN_FUNCTIONS out of order");
        rest = tail;
        i += 1;
    }
};

/// A DOUT function of Tab. 6-2 (L955-995).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DoutFunction {
    Ready,
    Error,
    PosReached,
    ZeroSpeed,
    MotorBrake,
    SpeedReached,
    EncIndex,
    SpeedLimit,
    DriverEnable,
    PositionLimit,
    HomeFound,
    EncWarning,
    PosTableActive,
}

/// Tab. 6-2: function code → function; the output is the OR of its functions.
///
/// Decision: Speed Limit, Driver Enable, Position Limit and Home Found are printed 0200h,
/// 0400h, 0800h, 0400h (0080h skipped, 0400h twice): the single-bit sequence 0080h, 0100h,
/// 0200h, 0400h is taken, as the sibling FD manuals have it (the extract's §3.7).
pub const DOUT_FUNCTIONS: [(u16, DoutFunction); 13] = [
    (0x0001, DoutFunction::Ready),
    (0x0002, DoutFunction::Error),
    (0x0004, DoutFunction::PosReached),
    (0x0008, DoutFunction::ZeroSpeed),
    (0x0010, DoutFunction::MotorBrake),
    (0x0020, DoutFunction::SpeedReached),
    (0x0040, DoutFunction::EncIndex),
    (0x0080, DoutFunction::SpeedLimit),
    (0x0100, DoutFunction::DriverEnable),
    (0x0200, DoutFunction::PositionLimit),
    (0x0400, DoutFunction::HomeFound),
    (0x8002, DoutFunction::EncWarning),
    (0x9001, DoutFunction::PosTableActive),
];

/// The BCD index of select inputs, bit 0 first; an input no DIN has counts as 0 (§5.5.3,
/// §5.5.4, §6.2.2): `Some(active)` for an assigned input, `None` for one not assigned.
pub fn selected_index(bits: &[Option<bool>]) -> u8 {
    bits.iter()
        .enumerate()
        .take(8)
        .fold(0u8, |acc, (i, b)| acc | (u8::from(b.unwrap_or(false)) << i))
}

/// §6.2.1: the analog input after offset and dead band, in 0.01 V: `v_in − offset`, reduced
/// toward zero by `dead` and 0 inside the dead band (the inside case is INFERRED, the outside
/// one the manual's worked example).
pub fn analog_out(v_in: i32, offset: i32, dead: i32) -> i32 {
    let x = v_in - offset;
    let dead = dead.abs();
    if x.abs() > dead {
        x - x.signum() * dead
    } else {
        0
    }
}

/// §6.2.1: the speed of an analog output (0.01 V) at `factor` rpm/V.
pub fn analog_speed_rpm(out: i32, factor: i32) -> i32 {
    out * factor / 100
}

/// §6.2.1, Analog_Dead_High / Analog_Dead_Low 2502h:0D / :0E: "if not 0, Analog_out above
/// Analog_Dead_High is treated as 0", likewise below Analog_Dead_Low. `out` with the command
/// it gives, or 0 where a window edge that is not 0 cuts it off.
///
/// Decision: the manual prints ">" for both edges (L1331-1332); for Dead_Low that would zero
/// every value above it, Dead_High's rule included, so it is read as "<": the two
/// are a window outside which the speed command is 0 (a broken wire reading full scale stops
/// the motor). Their unit is not printed; Analog_out's 0.01 V is taken. The window applies to
/// the speed command only: §6.3 names it for no torque command.
pub fn analog_window(out: i32, dead_high: i32, dead_low: i32) -> i32 {
    if (dead_high != 0 && out > dead_high) || (dead_low != 0 && out < dead_low) {
        0
    } else {
        out
    }
}

/// Notch_N 60F9h:03 → notch frequency in Hz (ch. 7, KINCO-SC-06).
pub const fn notch_hz(n: u32) -> u32 {
    n * 10 + 100
}

/// Speed_Fb_N 60F9h:05 → feedback filter bandwidth in Hz (KINCO-SC-07).
pub const fn speed_feedback_hz(n: u32) -> u32 {
    100 + 20 * n
}

/// Output_Filter_N 60F9h:15 → corner frequency in Hz, `None` for N = 1 (no filter):
/// f = −ln(1 − 1/N) / (2π · 62.5 µs) (KINCO-SC-08; the printed formula is garbled, this one
/// gives Tab. 4-5's values). Decision: the exact value; the table prints it to within 1 Hz,
/// neither truncated nor rounded throughout (1032.51 is printed 1032, 732.58 is 733).
pub fn output_filter_hz(n: u32) -> Option<f64> {
    if n < 2 {
        return None;
    }
    let x = 1.0 / f64::from(n);
    Some(-libm::log(1.0 - x) / (2.0 * core::f64::consts::PI * 62.5e-6))
}

/// One row of the stiffness table: Kpp in 0.01 Hz, the velocity bandwidth in 0.1 Hz, the
/// output filter in Hz (`None` = off).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stiffness {
    pub kpp: u16,
    pub kvp_bandwidth: u16,
    pub output_filter_hz: Option<u16>,
}

const fn s(kpp: u16, kvp_bandwidth: u16, filter: u16) -> Stiffness {
    Stiffness {
        kpp,
        kvp_bandwidth,
        output_filter_hz: if filter == 0 { None } else { Some(filter) },
    }
}

/// Tab. 4-5 = Tab. 7-2 (L670-689, L1806-1825): stiffness 0…31 (3040h:08).
pub const STIFFNESS: [Stiffness; 32] = [
    s(70, 25, 18),
    s(98, 35, 24),
    s(139, 50, 35),
    s(195, 70, 49),
    s(264, 95, 66),
    s(334, 120, 83),
    s(389, 140, 100),
    s(473, 170, 118),
    s(556, 200, 146),
    s(639, 230, 164),
    s(750, 270, 189),
    s(889, 320, 222),
    s(1056, 380, 268),
    s(1250, 450, 340),
    s(1500, 540, 360),
    s(1667, 600, 392),
    s(1945, 700, 464),
    s(2223, 800, 568),
    s(2500, 900, 568),
    s(2778, 1000, 733),
    s(3334, 1200, 733),
    s(3889, 1400, 1032),
    s(4723, 1700, 1032),
    s(5556, 2000, 1765),
    s(6389, 2300, 1765),
    s(7500, 2700, 1765),
    s(8612, 3100, 1765),
    s(9445, 3400, 0),
    s(10278, 3700, 0),
    s(11112, 4000, 0),
    s(12500, 4500, 0),
    s(13889, 5000, 0),
];

/// Inertia_Ratio 3040h:0B from the load and motor inertia (tn02, KINCO-SC-10): 30 = 3.0.
pub fn inertia_ratio(j_load: f64, j_motor: f64) -> i32 {
    ((j_load + j_motor) * 10.0 / j_motor) as i32
}

/// What an inertia measurement leaves in Inertia_Get_Result 3040h:09 and Inertia_Ratio
/// 3040h:0B (§7.1, KINCO-SC-12): success 1 and the measured ratio; above 250 result −3 with the
/// measured value; above 500 result −4 and 30. Decision: "above" is strict (> 250, > 500),
/// as printed.
pub fn tuning_result(measured_ratio: i32) -> (i8, i32) {
    if measured_ratio > 500 {
        (-4, 30)
    } else if measured_ratio > 250 {
        (-3, measured_ratio)
    } else {
        (1, measured_ratio)
    }
}

/// Max_Following_Error 6065h from Max_Following_Error_16 2FF0h:0E (KINCO-SC-09).
pub const fn max_following_error(max_16: u16) -> u32 {
    100 * max_16 as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The values of Tab. 6-5: its controlwords are CiA 402 commands (the sequences through
    /// the drive: `tests/kinco_modes.rs`).
    #[test]
    fn kinco_cw_values_are_cia402_commands() {
        use controlword::*;
        assert_eq!(DISABLE, Controlword::SHUTDOWN);
        assert_eq!(ENABLE, Controlword::ENABLE_OPERATION_CMD, "KINCO-CW-05");
        assert!(
            ENABLE_IMMEDIATE.contains(Controlword::CHANGE_SET_IMMEDIATELY),
            "KINCO-CW-05"
        );
        for (id, from, to) in [
            ("KINCO-CW-01", ENABLE_IMMEDIATE, START_ABSOLUTE),
            ("KINCO-CW-02", RELATIVE, START_RELATIVE),
            ("KINCO-CW-03", ENABLE, START_HOMING),
        ] {
            assert_eq!(
                to.0 & !from.0,
                Controlword::NEW_SET_POINT.0,
                "{id}: rising bit 4"
            );
        }
        assert!(
            START_RELATIVE.contains(Controlword::RELATIVE),
            "KINCO-CW-02"
        );
        assert!(
            !START_ABSOLUTE.contains(Controlword::RELATIVE),
            "KINCO-CW-01"
        );
        assert_eq!(
            FAULT_RESET.0 & !DISABLE.0,
            Controlword::FAULT_RESET.0,
            "KINCO-CW-04"
        );
        let modes: [i8; 6] = MODES.map(|m| m.mode);
        assert_eq!(modes, [-4, -3, 1, 3, 4, 6]);
        let bits = MODES
            .iter()
            .filter_map(|m| m.bit)
            .fold(0u32, |a, b| a | 1 << b);
        assert_eq!(bits, 0x2D, "6502h of the device file");
    }

    /// The LED codes and EMCY codes of both error words (Tab. 5-7, 5-8, ch. 8), each vector at
    /// its row; FFF.F.
    #[test]
    fn kinco_diag_led_and_emcy() {
        let led = |w, b| (led_code(b), error(w, b).and_then(|e| e.emcy));
        assert_eq!(led(ErrorWord::State, 0), (*b"000.1", None), "KINCO-DIAG-01");
        assert_eq!(
            led(ErrorWord::State, 5),
            (*b"002.0", Some(0x3210)),
            "KINCO-DIAG-02"
        );
        assert_eq!(
            led(ErrorWord::State, 9),
            (*b"020.0", Some(0x8611)),
            "KINCO-DIAG-03"
        );
        assert_eq!(
            led(ErrorWord::State, 15),
            (*b"800.0", Some(0x6310)),
            "KINCO-DIAG-04"
        );
        assert_eq!(LED_MOTOR_TYPE, *b"FFF.F", "KINCO-DIAG-05");
        assert_eq!(
            led(ErrorWord::State2, 0),
            (*b"000.1", Some(0x5210)),
            "KINCO-DIAG-06 (bit 0)"
        );
        assert_eq!(
            led(ErrorWord::State2, 9),
            (*b"020.0", Some(0x5442)),
            "KINCO-DIAG-06 (bit 9)"
        );
        assert_eq!(
            led(ErrorWord::State2, 15),
            (*b"800.0", Some(0x7306)),
            "KINCO-DIAG-07"
        );
        assert!(error(ErrorWord::State2, 5).is_none(), "reserved");
    }

    /// The §6.2.1 analog speed example: offset 2 V, dead band 1 V, 100 rpm/V.
    #[test]
    fn kinco_sc_01_02_analog_speed() {
        let out = analog_out(500, 200, 100);
        assert_eq!(
            (out, analog_speed_rpm(out, 100)),
            (200, 200),
            "KINCO-SC-01: +5 V → 2 V → 200 rpm"
        );
        let out = analog_out(-500, 200, 100);
        assert_eq!(
            (out, analog_speed_rpm(out, 100)),
            (-600, -600),
            "KINCO-SC-02: −5 V → −6 V → −600 rpm"
        );
        assert_eq!(analog_out(250, 200, 100), 0, "inside the dead band");
        // The same example with Analog_Dead_High = 1 V, Analog_Dead_Low = −5 V: +5 V gives
        // 2 V, beyond 1 V: 0 rpm; −5 V gives −6 V, below −5 V: 0 rpm; 2.5 V + 2 V offset
        // gives 0.5 V − dead band... inside.
        assert_eq!(analog_window(200, 100, -500), 0);
        assert_eq!(analog_window(-600, 100, -500), 0);
        assert_eq!(analog_window(50, 100, -500), 50);
        assert_eq!(analog_window(-600, 0, 0), -600, "0 = no edge");
    }

    /// The BCD selections of DIN speed, gear set and gain set; an input without the function
    /// counts 0.
    #[test]
    fn kinco_sc_03_04_05_bcd_selection() {
        assert_eq!(
            selected_index(&[Some(false), Some(true), Some(false)]),
            2,
            "KINCO-SC-03: Din Vel Index1 → Din_Speed[2]"
        );
        assert_eq!(
            selected_index(&[Some(false), Some(true), Some(true)]),
            6,
            "KINCO-SC-04: Multifunction1 + 2 → gear set 6"
        );
        assert_eq!(
            selected_index(&[Some(true), Some(false)]),
            1,
            "KINCO-SC-05: Gain_Switch0 → PI_Pointer 1"
        );
        assert_eq!(selected_index(&[None, Some(true), None]), 2);
        assert!(din_has(0x0003, DinFunction::Enable) && din_has(0x0003, DinFunction::ResetErrors));
        assert!(din_has(0x8004, DinFunction::Multifunction0));
        assert!(!din_has(0x8004, DinFunction::KviOff));
        assert!(din_has(0x8001, DinFunction::DinVelIndex2));
        assert!(!din_has(0x0001, DinFunction::DinVelIndex2));
        assert!(din_has(0x9004, DinFunction::StartPosTable));
        assert!(!din_has(0x9004, DinFunction::Multifunction0));
    }

    /// The filter formulas of ch. 7.
    #[test]
    fn kinco_sc_06_07_08_filters() {
        assert_eq!(
            (notch_hz(40), notch_hz(45)),
            (500, 550),
            "KINCO-SC-06: notch 40 → 500 Hz, 45 → 550 Hz"
        );
        assert_eq!(
            [25, 0, 45].map(speed_feedback_hz),
            [600, 100, 1000],
            "KINCO-SC-07: Speed_Fb_N 25, 0, 45"
        );
        assert_eq!(output_filter_hz(1), None, "KINCO-SC-08: N = 1, no filter");
        for (n, printed) in [
            (2, 1765.0),
            (3, 1032.0),
            (4, 733.0),
            (5, 568.0),
            (6, 464.0),
            (7, 392.0),
            (8, 340.0),
        ] {
            let f = output_filter_hz(n).unwrap_or(0.0);
            assert!((f - printed).abs() < 1.0, "KINCO-SC-08: N = {n}: {f}");
        }
    }

    /// The following error limit, the inertia ratio and the tuning results.
    #[test]
    fn kinco_sc_09_10_12_limits_and_tuning() {
        assert_eq!(max_following_error(5242), 524_200, "KINCO-SC-09");
        assert_eq!(inertia_ratio(2.0, 1.0), 30, "KINCO-SC-10");
        assert_eq!(tuning_result(251), (-3, 251), "KINCO-SC-12: > 250");
        assert_eq!(tuning_result(501), (-4, 30), "KINCO-SC-12: > 500");
        assert_eq!(tuning_result(30), (1, 30));
    }

    /// The stiffness table (Tab. 4-5 / 7-2) as data; the table's filter column is the output
    /// filter formula's value of some N. Through the drive: `tests/kinco_tuning.rs`.
    #[test]
    fn kinco_sc_13_stiffness_table() {
        assert_eq!(STIFFNESS[0], s(70, 25, 18), "KINCO-SC-13: stiffness 0");
        assert_eq!(
            STIFFNESS[12],
            s(1056, 380, 268),
            "KINCO-SC-13: stiffness 12"
        );
        assert_eq!(
            STIFFNESS[23],
            s(5556, 2000, 1765),
            "KINCO-SC-13: stiffness 23"
        );
        assert_eq!(
            STIFFNESS[31],
            s(13889, 5000, 0),
            "KINCO-SC-13: stiffness 31"
        );
        assert!(STIFFNESS.windows(2).all(|w| w[0].kpp < w[1].kpp));
        for n in 2..=8 {
            let f = output_filter_hz(n).unwrap_or(0.0);
            let near = |r: &Stiffness| {
                r.output_filter_hz
                    .is_some_and(|h| (f64::from(h) - f).abs() < 1.0)
            };
            assert!(STIFFNESS.iter().any(near), "N = {n}");
        }
    }

    #[test]
    fn dout_codes_are_single_bits_or_groups() {
        for (code, _) in DOUT_FUNCTIONS {
            assert!(code.count_ones() == 1 || code & 0x8000 != 0, "{code:04X}");
        }
        assert_eq!(HOME_FOUND.0, 0x8000);
    }
}
