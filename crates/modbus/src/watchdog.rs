//! The CMMO-ST's Modbus connection monitoring, "Node Guard / Timeout" (manual §4.3.4).
//!
//! - Every Modbus message the client sends restarts the timer.
//! - No message within the timeout triggers the error reaction "Timeout MODBUS TCP/IP":
//!   diagnostic 47h with Modbus holding control authority, else 48h (Appendix D).
//! - The timeout is set from 0 to 5000 ms; 0 disables it; 1…99 ms are accepted but act as
//!   100 ms. Factory setting: 100 ms, not activated (§4.2.1).
//!
//! Decisions: the timer runs from the moment the connection is opened (a client that
//! connects and never sends is as silent as one that stopped); it does not run without a
//! connection; entries above 5000 ms, which the manual does not allow, act as 5000 ms.
//!
//! Time is a plain millisecond count from any origin the caller chooses; the watchdog never
//! reads a clock.

/// Shortest effective timeout, ms.
pub const MIN_TIMEOUT_MS: u16 = 100;
/// Longest timeout, ms.
pub const MAX_TIMEOUT_MS: u16 = 5000;

/// The timeout the device uses for a configured value: `None` for 0 (disabled), at least
/// 100 ms, at most 5000 ms.
pub const fn effective_timeout_ms(configured_ms: u16) -> Option<u16> {
    match configured_ms {
        0 => None,
        1..=MIN_TIMEOUT_MS => Some(MIN_TIMEOUT_MS),
        MAX_TIMEOUT_MS.. => Some(MAX_TIMEOUT_MS),
        n => Some(n),
    }
}

/// The connection watchdog of one Modbus connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Watchdog {
    timeout_ms: Option<u16>,
    deadline_ms: Option<u64>,
}

impl Watchdog {
    /// A stopped watchdog with the configured timeout (see [`effective_timeout_ms`]).
    pub const fn new(configured_ms: u16) -> Watchdog {
        Watchdog {
            timeout_ms: effective_timeout_ms(configured_ms),
            deadline_ms: None,
        }
    }

    /// The effective timeout, `None` when disabled.
    pub const fn timeout_ms(&self) -> Option<u16> {
        self.timeout_ms
    }

    /// A connection was opened at `now_ms`: the timer starts.
    pub fn start(&mut self, now_ms: u64) {
        self.deadline_ms = self.timeout_ms.map(|t| now_ms.saturating_add(u64::from(t)));
    }

    /// A Modbus message arrived at `now_ms`: the timer restarts (if running).
    pub fn on_message(&mut self, now_ms: u64) {
        if self.deadline_ms.is_some() {
            self.start(now_ms);
        }
    }

    /// The connection is gone: the timer stops.
    pub fn stop(&mut self) {
        self.deadline_ms = None;
    }

    /// When it expires, if running.
    pub const fn deadline_ms(&self) -> Option<u64> {
        self.deadline_ms
    }

    /// `true` once, when `now_ms` reached the deadline; the watchdog then stops.
    pub fn poll(&mut self, now_ms: u64) -> bool {
        match self.deadline_ms {
            Some(d) if now_ms >= d => {
                self.deadline_ms = None;
                true
            }
            _ => false,
        }
    }
}
