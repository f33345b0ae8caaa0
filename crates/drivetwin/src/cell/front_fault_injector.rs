//! Wire faults on the link of one front end of the cell: a Modbus TCP server, an EtherCAT
//! chain, a single socketcand client. A link that wraps the front end's link
//! ([`crate::cell::link::FrontLink`]), as smoltcp's `phy::FaultInjector` wraps a device:
//! each frame is judged by the front end's faults ([`crate::cell::wire_faults`]) as it
//! crosses; one that passes goes on to the inner link, a lost one goes no further, a delayed
//! one is held here until its time. Then a frame that came in is given back to the runtime
//! ([`FrontFaultInjector::release`]), which takes it in without judging it again, and one
//! that goes out is handed to the inner link ([`FrontLink::transmit_held`]).
//!
//! Unlike a bus, a front end's link is a stream (a TCP connection, the master's sequence of
//! frames): a frame never overtakes one held before it on the same way. A frame the faults
//! let pass while an earlier one is held waits behind it, and a delayed one arrives no
//! earlier than the one before it. A link has two ways: in (a request, a master's frame, a
//! client's frame to the bus) and out (the bus's frames to a client); each keeps its own
//! order, and one set of faults judges both (a share of frames is counted over both). A
//! server's answers and a chain's returning frames follow what came in, so their faults
//! judge the way in alone ([`FrontFaultInjector::inbound`]).
//!
//! A passing frame is handed on at once: nothing is buffered for it and nothing allocated
//! (a held frame is kept by value).

use std::borrow::Borrow;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use od::time::earliest;
use od::Instant;

use crate::cell::link::{Addressed, At, FrontLink};
use crate::cell::wire_faults::{Sender, Verdict, WireFaults};

/// The order in which frames were held, over every front end of the cell: each held frame
/// takes the next number. Each front end's injector holds a clone of the cell's count.
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
#[derive(Debug, Clone, Default)]
pub struct Arrivals(Arc<AtomicU64>);

impl Arrivals {
    fn next(&self) -> u64 {
        // One thread runs the cell: the count needs no ordering with other memory.
        self.0.fetch_add(1, Ordering::Relaxed)
    }
}

/// A frame a fault held back: when it arrives, when it crossed, its number in [`Arrivals`],
/// the frame.
#[derive(Debug)]
struct Held<F> {
    at: Instant,
    crossed: At,
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

    /// What the faults make of a frame crossing this way at `at`; a held one is kept from
    /// `frame` (called only then, so a passing frame costs no copy).
    fn cross(
        &mut self,
        faults: &mut WireFaults,
        at: At,
        id: u32,
        arrivals: &Arrivals,
        frame: impl FnOnce() -> F,
    ) -> Verdict {
        let behind = self.0.back().map(|h| h.at);
        let due = match (faults.judge(at.clock, Sender::Outside, id), behind) {
            (v @ (Verdict::Lost | Verdict::Corrupt), _) => return v,
            (Verdict::Delay(due), b) => b.map_or(due, |b| b.max(due)),
            (Verdict::Pass, Some(b)) => b,
            (Verdict::Pass, None) => return Verdict::Pass,
        };
        self.0.push_back(Held {
            at: due,
            crossed: at,
            arrival: arrivals.next(),
            frame: frame(),
        });
        Verdict::Delay(due)
    }
}

/// What an injector gave back at a frame's time.
#[derive(Debug, PartialEq, Eq)]
pub enum Released<I> {
    /// A frame from the peer, for the cell to take in now, with the time it arrives (its
    /// fault's).
    In(Instant, I),
    /// A frame to the peer went on to the inner link, at this time.
    Out(Instant),
}

/// The frames a front end's peer sends, as an injector keeps them.
pub type HeldIn<L> = <<L as FrontLink>::In as ToOwned>::Owned;
type HeldOut<L> = <<L as FrontLink>::Out as ToOwned>::Owned;

