//! A link: the frame path of one bus or front end of the cell, where every frame crosses at
//! its time. What watches or disturbs the frames on the way is a link that wraps a link, as
//! smoltcp's `phy::Tracer` and `phy::FaultInjector` wrap a device, and wrappers stack:
//! [`crate::cell::fault_injector::FaultInjector`] applies the wire faults,
//! [`crate::cell::tracer::Tracer`] copies each frame to a trace file, taps or a pcap queue. The runtime
//! holds a wrapped link where it would otherwise hold a trace, taps and faults as fields of
//! its own; a [`Wire`] is the link itself, which carries every frame.
//!
//! A bus's link decides what becomes of a frame ([`Verdict`]); the runtime carries the frame
//! to the nodes on the bus, so a bus's link needs no buffer of its own and no allocation per
//! frame.
//!
//! A front end (a socketcand client, a Modbus TCP server, an EtherCAT chain) has a link of
//! its own to one peer, a [`FrontLink`], with a way in and a way out: the runtime offers it
//! what the peer sent ([`FrontLink::receive`]) and gives it what the cell sends
//! ([`FrontLink::transmit`]). The innermost link is the peer's end: a TCP connection's
//! [`SendBuffer`], which the runtime writes to the socket as the socket takes it, or the
//! chain's network interface. [`crate::cell::front_fault_injector::FrontFaultInjector`] and
//! [`crate::cell::tracer::Tracer`] wrap it, so the runtime holds one link per front end and
//! no trace or fault of its own.

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

/// A frame that is bytes (a Modbus request, an Ethernet frame): no identifier a fault could
/// filter on.
impl Addressed for [u8] {
    fn sender(&self) -> Sender {
        Sender::Outside
    }
    fn id(&self) -> u32 {
        0
    }
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

/// The link of one front end to its peer: a stream, with a way in (what the peer sends) and
/// a way out (what the cell sends it).
pub trait FrontLink {
    /// What the peer sends (a CAN frame, a request's bytes, an Ethernet frame).
    type In: ?Sized;
    /// What the cell sends the peer.
    type Out: ?Sized;

    /// `frame` came from the peer at `at`: [`Verdict::Pass`], the cell takes it in now;
    /// [`Verdict::Delay`], the link gives it back then; otherwise it is gone.
    fn receive(&mut self, at: At, frame: &Self::In) -> Verdict;

    /// `frame` goes to the peer at `at`: [`Verdict::Pass`], it is on its way (in the link's
    /// send buffer, or sent); [`Verdict::Delay`], the link sends it then; otherwise it is
    /// gone.
    fn transmit(&mut self, at: At, frame: &Self::Out) -> Verdict;

    /// `frame`, which crossed at `at` and was held back by a fault, goes out now: the link
    /// took it when it crossed, so it is written as then ([`FrontLink::transmit`] unless a
    /// link says otherwise).
    fn transmit_held(&mut self, at: At, frame: &Self::Out) {
        let _ = self.transmit(at, frame);
    }

    /// When the link next has a frame to give back or send by itself (one it delayed).
    fn deadline(&self) -> Option<Instant> {
        None
    }
}

/// The bytes a stream's peer has not taken yet: the way out of a TCP front end, written to
/// the socket by the runtime as the socket takes them (a client that does not read never
/// delays the others). Its capacity stays from frame to frame: no allocation per frame once
/// it has grown to the peer's pace.
#[derive(Debug, Default)]
pub struct SendBuffer(Vec<u8>);

impl SendBuffer {
    /// Empty, with room for `capacity` bytes.
    pub fn with_capacity(capacity: usize) -> Self {
        SendBuffer(Vec::with_capacity(capacity))
    }

    /// `bytes` after what waits.
    pub fn push(&mut self, bytes: &[u8]) {
        self.0.extend_from_slice(bytes);
    }

    /// What waits, first byte first.
    pub fn bytes(&self) -> &[u8] {
        &self.0
    }

    /// The first `n` bytes were written.
    pub fn consume(&mut self, n: usize) {
        self.0.drain(..n.min(self.0.len()));
    }

    pub fn len(&self) -> usize {
        self.0.len()
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Forgets what waits (its peer is gone).
    pub fn clear(&mut self) {
        self.0.clear();
    }

    /// The buffer itself, for an encoder that writes into a `Vec` (a Modbus answer).
    pub fn as_vec_mut(&mut self) -> &mut Vec<u8> {
        &mut self.0
    }
}

/// A byte stream whose peer's requests the cell takes in as they come and whose answers wait
/// in the buffer (a Modbus TCP connection).
impl FrontLink for SendBuffer {
    type In = [u8];
    type Out = [u8];

    fn receive(&mut self, _: At, _: &[u8]) -> Verdict {
        Verdict::Pass
    }

    fn transmit(&mut self, _: At, bytes: &[u8]) -> Verdict {
        self.push(bytes);
        Verdict::Pass
    }
}
