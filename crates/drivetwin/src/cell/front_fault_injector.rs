//! Wire faults on the link of one front end of the cell: a Modbus TCP server, an EtherCAT
//! chain, a single socketcand client. As [`crate::cell::fault_injector::FaultInjector`] on a
//! CAN bus, each frame is judged by the front end's faults ([`crate::cell::wire_faults`]) as
//! it crosses; a lost one goes no further, a delayed one is held here until its time and then
//! given back to the runtime ([`FrontFaultInjector::release`]), which takes it in then
//! without judging it again.
//!
//! Unlike a bus, a front end's link is a stream (a TCP connection, the master's sequence of
//! frames): a frame never overtakes one held before it on the same way. A frame the faults
//! let pass while an earlier one is held waits behind it, and a delayed one arrives no
//! earlier than the one before it. A link has two ways: in (a request, a master's frame, a
//! client's frame to the bus) and out (the bus's frames to a client); each keeps its own
//! order, and one set of faults judges both (a share of frames is counted over both).
//!
//! The injector holds no inner link: the front end's peer is the runtime's socket, and what
//! passes is handed on by the runtime at once, so nothing is buffered for a passing frame
//! and nothing is allocated for it (a held frame is kept by value).

use std::collections::VecDeque;

use od::time::earliest;
use od::Instant;

use crate::cell::wire_faults::{Sender, Verdict, WireFaults};

/// The order in which frames were held, over every front end of the cell: each held frame
/// takes the next number.
///
/// Shared by all the front ends' injectors because front ends meet in the cell: a client's
/// SDO request, an EtherCAT master's CoE write and a Modbus request can reach the same drive
/// (a chain's slave may be a drive on a bus as well). Frames due at the same turn are
/// therefore taken in across front ends in the order they arrived, so a drive sees writes
/// in the order the wires carried them, not in the order its front ends are looked at; the
/// order does not depend on the times the faults gave them either, so a run is the same bit
/// for bit. Within one way of one front end the order of arrival is also the order of time
/// (see the module doc), so the earliest arrival due is always at the head of some
/// injector's queue ([`FrontFaultInjector::due`]).
#[derive(Debug, Default)]
pub struct Arrivals(u64);

impl Arrivals {
    fn next(&mut self) -> u64 {
        let n = self.0;
        self.0 = self.0.wrapping_add(1);
        n
    }
}

/// A frame a fault held back: when it arrives, its number in [`Arrivals`], the frame.
#[derive(Debug)]
struct Held<F> {
    at: Instant,
    arrival: u64,
    frame: F,
}

/// The frames held on one way, in the order they came (`at` never decreasing).
#[derive(Debug)]
struct HeldFrames<F>(VecDeque<Held<F>>);

impl<F> HeldFrames<F> {
    fn new() -> Self {
        HeldFrames(VecDeque::new())
    }

    /// The arrival number of the first held frame when it is due by `now`.
    fn due(&self, now: Instant) -> Option<u64> {
        self.0.front().filter(|h| h.at <= now).map(|h| h.arrival)
    }

    fn deadline(&self) -> Option<Instant> {
        self.0.front().map(|h| h.at)
    }

    /// What the faults make of a frame coming on this way at `now`; a held one is kept from
    /// `frame`.
    fn cross(
        &mut self,
        faults: &mut WireFaults,
        now: Instant,
        id: u32,
        arrivals: &mut Arrivals,
        frame: impl FnOnce() -> F,
    ) -> Verdict {
        let behind = self.0.back().map(|h| h.at);
        let at = match (faults.judge(now, Sender::Outside, id), behind) {
            (v @ (Verdict::Lost | Verdict::Corrupt), _) => return v,
            (Verdict::Delay(at), b) => b.map_or(at, |b| b.max(at)),
            (Verdict::Pass, Some(b)) => b,
            (Verdict::Pass, None) => return Verdict::Pass,
        };
        self.0.push_back(Held {
            at,
            arrival: arrivals.next(),
            frame: frame(),
        });
        Verdict::Delay(at)
    }
}

