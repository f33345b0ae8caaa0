//! CMMP-AS diagnostic messages (App. B): the message number "main-sub" shown on the display,
//! its CiA 301 error code, and the error reaction of the error management 2100h (§5.18).
//!
//! The table is App. B.3 complete, as data: the `[[diagnostic]]` rows of
//! `devices/cmmp-as.toml`, generated into [`devices::CMMP_AS`].

use od::{Diagnostic, Reaction};

pub use crate::drive::diagnostics::GENERIC_ERROR;

/// A message number, e.g. 08-2: main index (error group) and sub-index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Number {
    pub main: u8,
    pub sub: u8,
}

impl Number {
    /// "08-2" or "8-2" (App. B.3 prints the main index without its leading zero).
    ///
    /// Over the bytes: every drive built parses App. B once ([`Reactions::default`]), and
    /// `str` trimming and `u8::from_str` were most of building one.
    pub fn parse(text: &str) -> Option<Number> {
        let text = text.as_bytes().trim_ascii();
        let dash = text.iter().position(|&b| b == b'-')?;
        let (main, sub) = (text.get(..dash)?, text.get(dash + 1..)?);
        Some(Number {
            main: decimal(main)?,
            sub: decimal(sub)?,
        })
    }
}

/// One to three decimal digits as a `u8`.
fn decimal(digits: &[u8]) -> Option<u8> {
    if digits.is_empty() {
        return None;
    }
    digits.iter().try_fold(0u8, |n, &b| {
        let d = b.checked_sub(b'0').filter(|d| *d <= 9)?;
        n.checked_mul(10)?.checked_add(d)
    })
}

/// One row of App. B.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Message {
    /// The CiA code; 1000h generic error where App. B prints "–" (see the device file).
    pub code: u16,
    pub number: Number,
    pub reaction: Reaction,
    pub row: &'static Diagnostic,
}

/// App. B as the device file gives it.
pub fn table() -> &'static [Diagnostic] {
    devices::CMMP_AS.diagnostics
}

/// The message of a row (`None` for a row whose number is not "main-sub").
pub fn message(row: &'static Diagnostic) -> Option<Message> {
    Some(Message {
        code: row.code.unwrap_or(GENERIC_ERROR),
        number: Number::parse(row.number)?,
        reaction: row.reaction,
        row,
    })
}

/// Every message of App. B, in table order.
pub fn messages() -> impl Iterator<Item = Message> {
    table().iter().filter_map(message)
}

/// The message of an error code: the first row with it (04-x, 17-0 before 27-0, as B.2 lists
/// them).
pub fn by_code(code: u16) -> Option<Message> {
    table()
        .iter()
        .filter(|d| d.code == Some(code))
        .find_map(message)
}

