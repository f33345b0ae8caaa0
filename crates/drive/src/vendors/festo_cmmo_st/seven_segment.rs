//! The 7-segment display of the CMMO-ST (manual §7.1.2 Tab. 7.3): an active error or warning
//! is shown as its hexadecimal diagnostic number; an information is not shown (§7.1.2: only
//! FCT and the web server show it).
//!
//! The display is on the device's front, not on the fieldbus: a master sees the same facts
//! through FC 0x07 / PNU 205 (the active error) and PNU 221 (the warnings), never the display
//! itself, so the twin exposes it on the device API ([`super::device::FhppDevice::seven_segment`]).

use core::fmt;

/// A message type of Tab. 7.1 that Tab. 7.3 gives a 7-segment row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MessageType {
    Error,
    Warning,
}

/// One 7-segment row of Tab. 7.3: the message type and the letter in front of its
/// hexadecimal code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Row {
    pub kind: MessageType,
    pub prefix: Option<char>,
}

/// Tab. 7.3, the 7-segment rows ("hexadecimal code" for both types).
pub const TAB_7_3: [Row; 2] = [
    // CMMO-ST C.4.7: an aborted file transfer shows "E27" (error 27h).
    Row {
        kind: MessageType::Error,
        prefix: Some('E'),
    },
    // Decision: Tab. 7.3 says only "hexadecimal code" and the manual prints no warning on the
    // display; without a printed letter the warning shows its two hex digits alone.
    Row {
        kind: MessageType::Warning,
        prefix: None,
    },
];

/// What the 7-segment display shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SevenSegment {
    /// No error and no warning: no diagnostic code (the display's other content is not
    /// described by this manual).
    NoMessage,
    /// The active error, by diagnostic number.
    Error(u8),
    /// A warning, by diagnostic number.
    Warning(u8),
}

impl SevenSegment {
    /// The display for the active error `fault` (PNU 205: the one of highest priority) and
    /// the present warnings `warnings` (PNU 221 as one bit field, bit n = number n).
    /// Decision: an error takes precedence over warnings (it is the one that stops the drive);
    /// of several warnings the display shows the lowest number (the manual gives no order).
    pub fn showing(fault: Option<u8>, warnings: u128) -> Self {
        match fault {
            Some(code) => SevenSegment::Error(code),
            None if warnings != 0 => SevenSegment::Warning(warnings.trailing_zeros() as u8),
            None => SevenSegment::NoMessage,
        }
    }

    /// The Tab. 7.3 row behind this display, `None` without a message.
    pub fn row(self) -> Option<&'static Row> {
        let kind = match self {
            SevenSegment::NoMessage => return None,
            SevenSegment::Error(_) => MessageType::Error,
            SevenSegment::Warning(_) => MessageType::Warning,
        };
        TAB_7_3.iter().find(|r| r.kind == kind)
    }
}

/// The characters on the display: "E27", "37", or nothing.
impl fmt::Display for SevenSegment {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let code = match *self {
            SevenSegment::NoMessage => return Ok(()),
            SevenSegment::Error(c) | SevenSegment::Warning(c) => c,
        };
        if let Some(p) = self.row().and_then(|r| r.prefix) {
            write!(f, "{p}")?;
        }
        write!(f, "{code:02X}")
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    /// FHPP-DIAG-03: an error shows "E" and its hex code (C.4.7 "E27"), a warning its hex
    /// code; nothing without a message.
    #[test]
    fn error_and_warning_codes_in_hex() {
        assert_eq!(SevenSegment::showing(Some(0x27), 0).to_string(), "E27");
        assert_eq!(
            SevenSegment::showing(Some(0x2F), 1 << 0x37).to_string(),
            "E2F"
        );
        assert_eq!(SevenSegment::showing(None, 1 << 0x37).to_string(), "37");
        assert_eq!(
            SevenSegment::showing(None, (1 << 0x48) | (1 << 0x40)),
            SevenSegment::Warning(0x40)
        );
        assert_eq!(SevenSegment::showing(None, 0), SevenSegment::NoMessage);
        assert_eq!(SevenSegment::NoMessage.to_string(), "");
        assert_eq!(SevenSegment::Error(0x0A).to_string(), "E0A");
    }
}