/// A frame an injector gives back at its time, with the way it came and its time.
#[derive(Debug, PartialEq, Eq)]
pub enum Released<I, O> {
    In(Instant, I),
    Out(Instant, O),
}

/// The faults of one front end's link and the frames they hold, kept as `I` on the way in
/// and `O` on the way out.
#[derive(Debug)]
pub struct FrontFaultInjector<I, O = ()> {
    faults: WireFaults,
    inbound: HeldFrames<I>,
    outbound: HeldFrames<O>,
}

impl<I, O> Default for FrontFaultInjector<I, O> {
    fn default() -> Self {
        Self::new()
    }
}

impl<I, O> FrontFaultInjector<I, O> {
    /// A link with no fault yet.
    pub fn new() -> Self {
        FrontFaultInjector {
            faults: WireFaults::default(),
            inbound: HeldFrames::new(),
            outbound: HeldFrames::new(),
        }
    }

    /// The faults active on the link (to add, end and list them).
    pub fn faults_mut(&mut self) -> &mut WireFaults {
        &mut self.faults
    }

    /// A frame with identifier `id` (0 where the front end's frames have none) comes in at
    /// `now`: [`Verdict::Pass`], it is taken in at once; lost or corrupted, it
    /// is gone; [`Verdict::Delay`], it is held until then, kept as `frame` (called only
    /// then, so a passing frame costs no copy).
    pub fn cross_in(
        &mut self,
        now: Instant,
        id: u32,
        arrivals: &mut Arrivals,
        frame: impl FnOnce() -> I,
    ) -> Verdict {
        self.inbound
            .cross(&mut self.faults, now, id, arrivals, frame)
    }

    /// As [`FrontFaultInjector::cross_in`], on the way out.
    pub fn cross_out(
        &mut self,
        now: Instant,
        id: u32,
        arrivals: &mut Arrivals,
        frame: impl FnOnce() -> O,
    ) -> Verdict {
        self.outbound
            .cross(&mut self.faults, now, id, arrivals, frame)
    }

    /// When the link next gives a frame back.
    pub fn deadline(&self) -> Option<Instant> {
        earliest(self.inbound.deadline(), self.outbound.deadline())
    }

    /// The arrival number ([`Arrivals`]) of the earliest held frame due by `now`, of either
    /// way: the runtime releases, of all its front ends, the one with the lowest first.
    pub fn due(&self, now: Instant) -> Option<u64> {
        match (self.inbound.due(now), self.outbound.due(now)) {
            (Some(i), Some(o)) => Some(i.min(o)),
            (i, o) => i.or(o),
        }
    }

