//! The FHPP state machine (CMMO-ST manual §5.2, Fig. 5.1/5.2, Tab. 5.2–5.4) with the
//! handshakes of §5.2.3 (Examples 1–6) and ch. 6 (homing, jog, teach, record selection,
//! direct mode), and control authority (PNU 125, CCON.LOCK, SCON.FCT/MMI).
//!
//! States, as Tab. 5.2 / Fig. 5.1 number them (the figure is missing from the text; the names
//! of S1…S3, S5, S6 follow the FHPP convention, S4 and "drive disabled" are named in the text):
//!
//! | state | name | SCON |
//! |---|---|---|
//! | S1 | controller switched on | – (left at once by T1) |
//! | S2 | drive blocked ("drive disabled") | ENABLED = 0, OPEN = 0 |
//! | S3 | drive enabled, operation blocked (STOP active) | ENABLED = 1, OPEN = 0 |
//! | S4 | operation enabled, with SA1…SA6 | ENABLED = 1, OPEN = 1 |
//! | S5 | fault reaction active | FAULT = 1 |
//! | S6 | fault | FAULT = 1 |
//!
//! There is no "quick stop / stop" state: CCON.STOP = 0 is T4 (S4 → S3 with the Quick-Stop
//! deceleration) and S5/S6 are the fault states of Tab. 5.2 (T7, T8 lead to them and the
//! acknowledge transitions T9–T11 leave from S6).
//!
//! One call of [`Fhpp::cycle`] is one bus cycle: the level transitions of Tab. 5.2 settle within
//! it (power-on CCON 00h → 03h answers SCON 13h at once, as Example 1 step 1.3 shows), each edge
//! (P / N) acts once, and held bits never re-trigger. Edges are taken against the previous
//! telegram of the fieldbus; while FCT or the web server holds device control the fieldbus
//! telegram is ignored (its bits are still recorded, so held bits do not become edges when the
//! control comes back).
//!
//! Contract with the motion layer: commands are emitted during `cycle`; the [`MotionStatus`]
//! passed to the next `cycle` must already reflect them (in particular `motion_complete` is
//! false from the cycle after a new task command until that task is done).

use super::control_bytes::{
    percent_of, Ccon, Cdir, ControlMode, Cpos, Edges, OperatingMode, OutputData,
};
use super::record_table::{RecordSelect, RecordTable, StartBehaviour};
use super::status_bytes::{InputData, Rsb, Scon, Sdir, Spos};

/// The main states of Fig. 5.1 (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum State {
    /// S1 controller switched on: the logic runs; T1 follows when no error is detected.
    ControllerSwitchedOn,
    /// S2 drive blocked / drive disabled: output stage off.
    DriveBlocked,
    /// S3 drive enabled: output stage on, STOP active (no positioning).
    DriveEnabled,
    /// S4 operation enabled, with the sub-states [`OpState`].
    OperationEnabled,
    /// S5 fault reaction active.
    FaultReaction,
    /// S6 fault.
    Fault,
}

impl State {
    /// The number n of "Sn".
    pub const fn number(self) -> u8 {
        match self {
            State::ControllerSwitchedOn => 1,
            State::DriveBlocked => 2,
            State::DriveEnabled => 3,
            State::OperationEnabled => 4,
            State::FaultReaction => 5,
            State::Fault => 6,
        }
    }
}

/// The sub-states SA1…SA6 of S4 "operation enabled" (Tab. 5.3). SA1 "ready" and SA3
/// "intermediate stop" are named in the text; the others follow the FHPP convention.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum OpState {
    /// SA1 ready: the only sub-state in which the operating mode may change.
    #[default]
    Ready,
    /// SA2 positioning task active (record or direct task).
    TaskActive,
    /// SA3 intermediate stop (halt of a position task; continue with START, delete with CLEAR).
    IntermediateStop,
    /// SA4 homing active.
    Homing,
    /// SA5 jog positive.
    JogPositive,
    /// SA6 jog negative.
    JogNegative,
}

impl OpState {
    /// The number n of "SAn".
    pub const fn number(self) -> u8 {
        match self {
            OpState::Ready => 1,
            OpState::TaskActive => 2,
            OpState::IntermediateStop => 3,
            OpState::Homing => 4,
            OpState::JogPositive => 5,
            OpState::JogNegative => 6,
        }
    }
}

/// The transitions of Tab. 5.2 (T1…T11) and Tab. 5.3 (TA1…TA12).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Transition {
    /// S1 → S2: switched on, no error.
    T1,
    /// S2 → S3: ENABLE = 1 (`xxx0.xxx1`), load voltage, control authority.
    T2,
    /// S3 → S4: STOP = 1, ENABLE = 1 (`xxx0.xx11`).
    T3,
    /// S4 → S3: STOP = 0 (`xxx0.xx01`); Quick Stop.
    T4,
    /// S3 → S2: ENABLE = 0.
    T5,
    /// S4 → S2: ENABLE = 0; Quick Stop.
    T6,
    /// any → S5: fault detected (highest priority).
    T7,
    /// S5 → S6: fault reaction completed.
    T8,
    /// S6 → S2: RESET rising with ENABLE = 0 (`xxx0.Pxx0`).
    T9,
    /// S6 → S3: minor fault, RESET rising with ENABLE = 1 (`xxx0.Pxx1`).
    T10,
    /// S6 → S6: RESET rising while the fault is still present.
    T11,
    /// SA1 → SA2: START rising, HALT = 1, axis referenced (`0xx0.00P1`).
    TA1,
    /// SA2 → SA1: motion complete.
    TA2,
    /// SA2 → SA3: HALT falling (`0xxx.xxxN`).
    TA3,
    /// SA3 → SA2: START rising, HALT = 1, CLEAR = 0 (`00xx.xxP1`).
    TA4,
    /// SA2 → SA2: a new task replaces (or follows) the running one.
    TA5,
    /// SA3 → SA1: CLEAR rising (`0Pxx.xxxx`).
    TA6,
    /// SA1 → SA4: HOM rising, HALT = 1 (`0xx0.0Px1`), or START with record 0.
    TA7,
    /// SA4 → SA1: homing finished, or aborted by HALT falling.
    TA8,
    /// SA1 → SA5: JOGP rising, HALT = 1 (`0xx0.Pxx1`).
    TA9,
    /// SA5 → SA1: JOGP falling or HALT falling.
    TA10,
    /// SA1 → SA6: JOGN rising, HALT = 1 (`0xxP.0xx1`).
    TA11,
    /// SA6 → SA1: JOGN falling or HALT falling.
    TA12,
}

