//! Wire faults as a link that wraps a link ([`crate::cell::link`]): each frame is judged by
//! the faults of its front end ([`crate::cell::wire_faults`]) before it reaches the inner
//! link; a lost frame goes no further, a delayed one is held here until its time and then
//! given back to the runtime ([`FaultInjector::release`]), which sends it on without judging
//! it again (it has had its fault). As smoltcp's `phy::FaultInjector`, but deterministic: a
//! share of frames is taken by a counter, so a run on the virtual clock is the same bit for
//! bit.

use od::time::earliest;
use od::Instant;

use crate::cell::link::{Addressed, At, Link};
use crate::cell::wire_faults::{Sender, Verdict, WireFaults};

/// A link with faults on its wire.
pub struct FaultInjector<L: Link>
where
    L::Frame: Sized,
{
    inner: L,
    faults: WireFaults,
    /// Frames a fault delays: when they arrive and the frame, in arrival order (a frame
    /// delayed to the same time as an earlier one comes after it).
    delayed: Vec<(Instant, L::Frame)>,
}

impl<L: Link> FaultInjector<L>
where
    L::Frame: Sized,
{
    /// `inner` with no fault yet.
    pub fn new(inner: L) -> Self {
        FaultInjector {
            inner,
            faults: WireFaults::default(),
            delayed: Vec::new(),
        }
    }

    /// The faults active on the link (to add, end and list them).
    pub fn faults_mut(&mut self) -> &mut WireFaults {
        &mut self.faults
    }

    /// The link it wraps.
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }

    /// The earliest delayed frame due by `now`, with the time it arrives (its fault's, not
    /// `now`); frames of the same time in the order they came.
    pub fn release(&mut self, now: Instant) -> Option<(Instant, L::Frame)> {
        if self.delayed.first().is_some_and(|(t, _)| *t <= now) {
            Some(self.delayed.remove(0))
        } else {
            None
        }
    }
}

impl<L: Link + Default> Default for FaultInjector<L>
where
    L::Frame: Sized,
{
    fn default() -> Self {
        Self::new(L::default())
    }
}

impl<L: Link> Link for FaultInjector<L>
where
    L::Frame: Addressed + Clone,
{
    type Frame = L::Frame;

    fn cross(&mut self, at: At, frame: &L::Frame) -> Verdict {
        match self.faults.judge(at.clock, frame.sender(), frame.id()) {
            Verdict::Pass => self.inner.cross(at, frame),
            Verdict::Delay(when) => {
                let i = self.delayed.partition_point(|(t, _)| *t <= when);
                self.delayed.insert(i, (when, frame.clone()));
                Verdict::Delay(when)
            }
            v @ (Verdict::Lost | Verdict::Corrupt) => v,
        }
    }

    fn cut_off(&self, at: Instant, who: Sender) -> bool {
        self.faults.cut_off(at, who) || self.inner.cut_off(at, who)
    }

    fn deadline(&self) -> Option<Instant> {
        earliest(self.delayed.first().map(|(t, _)| *t), self.inner.deadline())
    }

    fn unflushed(&self) -> bool {
        self.inner.unflushed()
    }

    fn flush(&mut self) {
        self.inner.flush()
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;
    use crate::cell::link::Wire;
    use crate::cell::wire_faults::{FaultKind, Reach, WireFault};
    use canopen::CanFrame;

    /// Counts the frames that reach it.
    #[derive(Default)]
    struct Counting(u32);

    impl Link for Counting {
        type Frame = CanFrame;
        fn cross(&mut self, _: At, _: &CanFrame) -> Verdict {
            self.0 += 1;
            Verdict::Pass
        }
    }

    fn fault(kind: FaultKind) -> WireFault {
        WireFault {
            reach: Reach::Outside,
            kind,
            cob_id: None,
            frames: None,
            lasting: None,
        }
    }

    fn at(ms: u64) -> At {
        At::on_clock(Instant::from_millis(ms))
    }

    fn frame(id: u16) -> CanFrame {
        CanFrame::new(id, &[]).unwrap()
    }

    #[test]
    fn a_lost_frame_never_reaches_the_inner_link() {
        let mut link = FaultInjector::new(Counting::default());
        link.faults_mut()
            .add(Instant::ZERO, fault(FaultKind::Drop { share: 0.5 }))
            .unwrap();
        let verdicts: Vec<Verdict> = (0..4).map(|_| link.cross(at(1), &frame(0x601))).collect();
        assert_eq!(
            verdicts,
            [Verdict::Pass, Verdict::Lost, Verdict::Pass, Verdict::Lost]
        );
        assert_eq!(link.inner_mut().0, 2);
    }

    #[test]
    fn delayed_frames_come_back_at_their_time_in_the_order_they_came() {
        let mut link: FaultInjector<Wire<CanFrame>> = FaultInjector::default();
        let id = link
            .faults_mut()
            .add(
                Instant::ZERO,
                fault(FaultKind::Delay {
                    by: Duration::from_millis(10),
                }),
            )
            .unwrap();
        assert_eq!(
            link.cross(at(0), &frame(1)),
            Verdict::Delay(Instant::from_millis(10))
        );
        assert_eq!(
            link.cross(at(0), &frame(2)),
            Verdict::Delay(Instant::from_millis(10))
        );
        link.faults_mut().remove(id).unwrap();
        // Without the fault a frame passes at once, ahead of those held.
        assert_eq!(link.cross(at(1), &frame(3)), Verdict::Pass);
        assert_eq!(link.deadline(), Some(Instant::from_millis(10)));
        assert!(link.release(Instant::from_millis(9)).is_none());
        let released: Vec<(Instant, u32)> =
            std::iter::from_fn(|| link.release(Instant::from_millis(20)))
                .map(|(t, f)| (t, f.id))
                .collect();
        let ten = Instant::from_millis(10);
        assert_eq!(released, [(ten, 1), (ten, 2)]);
        assert_eq!(link.deadline(), None);
    }

    #[test]
    fn a_cut_cable_cuts_off_its_node() {
        let mut link: FaultInjector<Wire<CanFrame>> = FaultInjector::default();
        link.faults_mut()
            .add(
                Instant::ZERO,
                WireFault::cable_break(Reach::Node(3), Some(Duration::from_millis(5))),
            )
            .unwrap();
        assert!(link.cut_off(Instant::from_millis(1), Sender::Node(3)));
        assert!(!link.cut_off(Instant::from_millis(1), Sender::Node(4)));
        assert!(!link.cut_off(Instant::from_millis(5), Sender::Node(3)));
    }
}
