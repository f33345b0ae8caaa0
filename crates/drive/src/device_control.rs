//! CiA 402 device control (§6.3): the power state machine driven by the controlword, and the
//! state bits of the statusword; where a manual departs from it, a [`Rules`] switch or the
//! personality's hook says so.

/// The states of CiA 402 Fig. 27.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum State {
    NotReadyToSwitchOn,
    SwitchOnDisabled,
    ReadyToSwitchOn,
    SwitchedOn,
    OperationEnabled,
    QuickStopActive,
    FaultReactionActive,
    Fault,
}

impl State {
    /// Whether the output stage is switched on (CiA 402 §6.3.1: high voltage may be applied
    /// to the motor from SWITCHED ON on).
    pub const fn power_enabled(self) -> bool {
        matches!(
            self,
            State::SwitchedOn
                | State::OperationEnabled
                | State::QuickStopActive
                | State::FaultReactionActive
        )
    }

    /// Statusword bits 0–3, 5, 6 of the state (CiA 402 §6.3.3 Tab. 30). `cia402_fault`:
    /// FAULT as CiA 402 prints it (xxxx xxxx x0xx 1000); without it FAULT shows as 000Fh like
    /// FAULT_REACTION_ACTIVE (a manufacturer's coding a personality may keep).
    pub const fn statusword_bits(self, cia402_fault: bool) -> u16 {
        match self {
            State::NotReadyToSwitchOn => 0x0000,
            State::SwitchOnDisabled => 0x0040,
            State::ReadyToSwitchOn => 0x0021,
            State::SwitchedOn => 0x0023,
            State::OperationEnabled => 0x0027,
            State::QuickStopActive => 0x0007,
            State::FaultReactionActive => 0x000F,
            State::Fault => {
                if cia402_fault {
                    0x0008
                } else {
                    0x000F
                }
            }
        }
    }

    pub const fn name(self) -> &'static str {
        match self {
            State::NotReadyToSwitchOn => "NOT READY TO SWITCH ON",
            State::SwitchOnDisabled => "SWITCH ON DISABLED",
            State::ReadyToSwitchOn => "READY TO SWITCH ON",
            State::SwitchedOn => "SWITCHED ON",
            State::OperationEnabled => "OPERATION ENABLED",
            State::QuickStopActive => "QUICK STOP ACTIVE",
            State::FaultReactionActive => "FAULT REACTION ACTIVE",
            State::Fault => "FAULT",
        }
    }
}

/// A device-control command decoded from controlword bits 0–3 and 7 (CiA 402 §6.3.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    Shutdown,
    SwitchOn,
    /// Switch on and enable operation at once (0Fh from READY TO SWITCH ON: transitions 3+4).
    EnableOperation,
    DisableVoltage,
    QuickStop,
    DisableOperation,
}

impl Command {
    /// Decodes bits 0–3; bit 7 (fault reset) is an edge handled separately.
    pub const fn from_controlword(cw: u16) -> Option<Self> {
        if cw & 0x0002 == 0 {
            return Some(Command::DisableVoltage); // x x 0 x
        }
        if cw & 0x0004 == 0 {
            return Some(Command::QuickStop); // x 0 1 x
        }
        match cw & 0x000F {
            0x06 | 0x0E => Some(Command::Shutdown), // x 1 1 0
            0x07 => Some(Command::SwitchOn),        // 0 1 1 1 (= disable operation from OE)
            0x0F => Some(Command::EnableOperation), // 1 1 1 1
            _ => None,
        }
    }
}

/// What a transition asks of the motion side.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reaction {
    None,
    /// Output stage off at once, the motor coasts (605Bh = 0, Disable Voltage).
    Coast,
    /// Output stage on, control per mode (brake released).
    Enable,
    /// Brake the motion with the quick-stop deceleration; the state machine waits for
    /// [`DeviceControl::stopped`] (605Ah = 2, 605Ch = −1).
    QuickStopRamp,
}

/// What a personality's option codes and manual make of the state machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rules {
    /// 0Fh in READY TO SWITCH ON runs transitions 3 and 4 at once.
    pub enable_from_ready: bool,
    /// 605Ah quick_stop_option_code: 1–4 end the quick stop in SWITCH ON DISABLED, 5–8 stay
    /// in QUICK STOP ACTIVE (CiA 402 §6.3.4).
    pub quick_stop_option: i16,
}

impl Default for Rules {
    /// 0Fh from READY TO SWITCH ON runs transitions 3 + 4; 605Ah = 2, CiA 402's default
    /// (§6.3.4: slow down on the quick-stop ramp, then SWITCH ON DISABLED).
    fn default() -> Self {
        Rules {
            enable_from_ready: true,
            quick_stop_option: 2,
        }
    }
}

/// The device control state machine.
#[derive(Debug, Clone, Copy)]
pub struct DeviceControl {
    state: State,
    last_controlword: u16,
    rules: Rules,
}

impl Default for DeviceControl {
    fn default() -> Self {
        Self::with_rules(Rules::default())
    }
}

impl DeviceControl {
    pub const fn with_rules(rules: Rules) -> Self {
        DeviceControl {
            state: State::NotReadyToSwitchOn,
            last_controlword: 0,
            rules,
        }
    }

