//! The diagnostic messages of the CMMO-ST (manual App. D, §7.2.2 Tab. 7.9) as data (the
//! `[[diagnostic]]` rows of `devices/cmmo-st.toml`), and the error-management coding of PNU 234 / 238 / 242 / 246 (§B.4.5, fhpp §3.2.1).
//!
//! Every message has a number, a name, the classes it may be given (F error / W warning /
//! I information), whether it is always logged or logging is configurable, its acknowledge
//! type and the reactions A…G that PNU 242 may select. The factory class and reaction were
//! printed in bold, and the bold is lost in the Chinese text (fhpp §9.9): the defaults are
//! derived from the permitted sets by one rule ([`Diagnostic::default_reaction`],
//! [`Diagnostic::default_handling`]), the rule `devices/cmmo-st.toml` decision D8 uses for
//! the dictionary defaults (a test checks that both agree for all 255 subindices).
//!
//! The manual lists 57 numbers (the extract's "56" misses 24h, which the manual prints in
//! another table layout); "value is out of range" is printed as a second "40h" and sits at
//! 4Ch here (decision D6 of the device file).

use super::fhpp::state_machine::{Ack, Reaction};

/// The class a diagnostic has at run time (PNU 246 bits 5, 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Class {
    /// F: the drive enters the fault state with this reaction (SCON.FAULT, PNU 220).
    Fault(Reaction),
    /// W: SCON.WARN and PNU 221, cleared when the cause has gone.
    Warning,
    /// I: no effect on the drive; only the diagnostic memory sees it.
    Information,
    /// "-/-/-" (3Dh start-up event, 4Fh system information): a memory entry only.
    Event,
}

/// Whether a message is always logged or logging is configurable (App. D "Diag. memory").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Logging {
    Always,
    Optional,
}

/// The classes a message may be given, "F/W/I" with "-" for an impossible one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Classes(u8);

impl Classes {
    pub const F: Classes = Classes(1);
    pub const W: Classes = Classes(2);
    pub const I: Classes = Classes(4);
    const NONE: Classes = Classes(0);

    pub const fn contains(self, other: Classes) -> bool {
        self.0 & other.0 == other.0 && other.0 != 0
    }
}

/// PNU 246 bit 5: 1 = error (F), 0 = warning (W).
pub const HANDLING_FAULT: u16 = 0x20;
/// PNU 246 bit 6: 1 = information (I).
pub const HANDLING_INFORMATION: u16 = 0x40;
/// PNU 246 bit 7: 1 = logged in the diagnostic memory.
pub const HANDLING_LOG: u16 = 0x80;
/// PNU 246 bits 0…4 and 8…15 are reserved.
const HANDLING_DEFINED: u16 = HANDLING_FAULT | HANDLING_INFORMATION | HANDLING_LOG;
/// PNU 234 / 238 for a number that is not assigned (Tab. B.31, B.32).
pub const UNASSIGNED: u16 = 0xFFFF;

/// One message of App. D.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Diagnostic {
    pub code: u8,
    /// The English name the manual prints next to the Chinese one.
    pub name: &'static str,
    pub classes: Classes,
    pub logging: Logging,
    /// App. D "Ack". Messages that cannot be an error ("–") carry `Immediately`.
    pub ack: Ack,
    /// Reactions PNU 242 may select, in the PNU 234 bit coding (0 = none).
    pub reactions: u16,
}

const B: u16 = 0x02;
const E: u16 = 0x10;
const F: u16 = 0x20;
const G: u16 = 0x40;

impl Diagnostic {
    /// PNU 234: the permitted reactions.
    pub const fn permissible_reactions(&self) -> u16 {
        self.reactions
    }

    /// PNU 238: which PNU 246 bits may be changed: bit 5 when both F and W are possible,
    /// bit 6 when I is, bit 7 when logging is optional.
    pub const fn permissible_handling(&self) -> u16 {
        let mut m = 0;
        if self.classes.contains(Classes::F) && self.classes.contains(Classes::W) {
            m |= HANDLING_FAULT;
        }
        if self.classes.contains(Classes::I) {
            m |= HANDLING_INFORMATION;
        }
        if matches!(self.logging, Logging::Optional) {
            m |= HANDLING_LOG;
        }
        m
    }

    /// PNU 242 factory value. Rule (D8, the bold letter being lost): the only permitted letter
    /// if there is one; else E, F, G (output stage stays on) in that order; else B.
    pub const fn default_reaction(&self) -> u16 {
        let r = self.reactions;
        if r.count_ones() == 1 {
            r
        } else if r & E != 0 {
            E
        } else if r & F != 0 {
            F
        } else if r & G != 0 {
            G
        } else if r & B != 0 {
            B
        } else {
            0
        }
    }

    /// PNU 246 factory value: F where F is possible (App. D lists F first), else W; logged.
    pub const fn default_handling(&self) -> u16 {
        if self.classes.contains(Classes::F) {
            HANDLING_FAULT | HANDLING_LOG
        } else {
            HANDLING_LOG
        }
    }

