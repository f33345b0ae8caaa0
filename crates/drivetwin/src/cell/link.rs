//! A link: the frame path of one bus or front end of the cell, where every frame crosses at
//! its time. What watches or disturbs the frames on the way is a link that wraps a link, as
//! smoltcp's `phy::Tracer` and `phy::FaultInjector` wrap a device, and wrappers stack:
//! [`crate::cell::fault_injector::FaultInjector`] applies the wire faults,
//! `crate::trace::tracer::Tracer` copies each frame to a trace file, taps or a pcap queue. The runtime
//! holds a wrapped link where it would otherwise hold a trace, taps and faults as fields of
//! its own; a [`Wire`] is the link itself, which carries every frame.
//!
//! A link decides what becomes of a frame ([`Verdict`]); the runtime carries the frame to
//! the nodes on the link, so a link needs no buffer of its own and no allocation per frame.

use std::marker::PhantomData;
use std::time::Duration;

use canopen::CanFrame;
use od::Instant;

use crate::cell::wire_faults::{Sender, Verdict};

/// When a frame crosses a link: on the cell's clock, and by the wall clock as traces and
/// socketcand stamp it (on the virtual clock both are the cell's).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct At {
    pub clock: Instant,
    /// Since the Unix epoch (real time) or since the clock's zero (virtual time).
    pub stamp: Duration,
}

impl At {
    /// `clock` on the cell's clock, stamped with the same time (the virtual clock's, or a
    /// link whose frames are never written with a wall-clock stamp).
    pub fn on_clock(clock: Instant) -> At {
        At {
            clock,
            stamp: Duration::from_nanos(clock.as_nanos()),
        }
    }
}

/// What a link's frame says about itself to the wrappers that judge it.
pub trait Addressed {
    /// Who sent it, as the faults see it.
    fn sender(&self) -> Sender;
    /// Its identifier (a CAN identifier; 0 where a front end's frames have none).
    fn id(&self) -> u32;
}

impl Addressed for CanFrame {
    /// A frame seen on the bus from outside the cell's drives.
    fn sender(&self) -> Sender {
        Sender::Outside
    }
    fn id(&self) -> u32 {
        self.id
    }
}

/// The frame path of one bus or front end.
pub trait Link {
    /// What crosses it (a CAN frame, an Ethernet frame's bytes).
    type Frame: ?Sized;

    /// `frame` crosses the link at `at`: whether it arrives now, later or never.
    fn cross(&mut self, at: At, frame: &Self::Frame) -> Verdict;

    /// Whether `who` is cut off from the link at `at`: it neither sends nor receives.
    fn cut_off(&self, _at: Instant, _who: Sender) -> bool {
        false
    }

    /// When the link next has a frame to give back by itself (one it delayed).
    fn deadline(&self) -> Option<Instant> {
        None
    }

    /// Whether the link holds written frames not yet flushed out (a trace's buffer).
    fn unflushed(&self) -> bool {
        false
    }

    /// Writes out what the link buffers; a failure is logged, never stops the cell.
    fn flush(&mut self) {}
}

/// The wire itself: every frame passes, at once.
#[derive(Debug)]
pub struct Wire<F: ?Sized>(PhantomData<fn(&F)>);

impl<F: ?Sized> Wire<F> {
    pub fn new() -> Self {
        Wire(PhantomData)
    }
}

impl<F: ?Sized> Default for Wire<F> {
    fn default() -> Self {
        Self::new()
    }
}

impl<F: ?Sized> Link for Wire<F> {
    type Frame = F;

    fn cross(&mut self, _: At, _: &F) -> Verdict {
        Verdict::Pass
    }
}
