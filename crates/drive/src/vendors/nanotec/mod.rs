//! Nanotec stepper and BLDC controllers with the CANopen firmware (SMCI47-S, PD4-N; the CANopen
//! reference manual and its extract, kept beside the project): the modes of 6502h (§9.43), the one
//! option code 605Ah = 3, the bit-valued EMCY codes of §13.3 with their reaction table (legacy and
//! new by 2020h; §7.1 of the extract), the homing methods of §5.3 and the [`Capabilities`] it
//! switches on in the engine (feed constant, PP target limits, IP on the SYNC interval, immediate
//! homing speed changes) as tables; as behaviour the statusword (bit 9 remote always set,
//! bit 4 from Switched On, bit 8 PLL sync), 60FDh, the 6060h rules (no PV, torque only in closed
//! loop, no change during a brake wait), the shared target 60C1h:01 / 607Ah and torque mode on the
//! stepper's closed loop.

pub mod rotary_switches;

pub mod units;

use od::{AbortCode, ObjectAccess};

use crate::axis::Demand;
use crate::controlword::Controlword;
use crate::device_control::State;
use crate::digital_inputs::InputWiring;
use crate::drive::diagnostics::emcy_code;
use crate::drive::object_writes::Hook;
use crate::drive::refusal::{Refusal, Request};
use crate::drive::{mode, Drive, RPM_PER_INCREMENT_S};
use crate::homing::{engine_method, Method, Speed, Step, Until};
use crate::personality::{
    BldcSettings, Capabilities, ErrorReaction, ErrorSpec, ExternalHomeSwitch, Fault,
    HardwareEnable, ModeSpec, OptionCode, Personality, PlantMotor, Vendor,
};
use crate::statusword::Statusword;
use crate::stepper::StepperData;
use crate::trajectory::Trajectory;
use units::{load_angle_spacing_rpm, torque_current_ma};

/// Nanotec EMCY codes (§13.3): one bit per cause.
///
/// Decision: the manual does not say which code set goes into bytes 0–1 of the EMCY in the
/// legacy and the new format (2020h); the twin sends these §13.3 codes in
/// both, as §13.2 calls bytes 0–1 the "Emergency Error Code" beside the §13.3 table of these
/// codes, and the error register 1001h bit 0 (generic, §7.4). The CiA codes of §17 are the
/// firmware's names for the standard ranges; no Nanotec cause is mapped to them in the text.
pub mod emcy {
    pub const UNDERVOLTAGE: u16 = 0x0001;
    pub const OVERTEMPERATURE: u16 = 0x0002;
    pub const LIFEGUARD: u16 = 0x0004;
    pub const DATA_ERROR: u16 = 0x0008;
    pub const TRAVEL_DIRECTION: u16 = 0x0020;
    pub const STEP_CALCULATION: u16 = 0x0040;
    pub const OVERCURRENT: u16 = 0x0080;
    pub const TRANSMIT_ERRORS: u16 = 0x0100;
    pub const RECEIVE_ERRORS: u16 = 0x0200;
    pub const TRANSMIT_BUFFER_FULL: u16 = 0x0400;
    /// The target exceeds the software position limit (or the position range limit).
    pub const POSITION_LIMIT: u16 = 0x0800;
    /// Position overflow.
    pub const POSITION_OVERFLOW: u16 = 0x1000;
}

const fn mode(mode: i8, bit: Option<u8>) -> ModeSpec {
    ModeSpec {
        mode,
        bit,
        ethercat_only: false,
    }
}