/// Who holds device control (PNU 125, SCON.FCT/MMI, §B.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Authority {
    /// The fieldbus (IO-Link, I-Port or Modbus): PNU 125 = 1, preset after every power-on.
    #[default]
    Fieldbus,
    /// The Festo Configuration Tool: PNU 125 = 0, SCON.FCT/MMI = 1.
    Fct,
    /// The built-in web server: PNU 125 = 0, SCON.FCT/MMI = 1.
    WebServer,
}

/// Why a change of device control was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AuthorityError {
    /// CCON.LOCK = 1: a local tool cannot take device control.
    Locked,
    /// PNU 125 := 1 cannot take control away from FCT (FPC error 17).
    FctHasControl,
    /// PNU 125 only accepts the value 1.
    InvalidValue,
}

impl AuthorityError {
    /// The FPC error code a PNU 125 write answers with (Tab. C.7).
    pub const fn fpc_error(self) -> u8 {
        match self {
            AuthorityError::Locked => 0x0B,
            AuthorityError::FctHasControl => 0x11,
            AuthorityError::InvalidValue => 0x02,
        }
    }
}

/// Error reactions A…G (§7.1, PNU 234/242 bit coding).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Reaction {
    /// Output stage off, no ramp (free-wheeling).
    A,
    /// Output stage off after the Quick-Stop ramp.
    B,
    /// Output stage off after the deceleration ramp.
    C,
    /// Output stage off after finishing the record.
    D,
    /// Output stage stays on; Quick-Stop ramp.
    E,
    /// Output stage stays on; deceleration ramp.
    F,
    /// Output stage stays on; finish the record.
    G,
}

impl Reaction {
    /// The PNU 234/242 bit value (0x0001 = A … 0x0040 = G).
    pub const fn bit(self) -> u16 {
        match self {
            Reaction::A => 0x01,
            Reaction::B => 0x02,
            Reaction::C => 0x04,
            Reaction::D => 0x08,
            Reaction::E => 0x10,
            Reaction::F => 0x20,
            Reaction::G => 0x40,
        }
    }

    /// From a single PNU 242 bit.
    pub const fn from_bit(bit: u16) -> Option<Self> {
        match bit {
            0x01 => Some(Reaction::A),
            0x02 => Some(Reaction::B),
            0x04 => Some(Reaction::C),
            0x08 => Some(Reaction::D),
            0x10 => Some(Reaction::E),
            0x20 => Some(Reaction::F),
            0x40 => Some(Reaction::G),
            _ => None,
        }
    }

    /// Reactions A…D switch the output stage off.
    pub const fn output_stage_off(self) -> bool {
        matches!(self, Reaction::A | Reaction::B | Reaction::C | Reaction::D)
    }
}

/// How a fault can be acknowledged (App. D "Ack" column, PNU 230).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Ack {
    /// Can be acknowledged at once (PNU 230 = 2).
    Immediately,
    /// Only once the cause is gone (PNU 230 = 1).
    AfterCause,
    /// Not by RESET: a software reset (PNU 127:3) or power cycle is needed (PNU 230 = 0).
    NotAckable,
}

/// A fault (diagnostic of class F) as the diagnostics layer classifies it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Fault {
    /// Diagnostic number (App. D, 01h…4Fh).
    pub code: u8,
    pub reaction: Reaction,
    pub ack: Ack,
}

impl Fault {
    /// Tab. 5.2 tells a "serious" error (T9) from a "minor" one (T10) without defining them.
    /// Decision: serious = the reaction switches the output stage off (A…D); minor = it stays
    /// on (E…G), which is what lets T10 acknowledge "without switching the controller off".
    pub const fn serious(&self) -> bool {
        self.reaction.output_stage_off()
    }
}

/// What the motion layer reports each cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MotionStatus {
    /// Axis speed ≥ the MOV limit (SPOS.MOV).
    pub moving: bool,
    /// The current task's MC condition holds: actual value inside the target window of its task
    /// type for PNU 1023 (position: PNU 1022, velocity: 561, force: 552); for homing, homing
    /// done; for a Halt / Stop / QuickStop, the axis has stopped.
    pub motion_complete: bool,
    /// Following error active (SPOS.FOLERR, diagnostic 2Fh).
    pub following_error: bool,
    /// The axis left the standstill window after MC (SPOS.STILL, diagnostic 37h).
    pub standstill_error: bool,
    /// Axis referenced (SPOS.REF).
    pub referenced: bool,
    /// Velocity limit reached (SDIR/RSB.VLIM).
    pub velocity_limit: bool,
    /// Stroke limit reached (SDIR/RSB.XLIM).
    pub stroke_limit: bool,
    /// Actual position \[SINC\].
    pub actual_position: i32,
    /// Actual velocity \[SINC/s\].
    pub actual_velocity: i32,
    /// Actual force \[‰ of PNU 555\].
    pub actual_force: i32,
    /// A warning is present (SCON.WARN).
    pub warning: bool,
    /// A fault detected by the motion layer or plant; reported every cycle while its cause is
    /// present.
    pub fault: Option<Fault>,
}

/// The reference of a relative direct-mode move (PNU 524 bit 0, RCB1.REL).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RelativeTo {
    /// Relative to the last set-point (target) position.
    LastSetpoint,
    /// Relative to the actual position (PNU 524 default).
    ActualPosition,
}

/// What the state machine asks the motion layer to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MotionCommand {
    /// Switch the output stage on (controller enabled; the controller now owns the brake).
    Enable,
    /// Switch the output stage off.
    Disable,
    /// CCON.BRAKE while the controller is disabled: `true` = release the brake, `false` = end
    /// the manual release (the brake follows the output stage again).
    ManualBrake { open: bool },
    /// Start the parameterised homing (PNU 1010…1017).
    Home,
    /// Start record `number` (1…64) of the record table; the motion layer reads its data.
    Record { number: u8, mode: ControlMode },
    /// Direct position mode, absolute target \[SINC\].
    MoveAbsolute {
        target: i32,
        velocity: u32,
        velocity_percent: u8,
    },
    /// Direct position mode, relative distance \[SINC\].
    MoveRelative {
        distance: i32,
        velocity: u32,
        velocity_percent: u8,
        reference: RelativeTo,
    },
    /// Direct velocity mode: signed velocity \[SINC/s\], ramp \[SINC/s²\] = % of PNU 560.
    Velocity {
        velocity: i32,
        ramp: u32,
        ramp_percent: u8,
        stroke_monitoring: bool,
    },
    /// Direct force mode: signed set-point \[‰ of PNU 555\], velocity limit = % of PNU 540.
    Force {
        setpoint: i32,
        velocity_limit: u32,
        velocity_percent: u8,
        stroke_monitoring: bool,
    },
    /// Jog (PNU 530…534): `positive` = towards increasing actual value.
    Jog { positive: bool },
    /// Brake with the task's ramp. Position task: it stays pending (intermediate stop);
    /// velocity, force, homing and jog: the task ends.
    Halt,
    /// Continue the halted position task (TA4).
    Continue,
    /// Delete the remaining path of the halted task (TA6, CPOS.CLEAR).
    Clear,
    /// Abort the task with its deceleration ramp (fault reactions C, F).
    Stop,
    /// Abort the task with the Quick-Stop deceleration PNU 1029 (CCON.STOP = 0, ENABLE = 0,
    /// fault reactions B, E).
    QuickStop,
}

