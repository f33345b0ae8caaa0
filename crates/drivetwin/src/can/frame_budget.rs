//! A socketcand client may put frames on the bus no faster than the bus carries them: a token
//! bucket filled at the bus's highest frame rate (its bit rate over the shortest frame, 47 bits
//! with the intermission). A client that floods loses what is beyond it, as a CAN controller
//! loses what overflows its transmit queue, and cannot starve the others of the loop or of the
//! bus.

use std::time::Instant;

/// Bits of the shortest frame on the bus: a data frame without data, with the intermission.
const SHORTEST_FRAME_BITS: f64 = 47.0;
/// Frames a client may send at once before the rate applies: a master's start-up burst (SDO
/// configuration of a 127-node bus, a test's storm of bad frames).
const BURST: f64 = 1024.0;

#[derive(Debug, Clone)]
pub struct FrameBudget {
    per_second: f64,
    tokens: f64,
    last: Option<Instant>,
    /// Frames refused so far.
    pub dropped: u64,
}

impl FrameBudget {
    /// The budget of a client on a bus of `bitrate` bit/s.
    pub fn for_bitrate(bitrate: u32) -> Self {
        FrameBudget {
            per_second: f64::from(bitrate.max(1)) / SHORTEST_FRAME_BITS,
            tokens: BURST,
            last: None,
            dropped: 0,
        }
    }

    /// Whether the client may send a frame at `now`; a refusal is counted.
    pub fn take(&mut self, now: Instant) -> bool {
        if let Some(last) = self.last {
            let earned = now.saturating_duration_since(last).as_secs_f64() * self.per_second;
            self.tokens = (self.tokens + earned).min(BURST);
        }
        self.last = Some(now);
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            self.dropped += 1;
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn a_client_sends_at_most_the_bus_rate_after_its_burst() {
        let t0 = Instant::now();
        let mut b = FrameBudget::for_bitrate(1_000_000);
        let sent = (0..5000).filter(|_| b.take(t0)).count();
        assert_eq!(sent, 1024, "the burst");
        // One second later: 21 276 more at most (1 Mbit/s / 47 bits), capped by the burst.
        let t1 = t0 + Duration::from_secs(1);
        let sent = (0..5000).filter(|_| b.take(t1)).count();
        assert_eq!(sent, 1024);
        // 10 ms later: 212 (21 276 frames/s).
        let t2 = t1 + Duration::from_millis(10);
        let sent = (0..5000).filter(|_| b.take(t2)).count();
        assert_eq!(sent, 212);
        // Spread over a second, 1000 frames at 1 ms intervals all pass.
        let mut b = FrameBudget::for_bitrate(125_000);
        let ok = (0..1000u32)
            .filter(|i| b.take(t0 + Duration::from_millis(u64::from(*i))))
            .count();
        assert_eq!(ok, 1000);
        assert_eq!(b.dropped, 0);
    }
}
