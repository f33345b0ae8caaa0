//! The CMMP-AS's error management (§5.18, App. B): every diagnostic message has a number
//! "main-sub" ([`messages`]); 2100h sets a reaction per main number (none, a diagnostic-memory
//! entry, a warning, controller enable off, braking at the current limit, output stage off),
//! never below the manufacturer's minimum; a warning shows in 200Fh last_warning_code,
//! statusword bit 7 and the display; the diagnostic memory keeps the messages with their
//! additional information. 6510h:22 sets the reaction of 17 following error (the manual's
//! extract, part 2 §5.7).

use heapless::Deque;
use od::{AbortCode, ObjectAccess};

use super::messages::{self, reaction, Message, Number, Reactions};
use super::CmmpAs;
use crate::axis::Demand;
use crate::drive::Drive;
use crate::personality::{ErrorReaction, Fault};

/// One entry of the diagnostic memory (App. B: "No." and "additional information", read in
/// FCT or through FHPP PNU 203/213).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemoryEntry {
    pub number: Number,
    pub code: u16,
    /// The message's additional information (e.g. 02-0: state number and DC-link voltage).
    pub info: u32,
}

/// What the error management keeps beside the engine's faults.
#[derive(Debug, Clone, Default)]
pub struct ErrorManagement {
    /// 2100h: the reaction per main error number.
    reactions: Reactions,
    /// The last warning and whether it is still active (200Fh).
    warning: Option<(Message, bool)>,
    /// The diagnostic memory: messages with their additional information, oldest first.
    memory: Deque<MemoryEntry, 16>,
}

impl ErrorManagement {
    /// The active warning's message.
    pub(crate) fn active_warning(&self) -> Option<Message> {
        self.warning.filter(|(_, active)| *active).map(|(m, _)| m)
    }

