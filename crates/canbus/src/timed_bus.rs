//! A CAN bus that takes the time a real one does: each frame occupies the bus for its exact
//! bit time ([`frame_time`](crate::frame_time)), and when several frames are ready as the bus
//! falls idle, the one with the lowest identifier wins the arbitration (ISO 11898-1: a
//! dominant 0 overwrites a recessive 1, bit by bit from the identifier's MSB). The others
//! wait and try again at the next idle bus, so a burst of frames leaves one after the other
//! and a bus asked for more than it can carry falls behind.
//!
//! Sans-IO: nodes [`submit`](TimedBus::submit) frames at the instant they are ready; the
//! runtime asks [`deadline`](TimedBus::deadline) when the next frame will have crossed the
//! wire and [`poll`](TimedBus::poll)s it out then. The same inputs give the same order and
//! the same instants, bit for bit.
//!
//! Decisions: two frames with the same arbitration field (two nodes sending one identifier,
//! an error on a real bus) leave in the order they were submitted; a frame counts as
//! received at the end of its EOF + intermission.

use heapless::Vec;
use od::Instant;

use crate::frame_time::{bits_to_nanos, frame_bits};
use crate::CanFrame;

/// A frame waiting for the bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Pending {
    ready: Instant,
    seq: u64,
    source: u16,
    frame: CanFrame,
    /// Its bit time on this bus, computed once at submission.
    nanos: u64,
    key: u64,
}

/// A frame that crossed the bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Transmission {
    /// Who sent it (a node ID, or any number the runtime gives its outside clients).
    pub source: u16,
    pub frame: CanFrame,
    /// When its sender had it ready.
    pub ready: Instant,
    /// Start of frame, after it won the arbitration.
    pub start: Instant,
    /// End of the intermission: the bus is free again.
    pub end: Instant,
}

impl Transmission {
    /// How long the frame waited for the bus, ns.
    pub fn queued_nanos(&self) -> u64 {
        self.start.as_nanos().saturating_sub(self.ready.as_nanos())
    }
}

/// No room left in the bus's transmit queue.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QueueFull;

/// The arbitration field as a number: the lower wins. Standard: `ID[10:0]`, RTR, IDE = 0;
/// extended: `ID[28:18]`, SRR = 1, IDE = 1, `ID[17:0]`, RTR.
pub fn arbitration_key(frame: &CanFrame) -> u64 {
    let rtr = u64::from(frame.rtr);
    if frame.extended {
        let base = u64::from(frame.id >> 18) & 0x7FF;
        let ext = u64::from(frame.id) & 0x3FFFF;
        (base << 21) | (1 << 20) | (1 << 19) | (ext << 1) | rtr
    } else {
        ((u64::from(frame.id) & 0x7FF) << 21) | (rtr << 20)
    }
}

/// One bus at one bit rate, with room for `N` waiting frames.
#[derive(Debug, Clone)]
pub struct TimedBus<const N: usize> {
    bitrate: u32,
    pending: Vec<Pending, N>,
    busy_until: Instant,
    seq: u64,
    busy_nanos: u64,
}

impl<const N: usize> TimedBus<N> {
    /// An idle bus at `bitrate` bit/s (at least 1).
    pub fn new(bitrate: u32) -> Self {
        TimedBus {
            bitrate: bitrate.max(1),
            pending: Vec::new(),
            busy_until: Instant::ZERO,
            seq: 0,
            busy_nanos: 0,
        }
    }

    pub fn bitrate(&self) -> u32 {
        self.bitrate
    }

    /// How long `frame` occupies this bus, ns.
    pub fn frame_nanos(&self, frame: &CanFrame) -> u64 {
        bits_to_nanos(frame_bits(frame), self.bitrate)
    }

    /// `source` has `frame` ready at `now`.
    pub fn submit(&mut self, now: Instant, source: u16, frame: CanFrame) -> Result<(), QueueFull> {
        let p = Pending {
            ready: now,
            seq: self.seq,
            source,
            frame,
            nanos: self.frame_nanos(&frame),
            key: arbitration_key(&frame),
        };
        self.pending.push(p).map_err(|_| QueueFull)?;
        self.seq += 1;
        Ok(())
    }

