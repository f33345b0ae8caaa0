//! Heartbeat producer (1017h) and consumer (1016h), CiA 301 §7.2.8.3.2.2.

use core::time::Duration;

use od::{Instant, ObjectAccess};

/// Sends the node's state every 1017h milliseconds; the boot-up message counts as the first
/// heartbeat (CiA 301, heartbeat protocol).
#[derive(Debug, Default, Clone)]
pub struct HeartbeatProducer {
    period_ms: u16,
    next: Option<Instant>,
}

impl HeartbeatProducer {
    /// The boot-up message went out at `now`: the next heartbeat is one period later.
    pub fn booted(&mut self, now: Instant, od: &dyn ObjectAccess) {
        self.period_ms = od.read_u16(0x1017, 0).unwrap_or(0);
        self.next = self.schedule(now);
    }

    fn schedule(&self, from: Instant) -> Option<Instant> {
        (self.period_ms > 0).then(|| from + Duration::from_millis(u64::from(self.period_ms)))
    }

    /// Picks up a changed 1017h: a new period starts counting from the change.
    pub fn refresh(&mut self, now: Instant, od: &dyn ObjectAccess) {
        let period = od.read_u16(0x1017, 0).unwrap_or(0);
        if period != self.period_ms {
            self.period_ms = period;
            self.next = self.schedule(now);
        }
    }

    /// Whether a heartbeat is due at `now`.
    pub fn due(&mut self, now: Instant, od: &dyn ObjectAccess) -> bool {
        let period = self.period_ms;
        self.refresh(now, od);
        if period != self.period_ms {
            return false;
        }
        match self.next {
            Some(t) if now >= t => {
                // Keep the grid: the next beat is a period after the one that was due.
                let mut next = t + Duration::from_millis(u64::from(period));
                if next <= now {
                    next = now + Duration::from_millis(u64::from(period));
                }
                self.next = Some(next);
                true
            }
            _ => false,
        }
    }

    pub fn deadline(&self) -> Option<Instant> {
        self.next
    }
    pub fn stop(&mut self) {
        self.next = None;
        self.period_ms = 0;
    }
}

/// Most producers one node watches.
pub const MAX_CONSUMED: usize = 8;

#[derive(Debug, Clone, Copy, Default)]
struct Watch {
    node: u8,
    period_ms: u16,
    /// When the heartbeat is overdue; `None` until the first one arrives (monitoring starts
    /// with the first heartbeat, CiA 301 §7.2.8.3.2.2).
    deadline: Option<Instant>,
    lost: bool,
}

/// What the consumer noticed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConsumerEvent {
    /// No heartbeat from `node` within its consumer time.
    Lost { node: u8 },
    /// `node` is heard again after a loss.
    Resumed { node: u8 },
}

/// Watches other nodes' heartbeats as 1016h configures them.
#[derive(Debug, Clone, Default)]
pub struct HeartbeatConsumer {
    watches: [Watch; MAX_CONSUMED],
}

impl HeartbeatConsumer {
    /// Re-reads 1016h (sub 1…): `node << 16 | time_ms`, 0 = unused.
    fn refresh(&mut self, od: &dyn ObjectAccess) {
        // Only the sub-indices 1016h:00 counts (a device without 1016h watches nothing): the
        // consumer refreshes at every poll.
        let entries = od.read_u8(0x1016, 0).unwrap_or(0);
        for (i, w) in self.watches.iter_mut().enumerate() {
            let v = if i < usize::from(entries) {
                od.read_u32(0x1016, (i + 1) as u8).unwrap_or(0)
            } else {
                0
            };
            let node = ((v >> 16) & 0xFF) as u8;
            let period_ms = (v & 0xFFFF) as u16;
            if node != w.node || period_ms != w.period_ms {
                *w = Watch {
                    node,
                    period_ms,
                    deadline: None,
                    lost: false,
                };
            }
        }
    }

    /// A heartbeat (or boot-up) of `node` arrived.
    pub fn on_heartbeat(
        &mut self,
        now: Instant,
        node: u8,
        od: &dyn ObjectAccess,
    ) -> Option<ConsumerEvent> {
        self.refresh(od);
        let mut event = None;
        for w in self.watches.iter_mut() {
            if w.node == node && w.node != 0 && w.period_ms != 0 {
                w.deadline = Some(now + Duration::from_millis(u64::from(w.period_ms)));
                if w.lost {
                    w.lost = false;
                    event = Some(ConsumerEvent::Resumed { node });
                }
            }
        }
        event
    }

    /// Reports the first watch whose heartbeat is overdue at `now`.
    pub fn poll(&mut self, now: Instant, od: &dyn ObjectAccess) -> Option<ConsumerEvent> {
        self.refresh(od);
        for w in self.watches.iter_mut() {
            if let Some(d) = w.deadline {
                if now >= d {
                    w.deadline = None;
                    w.lost = true;
                    return Some(ConsumerEvent::Lost { node: w.node });
                }
            }
        }
        None
    }

    pub fn deadline(&self) -> Option<Instant> {
        self.watches.iter().filter_map(|w| w.deadline).min()
    }

    pub fn clear(&mut self) {
        self.watches = [Watch::default(); MAX_CONSUMED];
    }
}