    /// Whether the last warning is `number` and `active`.
    fn warning_is(&self, number: Number, active: bool) -> bool {
        self.warning
            .is_some_and(|(m, a)| m.number == number && a == active)
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, CmmpAs> {
    /// A diagnostic message with the reaction 2100h sets for its main number (§5.18): none /
    /// buffer entry change nothing, a warning shows in 200Fh, the display and statusword bit
    /// 7, a stopping reaction reports the error (EMCY) and stops. A code missing from App. B
    /// stops; `critical` ones switch the output stage off at once. `fault` is the condition
    /// the engine detected: 02-0 keeps the DC-link voltage as its additional information.
    pub(crate) fn cmmp_error_reaction(
        &mut self,
        code: u16,
        critical: bool,
        fault: Option<Fault>,
    ) -> ErrorReaction {
        let info = match fault {
            Some(Fault::DcLinkUndervoltage) => messages::undervoltage_info(
                self.dc.state() as u16,
                self.dc_link_mv.unwrap_or_default(),
            ),
            _ => 0,
        };
        let message = self.message_of(code);
        self.numbered_message_reaction(code, message, critical, info)
    }

    /// The reaction of a message known by its number (two messages may share a code) with
    /// the table of reactions per main number ([`Reactions`]): none / buffer entry change
    /// nothing, a warning shows in 200Fh and statusword bit 7, a stopping reaction reports the
    /// error and stops. Without a message the error stops; `critical` ones switch the output
    /// stage off at once.
    pub(crate) fn numbered_message_reaction(
        &mut self,
        code: u16,
        message: Option<Message>,
        critical: bool,
        info: u32,
    ) -> ErrorReaction {
        let errors = &self.vendor.errors;
        if let Some(m) = message {
            // Every reaction but "no action" makes an entry, once per occurrence: an error
            // until it is acknowledged, a warning while active, a plain entry while it is
            // the newest one.
            let fixed = match m.reaction {
                od::Reaction::Ignore => Some(reaction::BUFFER_ENTRY),
                od::Reaction::Warning => Some(reaction::WARNING),
                _ => None,
            };
            let logged = match fixed.or(errors.reactions.get(m.number.main)).unwrap_or(0) {
                reaction::NONE => true,
                reaction::BUFFER_ENTRY => errors
                    .memory
                    .back()
                    .is_some_and(|e| e.code == code && e.number == m.number),
                reaction::WARNING => errors.warning_is(m.number, true),
                _ => self.faults.contains(&code),
            };
            if !logged {
                let memory = &mut self.vendor.errors.memory;
                if memory.is_full() {
                    memory.pop_front();
                }
                let _ = memory.push_back(MemoryEntry {
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
                .and_then(|m| self.vendor.errors.reactions.get(m.number.main))
                .unwrap_or(if critical {
                    reaction::OUTPUT_STAGE_OFF
                } else {
                    reaction::CONTROLLER_ENABLE_OFF
                }),
        };
        match (r, message) {
            (reaction::NONE | reaction::BUFFER_ENTRY, _) => ErrorReaction::Ignore,
            (reaction::WARNING, Some(m)) => {
                self.set_warning(m, true);
                ErrorReaction::Ignore
            }
            (reaction::OUTPUT_STAGE_OFF, _) => ErrorReaction::OutputStageOff,
            (reaction::BRAKE_MAX_CURRENT, _) => ErrorReaction::BrakeMaxCurrent,
            _ => ErrorReaction::QuickStop,
        }
    }

    /// The message behind error `code`: one raised by its number, else the first with
    /// the code.
    pub(crate) fn message_of(&self, code: u16) -> Option<Message> {
        messages::of_code(&self.injected, code)
    }

    /// 200Fh last_warning_code and statusword bit 7.
    pub(crate) fn set_warning(&mut self, message: Message, active: bool) {
        if self.vendor.errors.warning_is(message.number, active) {
            return;
        }
        self.vendor.errors.warning = Some((message, active));
        let code = messages::warning_code(message.number, active);
        let _ = self.od.write_internal(0x200F, 0, &code.to_le_bytes());
    }

    /// Ends the warning `number` if it is the active one (its cause is gone; the drive
    /// resets warnings itself).
    pub(crate) fn end_warning(&mut self, number: Number) {
        if let Some((m, true)) = self.vendor.errors.warning {
            if m.number == number {
                self.set_warning(m, false);
            }
        }
    }

    /// The diagnostic memory, oldest entry first.
    pub fn diagnostic_memory(&self) -> impl Iterator<Item = &MemoryEntry> {
        self.vendor.errors.memory.iter()
    }

    /// At power-on and after a reload: the reaction table is not part of the stored set, it
    /// starts from its defaults; then 6510h:22 sets the reaction of 17.
    pub(crate) fn reset_reactions(&mut self) {
        self.vendor.errors.reactions.reset();
        self.following_error_reaction();
    }

    /// 6510h:22 > 0 sets the reaction of error 17 to output stage off, 0 to no action (the
    /// manual's extract, part 2 §5.7); 2100h can change it afterwards.
    pub(crate) fn following_error_reaction(&mut self) {
        let r = if self.value(0x6510, 0x22) > 0 {
            reaction::OUTPUT_STAGE_OFF
        } else {
            reaction::NONE
        };
        let _ = self.vendor.errors.reactions.set(17, r);
        self.show_reaction();
    }

    /// 6510h:22 following_error hard limit: beyond it with the output stage on, error 17-0
    /// (§5.7: "the output stage switches off at once, the motor coasts", the reaction
    /// 6510h:22 sets; 2100h may make it a warning); within it the warning 17-0 ends.
    pub(crate) fn supervise_following_error_limit(&mut self, fe: i64) {
        let power = !matches!(self.demand, Demand::Off);
        let hard = self.cycle_value(0x6510, 0x22);
        if power
            && hard > 0
            && fe.abs()
                > self
                    .fg
                    .position_magnitude_to_internal(hard.clamp(0, u32::MAX as i64) as u32)
        {
            self.raise_fault(Fault::FollowingError);
        } else {
            self.end_warning(Number { main: 17, sub: 0 });
        }
    }

    /// 2100h:02 shows the reaction of the main number selected in 2100h:01.
    fn show_reaction(&mut self) {
        let main = self.od.get_unsigned(0x2100, 1).unwrap_or(1) as u8;
        if let Some(r) = self.vendor.errors.reactions.get(main) {
            let _ = self.od.write_internal(0x2100, 2, &[r]);
        }
    }

    /// 2100h:01h: the error group whose reaction 2100h:02h shows.
    pub(crate) fn write_reaction_group(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        self.show_reaction();
        Ok(())
    }

    /// 2100h:02h: the reaction of the selected error group.
    pub(crate) fn write_reaction(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        // §5.18: a reaction below the manufacturer's minimum is clamped to it.
        self.od.entry(index, sub)?;
        let code = match data {
            [b] => *b,
            _ => return self.od.write(index, sub, data),
        };
        let main = self.od.get_unsigned(0x2100, 1).unwrap_or(1) as u8;
        self.vendor
            .errors
            .reactions
            .set(main, code)
            .map_err(|_| AbortCode::INVALID_VALUE)?;
        self.show_reaction();
        Ok(())
    }

    /// 6510h:22h: the following-error reaction.
    pub(crate) fn write_following_error_reaction(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        self.following_error_reaction();
        self.params_dirty = true;
        Ok(())
    }
}