    /// Whether `value` may be written to PNU 242 for this message: one permitted bit (or
    /// the value it already has for messages without a choice).
    pub const fn accepts_reaction(&self, value: u16) -> bool {
        value.count_ones() == 1 && self.reactions & value == value
    }

    /// Whether `value` may be written to PNU 246: reserved bits 0, only the bits of PNU 238
    /// differ from the factory value, and the class it names is one the message can have.
    pub const fn accepts_handling(&self, value: u16) -> bool {
        if value & !HANDLING_DEFINED != 0 {
            return false;
        }
        let changed = value ^ self.default_handling();
        if changed & !self.permissible_handling() != 0 {
            return false;
        }
        // Bit 6 overrides bit 5; with bit 6 clear the class is bit 5's.
        value & HANDLING_INFORMATION != 0
            || self.classes.0 == 0
            || (value & HANDLING_FAULT != 0 && self.classes.contains(Classes::F))
            || (value & HANDLING_FAULT == 0 && self.classes.contains(Classes::W))
    }

    /// The class PNU 246 `handling` and PNU 242 `reaction` give this message at run time.
    /// A fault whose PNU 242 holds no single permitted reaction (34h STO prints "0") switches
    /// the output stage off without a ramp (A): decision, STO takes the torque away.
    pub fn class(&self, handling: u16, reaction: u16) -> Class {
        if self.classes.0 == 0 {
            return Class::Event;
        }
        if handling & HANDLING_INFORMATION != 0 && self.classes.contains(Classes::I) {
            return Class::Information;
        }
        let fault = if self.classes.contains(Classes::F) && self.classes.contains(Classes::W) {
            handling & HANDLING_FAULT != 0
        } else {
            self.classes.contains(Classes::F)
        };
        if !fault {
            return if self.classes.contains(Classes::W) {
                Class::Warning
            } else {
                Class::Information
            };
        }
        let r = if self.accepts_reaction(reaction) {
            reaction
        } else {
            self.default_reaction()
        };
        Class::Fault(Reaction::from_bit(r).unwrap_or(Reaction::A))
    }

    /// Whether an occurrence goes to the diagnostic memory (PNU 246 bit 7, "always" messages
    /// always).
    pub const fn logged(&self, handling: u16) -> bool {
        matches!(self.logging, Logging::Always) || handling & HANDLING_LOG != 0
    }
}

impl Diagnostic {
    /// The message a `[[diagnostic]]` row of `devices/cmmo-st.toml` gives ("2Fh", classes
    /// "F/W/-", reactions "BC", memory, ack); `None` for a row that is not one.
    pub fn of(row: &'static od::Diagnostic) -> Option<Diagnostic> {
        let code = number(row.number)?;
        let mut classes = Classes::NONE;
        for (i, c) in row.classes.split('/').enumerate() {
            match (i, c) {
                (0, "F") => classes.0 |= Classes::F.0,
                (1, "W") => classes.0 |= Classes::W.0,
                (2, "I") => classes.0 |= Classes::I.0,
                (_, "-") => {}
                _ => return None,
            }
        }
        let reactions = row
            .reactions
            .bytes()
            .filter(|b| (b'A'..=b'G').contains(b))
            .fold(0u16, |r, b| r | 1 << (b - b'A'));
        Some(Diagnostic {
            code,
            name: row.text,
            classes,
            logging: match row.memory {
                "optional" => Logging::Optional,
                _ => Logging::Always,
            },
            ack: match row.ack {
                "after_cause" => Ack::AfterCause,
                "reset" => Ack::NotAckable,
                _ => Ack::Immediately,
            },
            reactions,
        })
    }
}

/// A diagnostic number as App. D prints it ("2Fh"; "2F" and "0x2F" too).
pub fn number(text: &str) -> Option<u8> {
    // As App. D prints it ("2Fh"), without the general parse.
    if let &[hi, lo, b'h'] = text.as_bytes() {
        let digit = |b: u8| char::from(b).to_digit(16);
        if let (Some(hi), Some(lo)) = (digit(hi), digit(lo)) {
            return u8::try_from(hi << 4 | lo).ok();
        }
    }
    let t = text.trim();
    let t = t.strip_prefix("0x").unwrap_or(t);
    let t = t
        .strip_suffix('h')
        .or_else(|| t.strip_suffix('H'))
        .unwrap_or(t);
    u8::from_str_radix(t, 16).ok()
}

/// App. D as the device file gives it (`[[diagnostic]]` of `devices/cmmo-st.toml`).
pub fn table() -> &'static [od::Diagnostic] {
    devices::CMMO_ST.diagnostics
}

/// Every message of App. D, sorted by number.
pub fn all() -> impl Iterator<Item = Diagnostic> {
    table().iter().filter_map(Diagnostic::of)
}

