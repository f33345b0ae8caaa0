//! Application synchronisation: when the device takes the outputs of SM2 and latches its
//! inputs, and when it declares the synchronisation lost (spec §7.5, §8.2).
//!
//! Two modes, as a drive runs them:
//! * **Free run / SM-synchronous** (no SYNC0): the arrival of the frame is the time base; the
//!   device takes each output buffer when it arrives ("without DC the firmware can use the
//!   arrival of the EtherCAT frame as the time base").
//! * **DC SYNC0**: the drive's cycle is triggered by the SYNC0 event; the output buffer that
//!   arrived since the previous event is taken at the event, and the inputs are latched then.
//!   Every SYNC0 cycle must bring one new output buffer ("the EtherCAT frame cycle time must
//!   be exactly matched to the cycle time of the interpolator").
//!
//! The loss of synchronisation is judged by a leaky error counter in the manner of the
//! ETG.1020 SM-event-missed counter: a SYNC0 event without a new output buffer adds
//! [`MISS_WEIGHT`], one with a buffer takes 1 away, and the synchronisation is lost at
//! [`ERROR_LIMIT`]. Decision (the manual gives no numbers): weight 3 and limit 9 — three
//! cycles missed in a row, or a master whose cycle slips against SYNC0 more often than one
//! event in three, is an error; the occasional slip of an unsynchronised master is not.
//! Counting starts with the first output buffer after the device entered Op, so a master that
//! requests Op before it sends process data (ethercrab's `into_op`) is not punished.

/// Added to the error counter for a SYNC0 event without new outputs.
pub const MISS_WEIGHT: u16 = 3;
/// Error counter value at which the synchronisation is lost.
pub const ERROR_LIMIT: u16 = 9;

/// What a SYNC0 event brings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sync0Outcome {
    /// A new output buffer arrived in this cycle: the device takes it now.
    pub take_outputs: bool,
    /// The error counter reached [`ERROR_LIMIT`] with this event (reported once).
    pub lost: bool,
}

/// The synchronisation state of one device.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SyncMonitor {
    pending: bool,
    armed: bool,
    lost: bool,
    counter: u16,
    /// SYNC0 events handled.
    pub events: u64,
    /// SYNC0 events without a new output buffer while armed.
    pub missed: u64,
}

impl SyncMonitor {
    pub const fn new() -> Self {
        SyncMonitor {
            pending: false,
            armed: false,
            lost: false,
            counter: 0,
            events: 0,
            missed: 0,
        }
    }

    /// Leaving Op, or SYNC0 reconfigured: start again (the counters of events stay).
    pub fn reset(&mut self) {
        self.pending = false;
        self.armed = false;
        self.lost = false;
        self.counter = 0;
    }

    /// A new output buffer arrived (in Op).
    pub fn outputs_received(&mut self) {
        self.pending = true;
        self.armed = true;
    }

    /// A new output buffer is waiting for the next SYNC0 event.
    pub fn outputs_pending(&self) -> bool {
        self.pending
    }

    /// The synchronisation was lost and not reset since.
    pub fn is_lost(&self) -> bool {
        self.lost
    }

    /// The error counter (0 … [`ERROR_LIMIT`]).
    pub fn error_counter(&self) -> u16 {
        self.counter
    }

    /// One SYNC0 event.
    pub fn sync0(&mut self) -> Sync0Outcome {
        self.events = self.events.wrapping_add(1);
        let take_outputs = core::mem::take(&mut self.pending);
        if !self.armed {
            return Sync0Outcome {
                take_outputs,
                lost: false,
            };
        }
        if !take_outputs {
            self.missed = self.missed.wrapping_add(1);
        }
        if self.lost {
            return Sync0Outcome {
                take_outputs,
                lost: false,
            };
        }
        self.counter = if take_outputs {
            self.counter.saturating_sub(1)
        } else {
            self.counter.saturating_add(MISS_WEIGHT).min(ERROR_LIMIT)
        };
        let lost = self.counter >= ERROR_LIMIT;
        self.lost = lost;
        Sync0Outcome { take_outputs, lost }
    }

    /// `n` SYNC0 events at once without outputs (the device was not polled for a while):
    /// the outcome of the first, and the rest counted as missed.
    pub fn sync0_many(&mut self, n: u64) -> Sync0Outcome {
        let mut first = self.sync0();
        for _ in 1..n.min(u64::from(ERROR_LIMIT)) {
            first.lost |= self.sync0().lost;
        }
        if n > u64::from(ERROR_LIMIT) {
            let rest = n - u64::from(ERROR_LIMIT);
            self.events = self.events.wrapping_add(rest);
            if self.armed {
                self.missed = self.missed.wrapping_add(rest);
            }
        }
        first
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_counting_before_the_first_outputs() {
        let mut m = SyncMonitor::new();
        for _ in 0..100 {
            assert_eq!(
                m.sync0(),
                Sync0Outcome {
                    take_outputs: false,
                    lost: false
                }
            );
        }
        assert_eq!(m.missed, 0);
        assert_eq!(m.events, 100);
    }

    #[test]
    fn one_buffer_per_cycle_keeps_the_counter_at_zero() {
        let mut m = SyncMonitor::new();
        for _ in 0..1000 {
            m.outputs_received();
            let o = m.sync0();
            assert!(o.take_outputs && !o.lost);
        }
        assert_eq!(m.error_counter(), 0);
    }

    #[test]
    fn three_missed_cycles_in_a_row_lose_the_synchronisation_once() {
        let mut m = SyncMonitor::new();
        m.outputs_received();
        assert!(m.sync0().take_outputs);
        assert!(!m.sync0().lost);
        assert!(!m.sync0().lost);
        assert!(m.sync0().lost, "third miss reaches the limit");
        assert!(m.is_lost());
        assert!(!m.sync0().lost, "reported once");
        assert_eq!(m.missed, 4);
        m.reset();
        assert!(!m.is_lost());
        assert!(!m.sync0().lost, "disarmed after a reset");
    }

    #[test]
    fn an_occasional_slip_is_tolerated() {
        // A master whose cycle slips: every fourth SYNC0 finds no new buffer (and the next
        // one finds two; only the newer counts).
        let mut m = SyncMonitor::new();
        for i in 0..10_000 {
            if i % 4 != 3 {
                m.outputs_received();
            }
            assert!(!m.sync0().lost, "cycle {i}");
        }
        assert_eq!(m.missed, 2500);
    }

    #[test]
    fn a_slip_every_other_cycle_is_an_error() {
        let mut m = SyncMonitor::new();
        let mut lost = false;
        for i in 0..20 {
            if i % 2 == 0 {
                m.outputs_received();
            }
            lost |= m.sync0().lost;
        }
        assert!(lost);
    }

    #[test]
    fn many_events_at_once() {
        let mut m = SyncMonitor::new();
        m.outputs_received();
        let o = m.sync0_many(1000);
        assert!(o.take_outputs);
        assert!(m.is_lost());
        assert_eq!(m.events, 1000);
        assert_eq!(m.missed, 999);
    }
}