/// A start the drive did not accept.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Refusal {
    /// The axis is not referenced (TA1 condition): diagnostic 28h "homing required".
    NotReferenced,
    /// Record number above 64 or record data that cannot be interpreted: diagnostic 3Fh.
    InvalidRecord(u8),
    /// Direct mode with CDIR.COM = 11 (reserved): diagnostic 3Fh (decision: the manual names
    /// no diagnostic; 3Fh covers "data or type cannot be interpreted").
    InvalidControlMode,
}

impl Refusal {
    /// The diagnostic number the diagnostics layer raises for it (App. D).
    pub const fn diagnostic(self) -> u8 {
        match self {
            Refusal::NotReferenced => 0x28,
            Refusal::InvalidRecord(_) | Refusal::InvalidControlMode => 0x3F,
        }
    }
}

/// What one cycle reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Event {
    /// A transition of Tab. 5.2 / 5.3 was taken.
    Transition(Transition),
    /// The motion layer must do this.
    Motion(MotionCommand),
    /// A start was refused; the diagnostics layer raises [`Refusal::diagnostic`].
    Refused(Refusal),
    /// TEACH falling edge: store `position` into the target of PNU 520, record `record`.
    Teach { record: u8, position: i32 },
}

/// The parameters the state machine itself needs (the device keeps them in sync with the PNUs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Config {
    /// PNU 540 base value velocity \[SINC/s\] (direct position and force modes, byte 4 %).
    pub base_velocity: u32,
    /// PNU 560 base value acceleration \[SINC/s²\] (direct velocity mode ramp, byte 4 %).
    pub base_acceleration: u32,
    /// PNU 583 start condition in direct mode (default: ignore).
    pub start_condition: StartBehaviour,
    /// PNU 524 bit 0: relative direct moves refer to the actual position (default 1).
    pub relative_to_actual: bool,
    /// PNU 400:1: the record a teach writes in direct mode.
    pub teach_record: u8,
    /// PNU 523:7 = 1 (factory): in force mode actual value 1 is the torque, else the velocity.
    pub force_actual1_torque: bool,
    /// PNU 523:8 = 1: in force mode actual value 2 is the torque; 0 (factory) the position.
    pub force_actual2_torque: bool,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            base_velocity: 0,
            base_acceleration: 0,
            start_condition: StartBehaviour::Ignore,
            relative_to_actual: true,
            teach_record: 1,
            force_actual1_torque: true,
            force_actual2_torque: false,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct ActiveFault {
    fault: Fault,
    /// Raised through [`Fhpp::raise_fault`] and not yet declared gone.
    external_cause: bool,
    /// A task was running when the fault came (reactions D, G finish it).
    task_running: bool,
}

/// A task the drive runs in S4.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Task {
    mode: ControlMode,
    /// The CDIR of a direct task (SDIR feedback); `None` for records.
    cdir: Option<Cdir>,
    /// What a new start does while this task runs (RCB3 or PNU 583).
    behaviour: StartBehaviour,
}

/// A start accepted at its START edge, ready to be handed to the motion layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Prepared {
    command: MotionCommand,
    task: Task,
    /// Record number feedback to show once it runs (record selection).
    record: Option<u8>,
    homing: bool,
}

/// The FHPP device side: state machine, handshakes and the cyclic status image.
#[derive(Debug, Clone)]
pub struct Fhpp {
    config: Config,
    state: State,
    sub: OpState,
    authority: Authority,
    /// CCON.LOCK of the last fieldbus telegram.
    lock: bool,
    load_voltage: bool,
    safety_ok: bool,
    warning: bool,
    prev_ccon: Ccon,
    prev_cpos: Cpos,
    /// Byte 3 of the last fieldbus telegram read as CDIR (SDIR feedback while no task runs).
    last_cdir: Cdir,
    opm: OperatingMode,
    stage_on: bool,
    brake_released: bool,
    mc: bool,
    /// MC becomes 1 as soon as the axis has stopped (after halt, stop, abort).
    awaiting_stop: bool,
    /// The CPOS bit whose start was acknowledged; ACK falls when the PLC clears it.
    ack_trigger: Option<Cpos>,
    teach_ack: bool,
    task: Option<Task>,
    queued: Option<Prepared>,
    record_feedback: u8,
    rsb_chain: Rsb,
    /// PNU 425 = 1: MC shows 1 in the telegram of the cycle after a record switch.
    mc_pulse: bool,
    fault: Option<ActiveFault>,
    raised: Option<Fault>,
    inputs: InputData,
}

impl Default for Fhpp {
    fn default() -> Self {
        Fhpp::new(Config::default())
    }
}

impl Fhpp {
    /// Power-on: S1, the fieldbus holds device control (PNU 125 = 1), load voltage present,
    /// STO and the enable input satisfied (PNU 280 all 1), MC not yet set.
    pub fn new(config: Config) -> Self {
        let mut fhpp = Fhpp {
            config,
            state: State::ControllerSwitchedOn,
            sub: OpState::Ready,
            authority: Authority::Fieldbus,
            lock: false,
            load_voltage: true,
            safety_ok: true,
            warning: false,
            prev_ccon: Ccon::EMPTY,
            prev_cpos: Cpos::EMPTY,
            last_cdir: Cdir::EMPTY,
            opm: OperatingMode::RecordSelection,
            stage_on: false,
            brake_released: false,
            mc: false,
            awaiting_stop: false,
            ack_trigger: None,
            teach_ack: false,
            task: None,
            queued: None,
            record_feedback: 0,
            rsb_chain: Rsb::EMPTY,
            mc_pulse: false,
            fault: None,
            raised: None,
            inputs: InputData::default(),
        };
        fhpp.inputs = fhpp.build_inputs(&MotionStatus::default());
        fhpp
    }

