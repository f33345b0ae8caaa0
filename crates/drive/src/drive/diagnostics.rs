//! Any message of the device file's diagnostic table (`[[diagnostic]]`) raised and cleared
//! by its number from outside (fault injection through the API, a scenario, the cell file):
//! the drive reacts as if its own supervision had raised it — the personality's error
//! management picks the reaction ([`message_reaction`](Vendor#method.message_reaction)), the
//! EMCY, 1001h and 1003h follow from the [`DriveEvent`](super::DriveEvent)s.
//!
//! A raised message stays a cause (it blocks the fault reset) until it is cleared; the fault
//! reset then acknowledges it (CiA 402 §6.3.1 transition 15: the fault reset leaves FAULT
//! once the cause is removed).
//!
//! Decision: a message the table gives no CiA code ("–") is reported with 1000h, generic
//! error (CiA 301 §7.2.7.1 Tab. 21); the vendor's error management still knows it by its
//! number.

use od::Diagnostic;

use super::Drive;
use crate::personality::Vendor;

/// The EMCY code of a message without a CiA code of its own: 1000h generic error (CiA 301
/// §7.2.7.1 Tab. 21).
pub const GENERIC_ERROR: u16 = 0x1000;

/// Why a message cannot be raised or cleared.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiagnosticError {
    /// The device's table has no message with this number.
    Unknown,
    /// Too many messages raised at once (16).
    Full,
    /// The message was not raised by its number.
    NotRaised,
}

/// The EMCY code a message is reported with.
pub fn emcy_code(row: &Diagnostic) -> u16 {
    row.code.unwrap_or(GENERIC_ERROR)
}

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// The device's diagnostic table (`[[diagnostic]]` of its device file).
    pub fn diagnostic_table(&self) -> &'static [Diagnostic] {
        self.od.description().diagnostics
    }

    /// Raises message `number` ("08-2", "0800h": as the table prints it) as if the drive had
    /// detected it; it stays until [`Drive::clear_diagnostic`].
    pub fn raise_diagnostic(
        &mut self,
        number: &str,
    ) -> Result<&'static Diagnostic, DiagnosticError> {
        let row = self
            .od
            .description()
            .diagnostic(number)
            .ok_or(DiagnosticError::Unknown)?;
        if !self.injected.iter().any(|d| core::ptr::eq(*d, row)) {
            self.injected.push(row).map_err(|_| DiagnosticError::Full)?;
        }
        let code = emcy_code(row);
        let r = V::message_reaction(self, row, true);
        self.report_error(code, row.register, r);
        // Only an error blocks the fault reset; a warning or a log entry does not.
        if (self.faults.contains(&code) || self.notices.contains(&code))
            && !self.causes.contains(&code)
        {
            let _ = self.causes.push(code);
        }
        Ok(row)
    }

    /// Clears message `number` raised by [`Drive::raise_diagnostic`]: its cause is gone (a
    /// warning or an EMCY-only message ends now; an error waits for the fault reset).
    pub fn clear_diagnostic(
        &mut self,
        number: &str,
    ) -> Result<&'static Diagnostic, DiagnosticError> {
        let row = self
            .od
            .description()
            .diagnostic(number)
            .ok_or(DiagnosticError::Unknown)?;
        let at = self
            .injected
            .iter()
            .position(|d| core::ptr::eq(*d, row))
            .ok_or(DiagnosticError::NotRaised)?;
        self.injected.remove(at);
        let code = emcy_code(row);
        V::message_cleared(self, row);
        // Another raised message with the same code keeps the cause.
        if !self.injected.iter().any(|d| emcy_code(d) == code) {
            self.clear_fault(code);
        }
        Ok(row)
    }

    /// Whether a message raised by its number is reported with `code` (its cause stays when
    /// the simulation's own supervision finds none).
    pub(crate) fn injected_code(&self, code: u16) -> bool {
        self.injected.iter().any(|d| emcy_code(d) == code)
    }

    /// The messages raised by their number and not yet cleared, in the order raised.
    pub fn raised_diagnostics(&self) -> impl Iterator<Item = &'static Diagnostic> + '_ {
        self.injected.iter().copied()
    }

    /// Whether message `row` is active: raised by its number, or its code an error not yet
    /// acknowledged, an EMCY-only message or the vendor's active warning
    /// ([`active_warning`](Vendor#method.active_warning)).
    pub fn diagnostic_active(&self, row: &'static Diagnostic) -> bool {
        if self.injected.iter().any(|d| core::ptr::eq(*d, row)) {
            return true;
        }
        let code = emcy_code(row);
        let by_code = |c: &u16| {
            *c == code
                && self
                    .od
                    .description()
                    .diagnostics
                    .iter()
                    .find(|d| emcy_code(d) == code)
                    .is_some_and(|d| core::ptr::eq(d, row))
        };
        if self.faults.iter().any(by_code) || self.notices.iter().any(by_code) {
            return true;
        }
        V::active_warning(self).is_some_and(|w| w.number == row.number)
    }
}