/// The Nanotec controllers.
///
/// Decision: 6060h lists 3 (PV) but 6502h and the text say PV is not supported (§9): 3 is
/// refused with 0609 0030h. 0 ("no mode") is taken; the drive then holds its position.
pub const NANOTEC: Personality = Personality {
    devices: &["nanotec-smci47s", "nanotec-pd4n"],
    // §9.43 6502h = 6Bh: PP bit 0, VL bit 1, TQ bit 3, HM bit 5, IP bit 6 (NT-SC-10); −1 / −2
    // the closed-loop test runs (§11.2).
    modes: &[
        mode(-2, None),
        mode(-1, None),
        mode(0, None),
        mode(1, Some(0)),
        mode(2, Some(1)),
        mode(4, Some(3)),
        mode(6, Some(5)),
        mode(7, Some(6)),
    ],
    // 605Ah = 3, the only value (§4.4). Decision: §4.4 reads it "brake with maximum current,
    // then Switch On Disabled", §4.2 (L769) says the quick stop brakes "with the ramp set in
    // 6085h" (604Ah in VL, abrupt in IP, §7.3); the twin brakes with 6085h, then Switch On
    // Disabled (NT-CW-07), the rule that names an object a master sets (docs/decisions.md).
    option_codes: &[OptionCode {
        index: crate::personality::QUICK_STOP_OPTION,
        value: 3,
        fixed: true,
    }],
    // §2.4 L504: "only the jump from Ready to Switch On to Operation Enabled is possible".
    enable_from_ready: true,
    // 1001h: only generic (bit 0) and communication (bit 4) are used (§7.4).
    errors: &[
        ErrorSpec {
            fault: Fault::SoftwareLimit,
            code: emcy::POSITION_LIMIT,
            register: 0x01,
            critical: false,
        },
        ErrorSpec {
            fault: Fault::PositionOverflow,
            code: emcy::POSITION_OVERFLOW,
            register: 0x01,
            critical: false,
        },
    ],
    stepper_plant: true,
    pp_overwrite_queued: true,
    capabilities: Capabilities {
        feed_constant: true,
        pp_target_limits: true,
        ip_follows_sync: true,
        ip_changing_until_synchronised: false,
        ip_abrupt_quick_stop: true,
        homing_immediate: true,
        brake_in_60fe: false,
        zero_ramp_is_abrupt: false,
        vl_actual_closed_loop_only: true,
        internal_position_in_user_units: false,
    },
    homing_methods: &HOMING_METHODS,
    // §5.3 −4 … −7 and §11.17: the bit 2010h:01 of 2010h:02, written by an RPDO.
    external_home_switch: Some(ExternalHomeSwitch {
        index: 0x2010,
        bit_sub: 1,
        value_sub: 2,
        methods: &[-4, -5, -6, -7],
    }),
    hardware_enable: Some(HardwareEnable {
        what: "a bit-rate code in 2005h (the rotary switch is node + 128)",
        effect: "the controller answers on CAN but accepts no motion commands",
        rule: "Nanotec §1.1.3 step 7 (L333): with the switch at node + 128 and a value outside \
            130…135 in 2005h the controller answers on CAN but accepts no motion commands",
    }),
};

/// A reaction of the reaction table (the extract's §7.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reaction {
    /// "Power Off": the power stage off (fault).
    PowerOff,
    /// "Quickstop + Power Off": the quick-stop ramp, then the power stage off (fault).
    QuickStopPowerOff,
    /// "Quickstop": the quick-stop ramp, no fault.
    QuickStop,
    /// "motor does not start" at standstill, "motor finishes the current job" while moving,
    /// "–": the EMCY only.
    ///
    /// Decision: the manual does not say what refuses the next start; the twin reports the
    /// EMCY and leaves the state machine alone.
    MessageOnly,
}

impl From<Reaction> for ErrorReaction {
    fn from(r: Reaction) -> Self {
        match r {
            Reaction::PowerOff => ErrorReaction::OutputStageOff,
            Reaction::QuickStopPowerOff => ErrorReaction::QuickStop,
            Reaction::QuickStop => ErrorReaction::QuickStopNoFault,
            Reaction::MessageOnly => ErrorReaction::MessageOnly,
        }
    }
}

/// The reaction of a diagnostic row with a fixed reaction (the §17 rows of the device file; each
/// row's comment gives the decision): "ps_off" Power Off, "quick_stop" Quickstop + Power Off,
/// "warning" the EMCY only; anything else as the reaction table's default for a code it does not
/// list (Quickstop + Power Off).
pub fn fixed_reaction(r: od::Reaction) -> ErrorReaction {
    match r {
        od::Reaction::PsOff => Reaction::PowerOff.into(),
        od::Reaction::Warning | od::Reaction::Ignore => Reaction::MessageOnly.into(),
        _ => Reaction::QuickStopPowerOff.into(),
    }
}

/// One row of the reaction table (the extract's §7.1): the code and its reactions, legacy
/// (2020h = 1) and new (2020h = 0), at standstill and while moving.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReactionRow {
    pub code: u16,
    pub legacy: (Reaction, Reaction),
    pub new: (Reaction, Reaction),
}

impl ReactionRow {
    pub const fn reaction(&self, legacy: bool, moving: bool) -> Reaction {
        let (standstill, running) = if legacy { self.legacy } else { self.new };
        if moving {
            running
        } else {
            standstill
        }
    }
}

const fn reactions(
    code: u16,
    legacy: (Reaction, Reaction),
    new: (Reaction, Reaction),
) -> ReactionRow {
    ReactionRow { code, legacy, new }
}

use Reaction::{MessageOnly as Msg, PowerOff as Off, QuickStop as Qs, QuickStopPowerOff as QsOff};