/// The message behind error `code`: one of the rows `raised` by their number, else the first
/// of App. B with the code ([`by_code`]).
pub fn of_code(raised: &[&'static Diagnostic], code: u16) -> Option<Message> {
    raised
        .iter()
        .filter_map(|d| message(d))
        .find(|m| m.code == code)
        .or_else(|| by_code(code))
}

/// The message numbered `number`.
pub fn by_number(number: Number) -> Option<Message> {
    messages().find(|m| m.number == number)
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
    /// Each group's [`minimum`], taken from App. B once (a write clamps to it).
    minimum: [u8; MAX_MAIN as usize + 1],
    /// The defaults of `codes`, to return to without another pass over App. B.
    defaults: [u8; MAX_MAIN as usize + 1],
}

impl Default for Reactions {
    /// The defaults: a fixed "PS off" group is 8, a fixed "QStop" group 5 (controller
    /// enable off with the quick-stop ramp). Decision: App. B prints no default for the
    /// configurable groups (the reaction column of B.3 is empty in the manual); they stop
    /// the drive with the quick-stop ramp (5), except 17 following error, which follows
    /// 6510h:22 and is "no action" while that limit is 0 (the manual's extract, part 2 §5.7).
    fn default() -> Self {
        // One pass over App. B (a drive is built with these; a pass per group made building
        // one take a millisecond): each group's fixed minimum (as [`minimum`]) and whether
        // every message of it is a warning.
        const GROUPS: usize = MAX_MAIN as usize + 1;
        let mut fixed: [Option<u8>; GROUPS] = [None; GROUPS];
        let mut warnings_only: [Option<bool>; GROUPS] = [None; GROUPS];
        for msg in messages() {
            let main = usize::from(msg.number.main);
            if let Some(f) = fixed.get_mut(main) {
                *f = Some(
                    f.unwrap_or(reaction::NONE)
                        .max(fixed_reaction(msg.reaction)),
                );
            }
            if let Some(w) = warnings_only.get_mut(main) {
                *w = Some(w.unwrap_or(true) && msg.reaction == Reaction::Warning);
            }
        }
        let mut codes = [reaction::CONTROLLER_ENABLE_OFF; GROUPS];
        for (main, (c, f)) in codes.iter_mut().zip(fixed).enumerate() {
            if let (true, Some(f)) = (main != 0, f) {
                *c = (*c).max(f);
            }
        }
        if let Some(c) = codes.get_mut(17) {
            *c = reaction::NONE;
        }
        // Decision: a group whose every message is "Warn" (66, 84) shows the warning reaction
        // (3) in 2100h, the reaction the message has.
        for (c, w) in codes.iter_mut().zip(warnings_only) {
            if w == Some(true) {
                *c = reaction::WARNING;
            }
        }
        Reactions {
            codes,
            minimum: fixed.map(|f| f.unwrap_or(reaction::NONE)),
            defaults: codes,
        }
    }
}

/// The 2100h code of a message's fixed reaction (0 where it is configurable).
fn fixed_reaction(r: Reaction) -> u8 {
    match r {
        Reaction::PsOff => reaction::OUTPUT_STAGE_OFF,
        Reaction::QuickStop => reaction::CONTROLLER_ENABLE_OFF,
        _ => reaction::NONE,
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
        messages()
            .filter(|m| m.number.main == main)
            .map(|m| fixed_reaction(m.reaction))
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
    /// Every reaction back to its default (the table is not part of the stored set).
    pub fn reset(&mut self) {
        self.codes = self.defaults;
    }

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
        if main == 0 {
            return Err(ReactionError::Number);
        }
        let min = *self
            .minimum
            .get(usize::from(main))
            .ok_or(ReactionError::Number)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The byte parse takes what "main-sub" through `str::parse::<u8>` took (no sign).
        #[test]
        fn number_parse_is_the_str_parse(text in "[ 0-9+-]{0,8}") {
            let by_str = text.trim().split_once('-').and_then(|(m, s)| {
                let plain = |t: &str| !t.starts_with('+');
                Some(Number {
                    main: m.parse().ok().filter(|_| plain(m))?,
                    sub: s.parse().ok().filter(|_| plain(s))?,
                })
            });
            prop_assert_eq!(Number::parse(&text), by_str);
        }
    }

    #[test]
    fn numbers_as_app_b_prints_them() {
        assert_eq!(Number::parse("08-2"), Some(Number { main: 8, sub: 2 }));
        assert_eq!(Number::parse(" 8-2 "), Some(Number { main: 8, sub: 2 }));
        assert_eq!(Number::parse("255-0"), Some(Number { main: 255, sub: 0 }));
        for bad in ["256-0", "8-", "-2", "8", "8-2-1", "a-1", ""] {
            assert_eq!(Number::parse(bad), None, "{bad:?}");
        }
    }

    /// The one-pass defaults are the per-group rule written out: at least controller enable
    /// off and the group's fixed minimum, 17 "no action", a group of warnings only 3.
    #[test]
    fn default_reactions_follow_each_groups_messages() {
        let r = Reactions::default();
        for main in 1..=MAX_MAIN {
            let mut group = messages().filter(|m| m.number.main == main).peekable();
            let listed = group.peek().is_some();
            let warnings_only = listed && group.all(|m| m.reaction == Reaction::Warning);
            let want = if warnings_only {
                reaction::WARNING
            } else if main == 17 {
                reaction::NONE
            } else if listed {
                reaction::CONTROLLER_ENABLE_OFF.max(minimum(main).unwrap_or(0))
            } else {
                reaction::CONTROLLER_ENABLE_OFF
            };
            assert_eq!(r.get(main), Some(want), "group {main}");
            let mut w = r.clone();
            assert_eq!(
                w.set(main, 0),
                Ok(minimum(main).unwrap()),
                "group {main} clamps to its minimum"
            );
        }
        let mut w = r.clone();
        assert_eq!(w.set(0, 5), Err(ReactionError::Number));
        assert_eq!(w.set(MAX_MAIN + 1, 5), Err(ReactionError::Number));
    }
}
