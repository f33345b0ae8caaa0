//! The wire's side of the cell loop ([`crate::cell::wire_faults`]): faults of a bus go to its
//! wire ([`crate::cell::can_segment::SegmentBus`]); those of a Modbus server, an EtherCAT chain or a single socketcand client to the
//! [`FrontFaultInjector`] wrapping that front end's link, which holds the frames they delay
//! until the loop releases them, across front ends in the order they arrived; traces of a bus
//! started and stopped while the cell runs, and taps that see every frame of a bus, on the
//! bus's port ([`crate::cell::can_segment::SegmentBus::port`], a
//! [`crate::cell::tracer::Tracer`]): the bus holds its faults and its trace, the loop neither.

use std::time::Instant;

use od::time::earliest;

use super::{CellLoop, Connection, Kind};
use crate::cell::front_fault_injector::{FrontFaultInjector, Released};
use crate::cell::link::FrontLink;
use crate::cell::wire_faults::{FrontEnd, WireAnswer, WireError, WireFaults, WireRequest};
use crate::trace::TraceWriter;

/// The front end whose held frame is due first.
enum Holder {
    Modbus(usize),
    Chain(usize),
    /// A socketcand client, by its connection.
    Client(usize),
}

impl CellLoop {
    /// The earliest held request or frame, of every front end.
    pub(super) fn held_deadline(&self) -> Option<Instant> {
        let mut at = None;
        for m in &self.modbus_links {
            at = earliest(at, m.deadline());
        }
        for c in &self.chains {
            at = earliest(at, c.link.deadline());
        }
        for c in self.slots.iter().flatten() {
            if let Kind::Socketcand { link, .. } = &c.kind {
                at = earliest(at, link.deadline());
            }
        }
        at.map(|t| self.wall(t))
    }

    /// Of the held requests and frames due by `t`, the front end of the one that arrived
    /// first ([`crate::cell::front_fault_injector::Arrivals`]).
    fn first_due(&self, t: od::Instant) -> Option<Holder> {
        let mut first: Option<(u64, Holder)> = None;
        let mut take = |arrival: Option<u64>, holder: Holder| {
            if let Some(a) = arrival {
                if first.as_ref().is_none_or(|(f, _)| a < *f) {
                    first = Some((a, holder));
                }
            }
        };
        for (d, m) in self.modbus_links.iter().enumerate() {
            take(m.due(t), Holder::Modbus(d));
        }
        for (c, chain) in self.chains.iter().enumerate() {
            take(chain.link.inner().due(t), Holder::Chain(c));
        }
        for (slot, c) in self.slots.iter().enumerate() {
            if let Some(Connection {
                kind: Kind::Socketcand { link, .. },
                ..
            }) = c
            {
                take(link.due(t), Holder::Client(slot));
            }
        }
        first.map(|(_, h)| h)
    }

    /// Held requests and frames whose time has come arrive, in the order they came, across
    /// front ends as well.
    pub(super) fn release_held(&mut self, now: Instant) {
        let t = self.now(now);
        while let Some(holder) = self.first_due(t) {
            match holder {
                Holder::Modbus(drive) => {
                    let Some(Released::In(_, bytes)) =
                        self.modbus_links.get_mut(drive).and_then(|m| m.release(t))
                    else {
                        break;
                    };
                    // Answered on the connection it came on: held requests go with their
                    // connection when it closes.
                    if let Some(slot) = self.modbus_slot(drive) {
                        self.modbus_request(slot, drive, &bytes, t);
                    }
                }
                Holder::Chain(c) => {
                    let Some(Released::In(_, frame)) = self
                        .chains
                        .get_mut(c)
                        .and_then(|ch| ch.link.inner_mut().release(t))
                    else {
                        break;
                    };
                    self.ethercat_frame(c, frame, t);
                }
                Holder::Client(slot) => {
                    let Some(Some(Connection {
                        kind: Kind::Socketcand { link, bus, .. },
                        ..
                    })) = self.slots.get_mut(slot)
                    else {
                        break;
                    };
                    match link.release(t) {
                        // Its frame reaches the bus now.
                        Some(Released::In(_, frame)) => {
                            let bus = *bus;
                            self.bus(bus, frame, super::Source::Client(slot), now);
                        }
                        // The bus's frame is in its send buffer now.
                        Some(Released::Out(_)) => self.mark_dirty(slot),
                        None => break,
                    }
                }
            }
        }
    }

