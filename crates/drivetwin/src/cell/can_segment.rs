//! A CAN segment: one simulated CAN bus of a cell ([`SegmentBus`]), between stations of the
//! cell's list ([`super::can_cell::CanCell`]), which it names by id. Frames a
//! station sends reach the other stations of the segment as well as the bus's front ends; with
//! a bit rate ([`super::bus_timing`]) they do so when they have crossed the bus, after the
//! arbitration. Each station's CAN controller counts its errors ([`NodeFaults`]), and the wire
//! carries its faults ([`super::wire_faults`]).
//!
//! A bus has two links, both its own: the wire between its stations, a
//! [`FaultInjector`] around a [`Wire`], which judges each transmission at its end of frame,
//! and its port, the bus as its front ends see it (a socketcand client, the SocketCAN
//! interface, a scenario's trace), a [`Tracer`] around a [`Wire`], which every frame from
//! outside crosses as it comes and every station's frame as it leaves the segment, and whose
//! sink ([`CanTrace`]) is the bus's trace file and taps. Neither the cell loop nor the
//! scenario rig keeps a trace or a fault of the bus's.

use std::collections::VecDeque;

use canbus::fault_confinement::{FaultConfinement, Transition, ERROR_FRAME_BITS};
use canbus::frame_time::bits_to_nanos;
use canopen::CanFrame;
use od::{time::earliest, Instant};

use super::bus_timing::{BusFigures, BusTiming, OUTSIDE};
use super::fault_injector::FaultInjector;
use super::link::{Addressed, At, Link, Wire};
use super::station::Station;
use super::stations::{StationId, Stations};
use super::tracer::{CanTrace, Tracer};
use super::wire_faults::{ActiveFault, Sender, Verdict, WireFault, WireFaultError};

/// A frame on the segment as its link sees it: the frame, the station that sent it (segment
/// order; none: from outside the segment) and that drive's node-ID, by which faults take it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SegmentFrame {
    pub frame: CanFrame,
    pub origin: Option<usize>,
    pub sender: Sender,
}

impl Addressed for SegmentFrame {
    fn sender(&self) -> Sender {
        self.sender
    }
    fn id(&self) -> u32 {
        self.frame.id
    }
}

/// Decision: the instant bus has no bit time, but a bus-off node still needs one
/// to count its recovery (128 × 11 recessive bits): that of 1 Mbit/s.
const UNTIMED_BITRATE: u32 = 1_000_000;

/// The bus of a CAN segment: the stations on it, named by id in the cell's [`Stations`], and
/// the model between them (arbitration, each station's CAN controller, the wire's faults).
pub struct SegmentBus {
    /// The stations on the bus, in segment order.
    members: Vec<StationId>,
    queue: VecDeque<(CanFrame, Option<usize>)>,
    /// The bus's bit time; none: frames cross at once (the instant bus).
    timing: Option<Box<BusTiming>>,
    /// Each drive's CAN controller: error counters and the transmit errors still to inject.
    faults: Vec<NodeFaults>,
    /// Disturbances the cell file plans: at a time, the node whose frames fail, how many.
    planned: Vec<(Instant, u8, u32)>,
    /// A planned change of one of its stations was carried out ([`super::planned`]): the
    /// bus polls by then, so the station's frames go out at the change's time.
    poll_by: Option<Instant>,
    /// The wire between the stations and the front ends, with its faults ([`super::wire_faults`]),
    /// which hold the frames they delay.
    wire: FaultInjector<Wire<SegmentFrame>>,
    /// The bus as its front ends see it: traced and tapped.
    port: Tracer<Wire<CanFrame>, CanTrace>,
    /// When asked for ([`SegmentBus::report_outside_frames`]): the frames from outside that
    /// crossed the bus, with their end of frame and whether a drive received them.
    outside_ends: Option<Vec<(Instant, CanFrame, bool)>>,
}

/// One drive's CAN controller.
#[derive(Debug, Clone, Copy, Default)]
pub struct NodeFaults {
    pub confinement: FaultConfinement,
    /// Its next transmissions that fail with an error frame.
    pub disturb: u32,
}

/// What became of one transmission attempt.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Attempt {
    Delivered,
    /// An error frame: the sender tries again if it is still on the bus.
    Failed,
    /// The sender is off the bus.
    Dropped,
}

/// Station `i` (segment order) of `members` in `stations`.
fn member<'a>(
    stations: &'a mut Stations,
    members: &[StationId],
    i: usize,
) -> Option<&'a mut Station> {
    stations.station_mut(*members.get(i)?)
}

