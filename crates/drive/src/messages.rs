//! CMMP-AS diagnostic messages (App. B): the message number "main-sub" shown on the display,
//! its CiA 301 error code, and the error reaction of the error management 2100h (§5.18).
//!
//! Only the messages the twin can raise (or is asked to inject) are listed; the table is data,
//! a message missing from it is still reported by its code.

/// A message number, e.g. 08-2: main index (error group) and sub-index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Number {
    pub main: u8,
    pub sub: u8,
}

/// The reaction column of App. B.2.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fixed {
    /// "PS off": output stage off, not configurable.
    PsOff,
    /// "QStop": quick stop with the parameterised profile, not configurable.
    QuickStop,
    /// "configurable" through 2100h.
    Configurable,
}

/// One row of App. B.2.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Message {
    pub code: u16,
    pub number: Number,
    pub reaction: Fixed,
}

const fn m(code: u16, main: u8, sub: u8, reaction: Fixed) -> Message {
    Message {
        code,
        number: Number { main, sub },
        reaction,
    }
}

use Fixed::{Configurable as C, PsOff as P, QuickStop as Q};

/// App. B.2 (L6830–6960), the rows the twin uses.
pub const MESSAGES: &[Message] = &[
    m(0x2312, 31, 0, C),
    m(0x3220, 2, 0, C),
    m(0x4310, 3, 0, Q),
    m(0x5114, 5, 0, P),
    m(0x5115, 5, 1, P),
    m(0x6180, 1, 0, P),
    m(0x7382, 8, 2, C),
    m(0x8081, 43, 0, C),
    m(0x8082, 43, 1, C),
    m(0x8083, 43, 2, C),
    m(0x8611, 17, 0, C),
    m(0x8780, 34, 0, C),
    m(0x8781, 34, 1, C),
    m(0x8A80, 11, 0, C),
    m(0x8A81, 11, 1, C),
    m(0x8A82, 11, 2, C),
    m(0x8A83, 11, 3, C),
    m(0x8A84, 11, 4, C),
    m(0x8A85, 11, 5, C),
    m(0x8A86, 11, 6, C),
];

/// The message of an error code.
pub fn by_code(code: u16) -> Option<&'static Message> {
    MESSAGES.iter().find(|m| m.code == code)
}

/// 2100h:02 error_reaction_code values (§5.18).
pub mod reaction {
    pub const NONE: u8 = 0;
    pub const BUFFER_ENTRY: u8 = 1;
    pub const WARNING: u8 = 3;
    pub const CONTROLLER_ENABLE_OFF: u8 = 5;
    pub const BRAKE_MAX_CURRENT: u8 = 7;
    pub const OUTPUT_STAGE_OFF: u8 = 8;
}

/// The highest main error number 2100h:01 accepts.
pub const MAX_MAIN: u8 = 96;

/// The error management of 2100h: the reaction per main error number.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reactions {
    codes: [u8; MAX_MAIN as usize + 1],
}

impl Default for Reactions {
    /// The defaults: a fixed "PS off" group is 8, a fixed "QStop" group 5 (controller
    /// enable off with the quick-stop ramp). Decision: App. B prints no default for the
    /// configurable groups (the reaction column of B.3 is empty in the manual); they stop
    /// the drive with the quick-stop ramp (5), except 17 following error, which follows
    /// 6510h:22 and is "no action" while that limit is 0 (cmmp-as-2 §5.7).
    fn default() -> Self {
        let mut codes = [reaction::CONTROLLER_ENABLE_OFF; MAX_MAIN as usize + 1];
        for msg in MESSAGES {
            if let (Some(c), Some(min)) = (
                codes.get_mut(usize::from(msg.number.main)),
                minimum(msg.number.main),
            ) {
                *c = (*c).max(min);
            }
        }
        if let Some(c) = codes.get_mut(17) {
            *c = reaction::NONE;
        }
        Reactions { codes }
    }
}

/// The manufacturer's minimum reaction of a main error number: the strongest fixed
/// reaction among its messages (8 for "PS off", 5 for "QStop"); 0 where every message is
/// configurable or the group is not listed.
pub fn minimum(main: u8) -> Option<u8> {
    if main == 0 || main > MAX_MAIN {
        return None;
    }
    Some(
        MESSAGES
            .iter()
            .filter(|m| m.number.main == main)
            .map(|m| match m.reaction {
                Fixed::PsOff => reaction::OUTPUT_STAGE_OFF,
                Fixed::QuickStop => reaction::CONTROLLER_ENABLE_OFF,
                Fixed::Configurable => reaction::NONE,
            })
            .max()
            .unwrap_or(reaction::NONE),
    )
}

/// Why a reaction write is refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReactionError {
    /// error_number outside 1 … 96.
    Number,
    /// Not one of 0, 1, 3, 5, 7, 8.
    Code,
}

impl Reactions {
    pub fn get(&self, main: u8) -> Option<u8> {
        if main == 0 {
            return None;
        }
        self.codes.get(usize::from(main)).copied()
    }

    /// Sets the reaction of `main`; a value below the manufacturer's minimum is clamped to
    /// it (§5.18, L4863). Returns the reaction now in force.
    pub fn set(&mut self, main: u8, code: u8) -> Result<u8, ReactionError> {
        if !matches!(code, 0 | 1 | 3 | 5 | 7 | 8) {
            return Err(ReactionError::Code);
        }
        let min = minimum(main).ok_or(ReactionError::Number)?;
        let slot = self
            .codes
            .get_mut(usize::from(main))
            .ok_or(ReactionError::Number)?;
        *slot = code.max(min);
        Ok(*slot)
    }
}

/// 200Fh last_warning_code (§5.18, L4885–4907): bit 15 active, bits 4 … 11 main number,
/// bits 0 … 3 sub number. Decision: the manual does not say whether the main number is
/// binary or BCD; the twin writes BCD, so the hex digits read as the displayed number
/// (08-2 → 8082h either way, 17-0 → 8170h).
pub fn warning_code(number: Number, active: bool) -> u16 {
    let bcd = u16::from(number.main / 10) << 4 | u16::from(number.main % 10);
    (u16::from(active) << 15) | (bcd << 4) | u16::from(number.sub & 0x0F)
}

/// The warning a 200Fh value names, and whether it is active.
pub fn decode_warning_code(code: u16) -> (Number, bool) {
    let bcd = (code >> 4) & 0xFF;
    let main = (bcd >> 4) * 10 + (bcd & 0x0F);
    (
        Number {
            main: main.min(u16::from(u8::MAX)) as u8,
            sub: (code & 0x0F) as u8,
        },
        code & 0x8000 != 0,
    )
}

/// Additional information of 02-0 DC-link undervoltage (App. B.3, L6997–7000): the upper 16
/// bits the number of the internal state machine's state, the lower 16 bits the DC-link
/// voltage at approx. 17.1 digits/V. Decision: the manual does not number the internal
/// states; the twin puts the device-control state there.
pub fn undervoltage_info(state: u16, dc_link_mv: u32) -> u32 {
    let digits = libm::round(f64::from(dc_link_mv) * 17.1 / 1000.0).min(f64::from(u16::MAX));
    (u32::from(state) << 16) | digits as u32
}
