//! Error management by message numbers (a vendor's diagnostic messages "main-sub" with a
//! reaction per main number, [`crate::messages`]): the reaction of a message, the diagnostic
//! memory and the warning it may show (statusword bit 7 and the last-warning object 200Fh).

use super::*;
use crate::messages::reaction;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// The reaction of a message known by its number (two messages may share a code) with
    /// the table of reactions per main number ([`Reactions`]): none / buffer entry change
    /// nothing, a warning shows in 200Fh and statusword bit 7, a stopping reaction reports the
    /// error and stops. Without a message the error stops; `critical` ones switch the output
    /// stage off at once.
    pub(crate) fn numbered_message_reaction(
        &mut self,
        code: u16,
        message: Option<messages::Message>,
        critical: bool,
        info: u32,
    ) -> ErrorReaction {
        if let Some(m) = message {
            // Every reaction but "no action" makes an entry, once per occurrence: an error
            // until it is acknowledged, a warning while active, a plain entry while it is
            // the newest one.
            let fixed = match m.reaction {
                od::Reaction::Ignore => Some(reaction::BUFFER_ENTRY),
                od::Reaction::Warning => Some(reaction::WARNING),
                _ => None,
            };
            let logged = match fixed.or(self.reactions.get(m.number.main)).unwrap_or(0) {
                reaction::NONE => true,
                reaction::BUFFER_ENTRY => self
                    .memory
                    .back()
                    .is_some_and(|e| e.code == code && e.number == m.number),
                reaction::WARNING => self.warning == Some((m.number, true)),
                _ => self.faults.contains(&code),
            };
            if !logged {
                if self.memory.is_full() {
                    self.memory.pop_front();
                }
                let _ = self.memory.push_back(MemoryEntry {
                    number: m.number,
                    code,
                    info,
                });
            }
        }
        // A message whose table reaction is "Ignore" (a memory entry only) or "Warn" is not
        // configurable; the others follow the reaction table.
        let r = match message.map(|m| m.reaction) {
            Some(od::Reaction::Ignore) => reaction::BUFFER_ENTRY,
            Some(od::Reaction::Warning) => reaction::WARNING,
            _ => message
                .and_then(|m| self.reactions.get(m.number.main))
                .unwrap_or(if critical {
                    reaction::OUTPUT_STAGE_OFF
                } else {
                    reaction::CONTROLLER_ENABLE_OFF
                }),
        };
        match (r, message) {
            (reaction::NONE | reaction::BUFFER_ENTRY, _) => ErrorReaction::Ignore,
            (reaction::WARNING, Some(m)) => {
                self.set_warning(m.number, true);
                ErrorReaction::Ignore
            }
            (reaction::OUTPUT_STAGE_OFF, _) => ErrorReaction::OutputStageOff,
            (reaction::BRAKE_MAX_CURRENT, _) => ErrorReaction::BrakeMaxCurrent,
            _ => ErrorReaction::QuickStop,
        }
    }

    /// The message behind error `code`: one raised by its number, else the first with
    /// the code.
    pub(crate) fn message_of(&self, code: u16) -> Option<messages::Message> {
        self.injected
            .iter()
            .filter_map(|d| messages::message(d))
            .find(|m| m.code == code)
            .or_else(|| messages::by_code(code))
    }

    /// 200Fh last_warning_code and statusword bit 7.
    pub(crate) fn set_warning(&mut self, number: Number, active: bool) {
        if self.warning == Some((number, active)) {
            return;
        }
        self.warning = Some((number, active));
        let code = messages::warning_code(number, active);
        if V::MANUFACTURER_OBJECTS {
            let _ = self.od.write_internal(0x200F, 0, &code.to_le_bytes());
        }
    }

    /// Ends the warning `number` if it is the active one (its cause is gone; the drive
    /// resets warnings itself).
    pub(crate) fn end_warning(&mut self, number: Number) {
        if self.warning == Some((number, true)) {
            self.set_warning(number, false);
        }
    }
}
