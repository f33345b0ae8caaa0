//! socketcand on the loop: the clients of a bus's server, their sessions' messages and
//! timers ([`crate::can::socketcand::session`]), and the server a bus joins
//! (`--socketcand-join`), whose frames are on the bus as any client's are.

use std::io::{self, Read, Write};
use std::time::Instant;

use mio::{Interest, Token};

use super::{CellLoop, Connection, Kind, Source, MAX_PENDING, READS_PER_TURN};
use crate::can::socketcand::client_link::ClientStream;
use crate::can::socketcand::session::{Effect, Session};
use crate::can::socketcand::Decoder;
use crate::cell::front_fault_injector::FrontFaultInjector;
use crate::cell::link::{At, FrontLink};
use crate::cell::wire_faults::Verdict;

impl CellLoop {
    pub(super) fn session_timers(&mut self, slot: usize, now: Instant) {
        let Some(Some(conn)) = self.slots.get_mut(slot) else {
            return;
        };
        let Kind::Socketcand { link, bus, .. } = &mut conn.kind else {
            return;
        };
        let totals = self.buses.get(*bus).map(|b| b.totals).unwrap_or_default();
        let client = link.inner_mut();
        if client.session.deadline().is_none_or(|d| d > now) {
            return;
        }
        let was_streaming = client.session.is_streaming();
        let effects = &mut self.effects;
        client.session.poll(now, totals, &mut |e| effects.push(e));
        if client.session.is_streaming() && !was_streaming {
            client.start_stream();
        }
        self.carry_out(slot, now);
        self.mark_dirty(slot);
    }

    pub(super) fn accept_socketcand(&mut self, b: usize) {
        loop {
            let Some((listener, config)) = self.buses.get(b).and_then(|x| x.socketcand.as_ref())
            else {
                return;
            };
            let (max, max_len) = (config.max_clients, config.max_message_len);
            match listener.accept() {
                Ok((stream, peer)) => {
                    let clients = self
                        .slots
                        .iter()
                        .flatten()
                        .filter(|c| matches!(c.kind, Kind::Socketcand { bus, .. } if bus == b))
                        .count();
                    if clients >= max {
                        tracing::warn!(%peer, max, "socketcand: too many clients, refusing");
                        // Best effort, never blocks the loop.
                        let _ = (&stream).write(b"< error too many clients >");
                        continue;
                    }
                    let bitrate = self.cell.bus(b).map_or(1_000_000, |x| x.bitrate());
                    let kind = Kind::Socketcand {
                        bus: b,
                        decoder: Decoder::with_max_len(max_len),
                        budget: crate::can::frame_budget::FrameBudget::for_bitrate(bitrate),
                        link: Box::new(FrontFaultInjector::new(
                            ClientStream::new(),
                            self.arrivals.clone(),
                        )),
                    };
                    tracing::info!(%peer, "socketcand client connected");
                    if let Some(slot) = self.add(stream, peer, kind) {
                        self.send_text(slot, Session::HELLO.to_string().as_bytes());
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    // E.g. out of file descriptors: the next connection tries again.
                    tracing::warn!(error = %e, "socketcand: accept failed");
                    return;
                }
            }
        }
    }

    pub(super) fn socketcand_messages(&mut self, slot: usize, now: Instant) {
        loop {
            let Some(Some(conn)) = self.slots.get_mut(slot) else {
                return;
            };
            let Kind::Socketcand {
                link, decoder, bus, ..
            } = &mut conn.kind
            else {
                return;
            };
            let Some(message) = decoder.next_message() else {
                return;
            };
            let Some((_, config)) = self.buses.get(*bus).and_then(|b| b.socketcand.as_ref()) else {
                return;
            };
            let effects = &mut self.effects;
            link.inner_mut()
                .session
                .on_message(config, now, message, &mut |e| effects.push(e));
            self.carry_out(slot, now);
        }
    }

    /// What a session asked for.
    pub(super) fn carry_out(&mut self, slot: usize, now: Instant) {
        let mut effects = std::mem::take(&mut self.effects);
        for effect in effects.drain(..) {
            match effect {
                Effect::Reply(m) => self.send_text(slot, m.to_string().as_bytes()),
                Effect::Open => {}
                Effect::SkipPending => {
                    if let Some(Some(Connection {
                        kind: Kind::Socketcand { link, .. },
                        ..
                    })) = self.slots.get_mut(slot)
                    {
                        link.inner_mut().skip_held();
                    }
                }
                Effect::Send(frame) => {
                    let t = self.now(now);
                    if let Some(Some(Connection {
                        kind:
                            Kind::Socketcand {
                                bus, budget, link, ..
                            },
                        peer,
                        ..
                    })) = self.slots.get_mut(slot)
                    {
                        if !budget.take(now) {
                            if budget.dropped == 1 {
                                // Once per client, not per frame.
                                tracing::warn!(%peer, "client sends faster than the bus carries: frames beyond its rate dropped");
                            }
                            continue;
                        }
                        let bus = *bus;
                        match link.receive(At::on_clock(t), &frame) {
                            Verdict::Pass => {}
                            // Lost, or held by the client's link until its time.
                            Verdict::Lost | Verdict::Corrupt | Verdict::Delay(_) => continue,
                        }
                        self.bus(bus, frame, Source::Client(slot), now);
                    }
                }
                Effect::Close => {
                    if let Some(Some(conn)) = self.slots.get_mut(slot) {
                        conn.closing = true;
                    }
                }
            }
        }
        self.effects = effects;
    }

    /// Frames from the socketcand server the bus joins: on the bus as any client's are.
    pub(super) fn read_upstream(&mut self, b: usize, now: Instant) {
        let mut buf = [0u8; 4096];
        let mut closed = false;
        for _ in 0..READS_PER_TURN {
            let Some(up) = self.buses.get_mut(b).and_then(|x| x.upstream.as_mut()) else {
                return;
            };
            match up.stream.read(&mut buf) {
                Ok(0) => {
                    closed = true;
                    break;
                }
                Ok(n) => up.decoder.push(buf.get(..n).unwrap_or(&[])),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    tracing::error!(bus = b, error = %e, "socketcand server joined: read failed");
                    closed = true;
                    break;
                }
            }
        }
        loop {
            let Some(up) = self.buses.get_mut(b).and_then(|x| x.upstream.as_mut()) else {
                return;
            };
            let Some(m) = up.decoder.next_message() else {
                break;
            };
            match m {
                Ok(crate::can::socketcand::Message::Frame { frame, .. }) => {
                    self.bus(b, frame, Source::Upstream, now);
                }
                Ok(other) => tracing::debug!(bus = b, message = %other, "socketcand server joined"),
                Err(e) => {
                    tracing::warn!(bus = b, error = %e, "socketcand server joined: bad message")
                }
            }
        }
        if closed {
            // The bus goes on with its own drives and clients.
            tracing::error!(
                bus = b,
                "the socketcand server joined closed the connection"
            );
            if let Some(mut up) = self.buses.get_mut(b).and_then(|x| x.upstream.take()) {
                let _ = self.poll.registry().deregister(&mut up.stream);
            }
        }
    }

