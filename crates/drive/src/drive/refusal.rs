//! Why the drive does not take a command: an input owns the object, the hardware enables are
//! missing, the mode is not the device's or its state forbids it, a fault's cause is still
//! there. A master that writes over the bus learns only an SDO abort code or a state that does
//! not move; a console asks [`Drive::refusal`] and shows the reason with the manual's rule.
//!
//! The engine's rules are CiA 402's; a personality adds its manual's rules (cited in their
//! text, [`refusal`](Vendor#method.refusal)); the engine asks them in the order the drive
//! checks them.

use core::fmt;

use super::*;
use crate::personality::HardwareEnable;

/// What was asked of the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// To OPERATION ENABLED (the controlword steps of CiA 402 Fig. 5, a fault reset first).
    Enable,
    /// Modes of operation 6060h := the mode.
    Mode(i8),
    /// A write of one object.
    Write { index: u16, sub: u8 },
}

/// Why the drive does not take a [`Request`] now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// A digital input function owns the object: a bus write cannot change it.
    InputOwns {
        /// 1 for DIN1.
        input: u8,
        /// The function's name as its manual prints it.
        function: &'static str,
        /// The object that gives the input its function (DINx_Function).
        function_object: (u16, u8),
        /// The object it owns.
        index: u16,
        sub: u8,
        rule: &'static str,
    },
    /// An input function the command needs is configured and inactive.
    InputInactive {
        input: u8,
        function: &'static str,
        rule: &'static str,
    },
    /// The hardware enables (or what stands for them on the device) are missing.
    HardwareEnable(&'static HardwareEnable),
    /// 6060h: a mode the device does not have (6502h supported_drive_modes).
    ModeUnsupported { mode: i8 },
    /// A rule of the device's state forbids it now.
    State {
        reason: &'static str,
        rule: &'static str,
    },
    /// A fault whose cause is still present: the fault reset does not acknowledge it.
    CausePresent { code: u16 },
}

impl Refusal {
    /// A name for programs (`input_owns_object`, …).
    pub fn kind(&self) -> &'static str {
        match self {
            Refusal::InputOwns { .. } => "input_owns_object",
            Refusal::InputInactive { .. } => "input_inactive",
            Refusal::HardwareEnable(_) => "hardware_enable_missing",
            Refusal::ModeUnsupported { .. } => "mode_not_supported",
            Refusal::State { .. } => "device_state",
            Refusal::CausePresent { .. } => "fault_cause_present",
        }
    }

    /// The manual's rule behind the refusal, with where it is written.
    pub fn rule(&self) -> &'static str {
        match self {
            Refusal::InputOwns { rule, .. }
            | Refusal::InputInactive { rule, .. }
            | Refusal::State { rule, .. } => rule,
            Refusal::HardwareEnable(h) => h.rule,
            Refusal::ModeUnsupported { .. } => MODE_RULE,
            Refusal::CausePresent { .. } => CAUSE_RULE,
        }
    }
}

/// CiA 402 §6.4.4: only the modes of 6502h.
const MODE_RULE: &str = "CiA 402 §6.4.4: modes of operation 6060h takes only the modes \
    supported_drive_modes 6502h lists; another value is refused (SDO abort 0609 0030h)";

/// CiA 402 §6.3.1 transition 15: the fault reset leaves FAULT once no fault is present.
const CAUSE_RULE: &str = "CiA 402 §6.3.1 transition 15: a fault reset leaves FAULT only when \
    the cause of the error has been removed";

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refusal::InputOwns {
                input,
                function,
                function_object: (fi, fs),
                index,
                sub,
                ..
            } => write!(
                f,
                "DIN{input} has the function {function} ({fi:04X}h:{fs:02X}): the input owns \
                 {index:04X}h:{sub:02X} and a write to it is refused; set {fi:04X}h:{fs:02X} \
                 to 0 to give it to the bus"
            ),
            Refusal::InputInactive {
                input, function, ..
            } => write!(
                f,
                "DIN{input} has the function {function} and is inactive: the drive cannot \
                 be enabled"
            ),
            Refusal::HardwareEnable(h) => write!(f, "{} missing: {}", h.what, h.effect),
            Refusal::ModeUnsupported { mode } => {
                write!(f, "mode {mode} is not a mode of this drive")
            }
            Refusal::State { reason, .. } => f.write_str(reason),
            Refusal::CausePresent { code } => write!(
                f,
                "the cause of error {code:04X}h is still present: the fault reset does not \
                 acknowledge it"
            ),
        }
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// Why the drive does not (or did not) take `request` now; `None`: nothing the drive
    /// knows of stands in its way.
    pub fn refusal(&self, request: Request) -> Option<Refusal> {
        V::refusal(self, request).or_else(|| self.engine_refusal(request))
    }

    /// What the engine itself checks: the hardware enables of transition 2, a fault cause,
    /// the modes of the personality.
    fn engine_refusal(&self, request: Request) -> Option<Refusal> {
        match request {
            Request::Enable => {
                if let Some(&code) = self.causes.first() {
                    return Some(Refusal::CausePresent { code });
                }
                // A drive without hardware enables of its own has none to miss.
                let h = self.personality.hardware_enable.as_ref()?;
                (!V::enables(self)).then_some(Refusal::HardwareEnable(h))
            }
            Request::Mode(m) => (!self.personality.accepts_mode(m, self.settings.ethercat))
                .then_some(Refusal::ModeUnsupported { mode: m }),
            Request::Write { .. } => None,
        }
    }
}
