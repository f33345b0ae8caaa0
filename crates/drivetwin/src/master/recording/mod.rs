//! Recordings of a node's answers: a script of requests run against a node (a real drive over
//! SocketCAN or socketcand, or a twin), every request and answer written with its time, and
//! the comparison of two runs of the same requests.
//!
//! Sans-IO: [`script`] turns a TOML script or a candump log into steps, [`sdo_transfer`]
//! expands an SDO read or write into its request frames, [`gather`] decides which frames
//! answer a request and when a step is over, [`file`](mod@file) parses and emits the recording (a
//! candump log with `req` / `ans` as the interface and `# step` lines), [`compare`] reports
//! what differs. `master::recorder` moves the frames.
//!
//! **Decision:** frames that differ between two runs of the same drive are no answers:
//! heartbeats (701h…77Fh, their phase is the node's own clock), SYNC (080h) and TIME (100h)
//! from another producer, unless a step awaits them (an NMT step awaits the node's heartbeat
//! or boot-up); a heartbeat's time is never compared. The list is the recording's `ignore`;
//! a boot-up is always an answer.

pub mod compare;
pub mod file;
pub mod gather;
pub mod script;
pub mod sdo_transfer;

use std::time::Duration;

use canopen::CanFrame;

/// How the answers to one request are gathered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AnswerRule {
    /// Every frame within this time after the request is an answer.
    pub window: Duration,
    /// And the step lasts until this frame has come (an SDO response, a heartbeat).
    pub until: Option<Awaited>,
}

/// The frame a step waits for, and how long.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Awaited {
    pub cob_id: u16,
    pub timeout: Duration,
}

/// One request and how its answers are gathered.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Step {
    /// What the step does, as the report names it (`sdo read 1018:01`).
    pub label: String,
    /// The script's line of the step (0: none).
    pub line: usize,
    pub request: CanFrame,
    pub rule: AnswerRule,
}

/// A frame seen in answer, with its time after the request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Answer {
    pub after: Duration,
    pub frame: CanFrame,
}

/// A step as it ran: when its request left (since the recording's start) and its answers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordedStep {
    pub step: Step,
    pub sent_at: Duration,
    pub answers: Vec<Answer>,
}

impl RecordedStep {
    /// Whether the awaited frame came (always true for a step that awaits none).
    pub fn awaited_came(&self) -> bool {
        match self.step.rule.until {
            None => true,
            Some(a) => self
                .answers
                .iter()
                .any(|x| x.frame.cob_id() == Some(a.cob_id)),
        }
    }
}

/// An inclusive range of COB-IDs (`701-77F`, or one `080`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CobRange {
    pub first: u16,
    pub last: u16,
}

impl CobRange {
    pub fn contains(&self, cob: u16) -> bool {
        (self.first..=self.last).contains(&cob)
    }

    /// `701-77F` or `080`, hex.
    pub fn parse(text: &str) -> Option<CobRange> {
        let hex = |t: &str| {
            u16::from_str_radix(t.trim(), 16)
                .ok()
                .filter(|v| *v <= 0x7FF)
        };
        let (first, last) = match text.split_once('-') {
            Some((a, b)) => (hex(a)?, hex(b)?),
            None => (hex(text)?, hex(text)?),
        };
        (first <= last).then_some(CobRange { first, last })
    }
}

impl std::fmt::Display for CobRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.first == self.last {
            write!(f, "{:03X}", self.first)
        } else {
            write!(f, "{:03X}-{:03X}", self.first, self.last)
        }
    }
}

/// The frames that are no answers unless awaited: SYNC, TIME, heartbeats.
pub const DEFAULT_IGNORE: [CobRange; 3] = [
    CobRange {
        first: 0x080,
        last: 0x080,
    },
    CobRange {
        first: 0x100,
        last: 0x100,
    },
    CobRange {
        first: 0x701,
        last: 0x77F,
    },
];

/// A whole run: the frames that are no answers, and the steps in order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Recording {
    pub ignore: Vec<CobRange>,
    pub steps: Vec<RecordedStep>,
}

/// A heartbeat's time is its producer's phase, not an answer's delay; a boot-up's is one.
pub fn time_matters(frame: &CanFrame) -> bool {
    is_boot_up(frame) || !matches!(frame.cob_id(), Some(0x701..=0x77F))
}

/// The boot-up message of a node (CiA 301 §7.2.8.3.2.4: 700h + node, one byte 00h).
pub fn is_boot_up(frame: &CanFrame) -> bool {
    matches!(frame.cob_id(), Some(0x701..=0x77F)) && !frame.rtr && frame.payload() == [0]
}

/// A mistake in a script or a recording, with the line it is on.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("line {line}: {what}")]
pub struct LineError {
    pub line: usize,
    pub what: String,
}

impl LineError {
    pub fn new(line: usize, what: impl Into<String>) -> Self {
        LineError {
            line,
            what: what.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cob_ranges_parse_and_print_as_the_recording_writes_them() {
        let r = CobRange::parse("701-77F").expect("range");
        assert!(r.contains(0x701) && r.contains(0x77F) && !r.contains(0x700));
        assert_eq!(r.to_string(), "701-77F");
        assert_eq!(
            CobRange::parse("080").map(|r| r.to_string()).as_deref(),
            Some("080")
        );
        assert_eq!(CobRange::parse("77F-701"), None);
        assert_eq!(CobRange::parse("800"), None);
        assert_eq!(CobRange::parse("x"), None);
    }

    #[test]
    fn a_heartbeats_time_does_not_count_and_a_boot_ups_does() {
        let f = |id, data: &[u8]| CanFrame::new(id, data).expect("frame");
        assert!(!time_matters(&f(0x701, &[0x05])));
        assert!(time_matters(&f(0x701, &[0x00])));
        assert!(is_boot_up(&f(0x77F, &[0x00])));
        assert!(!is_boot_up(&f(0x581, &[0x00])));
        assert!(time_matters(&f(0x581, &[0x60, 0, 0, 0, 0, 0, 0, 0])));
    }
}