/// A front end's link `L` with faults on its wire, and the frames they hold.
pub struct FrontFaultInjector<L: FrontLink>
where
    L::In: ToOwned,
    L::Out: ToOwned,
{
    inner: L,
    faults: WireFaults,
    /// Whether the faults judge the way out as well as the way in.
    judges_out: bool,
    arrivals: Arrivals,
    inbound: HeldFrames<HeldIn<L>>,
    outbound: HeldFrames<HeldOut<L>>,
}

impl<L: FrontLink> FrontFaultInjector<L>
where
    L::In: ToOwned,
    L::Out: ToOwned,
{
    /// `inner` with no fault yet, its faults judging both ways; frames it holds are counted
    /// in `arrivals`, the cell's.
    pub fn new(inner: L, arrivals: Arrivals) -> Self {
        FrontFaultInjector {
            inner,
            faults: WireFaults::default(),
            judges_out: true,
            arrivals,
            inbound: HeldFrames::new(),
            outbound: HeldFrames::new(),
        }
    }

    /// As [`FrontFaultInjector::new`], the faults judging only what comes in (a server's
    /// requests, a master's frames): what goes out answers it.
    pub fn inbound(inner: L, arrivals: Arrivals) -> Self {
        FrontFaultInjector {
            judges_out: false,
            ..Self::new(inner, arrivals)
        }
    }

    /// The faults active on the link (to add, end and list them).
    pub fn faults_mut(&mut self) -> &mut WireFaults {
        &mut self.faults
    }

    /// The link it wraps.
    pub fn inner(&self) -> &L {
        &self.inner
    }

    /// The link it wraps.
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }

    /// Forgets the frames held on either way (the peer's stream is gone).
    pub fn forget_held(&mut self) {
        self.inbound.0.clear();
        self.outbound.0.clear();
    }

    /// The arrival number ([`Arrivals`]) of the earliest held frame due by `now`, of either
    /// way: the runtime releases, of all its front ends, the one with the lowest first.
    pub fn due(&self, now: Instant) -> Option<u64> {
        match (self.inbound.due(now), self.outbound.due(now)) {
            (Some(i), Some(o)) => Some(i.min(o)),
            (i, o) => i.or(o),
        }
    }

    /// The earliest held frame due by `now`, of either way: one that came in is given back,
    /// one that goes out is handed to the inner link.
    pub fn release(&mut self, now: Instant) -> Option<Released<HeldIn<L>>> {
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
            let h = self.outbound.0.pop_front()?;
            self.inner.transmit_held(h.crossed, h.frame.borrow());
            Some(Released::Out(h.at))
        }
    }
}

