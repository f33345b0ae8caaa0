//! NMT (CiA 301 §7.2.8.3.1): node-control commands and the states a slave walks through.

/// NMT state as the error-control protocols (boot-up, heartbeat, guarding) report it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum NmtState {
    Initialising = 0x00,
    Stopped = 0x04,
    Operational = 0x05,
    PreOperational = 0x7F,
}

impl NmtState {
    pub const fn code(self) -> u8 {
        self as u8
    }
    pub const fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0x00 => NmtState::Initialising,
            0x04 => NmtState::Stopped,
            0x05 => NmtState::Operational,
            0x7F => NmtState::PreOperational,
            _ => return None,
        })
    }
    /// SDO is served in Pre-Operational and Operational only (CiA 301, NMT states and the
    /// services they allow).
    pub const fn serves_sdo(self) -> bool {
        matches!(self, NmtState::PreOperational | NmtState::Operational)
    }
    pub const fn name(self) -> &'static str {
        match self {
            NmtState::Initialising => "INITIALISING",
            NmtState::Stopped => "STOPPED",
            NmtState::Operational => "OPERATIONAL",
            NmtState::PreOperational => "PRE-OPERATIONAL",
        }
    }
}

/// An NMT node-control command specifier (frame `000h: [cs] [node]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum NmtCommand {
    Start = 0x01,
    Stop = 0x02,
    EnterPreOperational = 0x80,
    ResetNode = 0x81,
    ResetCommunication = 0x82,
}

impl NmtCommand {
    pub const fn from_cs(cs: u8) -> Option<Self> {
        Some(match cs {
            0x01 => NmtCommand::Start,
            0x02 => NmtCommand::Stop,
            0x80 => NmtCommand::EnterPreOperational,
            0x81 => NmtCommand::ResetNode,
            0x82 => NmtCommand::ResetCommunication,
            _ => return None,
        })
    }
    pub const fn cs(self) -> u8 {
        self as u8
    }
    pub const fn name(self) -> &'static str {
        match self {
            NmtCommand::Start => "start",
            NmtCommand::Stop => "stop",
            NmtCommand::EnterPreOperational => "pre-operational",
            NmtCommand::ResetNode => "reset-node",
            NmtCommand::ResetCommunication => "reset-communication",
        }
    }
}

/// The slave's NMT state machine (CiA 301 Fig. 48).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NmtSlave {
    state: NmtState,
}

/// What a command asks of the node beyond a state change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NmtOutcome {
    /// The state is now the given one (possibly unchanged).
    State(NmtState),
    /// Reset of the application (all objects back to the stored set), then boot-up.
    ResetApplication,
    /// Reset of the communication objects (1000h–1FFFh), then boot-up.
    ResetCommunication,
}

impl Default for NmtSlave {
    fn default() -> Self {
        NmtSlave {
            state: NmtState::Initialising,
        }
    }
}

impl NmtSlave {
    pub fn state(&self) -> NmtState {
        self.state
    }
    /// Initialisation done (transition 2): boot-up sent, now Pre-Operational.
    pub fn booted(&mut self) {
        self.state = NmtState::PreOperational;
    }
    /// A reset begins: the node is Initialising until the runtime boots it again.
    pub fn resetting(&mut self) {
        self.state = NmtState::Initialising;
    }

    /// Applies a node-control command. Commands are accepted in every state but
    /// Initialising (CiA 301 §7.3.2.2).
    pub fn command(&mut self, cmd: NmtCommand) -> Option<NmtOutcome> {
        if self.state == NmtState::Initialising {
            return None;
        }
        Some(match cmd {
            NmtCommand::Start => {
                self.state = NmtState::Operational;
                NmtOutcome::State(self.state)
            }
            NmtCommand::Stop => {
                self.state = NmtState::Stopped;
                NmtOutcome::State(self.state)
            }
            NmtCommand::EnterPreOperational => {
                self.state = NmtState::PreOperational;
                NmtOutcome::State(self.state)
            }
            NmtCommand::ResetNode => {
                self.state = NmtState::Initialising;
                NmtOutcome::ResetApplication
            }
            NmtCommand::ResetCommunication => {
                self.state = NmtState::Initialising;
                NmtOutcome::ResetCommunication
            }
        })
    }
}