    pub fn config(&self) -> &Config {
        &self.config
    }

    pub fn config_mut(&mut self) -> &mut Config {
        &mut self.config
    }

    pub fn state(&self) -> State {
        self.state
    }

    /// The sub-state of S4 (meaningful only in [`State::OperationEnabled`]).
    pub fn op_state(&self) -> OpState {
        self.sub
    }

    /// The accepted operating mode (SCON.OPM).
    pub fn operating_mode(&self) -> OperatingMode {
        self.opm
    }

    pub fn authority(&self) -> Authority {
        self.authority
    }

    /// The active fault, if any (S5, S6).
    pub fn fault(&self) -> Option<Fault> {
        self.fault.map(|f| f.fault)
    }

    /// Whether the output stage is on (SCON.ENABLED).
    pub fn output_stage_on(&self) -> bool {
        self.stage_on
    }

    /// The input telegram of the last cycle.
    pub fn inputs(&self) -> InputData {
        self.inputs
    }

    /// Load voltage present (SCON.VLOAD; T2 condition).
    pub fn set_load_voltage(&mut self, present: bool) {
        self.load_voltage = present;
    }

    /// PNU 280 all bits 1: both STO channels at 24 V and, with PNU 128 = 1, the ENABLE input.
    pub fn set_safety_ok(&mut self, ok: bool) {
        self.safety_ok = ok;
    }

    /// A warning of the diagnostics layer is present (SCON.WARN).
    pub fn set_warning(&mut self, present: bool) {
        self.warning = present;
    }

    /// A fault detected outside the motion layer (diagnostics, communication watchdog, …).
    /// T7 is taken at the next cycle; the cause counts as present until [`Self::fault_cause_gone`].
    pub fn raise_fault(&mut self, fault: Fault) {
        self.raised = match self.raised {
            Some(r) if r.serious() || !fault.serious() => Some(r),
            _ => Some(fault),
        };
    }

    /// The cause of the raised fault `code` has gone (it may now be acknowledged).
    pub fn fault_cause_gone(&mut self, code: u8) {
        if let Some(f) = self.fault.as_mut() {
            if f.fault.code == code {
                f.external_cause = false;
            }
        }
    }

    /// The motion layer met the switching condition of the running record (RCB2, §6.5.3)
    /// and started record `number` in `mode`: the record feedback (byte 3) shows it, RSB.RC1
    /// is set, MC stays 0 (pulsed for one telegram when `mc_pulse`, PNU 425 = 1). Returns
    /// false (and changes nothing) when no record task runs.
    pub fn record_chained(&mut self, number: u8, mode: ControlMode, mc_pulse: bool) -> bool {
        let running = self.state == State::OperationEnabled
            && self.sub == OpState::TaskActive
            && self.opm == OperatingMode::RecordSelection;
        let Some(task) = self.task.as_mut().filter(|_| running) else {
            return false;
        };
        task.mode = mode;
        self.record_feedback = number;
        self.rsb_chain |= Rsb::RC1;
        self.mc = false;
        self.mc_pulse = mc_pulse;
        true
    }

    /// RSB.RC1 / RSB.RCC of record chaining (record selection byte 4).
    pub fn chain_status(&self) -> Rsb {
        self.rsb_chain & (Rsb::RC1 | Rsb::RCC)
    }

    /// PNU 125 read: 1 = the fieldbus has control, 0 = FCT or the web server.
    pub fn control_logic(&self) -> u8 {
        u8::from(self.authority == Authority::Fieldbus)
    }

    /// PNU 125 write. 1 takes control back from the web server, but not from FCT (error 17).
    pub fn write_control_logic(&mut self, value: u8) -> Result<(), AuthorityError> {
        match (value, self.authority) {
            (1, Authority::Fct) => Err(AuthorityError::FctHasControl),
            (1, _) => {
                self.authority = Authority::Fieldbus;
                Ok(())
            }
            _ => Err(AuthorityError::InvalidValue),
        }
    }

    /// FCT or the web server asks for device control. Refused while the PLC sets CCON.LOCK.
    /// Decision: LOCK ("lock FCT access", Tab. 5.14: the local parameter interface) also locks
    /// out the web server, the other local tool that can take device control.
    pub fn request_local_control(&mut self, who: Authority) -> Result<(), AuthorityError> {
        if who == Authority::Fieldbus {
            return self.write_control_logic(1);
        }
        if self.lock && self.authority == Authority::Fieldbus {
            return Err(AuthorityError::Locked);
        }
        self.authority = who;
        Ok(())
    }

    /// The local tool gives device control back to the fieldbus.
    pub fn release_local_control(&mut self) {
        self.authority = Authority::Fieldbus;
    }

    /// One bus cycle: `out` is the PLC's output telegram, `records` the record list, `status`
    /// the motion layer's state. Events go to `emit`; returns the input telegram.
    pub fn cycle<F: FnMut(Event)>(
        &mut self,
        out: &OutputData,
        records: &RecordTable,
        status: &MotionStatus,
        mut emit: F,
    ) -> InputData {
        // Reserved bits (CCON.B4, CPOS.B7) "must be 0"; they are ignored.
        let ccon = out.ccon & Ccon::DEFINED;
        let cpos = out.cpos & Cpos::DEFINED;
        let plc = self.authority == Authority::Fieldbus;
        let (cc_edges, cp_edges) = if plc {
            (
                Edges::between(self.prev_ccon.0, ccon.0),
                Edges::between(self.prev_cpos.0, cpos.0),
            )
        } else {
            (Edges::default(), Edges::default())
        };
        self.lock = ccon.contains(Ccon::LOCK);
        let e = &mut emit;

        // T7 has the highest priority (Tab. 5.2 "*").
        self.detect_faults(status, e);
        // Internal conditions: motion complete (TA2, TA8), stopped after halt / stop.
        self.track_completion(status, e);
        // T1…T6, T8…T11; T4 / T6 before any TAx.
        self.main_transitions(ccon, cc_edges, plc, status, e);

        if plc {
            // §5.1.1: the operating mode changes only in SA1 "ready" (and while not enabled).
            // A reserved OPM (10, 11) is not accepted; the feedback keeps the last mode.
            let requested = ccon.operating_mode();
            let may_change = self.state != State::OperationEnabled
                || (self.sub == OpState::Ready && self.queued.is_none());
            if may_change && !matches!(requested, OperatingMode::Reserved(_)) {
                self.opm = requested;
            }
            if self.state == State::OperationEnabled {
                self.sub_transitions(out, cpos, cp_edges, records, status, e);
                self.teach(out, cp_edges, status, e);
            }
            if let Some(trigger) = self.ack_trigger {
                // Fig. 6.3 steps 3–4: ACK falls once the PLC has taken START (HOM, JOGx) away.
                if !cpos.intersects(trigger) {
                    self.ack_trigger = None;
                }
            }
        }
        if self.state != State::OperationEnabled {
            self.ack_trigger = None;
        }

        // CCON.BRAKE: only while the controller is disabled; once enabled it has priority.
        let release = plc && ccon.contains(Ccon::BRAKE) && !self.stage_on;
        if release != self.brake_released {
            self.brake_released = release;
            e(Event::Motion(MotionCommand::ManualBrake { open: release }));
        }

        self.prev_ccon = ccon;
        self.prev_cpos = cpos;
        if plc {
            self.last_cdir = out.cdir() & Cdir::DEFINED;
        }
        self.inputs = self.build_inputs_with(status, cpos);
        self.mc_pulse = false;
        self.inputs
    }