    pub fn state(&self) -> State {
        self.state
    }

    /// Self-test done (transition 1).
    pub fn initialised(&mut self) {
        if self.state == State::NotReadyToSwitchOn {
            self.state = State::SwitchOnDisabled;
        }
    }

    /// An error appeared (transition 13): fault reaction, then FAULT once the motion side
    /// reports it has stopped (transition 14).
    pub fn fault(&mut self) -> Reaction {
        match self.state {
            State::Fault | State::FaultReactionActive => Reaction::None,
            s if s.power_enabled() => {
                self.state = State::FaultReactionActive;
                Reaction::QuickStopRamp
            }
            _ => {
                self.state = State::Fault;
                Reaction::Coast
            }
        }
    }

    /// A critical error: straight to FAULT, output stage off at once (CiA 402 §6.3.1
    /// transitions 13 and 14 without a fault reaction).
    pub fn fault_immediate(&mut self) -> Reaction {
        let was_powered = self.state.power_enabled();
        self.state = State::Fault;
        if was_powered {
            Reaction::Coast
        } else {
            Reaction::None
        }
    }

    /// A quick stop the drive asks for itself (an error whose reaction is a quick stop
    /// without a fault): transition 11 from OPERATION ENABLED.
    pub fn quick_stop(&mut self) -> Reaction {
        if self.state == State::OperationEnabled {
            self.state = State::QuickStopActive;
            Reaction::QuickStopRamp
        } else {
            Reaction::None
        }
    }

    /// The motion side finished braking (quick stop, disable operation or fault reaction).
    pub fn stopped(&mut self) -> Reaction {
        match self.state {
            // Transition 12 (605Ah = 1 … 4): quick stop ends in SWITCH ON DISABLED.
            State::QuickStopActive if matches!(self.rules.quick_stop_option, 1..=4) => {
                self.state = State::SwitchOnDisabled;
                Reaction::Coast
            }
            // Transition 14.
            State::FaultReactionActive => {
                self.state = State::Fault;
                Reaction::Coast
            }
            _ => Reaction::None,
        }
    }

    /// Applies a controlword. `fault_present` blocks the fault reset (transition 15 needs the
    /// cause removed); `enables_present` are the hardware enables transition 2 needs.
    pub fn controlword(&mut self, cw: u16, fault_present: bool, enables_present: bool) -> Reaction {
        let reset_edge = cw & 0x0080 != 0 && self.last_controlword & 0x0080 == 0;
        self.last_controlword = cw;
        if self.state == State::Fault {
            if reset_edge && !fault_present {
                self.state = State::SwitchOnDisabled; // transition 15
            }
            return Reaction::None;
        }
        let Some(cmd) = Command::from_controlword(cw) else {
            return Reaction::None;
        };
        use Command::*;
        use State::*;
        let (next, reaction) = match (self.state, cmd) {
            (SwitchOnDisabled, Shutdown) if enables_present => (ReadyToSwitchOn, Reaction::None), // 2
            (ReadyToSwitchOn, SwitchOn) => (SwitchedOn, Reaction::Enable), // 3
            (ReadyToSwitchOn, EnableOperation) if self.rules.enable_from_ready => {
                (OperationEnabled, Reaction::Enable) // 3+4
            }
            // 7: the manual (ch. 6) lists Quick Stop only; CiA 402 also Disable Voltage.
            (ReadyToSwitchOn, DisableVoltage | QuickStop) => (SwitchOnDisabled, Reaction::None),
            (SwitchedOn, EnableOperation) => (OperationEnabled, Reaction::Enable), // 4
            (SwitchedOn, Shutdown) => (ReadyToSwitchOn, Reaction::Coast),          // 6
            // 10: the manual (ch. 6) lists Disable Voltage only; CiA 402 also Quick Stop.
            (SwitchedOn, DisableVoltage | QuickStop) => (SwitchOnDisabled, Reaction::Coast),
            // 5: the transition table says "coast", 605Ch = −1 says "brake with the quick-stop
            // deceleration": the option code is the object a master reads, so it wins; the
            // output stage stays on in SWITCHED ON (CiA 402 §6.3.1).
            (OperationEnabled, SwitchOn) => (SwitchedOn, Reaction::QuickStopRamp),
            (OperationEnabled, Shutdown) => (ReadyToSwitchOn, Reaction::Coast), // 8 (605Bh = 0)
            (OperationEnabled, DisableVoltage) => (SwitchOnDisabled, Reaction::Coast), // 9
            (OperationEnabled, QuickStop) => (QuickStopActive, Reaction::QuickStopRamp), // 11
            (QuickStopActive, DisableVoltage) => (SwitchOnDisabled, Reaction::Coast), // 12
            (s, _) => (s, Reaction::None),
        };
        self.state = next;
        reaction
    }

    /// Forces SWITCH ON DISABLED (e.g. the hardware enable dropped: transition 9/10/12).
    pub fn disable(&mut self) -> Reaction {
        match self.state {
            State::Fault | State::FaultReactionActive | State::NotReadyToSwitchOn => Reaction::None,
            _ => {
                self.state = State::SwitchOnDisabled;
                Reaction::Coast
            }
        }
    }
}
