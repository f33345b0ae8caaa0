//! The wire's side of the cell loop ([`crate::cell::wire_faults`]): faults of a bus go to its
//! cell, those of a Modbus server or an EtherCAT chain stay here; traces of a bus started and
//! stopped while the cell runs, and taps that see every frame of a bus, on the bus's link
//! ([`crate::trace::tracer::Tracer`]).

use std::time::Instant;

use canopen::CanFrame;

use super::CellLoop;
use crate::cell::wire_faults::{
    FrontEnd, Sender, Verdict, WireAnswer, WireError, WireFaults, WireRequest,
};
use crate::trace::TraceWriter;

/// What the faults of `front` make of a request or frame from outside at `now`.
pub(super) fn judge(
    faults: &mut [(FrontEnd, WireFaults)],
    front: FrontEnd,
    now: od::Instant,
) -> Verdict {
    match faults.iter_mut().find(|(fe, _)| *fe == front) {
        Some((_, f)) => f.judge(now, Sender::Outside, 0),
        None => Verdict::Pass,
    }
}

/// A Modbus request's bytes or an EtherCAT frame a `delay` fault holds back until `at` (the
/// cell's clock); later ones of the same front end wait behind it, so the order stays.
#[derive(Debug)]
pub(super) enum Held {
    Modbus {
        slot: usize,
        drive: usize,
        bytes: Vec<u8>,
        at: od::Instant,
    },
    Ethercat {
        chain: usize,
        frame: Vec<u8>,
        at: od::Instant,
    },
    /// A frame socketcand client `slot` (port `port`) sent to bus `bus`.
    FromClient {
        slot: usize,
        port: u16,
        bus: usize,
        frame: CanFrame,
        at: od::Instant,
    },
    /// A frame of the bus as socketcand text for client `slot` (port `port`).
    ToClient {
        slot: usize,
        port: u16,
        text: Vec<u8>,
        at: od::Instant,
    },
}

impl Held {
    pub(super) fn at(&self) -> od::Instant {
        match self {
            Held::Modbus { at, .. }
            | Held::Ethercat { at, .. }
            | Held::FromClient { at, .. }
            | Held::ToClient { at, .. } => *at,
        }
    }

    fn front(&self) -> FrontEnd {
        match self {
            Held::Modbus { drive, .. } => FrontEnd::Modbus(*drive),
            Held::Ethercat { chain, .. } => FrontEnd::Ethercat(*chain),
            Held::FromClient { port, .. } | Held::ToClient { port, .. } => FrontEnd::Client(*port),
        }
    }

    /// Held for client `slot`, in the direction `to_client`.
    fn is_client(&self, slot: usize, to_client: bool) -> bool {
        match self {
            Held::FromClient { slot: s, .. } => *s == slot && !to_client,
            Held::ToClient { slot: s, .. } => *s == slot && to_client,
            _ => false,
        }
    }
}

impl CellLoop {
    /// Whether what arrives now on `front` must wait: delayed by a fault until `delay`, or
    /// behind an earlier one still held. `None`: it is taken at once (or lost, `Some(None)`).
    pub(super) fn hold_until(
        &mut self,
        front: FrontEnd,
        t: od::Instant,
    ) -> Option<Option<od::Instant>> {
        let behind = self
            .held
            .iter()
            .filter(|h| h.front() == front)
            .map(Held::at)
            .max();
        match (judge(&mut self.front_faults, front, t), behind) {
            (Verdict::Lost | Verdict::Corrupt, _) => Some(None),
            (Verdict::Delay(at), b) => Some(Some(b.map_or(at, |b| b.max(at)))),
            (Verdict::Pass, Some(b)) => Some(Some(b)),
            (Verdict::Pass, None) => None,
        }
    }

    /// The earliest held request or frame.
    pub(super) fn held_deadline(&self) -> Option<Instant> {
        self.held.iter().map(Held::at).min().map(|t| self.wall(t))
    }

    /// Held requests and frames whose time has come arrive, in the order they came.
    pub(super) fn release_held(&mut self, now: Instant) {
        let t = self.now(now);
        while let Some(i) = self.held.iter().position(|h| h.at() <= t) {
            match self.held.remove(i) {
                Held::Modbus {
                    slot, drive, bytes, ..
                } => self.modbus_request(slot, drive, &bytes, t),
                Held::Ethercat { chain, frame, .. } => self.ethercat_frame(chain, frame, t),
                Held::FromClient {
                    slot, bus, frame, ..
                } => {
                    // Still connected: its frame reaches the bus now.
                    if self.slots.get(slot).is_some_and(Option::is_some) {
                        self.bus(bus, frame, super::Source::Client(slot), now);
                    }
                }
                Held::ToClient { slot, text, .. } => {
                    if let Some(Some(conn)) = self.slots.get_mut(slot) {
                        conn.pending.extend_from_slice(&text);
                        self.mark_dirty(slot);
                    }
                }
            }
        }
    }

    /// Whether some fault is on a single client (the per-frame check is skipped otherwise).
    pub(super) fn client_faults(&self) -> bool {
        self.front_faults
            .iter()
            .any(|(f, w)| matches!(f, FrontEnd::Client(_)) && !w.is_empty())
    }