/// The message with number `code`, `None` for an unassigned number.
pub fn lookup(code: u16) -> Option<Diagnostic> {
    let c = u8::try_from(code).ok()?;
    // App. D is sorted by number (`table_is_sorted_and_unique`): a binary search parses a
    // few numbers and one row, not every row before it (the device asks every cycle while
    // a following error lasts).
    let t = table();
    let i = t
        .binary_search_by_key(&Some(c), |r| number(r.number))
        .ok()?;
    t.get(i).and_then(Diagnostic::of)
}

/// The error-management subindex of diagnostic `code` (fhpp §8.4: number + 1).
pub const fn subindex(code: u8) -> u8 {
    code.saturating_add(1)
}

/// The diagnostic of error-management subindex `sub` (1…255 → 0…254).
pub const fn code_of_subindex(sub: u8) -> Option<u8> {
    sub.checked_sub(1)
}

/// Names for the numbers the twin raises itself (the table above is the full list).
pub mod code {
    /// 11h software limit positive (the set-point reached the upper limit).
    pub const SOFTWARE_LIMIT_POSITIVE: u8 = 0x11;
    /// 12h software limit negative.
    pub const SOFTWARE_LIMIT_NEGATIVE: u8 = 0x12;
    /// 13h positive direction locked (a start towards the limit passed).
    pub const POSITIVE_DIRECTION_LOCKED: u8 = 0x13;
    /// 14h negative direction locked.
    pub const NEGATIVE_DIRECTION_LOCKED: u8 = 0x14;
    /// 1Ah intermediate circuit (load) voltage exceeded.
    pub const LOAD_VOLTAGE_HIGH: u8 = 0x1A;
    /// 1Bh intermediate circuit (load) voltage too low.
    pub const LOAD_VOLTAGE_LOW: u8 = 0x1B;
    /// 24h drive function not supported in open-loop operation.
    pub const NOT_IN_OPEN_LOOP: u8 = 0x24;
    /// 28h homing required.
    pub const HOMING_REQUIRED: u8 = 0x28;
    /// 29h target position behind the negative software limit.
    pub const TARGET_BEHIND_NEGATIVE_LIMIT: u8 = 0x29;
    /// 2Ah target position behind the positive software limit.
    pub const TARGET_BEHIND_POSITIVE_LIMIT: u8 = 0x2A;
    /// 2Fh following error.
    pub const FOLLOWING_ERROR: u8 = 0x2F;
    /// 34h safe torque off.
    pub const STO: u8 = 0x34;
    /// 37h standstill monitoring.
    pub const STANDSTILL: u8 = 0x37;
    /// 3Bh homing method invalid.
    pub const HOMING_METHOD_INVALID: u8 = 0x3B;
    /// 3Dh start-up event (diagnostic memory).
    pub const START_UP: u8 = 0x3D;
    /// 3Fh record invalid.
    pub const RECORD_INVALID: u8 = 0x3F;
    /// 40h last teaching not successful.
    pub const TEACH_FAILED: u8 = 0x40;
    /// 47h Modbus connection with master control.
    pub const MODBUS_WITH_CONTROL: u8 = 0x47;
    /// 48h Modbus connection without master control.
    pub const MODBUS_WITHOUT_CONTROL: u8 = 0x48;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_is_sorted_and_unique() {
        let all: heapless::Vec<u8, 64> = all().map(|d| d.code).collect();
        assert!(all.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(all.len(), table().len(), "every row is an App. D message");
        assert_eq!(lookup(0x2F).map(|d| d.name), Some("Following error"));
        assert!(lookup(0x03).is_none());
        assert!(lookup(0x12F).is_none());
    }

    #[test]
    fn software_limit_reactions_are_the_manuals_0x0037() {
        // fhpp §8.1 example 2: 0x0037 = reactions A, B, C, E, F (11h…14h).
        for c in 0x11..=0x14 {
            assert_eq!(lookup(c).map(|d| d.permissible_reactions()), Some(0x0037));
        }
    }

    #[test]
    fn class_follows_pnu_246() {
        let fe = lookup(0x2F).unwrap();
        assert_eq!(fe.class(0xA0, 0x10), Class::Fault(Reaction::E));
        assert_eq!(fe.class(0x80, 0x10), Class::Warning);
        assert_eq!(fe.class(0xC0, 0x10), Class::Information);
        // A reaction outside PNU 234 falls back to the factory one.
        assert_eq!(fe.class(0xA0, 0x01), Class::Fault(Reaction::E));
        assert!(fe.accepts_handling(0x80) && fe.accepts_handling(0x20));
        assert!(!fe.accepts_handling(0xA1), "reserved bit");
        assert!(fe.accepts_reaction(0x20) && !fe.accepts_reaction(0x01));
        assert!(!fe.accepts_reaction(0x30), "one reaction only");
        let sw = lookup(0x01).unwrap();
        assert!(!sw.accepts_handling(0x80), "01h is F only, always logged");
        assert!(sw.accepts_handling(0xA0));
    }
}
