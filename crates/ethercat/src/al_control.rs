//! Application-layer state machine (ESM): AL control 0x0120, AL status 0x0130 and the
//! transition table (spec §4.1–§4.2: Init, Pre-Op, Safe-Op, Op; Bootstrap
//! where the device has it).

use crate::al_status_code::AlStatusCode;

/// AL state codes (bits 0–3 of AL control and AL status).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum AlState {
    Init = 1,
    PreOp = 2,
    Bootstrap = 3,
    SafeOp = 4,
    Op = 8,
}

impl AlState {
    pub const fn from_u8(v: u8) -> Option<Self> {
        match v {
            1 => Some(AlState::Init),
            2 => Some(AlState::PreOp),
            3 => Some(AlState::Bootstrap),
            4 => Some(AlState::SafeOp),
            8 => Some(AlState::Op),
            _ => None,
        }
    }

    pub const fn to_u8(self) -> u8 {
        self as u8
    }

    /// Order in the ESM ladder Init < Pre-Op < Safe-Op < Op (Bootstrap beside Init).
    const fn rank(self) -> u8 {
        match self {
            AlState::Init | AlState::Bootstrap => 0,
            AlState::PreOp => 1,
            AlState::SafeOp => 2,
            AlState::Op => 3,
        }
    }
}

/// AL control bit 4: error acknowledge.
pub const ERROR_ACK: u16 = 0x0010;
/// AL control bit 5: device identification request.
pub const ID_REQUEST: u16 = 0x0020;
/// AL status bit 4: error indication.
pub const ERROR_INDICATION: u16 = 0x0010;

/// A decoded AL control word.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AlControl {
    /// Requested state, raw (bits 0–3); not necessarily a valid state.
    pub requested: u8,
    pub error_ack: bool,
    pub id_request: bool,
}

impl AlControl {
    pub const fn from_u16(v: u16) -> Self {
        AlControl {
            requested: (v & 0x0F) as u8,
            error_ack: v & ERROR_ACK != 0,
            id_request: v & ID_REQUEST != 0,
        }
    }

    pub const fn new(state: AlState, error_ack: bool) -> Self {
        AlControl {
            requested: state as u8,
            error_ack,
            id_request: false,
        }
    }

    pub const fn to_u16(self) -> u16 {
        (self.requested as u16 & 0x0F)
            | if self.error_ack { ERROR_ACK } else { 0 }
            | if self.id_request { ID_REQUEST } else { 0 }
    }
}

/// A decoded AL status word.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AlStatus {
    pub state: AlState,
    pub error: bool,
}

impl AlStatus {
    /// Decode; an invalid state code reads as Init.
    pub fn from_u16(v: u16) -> Self {
        AlStatus {
            state: AlState::from_u8((v & 0x0F) as u8).unwrap_or(AlState::Init),
            error: v & ERROR_INDICATION != 0,
        }
    }

    pub const fn to_u16(self) -> u16 {
        self.state as u16 | if self.error { ERROR_INDICATION } else { 0 }
    }
}

/// Does the ESM allow `from → requested` (raw state code)? `Ok(target)` if the table
/// allows it (the slave's own checks still follow), `Err(code)` with the AL status code of
/// the refusal otherwise (spec §4.2 table):
///
/// * unknown state value (0, 5–7, 9–15) → 0x0012;
/// * Bootstrap requested from Init when not supported → 0x0013;
/// * skipping states upwards (Init → Safe-Op/Op, Pre-Op → Op), Bootstrap from anything but
///   Init, or leaving Bootstrap for anything but Init → 0x0011;
/// * every downward transition and "stay" is allowed.
pub fn check_transition(
    from: AlState,
    requested: u8,
    bootstrap_supported: bool,
) -> Result<AlState, AlStatusCode> {
    let to = AlState::from_u8(requested).ok_or(AlStatusCode::UNKNOWN_REQUESTED_STATE)?;
    if to == from {
        return Ok(to);
    }
    match (from, to) {
        (AlState::Init, AlState::Bootstrap) if bootstrap_supported => Ok(to),
        (AlState::Init, AlState::Bootstrap) => Err(AlStatusCode::BOOTSTRAP_NOT_SUPPORTED),
        (_, AlState::Bootstrap) => Err(AlStatusCode::INVALID_REQUESTED_STATE_CHANGE),
        (AlState::Bootstrap, AlState::Init) => Ok(to),
        (AlState::Bootstrap, _) => Err(AlStatusCode::INVALID_REQUESTED_STATE_CHANGE),
        _ if to.rank() <= from.rank() => Ok(to),
        _ if to.rank() == from.rank() + 1 => Ok(to),
        _ => Err(AlStatusCode::INVALID_REQUESTED_STATE_CHANGE),
    }
}

/// `to` lies above `from` in the ESM (a transition the slave may refuse).
pub fn is_upward(from: AlState, to: AlState) -> bool {
    to.rank() > from.rank() || (to == AlState::Bootstrap && from != AlState::Bootstrap)
}