/// The codes of §13.3 with their reactions (the extract's §7.1), as printed; 0010h is not used.
pub const REACTIONS: [ReactionRow; 12] = [
    reactions(emcy::UNDERVOLTAGE, (Off, QsOff), (Off, QsOff)),
    reactions(emcy::OVERTEMPERATURE, (Off, Off), (Off, Off)),
    reactions(emcy::LIFEGUARD, (Off, QsOff), (Msg, Qs)),
    reactions(emcy::DATA_ERROR, (Off, QsOff), (Off, QsOff)),
    reactions(emcy::TRAVEL_DIRECTION, (Off, QsOff), (Msg, Msg)),
    reactions(emcy::STEP_CALCULATION, (Off, QsOff), (Off, QsOff)),
    reactions(emcy::OVERCURRENT, (Off, Off), (Off, Off)),
    reactions(emcy::TRANSMIT_ERRORS, (Off, QsOff), (Msg, Qs)),
    reactions(emcy::RECEIVE_ERRORS, (Msg, Msg), (Msg, Qs)),
    reactions(emcy::TRANSMIT_BUFFER_FULL, (Msg, Msg), (Msg, Qs)),
    reactions(emcy::POSITION_LIMIT, (Msg, Msg), (Msg, Msg)),
    reactions(emcy::POSITION_OVERFLOW, (Msg, Msg), (Msg, Msg)),
];

const fn step(direction: i8, speed: Speed, until: Until) -> Step {
    Step {
        direction,
        speed,
        until,
        reverse: false,
    }
}

use crate::homing::Signal::Home;
use Speed::{Crawl, Search as Fast};
use Until::{Active, Inactive, Index};

/// §5.3: all 13 methods, 19–22, 33–35, the block methods −2 / −3 and the external I/O
/// methods −4 … −7. Clockwise is the positive direction (§9: positive VL speed is
/// "Rechtslauf").
///
/// Decision: the twin's home switch is logical (active on the cam); 19/21 (normally closed)
/// and 20/22 (normally open) differ only in the input's level, which the switch wiring of the
/// travel settings gives, so 19 and 22 run the same steps, as do 20 and 21.
pub const HOMING_METHODS: [Method; 13] = [
    // 19 … 22: the home-switch methods of CiA 402 (`homing::HOME_SWITCH_METHODS`).
    engine_method(19),
    engine_method(20),
    engine_method(21),
    engine_method(22),
    // 33: CW at 6099h:02 to the index mark, then reverse: CCW off the mark, stop (§5.3).
    // Decision: the index pulse is a point, so "moves off the index mark" is the pass back
    // over it; the reference is the mark, met on the way back at 6099h:02 with the immediate
    // stop of homing_immediate, so the shaft stands just on the mark's CCW side.
    (33, &[step(1, Crawl, Index), step(-1, Crawl, Index)]),
    // 34: CCW at 6099h:02 to the index mark, then CW off it (as 33, mirrored).
    (34, &[step(-1, Crawl, Index), step(1, Crawl, Index)]),
    // 35: the actual position becomes the home offset, no motion.
    (35, &[]),
    // −2 / −3: homing on block, CW / CCW at 6099h:01 until the shaft blocks (following error
    // beyond 6065h); the blocked position gets the home offset. Decision: the manual's second
    // pass at 6099h:02 after backing off one electrical revolution ends on the same block;
    // the twin's rigid stop makes it the same position, so one pass stands for both.
    (-2, &[step(1, Fast, Until::Stop)]),
    (-3, &[step(-1, Fast, Until::Stop)]),
    // −4 … −7: as 19 … 22 with the external I/O node's bit (2010h) for input 6.
    (
        -4,
        &[step(1, Fast, Active(Home)), step(-1, Crawl, Inactive(Home))],
    ),
    (
        -5,
        &[step(-1, Fast, Active(Home)), step(1, Crawl, Inactive(Home))],
    ),
    (
        -6,
        &[step(-1, Fast, Active(Home)), step(1, Crawl, Inactive(Home))],
    ),
    (
        -7,
        &[step(1, Fast, Active(Home)), step(-1, Crawl, Inactive(Home))],
    ),
];

/// Input 6, the reference switch (§9.1, §5.3), as bit 6 of [`Drive::force_inputs`] (bit n is
/// input n).
pub const INPUT_6: u16 = 1 << 6;

/// The long test run (6060h = −1).
pub const LONG_TEST_RUN: core::time::Duration = core::time::Duration::from_secs(2);
/// The short test run (6060h = −2).
pub const SHORT_TEST_RUN: core::time::Duration = core::time::Duration::from_millis(500);