    /// Frames waiting for the bus.
    pub fn queued(&self) -> usize {
        self.pending.len()
    }

    /// The next frame to cross the bus, with its instants (not yet taken out).
    fn next(&self) -> Option<(usize, Instant, Instant)> {
        let earliest = self.pending.iter().map(|p| p.ready).min()?;
        let start = earliest.max(self.busy_until);
        // Arbitration among every frame ready when the bus falls idle.
        let (i, p) = self
            .pending
            .iter()
            .enumerate()
            .filter(|(_, p)| p.ready <= start)
            .min_by_key(|(_, p)| (p.key, p.seq))?;
        let end = Instant::from_nanos(start.as_nanos() + p.nanos);
        Some((i, start, end))
    }

    /// When the next frame will have crossed the bus.
    pub fn deadline(&self) -> Option<Instant> {
        self.next().map(|(_, _, end)| end)
    }

    /// The next frame that has crossed the bus by `now`, in bus order; call until `None`.
    pub fn poll(&mut self, now: Instant) -> Option<Transmission> {
        let (i, start, end) = self.next()?;
        if end > now {
            return None;
        }
        let p = self.pending.swap_remove(i);
        self.busy_until = end;
        self.busy_nanos += end.as_nanos() - start.as_nanos();
        Some(Transmission {
            source: p.source,
            frame: p.frame,
            ready: p.ready,
            start,
            end,
        })
    }

    /// Whether `frame`, ready at `now`, would wait for the bus: the bus is still busy at
    /// `now`, or a frame already waiting at `now` wins the arbitration against it. A frame
    /// for which this is `false` starts at `now` (ISO 11898-1: arbitration at bus idle).
    pub fn would_wait(&self, now: Instant, frame: &CanFrame) -> bool {
        let key = arbitration_key(frame);
        self.busy_until > now || self.pending.iter().any(|p| p.ready <= now && p.key <= key)
    }

    /// The time the bus has been busy since it was made, ns: the bus load over a window is
    /// the difference of two readings over the window's length.
    pub fn busy_nanos(&self) -> u64 {
        self.busy_nanos
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(id, data).expect("test frame")
    }