    fn detect_faults<F: FnMut(Event)>(&mut self, status: &MotionStatus, e: &mut F) {
        if let Some(f) = self.raised.take() {
            self.take_t7(f, true, e);
        }
        if let Some(f) = status.fault {
            let overrides = match self.fault {
                None => true,
                // A serious error overrides a minor one (§5.2 "reaction to faults").
                Some(active) => {
                    f.code != active.fault.code && f.serious() && !active.fault.serious()
                }
            };
            if overrides {
                self.take_t7(f, false, e);
            }
        }
    }

    fn take_t7<F: FnMut(Event)>(&mut self, fault: Fault, external: bool, e: &mut F) {
        if let Some(active) = self.fault {
            if active.fault.serious() && !fault.serious() {
                return; // a minor error never replaces a serious one
            }
        }
        let task_running = self.task.is_some()
            || self
                .fault
                .is_some_and(|f| f.task_running && self.state == State::FaultReaction);
        self.abort_task();
        self.fault = Some(ActiveFault {
            fault,
            external_cause: external,
            task_running,
        });
        self.state = State::FaultReaction;
        e(Event::Transition(Transition::T7));
        if self.stage_on {
            match fault.reaction {
                Reaction::A => {
                    self.stage_on = false;
                    e(Event::Motion(MotionCommand::Disable));
                }
                Reaction::B | Reaction::E => e(Event::Motion(MotionCommand::QuickStop)),
                Reaction::C | Reaction::F => e(Event::Motion(MotionCommand::Stop)),
                Reaction::D | Reaction::G => {}
            }
        }
    }

    /// Ends whatever runs in S4 (task, homing, jog): back to SA1 without ACK; MC follows once
    /// the axis has stopped.
    fn abort_task(&mut self) {
        let active = self.task.is_some() || self.sub != OpState::Ready;
        self.sub = OpState::Ready;
        self.task = None;
        self.queued = None;
        self.ack_trigger = None;
        if active {
            self.mc = false;
            self.awaiting_stop = true;
        }
    }

    fn track_completion<F: FnMut(Event)>(&mut self, status: &MotionStatus, e: &mut F) {
        if self.awaiting_stop && !status.moving {
            self.awaiting_stop = false;
            self.mc = true;
        }
        if self.state != State::OperationEnabled {
            return;
        }
        match self.sub {
            OpState::TaskActive if !self.mc && status.motion_complete => {
                if let Some(next) = self.queued.take() {
                    // PNU 583 / RCB3 "wait": the queued task starts after MC (TA5).
                    self.commit(next, Transition::TA5, false, e);
                    return;
                }
                self.mc = true;
                if self.rsb_chain.contains(Rsb::RC1) {
                    // §6.5.3: RCC (valid while MC = 1) = 1: the chain ran to its last record's
                    // MC. A chain ended by halt, stop or a fault keeps RCC = 0 ("aborted").
                    self.rsb_chain |= Rsb::RCC;
                }
                match self.task.map(|t| t.mode) {
                    // Decision: a velocity or force task keeps running after its MC condition
                    // ("speed reached", "force reached"): it stays in SA2 with MC = 1 until HALT
                    // ends it or a new start replaces it. A position task is done: TA2.
                    Some(ControlMode::Velocity | ControlMode::Force) => {}
                    _ => {
                        self.task = None;
                        self.sub = OpState::Ready;
                        e(Event::Transition(Transition::TA2));
                    }
                }
            }
            OpState::Homing if status.motion_complete => {
                self.mc = true;
                self.task = None;
                self.sub = OpState::Ready;
                e(Event::Transition(Transition::TA8));
            }
            _ => {}
        }
    }