    /// What the faults of client `port` (connection `slot`) make of frame `id` at `t` in one
    /// direction: `None` passes now, `Some(None)` is lost (dropped, corrupted: the checksum
    /// discards it, the cable cut), `Some(Some(at))` arrives then (behind what is held).
    pub(super) fn client_verdict(
        &mut self,
        slot: usize,
        port: u16,
        to_client: bool,
        id: u32,
        t: od::Instant,
    ) -> Option<Option<od::Instant>> {
        let front = FrontEnd::Client(port);
        let behind = self
            .held
            .iter()
            .filter(|h| h.is_client(slot, to_client))
            .map(Held::at)
            .max();
        let verdict = match self.front_faults.iter_mut().find(|(f, _)| *f == front) {
            Some((_, f)) => f.judge(t, Sender::Outside, id),
            None => Verdict::Pass,
        };
        match (verdict, behind) {
            (Verdict::Lost | Verdict::Corrupt, _) => Some(None),
            (Verdict::Delay(at), b) => Some(Some(b.map_or(at, |b| b.max(at)))),
            (Verdict::Pass, Some(b)) => Some(Some(b)),
            (Verdict::Pass, None) => None,
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
                    let bus = self.buses.get_mut(b).ok_or(WireError::NoFrontEnd(front))?;
                    return Ok(WireAnswer::Added(bus.cell.add_wire_fault(t, fault)?));
                }
                self.check_front(front)?;
                // A delayed Modbus request or EtherCAT frame is held in the loop until it is
                // due ([`Held`]).
                Ok(WireAnswer::Added(self.faults_of(front)?.add(t, fault)?))
            }
            WireRequest::Remove { front, id } => {
                if let FrontEnd::Bus(b) = front {
                    let bus = self.buses.get_mut(b).ok_or(WireError::NoFrontEnd(front))?;
                    bus.cell.remove_wire_fault(id)?;
                    return Ok(WireAnswer::Done);
                }
                self.check_front(front)?;
                self.faults_of(front)?.remove(id)?;
                Ok(WireAnswer::Done)
            }
            WireRequest::Clear { front } => {
                if let FrontEnd::Bus(b) = front {
                    let bus = self.buses.get_mut(b).ok_or(WireError::NoFrontEnd(front))?;
                    bus.cell.clear_wire_faults();
                    return Ok(WireAnswer::Done);
                }
                self.check_front(front)?;
                self.faults_of(front)?.clear();
                Ok(WireAnswer::Done)
            }
            WireRequest::List { front } => {
                if let FrontEnd::Bus(b) = front {
                    let bus = self.buses.get_mut(b).ok_or(WireError::NoFrontEnd(front))?;
                    return Ok(WireAnswer::Faults(bus.cell.wire_faults(t)));
                }
                self.check_front(front)?;
                Ok(WireAnswer::Faults(
                    self.faults_of(front)?.active(t).to_vec(),
                ))
            }
            WireRequest::StartTrace { bus, path } => {
                let b = self
                    .buses
                    .get_mut(bus)
                    .ok_or(WireError::NoFrontEnd(FrontEnd::Bus(bus)))?;
                if b.link.sink_mut().is_tracing() {
                    return Err(WireError::Tracing(bus));
                }
                let channel = format!("can{bus}");
                let w = TraceWriter::create_for_bus(&path, &channel, b.cell.timed_bitrate())
                    .map_err(|e| WireError::Trace(format!("{}: {e}", path.display())))?;
                b.link.sink_mut().start(w);
                Ok(WireAnswer::Done)
            }
            WireRequest::StopTrace { bus } => {
                let b = self
                    .buses
                    .get_mut(bus)
                    .ok_or(WireError::NoFrontEnd(FrontEnd::Bus(bus)))?;
                let mut w = b.link.sink_mut().stop().ok_or(WireError::NoTrace(bus))?;
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
                    .buses
                    .get_mut(bus)
                    .ok_or(WireError::NoFrontEnd(FrontEnd::Bus(bus)))?;
                b.link.sink_mut().tap(frames);
                Ok(WireAnswer::Done)
            }
        }
    }

    fn check_front(&self, front: FrontEnd) -> Result<(), WireError> {
        let there =
            match front {
                FrontEnd::Bus(b) => b < self.buses.len(),
                FrontEnd::Modbus(m) => m < self.modbus.len(),
                FrontEnd::Ethercat(c) => c < self.chains.len(),
                FrontEnd::Client(port) => self.slots.iter().flatten().any(|c| {
                    c.peer.port() == port && matches!(c.kind, super::Kind::Socketcand { .. })
                }),
            };
        if there {
            Ok(())
        } else {
            Err(WireError::NoFrontEnd(front))
        }
    }

    fn faults_of(&mut self, front: FrontEnd) -> Result<&mut WireFaults, WireError> {
        if !self.front_faults.iter().any(|(f, _)| *f == front) {
            self.front_faults.push((front, WireFaults::default()));
        }
        self.front_faults
            .iter_mut()
            .find(|(f, _)| *f == front)
            .map(|(_, w)| w)
            .ok_or(WireError::NoFrontEnd(front))
    }
}