    /// The earliest held frame due by `now`, of either way, with the time it arrives (its
    /// fault's, not `now`).
    pub fn release(&mut self, now: Instant) -> Option<Released<I, O>> {
        let inbound = match (self.inbound.due(now), self.outbound.due(now)) {
            (Some(i), Some(o)) => i < o,
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (None, None) => return None,
        };
        if inbound {
            self.inbound
                .0
                .pop_front()
                .map(|h| Released::In(h.at, h.frame))
        } else {
            self.outbound
                .0
                .pop_front()
                .map(|h| Released::Out(h.at, h.frame))
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;
    use crate::cell::wire_faults::{FaultKind, Reach, WireFault};

    fn fault(kind: FaultKind) -> WireFault {
        WireFault {
            reach: Reach::Outside,
            kind,
            cob_id: None,
            frames: None,
            lasting: None,
        }
    }

    fn delay(ms: u64) -> WireFault {
        fault(FaultKind::Delay {
            by: Duration::from_millis(ms),
        })
    }

    fn ms(t: u64) -> Instant {
        Instant::from_millis(t)
    }

    type Link = FrontFaultInjector<u32, u32>;

    #[test]
    fn a_frame_passes_at_once_when_nothing_is_held() {
        let mut link = Link::new();
        let mut arrivals = Arrivals::default();
        let verdict = link.cross_in(ms(0), 0, &mut arrivals, || unreachable!("not kept"));
        assert_eq!(verdict, Verdict::Pass);
        assert_eq!(link.deadline(), None);
    }

    #[test]
    fn a_lost_frame_is_not_held() {
        let mut link = Link::new();
        let mut arrivals = Arrivals::default();
        link.faults_mut()
            .add(ms(0), fault(FaultKind::Drop { share: 1.0 }))
            .unwrap();
        assert_eq!(link.cross_in(ms(0), 0, &mut arrivals, || 1), Verdict::Lost);
        assert_eq!(link.deadline(), None);
    }

    #[test]
    fn a_frame_never_overtakes_one_held_on_its_way() {
        let mut link = Link::new();
        let mut arrivals = Arrivals::default();
        let id = link.faults_mut().add(ms(0), delay(10)).unwrap();
        assert_eq!(
            link.cross_in(ms(0), 0, &mut arrivals, || 1),
            Verdict::Delay(ms(10))
        );
        link.faults_mut().remove(id).unwrap();
        // No fault now, but frame 1 is held: frame 2 waits behind it.
        assert_eq!(
            link.cross_in(ms(1), 0, &mut arrivals, || 2),
            Verdict::Delay(ms(10))
        );
        // A shorter delay after a longer one arrives no earlier than the one before it.
        link.faults_mut().add(ms(2), delay(3)).unwrap();
        assert_eq!(
            link.cross_in(ms(2), 0, &mut arrivals, || 3),
            Verdict::Delay(ms(10))
        );
        assert_eq!(link.deadline(), Some(ms(10)));
        assert_eq!(link.release(ms(9)), None);
        let released: Vec<_> = std::iter::from_fn(|| link.release(ms(10))).collect();
        assert_eq!(
            released,
            [
                Released::In(ms(10), 1),
                Released::In(ms(10), 2),
                Released::In(ms(10), 3)
            ]
        );
        // Nothing held: a frame passes again.
        assert_eq!(
            link.cross_in(ms(11), 0, &mut arrivals, || 4),
            Verdict::Delay(ms(14))
        );
    }

    #[test]
    fn each_way_keeps_its_own_order() {
        let mut link = Link::new();
        let mut arrivals = Arrivals::default();
        let id = link.faults_mut().add(ms(0), delay(10)).unwrap();
        assert_eq!(
            link.cross_in(ms(0), 0, &mut arrivals, || 1),
            Verdict::Delay(ms(10))
        );
        link.faults_mut().remove(id).unwrap();
        // The way out holds nothing: its frame passes, ahead of the one held on the way in.
        assert_eq!(link.cross_out(ms(1), 0, &mut arrivals, || 2), Verdict::Pass);
        link.faults_mut().add(ms(2), delay(2)).unwrap();
        assert_eq!(
            link.cross_out(ms(2), 0, &mut arrivals, || 3),
            Verdict::Delay(ms(4))
        );
        assert_eq!(link.deadline(), Some(ms(4)));
        assert_eq!(link.release(ms(5)), Some(Released::Out(ms(4), 3)));
        assert_eq!(link.release(ms(5)), None);
        assert_eq!(link.release(ms(10)), Some(Released::In(ms(10), 1)));
    }

    #[test]
    fn both_ways_due_come_back_in_the_order_they_arrived() {
        let mut link = Link::new();
        let mut arrivals = Arrivals::default();
        link.faults_mut().add(ms(0), delay(10)).unwrap();
        link.cross_out(ms(0), 0, &mut arrivals, || 1);
        link.cross_in(ms(0), 0, &mut arrivals, || 2);
        link.cross_out(ms(1), 0, &mut arrivals, || 3);
        assert_eq!(link.due(ms(9)), None);
        assert_eq!(link.due(ms(11)), Some(0));
        let released: Vec<_> = std::iter::from_fn(|| link.release(ms(11))).collect();
        assert_eq!(
            released,
            [
                Released::Out(ms(10), 1),
                Released::In(ms(10), 2),
                Released::Out(ms(11), 3)
            ]
        );
    }

    /// Releases, as the runtime does, of the front ends' frames due by `now` the one that
    /// arrived first, until none is due.
    fn release_all(links: &mut [Link], now: Instant, order: &mut Vec<(Instant, u32)>) {
        loop {
            let next = links
                .iter()
                .enumerate()
                .filter_map(|(i, l)| l.due(now).map(|a| (a, i)))
                .min();
            let Some((_, i)) = next else { break };
            match links[i].release(now) {
                Some(Released::In(at, f)) => order.push((at, f)),
                other => panic!("{other:?}"),
            }
        }
    }

    #[test]
    fn front_ends_due_at_once_are_released_in_the_order_they_arrived() {
        // Two front ends sharing the cell's arrival count: A delays by 10 ms, B by 2 ms.
        let mut links = [Link::new(), Link::new()];
        let mut arrivals = Arrivals::default();
        links[0].faults_mut().add(ms(0), delay(10)).unwrap();
        links[1].faults_mut().add(ms(0), delay(2)).unwrap();
        let [a, b] = &mut links;
        assert_eq!(
            a.cross_in(ms(0), 0, &mut arrivals, || 1),
            Verdict::Delay(ms(10))
        );
        assert_eq!(
            b.cross_in(ms(1), 0, &mut arrivals, || 2),
            Verdict::Delay(ms(3))
        );
        assert_eq!(
            a.cross_in(ms(2), 0, &mut arrivals, || 3),
            Verdict::Delay(ms(12))
        );
        assert_eq!(
            b.cross_in(ms(3), 0, &mut arrivals, || 4),
            Verdict::Delay(ms(5))
        );
        // Due all at once: in the order they arrived, not by their times.
        let mut order = Vec::new();
        release_all(&mut links, ms(20), &mut order);
        assert_eq!(order, [(ms(10), 1), (ms(3), 2), (ms(12), 3), (ms(5), 4)]);
    }

    #[test]
    fn a_front_end_due_first_is_released_first() {
        let mut links = [Link::new(), Link::new()];
        let mut arrivals = Arrivals::default();
        links[0].faults_mut().add(ms(0), delay(10)).unwrap();
        links[1].faults_mut().add(ms(0), delay(2)).unwrap();
        let [a, b] = &mut links;
        a.cross_in(ms(0), 0, &mut arrivals, || 1);
        b.cross_in(ms(1), 0, &mut arrivals, || 2);
        a.cross_in(ms(2), 0, &mut arrivals, || 3);
        b.cross_in(ms(3), 0, &mut arrivals, || 4);
        let mut order = Vec::new();
        for now in [ms(4), ms(11), ms(20)] {
            release_all(&mut links, now, &mut order);
        }
        assert_eq!(order, [(ms(3), 2), (ms(10), 1), (ms(5), 4), (ms(12), 3)]);
    }

    #[test]
    fn a_share_is_counted_over_both_ways() {
        let mut link = Link::new();
        let mut arrivals = Arrivals::default();
        link.faults_mut()
            .add(ms(0), fault(FaultKind::Drop { share: 0.5 }))
            .unwrap();
        assert_eq!(link.cross_in(ms(0), 0, &mut arrivals, || 1), Verdict::Pass);
        assert_eq!(link.cross_out(ms(0), 0, &mut arrivals, || 2), Verdict::Lost);
        assert_eq!(link.cross_out(ms(0), 0, &mut arrivals, || 3), Verdict::Pass);
        assert_eq!(link.cross_in(ms(0), 0, &mut arrivals, || 4), Verdict::Lost);
    }
}