    fn main_transitions<F: FnMut(Event)>(
        &mut self,
        ccon: Ccon,
        edges: Edges,
        plc: bool,
        status: &MotionStatus,
        e: &mut F,
    ) {
        let enable = ccon.contains(Ccon::ENABLE);
        let stop_released = ccon.contains(Ccon::STOP);
        let mut reset = edges.rose(Ccon::RESET.0);
        // Level transitions settle within the cycle; at most S1 → S2 → S3 → S4 or S6 → S3 → S4.
        for _ in 0..6 {
            let taken = match self.state {
                State::ControllerSwitchedOn => {
                    // T1: switched on, no error detected (T7 would have been taken first).
                    self.state = State::DriveBlocked;
                    // Tab. 5.22: MC is set for the first time after power-on, in "drive disabled".
                    self.mc = true;
                    e(Event::Transition(Transition::T1));
                    true
                }
                State::DriveBlocked => {
                    // T2: ENABLE, load voltage, the PLC has control authority, PNU 280 all 1.
                    let go = plc && enable && self.load_voltage && self.safety_ok;
                    if go {
                        self.state = State::DriveEnabled;
                        self.stage_on = true;
                        e(Event::Transition(Transition::T2));
                        e(Event::Motion(MotionCommand::Enable));
                    }
                    go
                }
                State::DriveEnabled if plc => {
                    if !enable {
                        self.state = State::DriveBlocked;
                        self.stage_on = false;
                        e(Event::Transition(Transition::T5));
                        e(Event::Motion(MotionCommand::Disable));
                        true
                    } else if stop_released {
                        self.state = State::OperationEnabled;
                        self.sub = OpState::Ready;
                        e(Event::Transition(Transition::T3));
                        true
                    } else {
                        false
                    }
                }
                State::OperationEnabled if plc => {
                    if !enable {
                        // T6: ENABLE = 0 stops the current task with Quick Stop (Tab. 5.14).
                        self.abort_task();
                        self.state = State::DriveBlocked;
                        self.stage_on = false;
                        e(Event::Transition(Transition::T6));
                        e(Event::Motion(MotionCommand::QuickStop));
                        e(Event::Motion(MotionCommand::Disable));
                        true
                    } else if !stop_released {
                        // T4: STOP aborts the task with the Quick-Stop deceleration and resets it.
                        self.abort_task();
                        self.state = State::DriveEnabled;
                        e(Event::Transition(Transition::T4));
                        e(Event::Motion(MotionCommand::QuickStop));
                        true
                    } else {
                        false
                    }
                }
                State::FaultReaction => {
                    let done = self.reaction_complete(status);
                    if done {
                        self.state = State::Fault;
                        // Decision (§9.3): Tab. 5.22 "MC = 1: task complete, or error" wins over
                        // Example 3's "MC = 0" print: MC = 0 while the reaction brakes (S5, the
                        // snapshot of Example 3), MC = 1 once the drive has stopped (T8), and it
                        // stays 1 through the acknowledge (Example 3 step 3.3).
                        self.mc = true;
                        self.awaiting_stop = false;
                        e(Event::Transition(Transition::T8));
                        let off = self
                            .fault
                            .is_some_and(|a| a.fault.reaction.output_stage_off());
                        if off && self.stage_on {
                            self.stage_on = false;
                            e(Event::Motion(MotionCommand::Disable));
                        }
                    }
                    done
                }
                State::Fault if plc && reset => {
                    reset = false;
                    let t = self.acknowledge(enable, status);
                    e(Event::Transition(t));
                    if t == Transition::T9 && self.stage_on {
                        self.stage_on = false;
                        e(Event::Motion(MotionCommand::Disable));
                    }
                    t != Transition::T11
                }
                _ => false,
            };
            if !taken {
                break;
            }
        }
    }

    fn reaction_complete(&self, status: &MotionStatus) -> bool {
        match self.fault {
            None => true,
            Some(active) => match active.fault.reaction {
                // "Finish the record": wait for MC of the running task.
                Reaction::D | Reaction::G if active.task_running && self.stage_on => {
                    status.motion_complete || !status.moving
                }
                _ => !status.moving,
            },
        }
    }

    /// RESET rising in S6: T9, T10 or T11.
    fn acknowledge(&mut self, enable: bool, status: &MotionStatus) -> Transition {
        let Some(active) = self.fault else {
            self.state = State::DriveBlocked;
            return Transition::T9;
        };
        let cause_present =
            active.external_cause || status.fault.is_some_and(|f| f.code == active.fault.code);
        let ackable = match active.fault.ack {
            Ack::Immediately => true,
            Ack::AfterCause => !cause_present,
            Ack::NotAckable => false,
        };
        if !ackable {
            return Transition::T11;
        }
        if !enable {
            // T9 `xxx0.Pxx0`: acknowledged with the controller off → S2.
            self.fault = None;
            self.state = State::DriveBlocked;
            Transition::T9
        } else if !active.fault.serious() {
            // T10 `xxx0.Pxx1`. Decision (§9.18): the row text "CCON.ENABLE = 0" is a typo; the
            // pattern and "without switching the controller off" mean ENABLE = 1 → S3.
            self.fault = None;
            if self.stage_on {
                self.state = State::DriveEnabled;
            } else {
                // The fault came while the stage was off: back to S2, T2 follows if allowed.
                self.state = State::DriveBlocked;
            }
            Transition::T10
        } else {
            // Decision: a serious error is acknowledged only with ENABLE = 0 (T9's pattern);
            // RESET with ENABLE = 1 leaves the drive in S6 like T11.
            Transition::T11
        }
    }

    fn sub_transitions<F: FnMut(Event)>(
        &mut self,
        out: &OutputData,
        cpos: Cpos,
        edges: Edges,
        records: &RecordTable,
        status: &MotionStatus,
        e: &mut F,
    ) {
        let halt_released = cpos.contains(Cpos::HALT);
        let jogging = cpos.intersects(Cpos::JOGP | Cpos::JOGN);
        match self.sub {
            OpState::Ready => {
                if !halt_released {
                    return;
                }
                // Tab. 6.6: jog and homing have priority over START; Tab. 6.1: homing needs
                // "no jog command".
                if edges.rose(Cpos::HOM.0) && !jogging {
                    self.start_homing(Cpos::HOM, e);
                } else if edges.rose(Cpos::JOGP.0) && !cpos.contains(Cpos::JOGN) {
                    self.start_jog(true, e);
                } else if edges.rose(Cpos::JOGN.0) && !cpos.contains(Cpos::JOGP) {
                    self.start_jog(false, e);
                } else if edges.rose(Cpos::START.0) {
                    match self.prepare(out, records, status) {
                        Ok(p) if p.homing => self.start_homing(Cpos::START, e),
                        Ok(p) => self.commit(p, Transition::TA1, true, e),
                        Err(r) => e(Event::Refused(r)),
                    }
                }
            }
            OpState::TaskActive => {
                let Some(task) = self.task else {
                    self.sub = OpState::Ready;
                    return;
                };
                if !halt_released {
                    // TA3 (HALT is level-controlled and active low; its falling edge is the
                    // only way HALT = 0 reaches SA2).
                    e(Event::Transition(Transition::TA3));
                    e(Event::Motion(MotionCommand::Halt));
                    self.queued = None;
                    if task.mode == ControlMode::Position && !self.mc {
                        // Position mode: the task stays active (intermediate stop).
                        self.sub = OpState::IntermediateStop;
                    } else {
                        // Velocity and force modes: the task ends (Tab. 5.15 HALT).
                        self.task = None;
                        self.sub = OpState::Ready;
                        self.mc = false;
                        self.awaiting_stop = true;
                    }
                } else if edges.rose(Cpos::START.0) {
                    // A task that has reached its MC condition counts as finished (Tab. 5.4).
                    let behaviour = if self.mc {
                        StartBehaviour::Interrupt
                    } else {
                        task.behaviour
                    };
                    match (behaviour, self.prepare(out, records, status)) {
                        (StartBehaviour::Ignore, _) => {}
                        // Homing starts from SA1 only (TA7).
                        (_, Ok(p)) if p.homing => {}
                        (StartBehaviour::Interrupt, Ok(p)) => {
                            self.commit(p, Transition::TA5, true, e)
                        }
                        (StartBehaviour::Wait, Ok(p)) => {
                            self.queued = Some(p);
                            self.ack_trigger = Some(Cpos::START);
                        }
                        (_, Err(r)) => e(Event::Refused(r)),
                    }
                }
            }
            OpState::IntermediateStop => {
                if edges.rose(Cpos::CLEAR.0) {
                    e(Event::Transition(Transition::TA6));
                    e(Event::Motion(MotionCommand::Clear));
                    self.task = None;
                    self.sub = OpState::Ready;
                    if status.moving {
                        self.awaiting_stop = true;
                    } else {
                        self.mc = true;
                    }
                } else if halt_released && edges.rose(Cpos::START.0) && !cpos.contains(Cpos::CLEAR)
                {
                    // TA4 / Fig. 6.4: START restarts record N and acknowledges the halt.
                    e(Event::Transition(Transition::TA4));
                    e(Event::Motion(MotionCommand::Continue));
                    self.sub = OpState::TaskActive;
                    self.ack_trigger = Some(Cpos::START);
                }
            }
            OpState::Homing => {
                if !halt_released {
                    // TA8: homing can be aborted only by HALT.
                    e(Event::Transition(Transition::TA8));
                    e(Event::Motion(MotionCommand::Halt));
                    self.task = None;
                    self.sub = OpState::Ready;
                    self.awaiting_stop = true;
                }
            }
            OpState::JogPositive | OpState::JogNegative => {
                let positive = self.sub == OpState::JogPositive;
                let bit = if positive { Cpos::JOGP } else { Cpos::JOGN };
                if !cpos.contains(bit) || !halt_released {
                    let t = if positive {
                        Transition::TA10
                    } else {
                        Transition::TA12
                    };
                    e(Event::Transition(t));
                    e(Event::Motion(MotionCommand::Halt));
                    self.task = None;
                    self.sub = OpState::Ready;
                    self.awaiting_stop = true;
                }
            }
        }
    }