    #[test]
    fn a_frame_waits_behind_a_busy_bus_and_behind_a_higher_priority_frame_only() {
        let mut bus: TimedBus<8> = TimedBus::new(125_000);
        let low = frame(0x601, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]);
        let high = frame(0x181, &[1]);
        assert!(!bus.would_wait(Instant::ZERO, &low));
        bus.submit(Instant::ZERO, 1, high).unwrap();
        assert!(
            bus.would_wait(Instant::ZERO, &low),
            "0x181 wins against 0x601"
        );
        assert!(
            !bus.would_wait(Instant::ZERO, &frame(0x080, &[])),
            "0x080 wins"
        );
        let t = bus.deadline().unwrap();
        let tx = bus.poll(t).unwrap();
        assert!(bus.would_wait(Instant::from_nanos(tx.end.as_nanos() - 1), &low));
        assert!(!bus.would_wait(tx.end, &low));
    }

    fn drain<const N: usize>(bus: &mut TimedBus<N>) -> heapless::Vec<Transmission, 256> {
        let mut out = heapless::Vec::new();
        while let Some(t) = bus.deadline() {
            while let Some(tx) = bus.poll(t) {
                out.push(tx).expect("room");
            }
        }
        out
    }

    #[test]
    fn lowest_identifier_wins_the_arbitration() {
        let mut bus: TimedBus<8> = TimedBus::new(500_000);
        let t0 = Instant::from_millis(1);
        for id in [0x701u16, 0x181, 0x080, 0x601] {
            bus.submit(t0, id, frame(id, &[1])).expect("room");
        }
        let order: heapless::Vec<u32, 8> = drain(&mut bus).iter().map(|t| t.frame.id).collect();
        assert_eq!(order.as_slice(), &[0x080, 0x181, 0x601, 0x701]);
    }

    #[test]
    fn a_data_frame_wins_over_a_remote_frame_and_standard_over_extended() {
        let data = frame(0x123, &[]);
        let mut remote = data;
        remote.rtr = true;
        let ext = CanFrame::with_id(0x123 << 18, true, &[]).expect("frame");
        assert!(arbitration_key(&data) < arbitration_key(&remote));
        assert!(arbitration_key(&remote) < arbitration_key(&ext));
        assert!(arbitration_key(&ext) < arbitration_key(&frame(0x124, &[])));
    }

    #[test]
    fn frames_follow_each_other_without_overlap_and_in_exact_bit_time() {
        let mut bus: TimedBus<8> = TimedBus::new(125_000);
        bus.submit(Instant::ZERO, 1, frame(0x181, &[1, 2, 3, 4, 5, 6, 7, 8]))
            .expect("room");
        bus.submit(Instant::ZERO, 2, frame(0x182, &[0x55]))
            .expect("room");
        let tx = drain(&mut bus);
        assert_eq!(tx[0].start, Instant::ZERO);
        assert_eq!(
            tx[0].end.as_nanos(),
            8_000 * u64::from(frame_bits(&tx[0].frame))
        );
        assert_eq!(tx[1].start, tx[0].end, "the loser waits for the idle bus");
        assert_eq!(tx[1].queued_nanos(), tx[0].end.as_nanos());
        assert_eq!(bus.busy_nanos(), tx[1].end.as_nanos());
    }

    #[test]
    fn a_frame_ready_during_a_transmission_arbitrates_at_the_next_idle_bus() {
        let mut bus: TimedBus<8> = TimedBus::new(1_000_000);
        bus.submit(Instant::ZERO, 5, frame(0x705, &[5]))
            .expect("room");
        // Ready 10 µs later, while 705h is on the wire: lower identifiers do not preempt.
        bus.submit(Instant::from_nanos(10_000), 1, frame(0x081, &[0; 8]))
            .expect("room");
        bus.submit(Instant::from_nanos(20_000), 2, frame(0x181, &[0; 2]))
            .expect("room");
        let order: heapless::Vec<u32, 8> = drain(&mut bus).iter().map(|t| t.frame.id).collect();
        assert_eq!(order.as_slice(), &[0x705, 0x081, 0x181]);
    }

    /// 127 heartbeats at 125 kbit/s, all due at once, leave one after the other over the time the
    /// bit formula gives (55…65 bits each, 56…66 ms in all).
    #[test]
    fn heartbeats_of_127_nodes_spread_over_the_bit_time() {
        let mut bus: TimedBus<128> = TimedBus::new(125_000);
        for node in 1..=127u16 {
            bus.submit(Instant::ZERO, node, frame(0x700 + node, &[0x05]))
                .expect("room");
        }
        let tx = drain(&mut bus);
        assert_eq!(tx.len(), 127);
        let total_bits: u64 = tx.iter().map(|t| u64::from(frame_bits(&t.frame))).sum();
        let last = tx.last().expect("frames").end.as_nanos();
        assert_eq!(last, total_bits * 8_000);
        assert!(
            (127 * 55 * 8_000..=127 * 65 * 8_000).contains(&last),
            "{last} ns"
        );
        assert!(tx.windows(2).all(|w| w[0].frame.id < w[1].frame.id));
    }

    #[test]
    fn a_full_queue_refuses_the_frame() {
        let mut bus: TimedBus<2> = TimedBus::new(125_000);
        assert!(bus.submit(Instant::ZERO, 1, frame(1, &[])).is_ok());
        assert!(bus.submit(Instant::ZERO, 1, frame(2, &[])).is_ok());
        assert_eq!(bus.submit(Instant::ZERO, 1, frame(3, &[])), Err(QueueFull));
    }
}