impl<L: FrontLink> FrontLink for FrontFaultInjector<L>
where
    L::In: Addressed + ToOwned,
    L::Out: Addressed + ToOwned,
{
    type In = L::In;
    type Out = L::Out;

    fn receive(&mut self, at: At, frame: &L::In) -> Verdict {
        match self
            .inbound
            .cross(&mut self.faults, at, frame.id(), &self.arrivals, || {
                frame.to_owned()
            }) {
            Verdict::Pass => self.inner.receive(at, frame),
            v => v,
        }
    }

    fn transmit(&mut self, at: At, frame: &L::Out) -> Verdict {
        if !self.judges_out {
            return self.inner.transmit(at, frame);
        }
        match self
            .outbound
            .cross(&mut self.faults, at, frame.id(), &self.arrivals, || {
                frame.to_owned()
            }) {
            Verdict::Pass => self.inner.transmit(at, frame),
            v => v,
        }
    }

    fn transmit_held(&mut self, at: At, frame: &L::Out) {
        self.inner.transmit_held(at, frame);
    }

    fn deadline(&self) -> Option<Instant> {
        earliest(
            earliest(self.inbound.deadline(), self.outbound.deadline()),
            self.inner.deadline(),
        )
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

    fn at(t: u64) -> At {
        At::on_clock(ms(t))
    }

    /// A numbered frame.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    struct F(u32);

    impl Addressed for F {
        fn sender(&self) -> Sender {
            Sender::Outside
        }
        fn id(&self) -> u32 {
            0
        }
    }

    /// The peer's end: what it took in and what it sent, with the times.
    #[derive(Debug, Default)]
    struct Peer {
        received: Vec<u32>,
        sent: Vec<(Instant, u32)>,
    }

    impl FrontLink for Peer {
        type In = F;
        type Out = F;
        fn receive(&mut self, _: At, f: &F) -> Verdict {
            self.received.push(f.0);
            Verdict::Pass
        }
        fn transmit(&mut self, at: At, f: &F) -> Verdict {
            self.sent.push((at.clock, f.0));
            Verdict::Pass
        }
    }

    type Link = FrontFaultInjector<Peer>;

    fn link(arrivals: &Arrivals) -> Link {
        Link::new(Peer::default(), arrivals.clone())
    }

    #[test]
    fn a_frame_passes_at_once_when_nothing_is_held() {
        let mut link = link(&Arrivals::default());
        assert_eq!(link.receive(at(0), &F(1)), Verdict::Pass);
        assert_eq!(link.inner().received, [1]);
        assert_eq!(link.deadline(), None);
    }

    #[test]
    fn a_lost_frame_is_not_held() {
        let mut link = link(&Arrivals::default());
        link.faults_mut()
            .add(ms(0), fault(FaultKind::Drop { share: 1.0 }))
            .unwrap();
        assert_eq!(link.receive(at(0), &F(1)), Verdict::Lost);
        assert_eq!(link.deadline(), None);
        assert!(link.inner().received.is_empty());
    }

    #[test]
    fn a_frame_never_overtakes_one_held_on_its_way() {
        let mut link = link(&Arrivals::default());
        let id = link.faults_mut().add(ms(0), delay(10)).unwrap();
        assert_eq!(link.receive(at(0), &F(1)), Verdict::Delay(ms(10)));
        link.faults_mut().remove(id).unwrap();
        // No fault now, but frame 1 is held: frame 2 waits behind it.
        assert_eq!(link.receive(at(1), &F(2)), Verdict::Delay(ms(10)));
        // A shorter delay after a longer one arrives no earlier than the one before it.
        link.faults_mut().add(ms(2), delay(3)).unwrap();
        assert_eq!(link.receive(at(2), &F(3)), Verdict::Delay(ms(10)));
        assert_eq!(link.deadline(), Some(ms(10)));
        assert_eq!(link.release(ms(9)), None);
        let released: Vec<_> = std::iter::from_fn(|| link.release(ms(10))).collect();
        assert_eq!(
            released,
            [
                Released::In(ms(10), F(1)),
                Released::In(ms(10), F(2)),
                Released::In(ms(10), F(3))
            ]
        );
        // Given back to the runtime, not to the inner link.
        assert!(link.inner().received.is_empty());
        // Nothing held: a frame passes again.
        assert_eq!(link.receive(at(11), &F(4)), Verdict::Delay(ms(14)));
    }

    #[test]
    fn each_way_keeps_its_own_order() {
        let mut link = link(&Arrivals::default());
        let id = link.faults_mut().add(ms(0), delay(10)).unwrap();
        assert_eq!(link.receive(at(0), &F(1)), Verdict::Delay(ms(10)));
        link.faults_mut().remove(id).unwrap();
        // The way out holds nothing: its frame passes, ahead of the one held on the way in.
        assert_eq!(link.transmit(at(1), &F(2)), Verdict::Pass);
        link.faults_mut().add(ms(2), delay(2)).unwrap();
        assert_eq!(link.transmit(at(2), &F(3)), Verdict::Delay(ms(4)));
        assert_eq!(link.deadline(), Some(ms(4)));
        assert_eq!(link.release(ms(5)), Some(Released::Out(ms(4))));
        assert_eq!(link.release(ms(5)), None);
        assert_eq!(link.release(ms(10)), Some(Released::In(ms(10), F(1))));
        // A held frame goes out as it crossed: the inner link has it with its own time.
        assert_eq!(link.inner().sent, [(ms(1), 2), (ms(2), 3)]);
    }

    #[test]
    fn both_ways_due_come_back_in_the_order_they_arrived() {
        let mut link = link(&Arrivals::default());
        link.faults_mut().add(ms(0), delay(10)).unwrap();
        link.transmit(at(0), &F(1));
        link.receive(at(0), &F(2));
        link.transmit(at(1), &F(3));
        assert_eq!(link.due(ms(9)), None);
        assert_eq!(link.due(ms(11)), Some(0));
        let released: Vec<_> = std::iter::from_fn(|| link.release(ms(11))).collect();
        assert_eq!(
            released,
            [
                Released::Out(ms(10)),
                Released::In(ms(10), F(2)),
                Released::Out(ms(11))
            ]
        );
        assert_eq!(link.inner().sent, [(ms(0), 1), (ms(1), 3)]);
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
                Some(Released::In(at, f)) => order.push((at, f.0)),
                other => panic!("{other:?}"),
            }
        }
    }

    #[test]
    fn front_ends_due_at_once_are_released_in_the_order_they_arrived() {
        // Two front ends sharing the cell's arrival count: A delays by 10 ms, B by 2 ms.
        let arrivals = Arrivals::default();
        let mut links = [link(&arrivals), link(&arrivals)];
        links[0].faults_mut().add(ms(0), delay(10)).unwrap();
        links[1].faults_mut().add(ms(0), delay(2)).unwrap();
        let [a, b] = &mut links;
        assert_eq!(a.receive(at(0), &F(1)), Verdict::Delay(ms(10)));
        assert_eq!(b.receive(at(1), &F(2)), Verdict::Delay(ms(3)));
        assert_eq!(a.receive(at(2), &F(3)), Verdict::Delay(ms(12)));
        assert_eq!(b.receive(at(3), &F(4)), Verdict::Delay(ms(5)));
        // Due all at once: in the order they arrived, not by their times.
        let mut order = Vec::new();
        release_all(&mut links, ms(20), &mut order);
        assert_eq!(order, [(ms(10), 1), (ms(3), 2), (ms(12), 3), (ms(5), 4)]);
    }

    #[test]
    fn a_front_end_due_first_is_released_first() {
        let arrivals = Arrivals::default();
        let mut links = [link(&arrivals), link(&arrivals)];
        links[0].faults_mut().add(ms(0), delay(10)).unwrap();
        links[1].faults_mut().add(ms(0), delay(2)).unwrap();
        let [a, b] = &mut links;
        a.receive(at(0), &F(1));
        b.receive(at(1), &F(2));
        a.receive(at(2), &F(3));
        b.receive(at(3), &F(4));
        let mut order = Vec::new();
        for now in [ms(4), ms(11), ms(20)] {
            release_all(&mut links, now, &mut order);
        }
        assert_eq!(order, [(ms(3), 2), (ms(10), 1), (ms(5), 4), (ms(12), 3)]);
    }

    #[test]
    fn a_share_is_counted_over_both_ways() {
        let mut link = link(&Arrivals::default());
        link.faults_mut()
            .add(ms(0), fault(FaultKind::Drop { share: 0.5 }))
            .unwrap();
        assert_eq!(link.receive(at(0), &F(1)), Verdict::Pass);
        assert_eq!(link.transmit(at(0), &F(2)), Verdict::Lost);
        assert_eq!(link.transmit(at(0), &F(3)), Verdict::Pass);
        assert_eq!(link.receive(at(0), &F(4)), Verdict::Lost);
    }

    #[test]
    fn an_inbound_link_lets_everything_out() {
        let mut link = Link::inbound(Peer::default(), Arrivals::default());
        link.faults_mut()
            .add(ms(0), fault(FaultKind::Drop { share: 1.0 }))
            .unwrap();
        assert_eq!(link.transmit(at(0), &F(1)), Verdict::Pass);
        assert_eq!(link.receive(at(0), &F(2)), Verdict::Lost);
        assert_eq!(link.inner().sent, [(ms(0), 1)]);
    }
}
