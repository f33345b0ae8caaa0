// ---- diagnostics
//!
//! # Decisions
//!
//! - **Diagnostics** (§7, App. D): the messages are the table of [`crate::vendors::festo_cmmo_st::diagnostics`]; the
//!   class and reaction of each come from PNU 246 / 242 (subindex = number + 1), whose writes
//!   are checked against PNU 234 / 238 (rw2: output stage off). Errors go to the state
//!   machine (T7, the reaction A…G applied there), warnings to SCON.WARN / PNU 221,
//!   informations to the memory only. PNU 220 shows every fault present, PNU 205 / 230 /
//!   FC 0x07 the active one. A fault that a single event caused (a refused start, a passed
//!   limit) is acknowledgeable at once; an injected one ([`FhppDevice::fault`]) keeps its
//!   App. D acknowledge type and its cause until [`FhppDevice::clear_fault`].
//!   Raised from their simulated causes: 28h, 3Fh, 3Bh (starts), 2Fh, 37h (monitoring),
//!   11h…14h, 29h, 2Ah (software limits), 24h (force or index homing in open loop), 22h,
//!   23h, 2Eh, 3Ah (homing), 40h (teach), 1Bh
//!   ([`FhppDevice::set_load_voltage`]); 47h / 48h come from the Modbus runtime's watchdog.
//! - **Diagnostic memory** ([`crate::vendors::festo_cmmo_st::diagnostic_memory`]): incoming faults (01h), warnings
//!   (05h) and informations (09h) when PNU 246 bit 7 (or App. D "always") says so, the end of
//!   the active fault as 00h, 3Dh at power-on / clear / wrap; time stamps are the device's
//!   cycle clock in ms. Mirrored into PNU 200…204:4 at the end of a cycle that changed it, so
//!   every channel reads it through the dictionary; PNU 204:3 = 1 clears it.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>> FhppDevice<S> {
    /// The class diagnostic `code` has now: App. D through PNU 246 (class) and 242
    /// (reaction), subindex = number + 1 (fhpp §8.4). `None` for an unassigned number.
    pub fn diagnostic_class(&self, code: u8) -> Option<Class> {
        let d = self.diagnostic(code)?;
        Some(self.class_of(d))
    }

    /// App. D's message `code` (the following error without a search).
    pub(super) fn diagnostic(&self, code: u8) -> Option<Diagnostic> {
        match self.following_error_diagnostic {
            Some(d) if d.code == code => Some(d),
            _ => diagnostics::lookup(code.into()),
        }
    }

    pub(super) fn class_of(&self, d: Diagnostic) -> Class {
        let sub = diagnostics::subindex(d.code);
        let (handling, reaction) = match self.following_error_entries {
            (Some(h), Some(r)) if d.code == diag::FOLLOWING_ERROR => {
                let value = |e: &Entry| entry_i64(e, self.od.raw(e)) as u16;
                (value(h), value(r))
            }
            _ => (
                get_i64(&self.od, 246, sub) as u16,
                get_i64(&self.od, 242, sub) as u16,
            ),
        };
        d.class(handling, reaction)
    }

    pub(super) fn handling(&self, code: u8) -> u16 {
        get_i64(&self.od, 246, diagnostics::subindex(code)) as u16
    }

    pub(super) fn fault_for(&self, code: u8) -> Option<Fault> {
        let d = self.diagnostic(code)?;
        match self.class_of(d) {
            Class::Fault(reaction) => Some(Fault {
                code,
                reaction,
                ack: d.ack,
            }),
            _ => None,
        }
    }

    /// Raises diagnostic `code` (fault injection, communication monitoring): an error (per
    /// PNU 246) takes T7 at the next cycle with its PNU 242 reaction, a warning sets
    /// SCON.WARN, an information goes to the diagnostic memory only. The cause counts as
    /// present until [`Self::clear_fault`]. Unassigned numbers are ignored (see
    /// [`Self::inject`]).
    pub fn fault(&mut self, code: u8) {
        let _ = self.inject(code);
    }

    /// [`Self::fault`], telling an unassigned number apart.
    pub fn inject(&mut self, code: u8) -> Result<Class, UnknownDiagnostic> {
        let d = diagnostics::lookup(code.into()).ok_or(UnknownDiagnostic(code))?;
        let class = self.class_of(d);
        let bit = 1u128 << (code & 0x7F);
        match class {
            Class::Fault(reaction) => {
                self.injected |= bit;
                self.fhpp.raise_fault(Fault {
                    code,
                    reaction,
                    ack: d.ack,
                });
            }
            Class::Warning => self.warnings |= bit,
            Class::Information | Class::Event => self.log_event(d, class),
        }
        Ok(class)
    }

    /// Raises App. D message `number` as printed ("2Fh") from outside, as [`Self::inject`];
    /// it stays until [`Self::clear_diagnostic`].
    pub fn raise_diagnostic(
        &mut self,
        number: &str,
    ) -> Result<Class, crate::drive::diagnostics::DiagnosticError> {
        let code = diagnostics::number(number)
            .ok_or(crate::drive::diagnostics::DiagnosticError::Unknown)?;
        self.inject(code)
            .map_err(|_| crate::drive::diagnostics::DiagnosticError::Unknown)
    }

    /// Clears App. D message `number` raised by [`Self::raise_diagnostic`]: its cause is gone
    /// (an error may be acknowledged with CCON.RESET, a warning ends).
    pub fn clear_diagnostic(
        &mut self,
        number: &str,
    ) -> Result<(), crate::drive::diagnostics::DiagnosticError> {
        let code = diagnostics::number(number)
            .filter(|c| diagnostics::lookup((*c).into()).is_some())
            .ok_or(crate::drive::diagnostics::DiagnosticError::Unknown)?;
        self.clear_fault(code);
        Ok(())
    }

    /// Whether message `code` is active: the fault shown (PNU 205), a raised cause or a
    /// present warning.
    pub fn diagnostic_active(&self, code: u8) -> bool {
        let bit = 1u128.checked_shl(u32::from(code)).unwrap_or(0);
        self.fhpp.fault().is_some_and(|f| f.code == code)
            || self.injected & bit != 0
            || self.warnings & bit != 0
    }

    /// The load (intermediate circuit) voltage is switched on or off: SCON.VLOAD, the T2
    /// condition, and App. D 1Bh "intermediate circuit voltage too low" while it is off (an
    /// error with reaction A by default, acknowledgeable once the voltage is back; as a
    /// warning it clears by itself).
    pub fn set_load_voltage(&mut self, present: bool) {
        self.fhpp.set_load_voltage(present);
        if present {
            self.clear_fault(diag::LOAD_VOLTAGE_LOW);
        } else {
            self.fault(diag::LOAD_VOLTAGE_LOW);
        }
    }

    /// The cause of diagnostic `code` has gone: an error may now be acknowledged, a warning
    /// clears.
    pub fn clear_fault(&mut self, code: u8) {
        let bit = 1u128 << (code & 0x7F);
        self.injected &= !bit;
        self.warnings &= !bit;
        self.warnings_logged &= !bit;
        self.fhpp.fault_cause_gone(code);
    }

    /// Raises a diagnostic once (a refused start, a homing error, a passed software limit):
    /// an error is acknowledged at once (the cause was the event), a warning shows until the
    /// next start.
    pub(super) fn raise_once(&mut self, code: u8) {
        let Some(d) = diagnostics::lookup(code.into()) else {
            return;
        };
        let bit = 1u128 << (code & 0x7F);
        match self.class_of(d) {
            Class::Fault(reaction) => self.fhpp.raise_fault(Fault {
                code,
                reaction,
                ack: Ack::Immediately,
            }),
            Class::Warning => {
                self.warnings |= bit;
                self.once_warnings |= bit;
            }
            class => self.log_event(d, class),
        }
    }

    pub(super) fn clear_warning(&mut self, code: u8) {
        let bit = 1u128 << (code & 0x7F);
        self.warnings &= !bit;
        self.warnings_logged &= !bit;
    }

    /// What the 7-segment display shows (§7.1.2 Tab. 7.3): the active error (PNU 205),
    /// else a present warning (PNU 221), as its hexadecimal code.
    pub fn seven_segment(&self) -> SevenSegment {
        SevenSegment::showing(self.fhpp.fault().map(|f| f.code), self.warnings)
    }

    /// The diagnostic memory (PNU 200…204).
    pub fn diagnostic_memory(&self) -> &DiagnosticMemory {
        &self.memory
    }

    /// The device clock of the time stamps: ms since power-on, wrapping at 2³² (PNU 202).
    pub(super) fn now_ms(&self) -> u32 {
        self.cycles as u32
    }

    pub(super) fn log(&mut self, event: EventType, code: u8) {
        let Some(d) = diagnostics::lookup(code.into()) else {
            return;
        };
        if d.logged(self.handling(code)) {
            self.memory.log(event, code.into(), self.now_ms());
            self.memory_dirty = true;
        }
    }

    pub(super) fn log_event(&mut self, d: Diagnostic, class: Class) {
        let event = match class {
            Class::Fault(_) => EventType::Fault,
            Class::Warning => EventType::Warning,
            Class::Information => EventType::Information,
            Class::Event if d.code == diag::START_UP => EventType::SwitchOn,
            Class::Event => EventType::Information,
        };
        self.log(event, d.code);
    }

    /// Faults present now (PNU 220): the active one, injected ones whose cause is present,
    /// and the following error while it is an error.
    pub(super) fn current_faults(&self) -> u128 {
        let mut f = self.injected;
        if let Some(a) = self.fhpp.fault() {
            f |= 1u128 << (a.code & 0x7F);
        }
        if self.following_error && self.fault_for(diag::FOLLOWING_ERROR).is_some() {
            f |= 1u128 << diag::FOLLOWING_ERROR;
        }
        f
    }

    /// End of a cycle: new faults and warnings into the memory (incoming, 01h / 05h), the
    /// end of the active fault (acknowledged) as 00h, and the time-stamp wrap.
    pub(super) fn diagnose(&mut self) {
        self.memory.tick(self.now_ms());
        let faults = self.current_faults();
        let new = faults & !self.faults_present;
        self.faults_present = faults;
        let new_warnings = self.warnings & !self.warnings_logged;
        self.warnings_logged = self.warnings;
        let active = self.fhpp.fault().map(|f| f.code);
        let gone = match (self.last_fault, active) {
            (Some(old), None) => Some(old),
            _ => None,
        };
        self.last_fault = active;
        if let Some(code) = gone {
            // Acknowledged. An "immediately ackable" fault was an event: acknowledging it
            // ends it even if the injected cause was never declared gone.
            if diagnostics::lookup(code.into()).is_some_and(|d| d.ack == Ack::Immediately) {
                self.injected &= !(1u128 << (code & 0x7F));
            }
            self.log(EventType::Gone, code);
        }
        for (mask, event) in [(new, EventType::Fault), (new_warnings, EventType::Warning)] {
            let mut m = mask;
            while m != 0 {
                let code = m.trailing_zeros() as u8;
                m &= m - 1;
                self.log(event, code);
            }
        }
    }

    /// PNU 200…204 from the ring (after a change, once per cycle at most).
    pub(super) fn mirror_memory(&mut self) {
        self.memory_dirty = false;
        let od = &mut self.od;
        for (n, sub) in (0..diagnostic_memory::CAPACITY).zip(1u8..) {
            let e = self.memory.get(n);
            let vals = [
                (200, e.map_or(0, |e| e.event.value().into())),
                (
                    201,
                    e.map_or(diagnostic_memory::INVALID_NUMBER.into(), |e| {
                        e.number.into()
                    }),
                ),
                (202, e.map_or(0, |e| e.time_ms.into())),
                (203, e.map_or(0, |e| e.info.into())),
            ];
            for (pnu, v) in vals {
                let _ = od.set_value(pnu_index(pnu), sub, Value::Unsigned(v));
            }
        }
        let _ = od.set_value(pnu_index(204), 4, Value::Unsigned(self.memory.len() as u64));
    }

    /// PNU 204:3 = 1: clear the memory (a start-up event is written).
    pub(super) fn clear_memory(&mut self) {
        self.memory.clear(self.now_ms());
        self.mirror_memory();
    }

    /// PNU 242 / 246 writes: the value must be one App. D allows for that number (PNU 234 /
    /// 238), or its factory value; rw2: only with the output stage off.
    pub(super) fn check_error_management(
        &self,
        index: u16,
        sub: u8,
        data: &[u8],
        wire: bool,
    ) -> Result<(), AbortCode> {
        let reaction = index == pnu_index(242);
        if !reaction && index != pnu_index(246) {
            return Ok(());
        }
        let &[lo, hi] = data else {
            return Ok(()); // the dictionary answers the length error
        };
        let value = u16::from_le_bytes([lo, hi]);
        let d = diagnostics::code_of_subindex(sub).and_then(|c| diagnostics::lookup(c.into()));
        let factory = d.map_or(0, |d| {
            if reaction {
                d.default_reaction()
            } else {
                d.default_handling()
            }
        });
        let ok = value == factory
            || d.is_some_and(|d| {
                if reaction {
                    d.accepts_reaction(value)
                } else {
                    d.accepts_handling(value)
                }
            });
        if !ok {
            return Err(AbortCode::INVALID_VALUE);
        }
        if wire && self.fhpp.output_stage_on() {
            return Err(AbortCode::DEVICE_STATE);
        }
        Ok(())
    }
}