/// Appendix 18.1, the default load-angle curve of a stepper (65536 = 360° electrical).
pub const STEPPER_LOAD_ANGLES: [u16; 7] = [16384, 18384, 20384, 22384, 24384, 26384, 28384];

/// Appendix 18.2 ("Default Werte für BLDC Motoren"), the default load-angle curve of a BLDC
/// (200Ch:01 … 07, 65536 = 360° electrical). Appendix 18 lists no other BLDC default.
pub const BLDC_LOAD_ANGLES: [u16; 7] = [16384, 16500, 17000, 17500, 18000, 18500, 19000];

/// The default load-angle curve of Appendix 18 for motor type 2004h:07 = `motor_type`: 18.1
/// for a stepper (0), 18.2 for a BLDC (1, 2).
pub const fn default_load_angles(motor_type: u8) -> [u16; 7] {
    if motor_type == 0 {
        STEPPER_LOAD_ANGLES
    } else {
        BLDC_LOAD_ANGLES
    }
}

/// Statusword bits 0–3, 5, 6 of each state (§4.2, measured in the §2.4 example: 0260h,
/// 0221h, 0233h, 0237h with bits 4 and 9 added). Bit 5 is set in Switch On Disabled.
const STATE_BITS: [(State, u16); 8] = [
    (State::NotReadyToSwitchOn, 0x0000),
    (State::SwitchOnDisabled, 0x0060),
    (State::ReadyToSwitchOn, 0x0021),
    (State::SwitchedOn, 0x0023),
    (State::OperationEnabled, 0x0027),
    (State::QuickStopActive, 0x0007),
    (State::FaultReactionActive, 0x000F),
    (State::Fault, 0x0008),
];

/// The Nanotec: its statusword, reaction table, torque mode and closed-loop test runs.
#[derive(Debug, Clone, Copy, Default)]
pub struct Nanotec {
    /// A closed-loop test run in progress (6060h = −1 / −2) and when it ends.
    pub(crate) test_run: Option<(i8, od::Instant)>,
    /// The short closed-loop test run has aligned the encoder (200Bh found).
    pub(crate) closed_loop_aligned: bool,
}

impl Vendor for Nanotec {
    const MANUFACTURER_OBJECTS: bool = true;

