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
pub struct FaultInjector<L: Link> {
    inner: L,
    faults: WireFaults,
    /// Frames a fault delays: when they arrive and the frame, in arrival order (a frame
    /// delayed to the same time as an earlier one comes after it).
    delayed: Vec<(Instant, L::Frame)>,
}

impl<L: Link> FaultInjector<L> {
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

impl<L: Link + Default> Default for FaultInjector<L> {
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
