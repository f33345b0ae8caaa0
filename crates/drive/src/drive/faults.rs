//! The drive's faults: errors injected, raised and reported (the [`DriveEvent`]s behind the
//! EMCY, 1001h error register and 1003h predefined error field of CiA 301 §7.2.7.1 and
//! 603Fh error code of CiA 402 §6.3.1), their causes kept while present, cleared and
//! acknowledged.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// Raises a fault from outside (fault injection, a test): EMCY, fault reaction (quick-stop
    /// ramp), FAULT.
    /// The cause stays until [`Drive::clear_fault`].
    pub fn inject_fault(&mut self, code: u16, register: u8) {
        if !self.causes.contains(&code) {
            let _ = self.causes.push(code);
        }
        self.raise(code, register, false);
    }

    /// Removes an injected fault's cause; a fault reset then acknowledges the error.
    pub fn clear_fault(&mut self, code: u16) {
        if let Some(i) = self.causes.iter().position(|c| *c == code) {
            self.causes.remove(i);
        }
        V::error_cleared(self, code);
        self.clear_notice(code);
    }

    /// Reports the error `code` with the reaction the personality's error management gives
    /// it ([`error_reaction`](Vendor#method.error_reaction)); `critical` errors without a
    /// reaction of their own switch the output stage off at once (CiA 402 §6.3.1).
    pub(crate) fn raise(&mut self, code: u16, register: u8, critical: bool) {
        self.raise_detected(code, register, critical, None);
    }

    /// [`Drive::raise`] for a condition the engine detected (`fault`), so that the vendor's
    /// error management can add what it records of it.
    pub(crate) fn raise_detected(
        &mut self,
        code: u16,
        register: u8,
        critical: bool,
        fault: Option<Fault>,
    ) {
        let reaction = V::error_reaction(self, code, critical, fault);
        self.report_error(code, register, reaction);
    }

    /// Raises the personality's error for `fault`; `false` where the drive has none.
    pub(crate) fn raise_fault(&mut self, fault: Fault) -> bool {
        match self.personality.error(fault) {
            Some(e) => {
                self.raise_detected(e.code, e.register, e.critical, Some(fault));
                true
            }
            None => false,
        }
    }

    /// The error's EMCY and the device control's fault reaction.
    pub(crate) fn report_error(&mut self, code: u16, register: u8, reaction: ErrorReaction) {
        match reaction {
            ErrorReaction::Ignore => return,
            ErrorReaction::MessageOnly | ErrorReaction::QuickStopNoFault => {
                if !self.notices.contains(&code) && self.notices.push(code).is_ok() {
                    self.push_event(DriveEvent::Error { code, register });
                }
                if reaction == ErrorReaction::QuickStopNoFault {
                    let r = self.dc.quick_stop();
                    self.react(r);
                }
                return;
            }
            _ => {}
        }
        if !self.faults.contains(&code) {
            let _ = self.faults.push(code);
            self.push_event(DriveEvent::Error { code, register });
        }
        let r = match reaction {
            ErrorReaction::OutputStageOff => self.dc.fault_immediate(),
            ErrorReaction::BrakeMaxCurrent => {
                // Brakes with the vendor's emergency ramp, which the current limit caps.
                self.limit_stop = true;
                self.dc.fault()
            }
            _ => self.dc.fault(),
        };
        self.react(r);
    }

    /// A message-only error (EMCY without a fault) is over: the EMCY "error reset".
    pub(crate) fn clear_notice(&mut self, code: u16) {
        if let Some(i) = self.notices.iter().position(|c| *c == code) {
            self.notices.remove(i);
            self.push_event(DriveEvent::Cleared { code });
        }
    }

    /// Keeps `code` as a cause while `present` and raises it (with `register`); a cause that
    /// went lets the fault reset acknowledge the error.
    pub(crate) fn cause(&mut self, code: u16, present: bool, register: u8) {
        let at = self.causes.iter().position(|c| *c == code);
        match (present, at) {
            (true, None) => {
                let _ = self.causes.push(code);
                self.raise(code, register, false);
            }
            (true, Some(_)) => self.raise(code, register, false),
            // A message raised by its number stays until it is cleared.
            (false, Some(_)) if self.injected_code(code) => {}
            (false, Some(i)) => {
                self.causes.remove(i);
            }
            (false, None) => {}
        }
    }
}