    fn start_homing<F: FnMut(Event)>(&mut self, trigger: Cpos, e: &mut F) {
        e(Event::Transition(Transition::TA7));
        e(Event::Motion(MotionCommand::Home));
        if trigger == Cpos::START {
            // Record 0 = homing: its number is the feedback like any record's.
            self.record_feedback = 0;
        }
        self.task = Some(Task {
            mode: ControlMode::Position,
            cdir: None,
            behaviour: StartBehaviour::Ignore,
        });
        self.sub = OpState::Homing;
        self.mc = false;
        self.awaiting_stop = false;
        self.ack_trigger = Some(trigger);
    }

    fn start_jog<F: FnMut(Event)>(&mut self, positive: bool, e: &mut F) {
        let (t, sub, bit) = if positive {
            (Transition::TA9, OpState::JogPositive, Cpos::JOGP)
        } else {
            (Transition::TA11, OpState::JogNegative, Cpos::JOGN)
        };
        e(Event::Transition(t));
        e(Event::Motion(MotionCommand::Jog { positive }));
        self.task = Some(Task {
            mode: ControlMode::Position,
            cdir: None,
            behaviour: StartBehaviour::Ignore,
        });
        self.sub = sub;
        // Tab. 6.3: MOV = 1, MC = 0 while jogging; ACK = 1 "start executed (… jog …)".
        self.mc = false;
        self.awaiting_stop = false;
        self.ack_trigger = Some(bit);
    }

    /// Takes over the set-point data at the START edge (Tab. 5.15) and checks the start
    /// conditions (TA1: referenced; a valid record / control mode).
    fn prepare(
        &self,
        out: &OutputData,
        records: &RecordTable,
        status: &MotionStatus,
    ) -> Result<Prepared, Refusal> {
        let homing = Prepared {
            command: MotionCommand::Home,
            task: Task {
                mode: ControlMode::Position,
                cdir: None,
                behaviour: StartBehaviour::Ignore,
            },
            record: Some(0),
            homing: true,
        };
        match self.opm {
            OperatingMode::RecordSelection => {
                let number = match records.select(out.record_number()) {
                    RecordSelect::Homing => return Ok(homing),
                    RecordSelect::Record(n) => n,
                    RecordSelect::Invalid(n) => return Err(Refusal::InvalidRecord(n)),
                };
                let record = records.get(number).ok_or(Refusal::InvalidRecord(number))?;
                let (Some(mode), Some(behaviour), true) = (
                    record.control_mode(),
                    record.start_behaviour(),
                    record.is_valid(),
                ) else {
                    return Err(Refusal::InvalidRecord(number));
                };
                if !status.referenced {
                    return Err(Refusal::NotReferenced);
                }
                Ok(Prepared {
                    command: MotionCommand::Record { number, mode },
                    task: Task {
                        mode,
                        cdir: None,
                        behaviour,
                    },
                    record: Some(number),
                    homing: false,
                })
            }
            OperatingMode::Direct => {
                let cdir = out.cdir() & Cdir::DEFINED;
                let mode = cdir.control_mode().ok_or(Refusal::InvalidControlMode)?;
                // Decision: TA1's "axis referenced" applies to every direct task (the manual
                // lists "not referenced" as an error cause of direct mode without exception).
                if !status.referenced {
                    return Err(Refusal::NotReferenced);
                }
                let percent = out.setpoint1().min(100);
                let stroke_monitoring = !cdir.contains(Cdir::XLIM);
                let command = match mode {
                    ControlMode::Position if cdir.relative() => MotionCommand::MoveRelative {
                        distance: out.setpoint2,
                        velocity: percent_of(percent, self.config.base_velocity),
                        velocity_percent: percent,
                        reference: if self.config.relative_to_actual {
                            RelativeTo::ActualPosition
                        } else {
                            RelativeTo::LastSetpoint
                        },
                    },
                    ControlMode::Position => MotionCommand::MoveAbsolute {
                        target: out.setpoint2,
                        velocity: percent_of(percent, self.config.base_velocity),
                        velocity_percent: percent,
                    },
                    // §6.6: the velocity set-point is always absolute, CDIR.ABS is ignored.
                    ControlMode::Velocity => MotionCommand::Velocity {
                        velocity: out.setpoint2,
                        ramp: percent_of(percent, self.config.base_acceleration),
                        ramp_percent: percent,
                        stroke_monitoring,
                    },
                    // Decision (§9.11): the force set-point in bytes 5…8 is in ‰ of PNU 555
                    // (1000 = base value), the unit of PNU 418/581 and the force comparators.
                    ControlMode::Force => MotionCommand::Force {
                        setpoint: out.setpoint2,
                        velocity_limit: percent_of(percent, self.config.base_velocity),
                        velocity_percent: percent,
                        stroke_monitoring,
                    },
                };
                Ok(Prepared {
                    command,
                    task: Task {
                        mode,
                        cdir: Some(cdir),
                        behaviour: self.config.start_condition,
                    },
                    record: None,
                    homing: false,
                })
            }
            OperatingMode::Reserved(_) => Err(Refusal::InvalidControlMode),
        }
    }