    /// Writes what waits for the socketcand server joined; registers for writability while
    /// some is left; a server that takes nothing for [`MAX_PENDING`] bytes is left.
    pub(super) fn flush_upstream(&mut self, b: usize) {
        let Some(up) = self.buses.get_mut(b).and_then(|x| x.upstream.as_mut()) else {
            return;
        };
        let mut failed = false;
        while !up.pending.is_empty() {
            match up.stream.write(up.pending.bytes()) {
                Ok(0) => {
                    failed = true;
                    break;
                }
                Ok(n) => up.pending.consume(n),
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    tracing::error!(bus = b, error = %e, "socketcand server joined: write failed");
                    failed = true;
                    break;
                }
            }
        }
        let wants_write = !up.pending.is_empty();
        if up.pending.len() > MAX_PENDING {
            tracing::error!(
                bus = b,
                "the socketcand server joined does not take frames; left"
            );
            failed = true;
        }
        if failed {
            if let Some(mut up) = self.buses.get_mut(b).and_then(|x| x.upstream.take()) {
                let _ = self.poll.registry().deregister(&mut up.stream);
            }
            return;
        }
        if wants_write != up.wants_write {
            up.wants_write = wants_write;
            let interest = if wants_write {
                Interest::READABLE | Interest::WRITABLE
            } else {
                Interest::READABLE
            };
            if let Err(e) =
                self.poll
                    .registry()
                    .reregister(&mut up.stream, Token(3 + 3 * b), interest)
            {
                tracing::error!(bus = b, error = %e, "socketcand server joined: reregister failed");
            }
        }
    }
}
