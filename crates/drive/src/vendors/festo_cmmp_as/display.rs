//! The CMMP-AS 7-segment display (App. B, §5.17, Tab. 6.10): what it shows for an error, a
//! warning, safe standstill and a drive that is not parameterised. The characters a message
//! cycles through are given as text, one character a digit.

use core::fmt::Write;

use super::messages::{self, Number};
use super::CmmpAs;
use crate::drive::Drive;
use crate::personality::Vendor;

/// What the display shows, by priority.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Display {
    /// An error, cycled as `-E` main sub `-` (App. B: "- E 0 1 0 -").
    Error(Number),
    /// A warning: the same number framed by hyphens, without "E" ("- 1 7 0 -").
    Warning(Number),
    /// "H": the safety module reports safe standstill (2000h:01 bit 8).
    SafeStandstill,
    /// "A": not parameterised (6510h:C0 commissioning_state = 0).
    NotParameterised,
    /// Normal operation; the twin does not simulate the operating-mode indications.
    Operating,
}

impl Display {
    /// What to show: the oldest error first, then the warning, then "H", then "A".
    pub fn select(
        error: Option<Number>,
        warning: Option<Number>,
        safe_standstill: bool,
        commissioning_state: u32,
    ) -> Self {
        match (error, warning) {
            (Some(e), _) => Display::Error(e),
            (None, Some(w)) => Display::Warning(w),
            _ if safe_standstill => Display::SafeStandstill,
            _ if commissioning_state == 0 => Display::NotParameterised,
            _ => Display::Operating,
        }
    }

    /// The characters the display cycles through (empty in normal operation).
    pub fn text(&self) -> heapless::String<8> {
        let mut s = heapless::String::new();
        // At most 6 characters: always fits.
        let _ = match self {
            Display::Error(n) => write!(s, "-E{:02}{}-", n.main, n.sub),
            Display::Warning(n) => write!(s, "-{:02}{}-", n.main, n.sub),
            Display::SafeStandstill => s.write_str("H"),
            Display::NotParameterised => s.write_str("A"),
            Display::Operating => Ok(()),
        };
        s
    }
}

/// What the display of drive `d` shows with `warning` the active warning: the oldest error
/// by its App. B number (a message raised by its number, else the first with the error's
/// code), the warning, "H" for safe standstill, "A" while 6510h:C0 commissioning_state is 0.
fn shown<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor>(
    d: &Drive<S, V>,
    warning: Option<Number>,
) -> Display {
    let error = d
        .faults
        .iter()
        .find_map(|c| messages::of_code(&d.injected, *c))
        .map(|m| m.number);
    let commissioning = d.value(0x6510, 0xC0) as u32;
    Display::select(error, warning, d.safe_standstill, commissioning)
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, CmmpAs> {
    /// What the 7-segment display shows (App. B).
    pub fn display(&self) -> Display {
        let warning = self.vendor.errors.active_warning().map(|m| m.number);
        shown(self, warning)
    }
}