    /// 2001h ENABLE_CL, 2004h (the BLDC's currents and motor type, the load-angle
    /// spacing), 2006h pole pairs, 2007h the brake's times, 200Ah closed loop active, 200Bh,
    /// 2011h the encoder, 2020h the legacy homing: read by the stepper plant's settings and
    /// the hooks each cycle.
    const CACHED_OBJECTS: &'static [(u16, u8)] = &[
        (0x2001, 0),
        (0x2004, 1),
        (0x2004, 7),
        (0x2004, 8),
        (0x2004, 0x0C),
        (0x2004, 0x0D),
        (0x2004, 0x0E),
        (0x2006, 0),
        (0x2007, 1),
        (0x2007, 2),
        (0x2007, 3),
        (0x200A, 0),
        (0x200B, 0),
        (0x2011, 0),
        (0x2020, 0),
    ];

    /// §5.2 says only "halt: the motor stops"; the abort is reported as the CMMP-AS does
    /// (homing_error), as the twin has always run it.
    const HALT_IS_HOMING_ERROR: bool = true;

    /// The inputs as §9.1 numbers them: bit n of [`Drive::force_inputs`] is input n (1 … 6),
    /// input 6 the reference switch the methods 19 … 22 watch (§5.3), which 60FDh shows in bits
    /// 2 and 21 (`Drive::nanotec_digital_inputs`). The simulated home switch drives input 6.
    ///
    /// Decision: the manual names no limit-switch and no hardware-enable input (60FDh bits 0, 1
    /// and 3 read 0, §9.1; no homing method looks for a limit switch, §5.3; §2.4 puts no input
    /// before transition 2), so the Nanotec has none: it reads no limit switch (a homing search
    /// ends at the switch or the hard stop, and a travel's limit positions are not its inputs),
    /// and what stands for its hardware enable is the bit-rate code of the rotary switch
    /// ([`NANOTEC`]'s `hardware_enable`, `Vendor::enables` below), not an input.
    const INPUT_WIRING: InputWiring = InputWiring {
        negative_limit: 0,
        positive_limit: 0,
        home: INPUT_6,
        enables: 0,
    };

    /// Transition 2 needs no input (§2.4); it needs a bit-rate code the controller accepts
    /// (§1.1.3 step 7, NT-NODE-07), which the cell gives as `DriveSettings::enables_present`.
    fn enables<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> bool {
        d.settings.enables_present
    }

    fn for_device(_desc: &'static od::DeviceDescription) -> (&'static Personality, Self) {
        (&NANOTEC, Nanotec::default())
    }

    /// §5.3 (−2 / −3): on the block the position is set after the settle time 2004h:05 (ms).
    fn homing_block_settle<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
    ) -> core::time::Duration {
        core::time::Duration::from_millis(d.value(0x2004, 5).max(0) as u64)
    }

    fn power_on<S: AsRef<[u8]> + AsMut<[u8]>>(d: &mut Drive<S, Self>) {
        d.nanotec_power_on();
    }

    /// Torque mode is the Nanotec's own (ch. 8); the negative modes are the test runs (§11.2).
    fn mode_step<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &mut Drive<S, Self>,
        cw: Controlword,
        dt: f64,
    ) -> bool {
        match d.mode {
            mode::PROFILE_TORQUE => d.nanotec_torque(dt),
            m if m < 0 => d.nanotec_test_run(cw, dt),
            _ => return false,
        }
        true
    }

    fn write_hook<S: AsRef<[u8]> + AsMut<[u8]>>(index: u16, sub: u8) -> Option<Hook<S, Self>> {
        Drive::<S, Self>::nanotec_write_hook(index, sub)
    }

    /// §11.2: closed loop is on with an encoder (2011h ≠ 0) once 2001h ENABLE_CL is 1 or 2,
    /// or 3 after the short test run (6060h = −2). Decision: 1 / 2 at once (the long test
    /// run and the homing the real drive needs first are taken as done: the twin's encoder
    /// is aligned).
    #[inline]
    fn stepper_closed_loop<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> bool {
        let enable = d.value(0x2001, 0);
        (matches!(enable, 1 | 2) || (enable == 3 && d.vendor.closed_loop_aligned))
            && d.value(0x2011, 0) != 0
    }

    /// 200Ah: closed loop active.
    const CLOSED_LOOP_OBJECT: Option<(u16, u8)> = Some((0x200A, 0));

    /// 2004h:07 motor type: 0 stepper, 1 BLDC on its Hall sensors, 2 BLDC with encoder
    /// (values above 2 read as 2).
    fn plant_motor<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> PlantMotor {
        match d.value(0x2004, 7) {
            i64::MIN..=0 => PlantMotor::Stepper,
            1 => PlantMotor::BldcHall,
            _ => PlantMotor::BldcEncoder,
        }
    }

    /// 2004h:0C the commutation mode; 2004h:01 % of the motor's rated current
    /// continuously; 2004h:0D, when above 2004h:01, for a while of 2004h:0E. Decisions: the
    /// manual gives no unit for 0Dh / 0Eh; 0Dh is read in % like sub 1, 0Eh in ms (the I²t
    /// time).
    fn bldc_settings<S: AsRef<[u8]> + AsMut<[u8]>>(d: &Drive<S, Self>) -> BldcSettings {
        BldcSettings {
            commutation: d.value(0x2004, 0x0C) as u32,
            current_percent: d.value(0x2004, 1).clamp(1, 100) as f64,
            peak_percent: d.value(0x2004, 0x0D).clamp(0, 1000) as f64,
            peak_time_ms: d.value(0x2004, 0x0E).clamp(0, i64::from(u16::MAX)) as u16,
        }
    }

    /// Ch. 7: 60C1h is the target 607Ah shares, always open.
    fn ip_buffer_open_at_reset<S: AsRef<[u8]> + AsMut<[u8]>>(_d: &Drive<S, Self>) -> bool {
        true
    }

    fn refusal<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        request: Request,
    ) -> Option<Refusal> {
        d.nanotec_refusal(request)
    }

    fn state_bits<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &Drive<S, Self>,
        state: State,
        power: bool,
        _moving: bool,
    ) -> Statusword {
        d.nanotec_state_bits(state, power)
    }

    fn digital_inputs<S: AsRef<[u8]> + AsMut<[u8]>>(d: &mut Drive<S, Self>, position: i64) -> u32 {
        d.nanotec_digital_inputs(position)
    }

    fn error_reaction<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &mut Drive<S, Self>,
        code: u16,
        critical: bool,
        _fault: Option<Fault>,
    ) -> ErrorReaction {
        d.nanotec_error_reaction(code, critical)
    }

    /// §17: a message raised by its number with a fixed reaction keeps it (the §13.3 rows are
    /// "configurable" and follow the reaction table).
    fn message_reaction<S: AsRef<[u8]> + AsMut<[u8]>>(
        d: &mut Drive<S, Self>,
        row: &'static od::Diagnostic,
        by_number: bool,
    ) -> ErrorReaction {
        if by_number && row.reaction != od::Reaction::Configurable {
            return fixed_reaction(row.reaction);
        }
        let critical = row.reaction == od::Reaction::PsOff;
        d.nanotec_error_reaction(emcy_code(row), critical)
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Nanotec> {
    /// At power-on and after a reload: the motor's pole pairs 2006h (50 → 1.8°, 100 → 0.9°;
    /// "takes effect after a power cycle", §11.7) set the stepper's full steps per
    /// revolution, 4 × pole pairs.
    ///
    /// A controller without brake output (the PD4-N has no 2007h) has no holding brake.
    pub(crate) fn nanotec_power_on(&mut self) {
        if self.od.description().object(0x2007).is_none() && self.settings.brake_fitted {
            self.settings.brake_fitted = false;
            self.brake_engaged = false;
            self.axis.hold_brake(false);
        }
        let pole_pairs = self.value(0x2006, 0);
        if let (Some(stepper), Ok(pp @ 1..)) = (self.stepper_mut(), u32::try_from(pole_pairs)) {
            let data = StepperData {
                full_steps_per_rev: 4 * pp,
                ..*stepper.data()
            };
            if data != *stepper.data() {
                stepper.set_data(data);
            }
        }
    }

    /// The objects whose Nanotec rules do more than store a value.
    pub(crate) fn nanotec_write_hook(index: u16, sub: u8) -> Option<Hook<S, Nanotec>> {
        Some(match (index, sub) {
            (0x6060, 0x00) => Self::nanotec_write_mode,
            (0x60C1, 0x01) | (0x607A, 0x00) => Self::nanotec_write_target,
            // Ch. 7: the interpolator follows SYNC (60C2h is ignored) and 60C1h is always
            // open; 60C2h and 60C4h are stored only.
            (0x60C2, 0x01 | 0x02) | (0x60C4, 0x06) => Self::write_plain,
            (0x2004, 0x07) => Self::nanotec_write_motor_type,
            _ => return None,
        })
    }

    /// 6060h: PV (3) is refused (see [`NANOTEC`]); torque mode (4) needs the closed loop
    /// (§8.1: "closed loop must be active", 200Ah = 1).
    ///
    /// Decision: the manual does not say what happens without it; the write is refused with
    /// 0800 0022h (present device state), so a master learns it at once.
    fn nanotec_write_mode(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.write_mode_unless(index, sub, data, |d, m| {
            d.nanotec_refusal(Request::Mode(m))
                .map(|_| AbortCode::DEVICE_STATE)
        })
    }

    /// What the Nanotec refuses beyond the engine's rules: torque mode without the closed
    /// loop, a mode change while a brake wait time runs.
    pub(crate) fn nanotec_refusal(&self, request: Request) -> Option<Refusal> {
        let Request::Mode(m) = request else {
            return None;
        };
        if m == 4 && self.value(0x200A, 0) == 0 {
            return Some(Refusal::State {
                reason: "torque mode needs the closed loop (200Ah = 1)",
                rule: "Nanotec §5.5: for the torque mode the closed loop must be active",
            });
        }
        // §4.2: "while a brake wait time (2007h) is running, mode changes are not executed".
        self.brake_wait().then_some(Refusal::State {
            reason: "a brake wait time (2007h) is running",
            rule: "Nanotec §4.2: while a brake wait time (2007h) is running, mode changes \
                are not executed",
        })
    }

    /// 2004h:07, the motor type (§1.2 "Motortyp", §11.5): a write that changes the motor
    /// family (stepper 0 ↔ BLDC 1 / 2) loads the family's default load-angle curve of
    /// Appendix 18 into 200Ch:01 … 07 (18.2 for a BLDC, 18.1 for a stepper).
    ///
    /// Decision: the manual lists the appendix's curves as the motors' "Default Werte"
    /// without saying when the firmware takes them; the twin takes them when the motor
    /// type names the other family, so a BLDC starts with its own curve (a curve written
    /// after the type, or measured by the test run, stays). 1 ↔ 2 (the same BLDC, with or
    /// without encoder) keeps the curve; sub 8 … 10 are not used (§11.13) and stay.
    fn nanotec_write_motor_type(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        let before = self.value(index, sub) != 0;
        self.od.write(index, sub, data)?;
        let after = self.value(index, sub);
        if before != (after != 0) {
            self.store_load_angles(&default_load_angles(after.clamp(0, 2) as u8));
        }
        Ok(())
    }

    /// 200Ch:01 … 07 := `angles`.
    fn store_load_angles(&mut self, angles: &[u16; 7]) {
        for (n, angle) in (1u8..).zip(angles) {
            let e = self.od.description().entry(0x200C, n);
            self.store(e, i64::from(*angle));
        }
    }

    /// 60C1h:01 and 607Ah are one internal target (ch. 7): a write to either shows in both;
    /// in IP a set-point goes to the interpolator, which takes it at the next SYNC.
    fn nanotec_write_target(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        let (other, other_sub) = if index == 0x60C1 {
            (0x607A, 0)
        } else {
            (0x60C1, 1)
        };
        let _ = self.od.write_internal(other, other_sub, data);
        let user = self
            .value(0x60C1, 1)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        let increments = self.fg.position_to_internal(user) as f64;
        self.ip.set_point(increments);
        Ok(())
    }

    /// Torque mode (ch. 8): the current `6071h / 1000 × 2004h:01 % × rated current` as the
    /// closed loop's torque, the speed limited to 607Fh min⁻¹ in both directions; halt holds
    /// the motor (its falling edge starts again). Bit 10: without halt the set torque is
    /// reached (not cut by the speed limit), with halt the motor stands.
    ///
    /// Decisions: "rated current" is the motor's (the twin's current limits come from it);
    /// the speed limit takes the torque back linearly over the last 5 % below 607Fh.
    pub(crate) fn nanotec_torque(&mut self, dt: f64) {
        let rpm = f64::from(self.plant_velocity_rpm());
        if self.halted {
            let decel = self.accel(0x6085);
            self.traj.step_stop(decel, dt);
            self.position_demand(self.traj.velocity);
            // "Stopped" once the braking ramp has ended and the shaft stands inside the position
            // window (6067h) of the ramp's end: the plant's speed crosses zero while it still
            // overshoots the ramp.
            let window = self.fg.position_magnitude_to_internal(
                self.value(0x6067, 0).clamp(0, u32::MAX as i64) as u32,
            );
            let settled =
                (self.actual_internal() - libm::round(self.traj.position) as i64).abs() <= window;
            // Once stopped it stays so while the ramp stands: a closed-loop stepper's shaft
            // hunts by a few units against its friction.
            let stands = self.traj.velocity == 0.0;
            self.target_reached = stands && (self.target_reached || (rpm.abs() < 1.0 && settled));
            return;
        }
        // A BLDC (2004h:07 = 1 / 2) is the servo axis's motor.
        let rated = self
            .stepper()
            .map_or(self.axis.motor().data().rated_current, |s| {
                s.data().rated_current
            });
        let rated_ma = (rated * 1000.0) as u32;
        let percent = self.value(0x2004, 1).clamp(0, 100) as u8;
        let target = self.value(0x6071, 0).clamp(-1000, 1000) as i16;
        let current_a = torque_current_ma(target, percent, rated_ma) / 1000.0;
        let limit = self.value(0x607F, 0).max(0) as f64;
        let along = rpm * current_a.signum();
        let band = 0.05 * limit + 1.0;
        let factor = ((limit - along) / band).clamp(0.0, 1.0);
        self.demand = Demand::Torque {
            current_a: (current_a * factor) as f32,
        };
        self.target_reached = factor >= 1.0;
        self.traj = Trajectory {
            position: self.actual_internal() as f64,
            velocity: rpm / RPM_PER_INCREMENT_S,
        };
        self.demand_position = self.traj.position;
    }

    /// The closed-loop test runs (§11.2): 6060h = −1 "CL Motor Setup" measures the load-angle
    /// curve into 200Ch (and 2012h / 2013h / 2018h until the next restart), −2 "Short CL
    /// Motor Setup" the encoder offset 200Bh, only while it is 0, and then enables the closed
    /// loop for 2001h = 3.
    ///
    /// Decisions (the manual gives neither the start nor the duration): a run starts on the
    /// rising edge of bit 4 in Operation Enabled, as homing does, and bit 4 low aborts it; the
    /// long run takes [`LONG_TEST_RUN`], the short one [`SHORT_TEST_RUN`], with the shaft
    /// standing; the end shows as target reached (bit 10). The measured curve is Appendix
    /// 18's default curve of the motor type 2004h:07 (18.1 a stepper, 18.2 a BLDC; the
    /// twin's motor has no load angle of its own), at the support
    /// points of 2004h:08; 2012h holds the motor's rated current in mA; 200Bh is the
    /// electrical angle of the index pulse, `index position × pole pairs` in 65536ths.
    pub(crate) fn nanotec_test_run(&mut self, cw: Controlword, dt: f64) {
        self.hold(dt);
        if self.cw_rising.contains(Controlword::NEW_SET_POINT) && self.vendor.test_run.is_none() {
            let length = if self.mode == -1 {
                LONG_TEST_RUN
            } else {
                SHORT_TEST_RUN
            };
            self.vendor.test_run = Some((self.mode, self.now + length));
            self.target_reached = false;
        }
        if !cw.contains(Controlword::NEW_SET_POINT) && self.vendor.test_run.is_some() {
            self.vendor.test_run = None;
            return;
        }
        if let Some((mode, _)) = self.vendor.test_run.filter(|(_, end)| self.now >= *end) {
            self.vendor.test_run = None;
            self.target_reached = true;
            if mode == -1 {
                self.store_load_angle_curve();
            } else {
                self.align_encoder();
            }
        }
    }

    fn store_load_angle_curve(&mut self) {
        let spacing = load_angle_spacing_rpm(self.value(0x2004, 8).clamp(0, 0xFFFF) as u16);
        // A BLDC (no stepper) is the servo axis's motor.
        let rated = self
            .stepper()
            .map_or(self.axis.motor().data().rated_current, |s| {
                s.data().rated_current
            });
        let rated_ma = (rated * 1000.0) as i64;
        let curve = default_load_angles(self.value(0x2004, 7).clamp(0, 2) as u8);
        for (n, angle) in (1u8..).zip(curve) {
            let rpm = libm::round(f64::from(n - 1) * spacing) as i64;
            for (index, value) in [
                (0x200C, i64::from(angle)),
                (0x2013, i64::from(angle)),
                (0x2018, rpm.min(i64::from(i16::MAX))),
                (0x2012, rated_ma.min(i64::from(i16::MAX))),
            ] {
                if let Some(e) = self.od.description().entry(index, n) {
                    self.store(Some(e), value);
                }
            }
        }
    }

    fn align_encoder(&mut self) {
        if self.value(0x200B, 0) == 0 {
            let index = i64::from(self.settings.travel.index_phase.unwrap_or(0));
            let pole_pairs = self.value(0x2006, 0).max(1);
            let offset = (index * pole_pairs).rem_euclid(65536).max(1);
            if let Some(e) = self.od.description().entry(0x200B, 0) {
                self.store(Some(e), offset);
            }
        }
        self.vendor.closed_loop_aligned = true;
    }

    /// 60FDh (§9.1): inputs 1 … 6 in bits 16 … 21, input 6 (the reference switch) also in
    /// bit 2; bits 0, 1, 3 … 15 read 0. The levels are [`Drive::input_levels`]: the simulated
    /// home switch on input 6, the forced inputs over it.
    pub(crate) fn nanotec_digital_inputs(&self, position: i64) -> u32 {
        let levels = self.input_levels(position);
        let inputs = (1..=6u32)
            .filter(|n| levels.high(1 << n))
            .fold(0u32, |acc, n| acc | 1 << (15 + n));
        if levels.high(INPUT_6) {
            inputs | crate::digital_inputs::bit::HOME_SWITCH
        } else {
            inputs
        }
    }

    /// Statusword bits 0–6, 8 and 9 (§4.2, §3.3): bit 4 voltage enabled from Switched On
    /// (the motor is energised), bit 9 remote always, bit 8 PLL sync complete (IP, ch. 7).
    pub(crate) fn nanotec_state_bits(&self, state: State, power: bool) -> Statusword {
        let bits = STATE_BITS
            .iter()
            .find(|(s, _)| *s == state)
            .map_or(0, |(_, b)| *b);
        Statusword(bits)
            | Statusword::VOLTAGE_ENABLED.when(power)
            | Statusword::REMOTE
            | Statusword::BIT_8.when(self.ip.is_synchronised())
    }

    /// The reaction of the reaction table (the extract's §7.1) to `code`: the table's column for
    /// 2020h (1 legacy, 0 new) and whether the motor is moving. A code the table does not list
    /// switches the power off (with the quick-stop ramp unless `critical`).
    pub(crate) fn nanotec_error_reaction(&mut self, code: u16, critical: bool) -> ErrorReaction {
        let legacy = self.value(0x2020, 0) != 0;
        let moving = self.traj.velocity != 0.0 || self.velocity_set != 0.0;
        match REACTIONS.iter().find(|r| r.code == code) {
            Some(r) => r.reaction(legacy, moving).into(),
            None if critical => ErrorReaction::OutputStageOff,
            None => ErrorReaction::QuickStop,
        }
    }
}