impl SegmentBus {
    /// The bus between `members` (segment order), without a bit rate.
    pub fn new(members: Vec<StationId>) -> Self {
        let faults = vec![NodeFaults::default(); members.len()];
        SegmentBus {
            members,
            queue: VecDeque::new(),
            timing: None,
            faults,
            planned: Vec::new(),
            poll_by: None,
            wire: FaultInjector::default(),
            port: Tracer::new(Wire::new(), CanTrace::default()),
            outside_ends: None,
        }
    }

    /// The bus as its front ends see it: every frame on it crosses this link once (from
    /// outside as it comes, a station's as it leaves the segment), which traces and taps it
    /// (its sink, a [`CanTrace`]).
    pub fn port(&self) -> &Tracer<Wire<CanFrame>, CanTrace> {
        &self.port
    }

    /// The bus as its front ends see it, to pass a frame, start or stop its trace, add a tap.
    pub fn port_mut(&mut self) -> &mut Tracer<Wire<CanFrame>, CanTrace> {
        &mut self.port
    }

    /// The stations on the bus, in segment order.
    pub fn members(&self) -> &[StationId] {
        &self.members
    }

    /// The segment order of station `id`, if it is on this bus.
    pub(super) fn position(&self, id: StationId) -> Option<usize> {
        self.members.iter().position(|m| *m == id)
    }

    /// A station of the bus changed at `at` (a planned change): the bus polls by then.
    pub(super) fn poll_by(&mut self, at: Instant) {
        self.poll_by = earliest(self.poll_by, Some(at));
    }

    /// The bus's stations in `stations`, in segment order.
    pub fn stations<'a>(&'a self, stations: &'a Stations) -> impl Iterator<Item = &'a Station> {
        self.members.iter().filter_map(|id| stations.station(*id))
    }