    pub(super) fn wire(
        &mut self,
        request: WireRequest,
        now: Instant,
    ) -> Result<WireAnswer, WireError> {
        let t = self.now(now);
        match request {
            WireRequest::Now => Ok(WireAnswer::Now(now.saturating_duration_since(self.origin))),
            WireRequest::Add { front, fault } => {
                if let FrontEnd::Bus(b) = front {
                    let bus = self.cell.bus_mut(b).ok_or(WireError::NoFrontEnd(front))?;
                    return Ok(WireAnswer::Added(bus.add_wire_fault(t, fault)?));
                }
                self.check_front(front)?;
                // A delayed request or frame is held by the front end's link until it is due
                // ([`FrontFaultInjector`]).
                Ok(WireAnswer::Added(self.faults_of(front)?.add(t, fault)?))
            }
            WireRequest::Remove { front, id } => {
                if let FrontEnd::Bus(b) = front {
                    let bus = self.cell.bus_mut(b).ok_or(WireError::NoFrontEnd(front))?;
                    bus.remove_wire_fault(id)?;
                    return Ok(WireAnswer::Done);
                }
                self.check_front(front)?;
                self.faults_of(front)?.remove(id)?;
                Ok(WireAnswer::Done)
            }
            WireRequest::Clear { front } => {
                if let FrontEnd::Bus(b) = front {
                    let bus = self.cell.bus_mut(b).ok_or(WireError::NoFrontEnd(front))?;
                    bus.clear_wire_faults();
                    return Ok(WireAnswer::Done);
                }
                self.check_front(front)?;
                self.faults_of(front)?.clear();
                Ok(WireAnswer::Done)
            }
            WireRequest::List { front } => {
                if let FrontEnd::Bus(b) = front {
                    let bus = self.cell.bus_mut(b).ok_or(WireError::NoFrontEnd(front))?;
                    return Ok(WireAnswer::Faults(bus.wire_faults(t)));
                }
                self.check_front(front)?;
                Ok(WireAnswer::Faults(
                    self.faults_of(front)?.active(t).to_vec(),
                ))
            }
            WireRequest::StartTrace { bus, path } => {
                let b = self
                    .cell
                    .bus_mut(bus)
                    .ok_or(WireError::NoFrontEnd(FrontEnd::Bus(bus)))?;
                if b.port_mut().sink_mut().is_tracing() {
                    return Err(WireError::Tracing(bus));
                }
                let channel = format!("can{bus}");
                let w = TraceWriter::create_for_bus(&path, &channel, b.timed_bitrate())
                    .map_err(|e| WireError::Trace(format!("{}: {e}", path.display())))?;
                b.port_mut().sink_mut().start(Box::new(w));
                Ok(WireAnswer::Done)
            }
            WireRequest::StopTrace { bus } => {
                let b = self
                    .cell
                    .bus_mut(bus)
                    .ok_or(WireError::NoFrontEnd(FrontEnd::Bus(bus)))?;
                let mut w = b
                    .port_mut()
                    .sink_mut()
                    .stop()
                    .ok_or(WireError::NoTrace(bus))?;
                w.flush().map_err(|e| WireError::Trace(e.to_string()))?;
                Ok(WireAnswer::Done)
            }
            WireRequest::Send { bus, frame } => {
                if bus >= self.buses.len() {
                    return Err(WireError::NoFrontEnd(FrontEnd::Bus(bus)));
                }
                // Decision: as from a client that is none of the connected ones (no slot has
                // this number), so that every client, the interface and the drives get it.
                self.bus(bus, frame, super::Source::Client(usize::MAX), now);
                self.flush_dirty();
                Ok(WireAnswer::Done)
            }
            WireRequest::Tap { bus, frames } => {
                let b = self
                    .cell
                    .bus_mut(bus)
                    .ok_or(WireError::NoFrontEnd(FrontEnd::Bus(bus)))?;
                b.port_mut().sink_mut().tap(frames);
                Ok(WireAnswer::Done)
            }
        }
    }

    fn check_front(&self, front: FrontEnd) -> Result<(), WireError> {
        let there = match front {
            FrontEnd::Bus(b) => b < self.buses.len(),
            FrontEnd::Modbus(m) => m < self.modbus.len(),
            FrontEnd::Ethercat(c) => c < self.chains.len(),
            FrontEnd::Client(port) => self
                .slots
                .iter()
                .flatten()
                .any(|c| c.peer.port() == port && matches!(c.kind, Kind::Socketcand { .. })),
        };
        if there {
            Ok(())
        } else {
            Err(WireError::NoFrontEnd(front))
        }
    }

    /// The faults of `front`'s link (a bus's are its cell's); a client by its port.
    fn faults_of(&mut self, front: FrontEnd) -> Result<&mut WireFaults, WireError> {
        let faults = match front {
            FrontEnd::Bus(_) => None,
            FrontEnd::Modbus(m) => self
                .modbus_links
                .get_mut(m)
                .map(FrontFaultInjector::faults_mut),
            FrontEnd::Ethercat(c) => self
                .chains
                .get_mut(c)
                .map(|c| c.link.inner_mut().faults_mut()),
            FrontEnd::Client(port) => {
                self.slots
                    .iter_mut()
                    .flatten()
                    .find_map(|c| match &mut c.kind {
                        Kind::Socketcand { link, .. } if c.peer.port() == port => {
                            Some(link.faults_mut())
                        }
                        _ => None,
                    })
            }
        };
        faults.ok_or(WireError::NoFrontEnd(front))
    }
}