    /// Hands a prepared start to the motion layer. `acknowledge`: raise ACK now (a start from
    /// its START edge); a queued ("wait") start was acknowledged when it was queued.
    fn commit<F: FnMut(Event)>(
        &mut self,
        p: Prepared,
        t: Transition,
        acknowledge: bool,
        e: &mut F,
    ) {
        e(Event::Transition(t));
        e(Event::Motion(p.command));
        if let Some(n) = p.record {
            // Example 5: byte 3 shows the previous record until the start is accepted.
            self.record_feedback = n;
        }
        self.task = Some(p.task);
        self.sub = OpState::TaskActive;
        self.mc = false;
        self.awaiting_stop = false;
        self.rsb_chain = Rsb::EMPTY;
        if acknowledge {
            self.ack_trigger = Some(Cpos::START);
        }
    }

    /// Teach (§6.4). Decision (§9.14): the 4-step handshake of the SPOS.TEACH bit definition:
    /// CPOS.TEACH = 1 → SPOS.TEACH = 0 (ready); CPOS.TEACH falling → value taken,
    /// SPOS.TEACH = 1 (accepted). Tab. 6.5's "SPOS.TEACH = N" is not followed.
    fn teach<F: FnMut(Event)>(
        &mut self,
        out: &OutputData,
        edges: Edges,
        status: &MotionStatus,
        e: &mut F,
    ) {
        if edges.rose(Cpos::TEACH.0) {
            self.teach_ack = false;
        }
        if edges.fell(Cpos::TEACH.0) {
            let record = match self.opm {
                OperatingMode::RecordSelection => out.record_number(),
                _ => self.config.teach_record,
            };
            e(Event::Teach {
                record,
                position: status.actual_position,
            });
            self.teach_ack = true;
        }
    }

    fn build_inputs(&self, status: &MotionStatus) -> InputData {
        self.build_inputs_with(status, self.prev_cpos)
    }

    fn build_inputs_with(&self, status: &MotionStatus, cpos: Cpos) -> InputData {
        let faulted = matches!(self.state, State::FaultReaction | State::Fault);
        let scon = Scon::EMPTY
            .with(Scon::ENABLED, self.stage_on)
            .with(Scon::OPEN, self.state == State::OperationEnabled)
            .with(Scon::WARN, self.warning || status.warning)
            // Decision: FAULT = 1 in S5 and S6. The Chinese text of Tab. 5.21 reads "0 = no
            // fault or fault reaction active", a mistranslation of FHPP's "1 = fault, or fault
            // reaction active"; Example 3 shows FAULT = 1 while MC = 0 (the reaction).
            .with(Scon::FAULT, faulted)
            .with(Scon::VLOAD, self.load_voltage)
            .with(Scon::FCT_MMI, self.authority != Authority::Fieldbus)
            .union(Scon(self.opm.bits() << 6));
        let in_s4 = self.state == State::OperationEnabled;
        let halted = in_s4 && self.sub == OpState::IntermediateStop;
        let spos = Spos::EMPTY
            // SPOS.HALT mirrors CPOS.HALT, and stays 0 in SA3 until START acknowledges the halt.
            .with(Spos::HALT, cpos.contains(Cpos::HALT) && !halted)
            .with(Spos::ACK, in_s4 && self.ack_trigger.is_some())
            .with(Spos::MC, self.mc || self.mc_pulse)
            .with(Spos::TEACH, self.teach_ack)
            .with(Spos::MOV, status.moving)
            .with(Spos::FOLERR, status.following_error)
            .with(Spos::STILL, status.standstill_error)
            .with(Spos::REF, status.referenced);
        let limits = |v: u8, x: u8| {
            (if status.velocity_limit { v } else { 0 }) | (if status.stroke_limit { x } else { 0 })
        };
        match self.opm {
            OperatingMode::Direct => {
                // SDIR reports the running task's CDIR; with no task, the requested one.
                let cdir = match self.task.and_then(|t| t.cdir) {
                    Some(c) => c,
                    None => self.last_cdir,
                };
                let sdir = Sdir(cdir.0 & (Cdir::ABS | Cdir::COM1 | Cdir::COM2).0)
                    | Sdir(limits(Sdir::VLIM.0, Sdir::XLIM.0));
                let velocity_percent = if self.config.base_velocity == 0 {
                    0
                } else {
                    let p = u64::from(status.actual_velocity.unsigned_abs()) * 100
                        / u64::from(self.config.base_velocity);
                    p.min(255) as u8
                };
                let torque_percent = (status.actual_force.unsigned_abs() / 10).min(255) as u8;
                let (actual1, actual2) = match sdir.control_mode() {
                    Some(ControlMode::Velocity) => {
                        // PNU 523:12 = 1: velocity as an absolute value.
                        (
                            0,
                            i32::try_from(status.actual_velocity.unsigned_abs())
                                .unwrap_or(i32::MAX),
                        )
                    }
                    Some(ControlMode::Force) => (
                        if self.config.force_actual1_torque {
                            torque_percent
                        } else {
                            velocity_percent
                        },
                        if self.config.force_actual2_torque {
                            status.actual_force
                        } else {
                            status.actual_position
                        },
                    ),
                    _ => (velocity_percent, status.actual_position),
                };
                InputData {
                    scon,
                    spos,
                    byte3: sdir.0,
                    byte4: actual1,
                    actual2,
                }
            }
            _ => InputData {
                scon,
                spos,
                byte3: self.record_feedback,
                byte4: (self.rsb_chain & (Rsb::RC1 | Rsb::RCC)).0
                    | limits(Rsb::VLIM.0, Rsb::XLIM.0),
                actual2: status.actual_position,
            },
        }
    }
}