    /// Why a drive's load FMU stopped the cell, once one has (the first such drive's error).
    pub fn load_failure<'a>(
        &self,
        stations: &'a Stations,
    ) -> Option<&'a crate::cosim::FmuLoadError> {
        self.members
            .iter()
            .filter_map(|id| stations.station(*id))
            .find_map(|d| d.model.drive()?.load_failure())
    }

    /// From now on, every frame from outside that crosses the bus is kept for
    /// [`SegmentBus::take_outside_frames`] (an FMI-LS-BUS terminal confirms its master's).
    pub fn report_outside_frames(&mut self) {
        self.outside_ends.get_or_insert_with(Vec::new);
    }

    /// The frames from outside that crossed the bus since the last call: end of frame, the
    /// frame, and whether at least one drive received it (its acknowledgement). Drained, so
    /// the list keeps its room for the next ones (no allocation per step).
    pub fn take_outside_frames(&mut self) -> impl Iterator<Item = (Instant, CanFrame, bool)> + '_ {
        self.outside_ends
            .as_mut()
            .into_iter()
            .flat_map(|ends| ends.drain(..))
    }

    /// Whether `frame`, from outside at `now`, would wait for the bus: a timed bus that is
    /// busy or has a frame waiting that wins the arbitration (never on the instant bus).
    pub fn would_wait(&self, now: Instant, frame: &CanFrame) -> bool {
        self.timing
            .as_ref()
            .is_some_and(|t| t.would_wait(now, frame))
    }

    /// The bus takes the time a real one does at `bitrate` bit/s; a frame waiting longer
    /// than `late_after` for it counts as late.
    pub fn with_bitrate(mut self, bitrate: u32, late_after: std::time::Duration) -> Self {
        self.set_bitrate(bitrate, late_after);
        self
    }

    /// As [`SegmentBus::with_bitrate`], on a bus of a cell.
    pub fn set_bitrate(&mut self, bitrate: u32, late_after: std::time::Duration) {
        self.timing = Some(Box::new(BusTiming::new(bitrate, late_after)));
    }

    /// The bus's bit rate, if it has one (`bitrate` on its `[[bus]]`).
    pub fn timed_bitrate(&self) -> Option<u32> {
        self.timing.as_ref().map(|t| t.bitrate())
    }

    /// The bus's figures as of `now` (none on the instant bus).
    pub fn bus_figures(&mut self, now: Instant) -> Option<BusFigures> {
        self.timing.as_mut().map(|t| t.figures(now))
    }

    /// The next `frames` transmissions of station `id` fail with an error frame (a disturbed
    /// line at its connector): 16 make it error passive, 32 take it off the bus. False: the
    /// station is not on the bus.
    pub fn disturb(&mut self, id: StationId, frames: u32) -> bool {
        match self.position(id) {
            Some(drive) => self.disturb_at(drive, frames),
            None => false,
        }
    }

    /// [`SegmentBus::disturb`] of the station at `drive` in segment order.
    fn disturb_at(&mut self, drive: usize, frames: u32) -> bool {
        self.fit_faults();
        match self.faults.get_mut(drive) {
            Some(f) => {
                f.disturb = f.disturb.saturating_add(frames);
                true
            }
            None => false,
        }
    }

    /// Plans [`disturb`](Self::disturb) of the drive with node-ID `node` at `at`.
    pub fn plan_disturbance(&mut self, at: Instant, node: u8, frames: u32) {
        self.planned.push((at, node, frames));
    }

    /// Starts a fault on the bus's wire at `now` ([`super::wire_faults`]); its id.
    pub fn add_wire_fault(
        &mut self,
        now: Instant,
        fault: WireFault,
    ) -> Result<u32, WireFaultError> {
        self.wire.faults_mut().add(now, fault)
    }

    /// Ends wire fault `id`.
    pub fn remove_wire_fault(&mut self, id: u32) -> Result<(), WireFaultError> {
        self.wire.faults_mut().remove(id)
    }

    /// Ends every wire fault; frames already delayed still arrive.
    pub fn clear_wire_faults(&mut self) {
        self.wire.faults_mut().clear();
    }

    /// The wire faults active at `now`.
    pub fn wire_faults(&mut self, now: Instant) -> Vec<ActiveFault> {
        self.wire.faults_mut().active(now).to_vec()
    }

    /// Each station's CAN controller, with the station's id (in segment order).
    pub fn node_faults(&self) -> impl Iterator<Item = (StationId, &NodeFaults)> {
        self.members.iter().copied().zip(self.faults.iter())
    }

    /// Boots every drive of the bus; the boot-up messages go to `out`.
    pub fn boot(&mut self, stations: &mut Stations, now: Instant, out: &mut Vec<CanFrame>) {
        self.fit_faults();
        let SegmentBus { members, queue, .. } = self;
        for (i, id) in members.iter().enumerate() {
            if let Some(d) = stations.station_mut(*id) {
                d.boot(now, &mut |f| queue.push_back((f, Some(i))));
            }
        }
        self.deliver(stations, now, out);
    }

    /// A frame from the bus (not from one of this segment's stations). With a bit rate it enters
    /// the arbitration now and reaches the drives when it has crossed the bus.
    pub fn on_frame(
        &mut self,
        stations: &mut Stations,
        now: Instant,
        frame: &CanFrame,
        out: &mut Vec<CanFrame>,
    ) {
        if let Some(t) = self.timing.as_mut() {
            t.submit(now, OUTSIDE, *frame);
            self.deliver(stations, now, out);
            return;
        }
        self.attempt(stations, None, frame, now, out, true);
        self.deliver(stations, now, out);
    }

    /// A local interface (a serial port, a terminal) of station `id` reaches its objects at
    /// `now` through `f`; the frames the drive sends meanwhile go to `out` (nothing happens
    /// for a station not on the bus).
    pub fn local_access(
        &mut self,
        stations: &mut Stations,
        id: StationId,
        now: Instant,
        out: &mut Vec<CanFrame>,
        f: &mut dyn FnMut(&mut dyn od::ObjectAccess),
    ) {
        let Some(drive) = self.position(id) else {
            return;
        };
        let SegmentBus { members, queue, .. } = self;
        let Some(d) = member(stations, members, drive) else {
            return;
        };
        d.local_access(now, &mut |fr| queue.push_back((fr, Some(drive))), f);
        self.deliver(stations, now, out);
    }

    /// Runs the drives' timers; returns the next deadline.
    pub fn poll(
        &mut self,
        stations: &mut Stations,
        now: Instant,
        out: &mut Vec<CanFrame>,
    ) -> Option<Instant> {
        self.fit_faults();
        self.poll_by = None;
        self.start_planned(stations, now);
        self.release_delayed(stations, now, out);
        let SegmentBus {
            members,
            queue,
            faults,
            ..
        } = self;
        for (i, (id, f)) in members.iter().zip(faults.iter_mut()).enumerate() {
            let Some(d) = stations.station_mut(*id) else {
                continue;
            };
            if let Some(t) = f.confinement.poll(now) {
                d.can_state_changed(now, t, &mut |f| queue.push_back((f, Some(i))));
            }
            d.poll(now, &mut |f| queue.push_back((f, Some(i))));
        }
        self.deliver(stations, now, out);
        self.deadline(stations)
    }

    pub fn deadline(&self, stations: &Stations) -> Option<Instant> {
        let bus = self.timing.as_ref().and_then(|t| t.deadline());
        let planned = earliest(self.planned.iter().map(|(t, _, _)| *t).min(), self.poll_by);
        let planned = earliest(planned, self.wire.deadline());
        let recovery = self
            .faults
            .iter()
            .filter_map(|f| f.confinement.deadline())
            .min();
        self.stations(stations)
            .fold(earliest(earliest(bus, planned), recovery), |acc, d| {
                earliest(acc, d.deadline())
            })
    }

    /// A station added after the bus was made gets its controller.
    fn fit_faults(&mut self) {
        self.faults
            .resize(self.members.len(), NodeFaults::default());
    }

    /// Delayed frames due by `now` arrive (they have had their fault; on a timed bus they
    /// do not queue for the bus again).
    fn release_delayed(&mut self, stations: &mut Stations, now: Instant, out: &mut Vec<CanFrame>) {
        while let Some((at, f)) = self.wire.release(now) {
            while self.attempt(stations, f.origin, &f.frame, at, out, false) == Attempt::Failed {}
        }
        self.deliver(stations, now, out);
    }

    fn start_planned(&mut self, stations: &Stations, now: Instant) {
        let mut i = 0;
        while let Some(&(at, node, frames)) = self.planned.get(i) {
            if at > now {
                i += 1;
                continue;
            }
            self.planned.swap_remove(i);
            let on_bus = self
                .members
                .iter()
                .position(|id| stations.station(*id).is_some_and(|d| d.node_id() == node));
            match on_bus {
                Some(d) => {
                    self.disturb_at(d, frames);
                }
                None => tracing::warn!(node, "disturbance planned for a node not on the bus"),
            }
        }
    }

    /// The bus's bit rate (without one, 1 Mbit/s: the fastest CAN bus).
    pub fn bitrate(&self) -> u32 {
        self.timing
            .as_ref()
            .map_or(UNTIMED_BITRATE, |t| t.bitrate())
    }

    /// Sends queued frames to the bus and to every other station of the segment, in order; with a
    /// bit rate, they enter the arbitration and go out as they cross the bus.
    fn deliver(&mut self, stations: &mut Stations, now: Instant, out: &mut Vec<CanFrame>) {
        if self.timing.is_some() {
            self.cross(stations, now, out);
            return;
        }
        while let Some((frame, origin)) = self.queue.pop_front() {
            // A failed frame is sent again at once, until it passes or its node is off.
            while self.attempt(stations, origin, &frame, now, out, true) == Attempt::Failed {}
        }
    }

    /// Timed bus: the drives' new frames enter the arbitration at `now`; every frame that has
    /// crossed by `now` goes out (a drive's) and to the other drives at its end of frame,
    /// whose answers enter the arbitration then. A failed frame tries again after its error
    /// frame.
    fn cross(&mut self, stations: &mut Stations, now: Instant, out: &mut Vec<CanFrame>) {
        self.submit_queue(now);
        while let Some(tx) = self.timing.as_mut().and_then(|t| t.poll(now)) {
            let origin = (tx.source != OUTSIDE).then_some(usize::from(tx.source));
            if self.attempt(stations, origin, &tx.frame, tx.end, out, true) == Attempt::Failed {
                let bitrate = self.bitrate();
                let again = Instant::from_nanos(
                    tx.end.as_nanos() + bits_to_nanos(ERROR_FRAME_BITS, bitrate),
                );
                if let Some(t) = self.timing.as_mut() {
                    t.submit(again, tx.source, tx.frame);
                }
            }
            self.submit_queue(tx.end);
        }
    }

    /// The drives' frames enter the arbitration at `at`; a node off the bus sends nothing.
    fn submit_queue(&mut self, at: Instant) {
        let SegmentBus {
            queue,
            timing,
            faults,
            ..
        } = self;
        let Some(timing) = timing.as_mut() else {
            return;
        };
        while let Some((frame, origin)) = queue.pop_front() {
            if origin.is_some_and(|i| faults.get(i).is_some_and(|f| !f.confinement.on_bus())) {
                continue;
            }
            let source = origin
                .and_then(|i| u16::try_from(i).ok())
                .unwrap_or(OUTSIDE);
            timing.submit(at, source, frame);
        }
    }

    /// One transmission of `frame` by `origin` (`None`: from outside) ending at `at`: an
    /// error frame when the sender is disturbed, else the frame on the bus, to `out` (a
    /// drive's) and to every other drive on the bus. The controllers count either. With
    /// `judge`, the wire's faults decide first what becomes of the frame.
    fn attempt(
        &mut self,
        stations: &mut Stations,
        origin: Option<usize>,
        frame: &CanFrame,
        at: Instant,
        out: &mut Vec<CanFrame>,
        judge: bool,
    ) -> Attempt {
        let bitrate = self.bitrate();
        let sender = match origin
            .and_then(|i| self.members.get(i))
            .and_then(|id| stations.station(*id))
        {
            Some(d) => Sender::Node(d.node_id()),
            None => Sender::Outside,
        };
        let verdict = if judge {
            let f = SegmentFrame {
                frame: *frame,
                origin,
                sender,
            };
            self.wire.cross(At::on_clock(at), &f)
        } else {
            Verdict::Pass
        };
        match verdict {
            Verdict::Pass | Verdict::Corrupt => {}
            // Decision: a frame of a node whose cable is cut, or dropped, is simply not on
            // the bus; the node's controller is not made to count missing acknowledgements.
            Verdict::Lost => return Attempt::Dropped,
            // Held by the link until its time ([`SegmentBus::release_delayed`]).
            Verdict::Delay(_) => return Attempt::Delivered,
        }
        let corrupt = verdict == Verdict::Corrupt;
        let SegmentBus {
            members,
            queue,
            faults,
            wire: link,
            ..
        } = self;
        let members: &[StationId] = members;
        if corrupt && origin.is_none() {
            // ISO 11898-1: every receiver sees the CRC fail and counts it; the outside
            // sender's own retransmission is its host's, not simulated: the frame is lost.
            for j in 0..members.len() {
                let node = member(stations, members, j).map_or(0, |d| d.node_id());
                if link.cut_off(at, Sender::Node(node)) {
                    continue;
                }
                let t = faults
                    .get_mut(j)
                    .and_then(|f| f.confinement.receive_error());
                if let (Some(t), Some(d)) = (t, member(stations, members, j)) {
                    d.can_state_changed(at, t, &mut |f| queue.push_back((f, Some(j))));
                }
            }
            return Attempt::Dropped;
        }
        let react = |stations: &mut Stations,
                     queue: &mut VecDeque<(CanFrame, Option<usize>)>,
                     i: usize,
                     t: Option<Transition>| {
            if let (Some(t), Some(d)) = (t, member(stations, members, i)) {
                d.can_state_changed(at, t, &mut |f| queue.push_back((f, Some(i))));
            }
        };
        if let Some(i) = origin {
            let Some(f) = faults.get_mut(i) else {
                return Attempt::Dropped;
            };
            if !f.confinement.on_bus() {
                return Attempt::Dropped;
            }
            if corrupt || f.disturb > 0 {
                if !corrupt {
                    f.disturb -= 1;
                }
                let t = f.confinement.transmit_error(at, bitrate);
                react(stations, queue, i, t);
                for j in 0..faults.len() {
                    if j != i {
                        let t = faults
                            .get_mut(j)
                            .and_then(|f| f.confinement.receive_error());
                        react(stations, queue, j, t);
                    }
                }
                let on_bus = faults.get(i).is_some_and(|f| f.confinement.on_bus());
                return if on_bus {
                    Attempt::Failed
                } else {
                    Attempt::Dropped
                };
            }
            let t = f.confinement.transmit_ok();
            react(stations, queue, i, t);
            if !link.cut_off(at, Sender::Outside) {
                out.push(*frame);
            }
        }
        let mut received = false;
        for j in 0..members.len() {
            if Some(j) == origin {
                continue;
            }
            let node = member(stations, members, j).map_or(0, |d| d.node_id());
            if link.cut_off(at, Sender::Node(node)) {
                continue;
            }
            let Some(f) = faults.get_mut(j) else {
                continue;
            };
            if !f.confinement.on_bus() {
                continue;
            }
            let t = f.confinement.receive_ok();
            react(stations, queue, j, t);
            received = true;
            if let Some(d) = member(stations, members, j) {
                d.on_can_frame(at, frame, &mut |f| queue.push_back((f, Some(j))));
            }
        }
        if let (None, Some(ends)) = (origin, self.outside_ends.as_mut()) {
            ends.push((at, *frame, received));
        }
        Attempt::Delivered
    }
}
