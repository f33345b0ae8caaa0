//! When the cell loop turns next, published for the control handles: a request that can wait
//! for a turn the loop makes anyway (the drives step every millisecond) rides on it instead
//! of waking the loop with its waker, so a browser's polls and the scope's samples add no
//! wake-up, no context switch and no preemption point to the loop (`docs/performance.md`,
//! "Browser tabs on the console").
//!
//! Lost wake-ups are ruled out the way two threads that each store then load rule them out
//! (sequentially consistent order): a sender sends its request, counts it as pending *then*
//! reads the published turn; the loop publishes its turn *then* reads the pending count, and
//! does not sleep while one is pending. Either the loop sees the request (sent before it was
//! counted, so the loop's next turn finds it), or the sender sees the turn the loop is about
//! to sleep to. The count may dip below zero for a moment (the loop took a request its sender
//! has not counted yet); the loop never waits for a sender.

use std::sync::atomic::{AtomicIsize, AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// No turn is planned (the loop sleeps until a socket or the waker wakes it), or it is busy
/// and publishes none.
const NONE: u64 = u64::MAX;

/// The loop's next planned turn and the requests waiting for one.
#[derive(Debug)]
pub struct NextTurn {
    /// The zero of [`NextTurn::at_ns`].
    origin: Instant,
    /// Nanoseconds after `origin` of the instant the loop sleeps until, or [`NONE`].
    at_ns: AtomicU64,
    /// Requests counted by their senders less those taken by the loop.
    pending: AtomicIsize,
}

impl Default for NextTurn {
    fn default() -> Self {
        NextTurn {
            origin: Instant::now(),
            at_ns: AtomicU64::new(NONE),
            pending: AtomicIsize::new(0),
        }
    }
}

impl NextTurn {
    /// The loop, before it waits: it sleeps until `at` (`None`: until a socket or the waker
    /// wakes it). Answers whether requests are pending; then the loop must not sleep.
    pub fn publish(&self, at: Option<Instant>) -> bool {
        let ns = at.map_or(NONE, |at| {
            u64::try_from(at.saturating_duration_since(self.origin).as_nanos()).unwrap_or(NONE)
        });
        self.at_ns.store(ns, Ordering::SeqCst);
        self.pending.load(Ordering::SeqCst) > 0
    }

    /// The loop took one request.
    pub fn taken(&self) {
        self.pending.fetch_sub(1, Ordering::SeqCst);
    }

    /// A sender, after it sent a request (and before [`NextTurn::comes_within`]).
    pub fn sent(&self) {
        self.pending.fetch_add(1, Ordering::SeqCst);
    }

    /// A sender, after it sent a request: whether the loop turns by `now + within` anyway
    /// (then the request is served at that turn and the waker stays quiet). A turn already
    /// past is a loop that is running: it publishes its next one before it sleeps, and the
    /// sender wakes it to be safe.
    pub fn comes_within(&self, now: Instant, within: Duration) -> bool {
        let ns = self.at_ns.load(Ordering::SeqCst);
        if ns == NONE {
            return false;
        }
        let at = self.origin + Duration::from_nanos(ns);
        at >= now && at <= now + within
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_rides_on_a_turn_that_comes_soon_enough() {
        let turn = NextTurn::default();
        let now = Instant::now();
        assert!(
            !turn.comes_within(now, Duration::from_millis(2)),
            "none yet"
        );
        assert!(!turn.publish(Some(now + Duration::from_micros(800))));
        assert!(turn.comes_within(now, Duration::from_millis(2)));
        assert!(
            !turn.comes_within(now, Duration::from_micros(500)),
            "too far"
        );
        assert!(
            !turn.comes_within(now + Duration::from_millis(1), Duration::from_millis(2)),
            "already past: the loop is running"
        );
        assert!(!turn.publish(None));
        assert!(
            !turn.comes_within(now, Duration::from_secs(1)),
            "no turn planned"
        );
    }

    #[test]
    fn the_loop_does_not_sleep_while_a_request_is_pending() {
        let turn = NextTurn::default();
        turn.sent();
        assert!(turn.publish(Some(Instant::now() + Duration::from_millis(1))));
        turn.taken();
        assert!(!turn.publish(Some(Instant::now() + Duration::from_millis(1))));
        // Taken before its sender counted it: no turn without a request in between.
        turn.taken();
        assert!(!turn.publish(None));
        turn.sent();
        assert!(!turn.publish(None));
    }
}
