//! The loop's TCP connections (socketcand clients, CI terminals, Modbus clients): accepted
//! onto a slot, read a bounded number of times per turn, and written from their link's send
//! buffer ([`send_buffer`]), so that a client that does not read never delays the others
//! ([`MAX_PENDING`]).

use std::io::{self, Read, Write};
use std::net::SocketAddr;
use std::time::Instant;

use mio::net::TcpStream;
use mio::{Interest, Token};

use crate::cell::link::{At, FrontLink, SendBuffer};
use crate::cell::wire_faults::Verdict;

use super::{
    cell_time, CellLoop, Connection, Kind, Listener, ModbusLink, FIRST_DYNAMIC, MAX_PENDING,
    READS_PER_TURN,
};

/// The send buffer of a connection of kind `kind`: a socketcand client's and a terminal's
/// are their own, a Modbus connection's is its server's link's (one connection at a time).
pub(super) fn send_buffer<'a>(
    kind: &'a mut Kind,
    modbus: &'a mut [ModbusLink],
) -> Option<&'a mut SendBuffer> {
    match kind {
        Kind::Socketcand { link, .. } => Some(link.inner_mut().sent_mut()),
        Kind::Console { sent, .. } => Some(sent),
        Kind::Modbus { drive } => modbus.get_mut(*drive).map(ModbusLink::inner_mut),
    }
}

impl CellLoop {
    pub(super) fn accept(&mut self, i: usize) {
        loop {
            let (accepted, console) = match self.listeners.get(i) {
                Some(Listener::Console {
                    listener,
                    drive,
                    terminal,
                }) => (listener.accept(), Ok((*drive, *terminal))),
                Some(Listener::Modbus { listener, drive }) => (listener.accept(), Err(*drive)),
                None => return,
            };
            match accepted {
                Ok((stream, peer)) => match console {
                    Err(modbus) => self.accept_modbus(stream, peer, modbus),
                    Ok((drive, terminal)) => {
                        tracing::info!(%peer, station = drive.index(), "CI terminal connected");
                        let kind = Kind::Console {
                            drive,
                            terminal: terminal(),
                            sent: SendBuffer::with_capacity(1024),
                        };
                        self.add(stream, peer, kind);
                    }
                },
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    tracing::warn!(error = %e, "accept failed");
                    return;
                }
            }
        }
    }

    pub(super) fn add(
        &mut self,
        mut stream: TcpStream,
        peer: SocketAddr,
        kind: Kind,
    ) -> Option<usize> {
        if let Err(e) = stream.set_nodelay(true) {
            tracing::debug!(%peer, error = %e, "could not set TCP_NODELAY");
        }
        limit_send_buffer(&stream, peer);
        let slot = match self.slots.iter().position(Option::is_none) {
            Some(s) => s,
            None => {
                self.slots.push(None);
                self.slots.len() - 1
            }
        };
        let token = Token(FIRST_DYNAMIC + self.listeners.len() + slot);
        if let Err(e) = self
            .poll
            .registry()
            .register(&mut stream, token, Interest::READABLE)
        {
            tracing::warn!(%peer, error = %e, "cannot watch the connection");
            return None;
        }
        let conn = Connection {
            stream,
            peer,
            kind,
            wants_write: false,
            closing: false,
        };
        if let Some(s) = self.slots.get_mut(slot) {
            *s = Some(conn);
        }
        Some(slot)
    }

    /// Closes a connection, telling the drive behind a Modbus one why.
    pub(super) fn close(&mut self, slot: usize, reason: modbus::CloseReason) {
        if let Some(Some(Connection {
            kind: Kind::Modbus { drive },
            ..
        })) = self.slots.get(slot)
        {
            if let Some(m) = self.modbus.get_mut(*drive) {
                m.close_connection_because(reason, &mut self.cell.stations);
            }
        }
        self.remove(slot);
    }

    pub(super) fn remove(&mut self, slot: usize) {
        if let Some(s) = self.slots.get_mut(slot) {
            if let Some(mut conn) = s.take() {
                if let Kind::Modbus { drive } = conn.kind {
                    // What was on its way to the client, and the requests a fault still
                    // holds, went with the connection.
                    if let Some(link) = self.modbus_links.get_mut(drive) {
                        link.inner_mut().clear();
                        link.forget_held();
                    }
                }
                let _ = self.poll.registry().deregister(&mut conn.stream);
                tracing::info!(peer = %conn.peer, "connection closed");
            }
        }
    }

    /// Reads what a connection has sent and acts on it. `closed`: the event said the peer
    /// has closed its end, so the socket is read to its end of file whatever the length of
    /// the read before (an edge-triggered poll reports the close only once).
    pub(super) fn read(&mut self, slot: usize, now: Instant, closed: bool) {
        let mut buf = [0u8; 4096];
        for _ in 0..READS_PER_TURN {
            let Some(Some(conn)) = self.slots.get_mut(slot) else {
                return;
            };
            let n = match conn.stream.read(&mut buf) {
                Ok(0) => {
                    self.close(slot, modbus::CloseReason::Peer);
                    return;
                }
                Ok(n) => n,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    tracing::debug!(error = %e, "read failed");
                    self.close(slot, modbus::CloseReason::Peer);
                    return;
                }
            };
            let bytes = buf.get(..n).unwrap_or(&[]);
            self.received(slot, bytes, now);
            if n < buf.len() && !closed {
                // A short read emptied the socket; the next bytes raise a new event.
                return;
            }
        }
        // More may wait, and no new event comes for it (edge-triggered): read on next turn,
        // after the others have had theirs.
        if !self.more_to_read.contains(&slot) {
            self.more_to_read.push(slot);
        }
    }

    pub(super) fn received(&mut self, slot: usize, bytes: &[u8], now: Instant) {
        let Some(Some(conn)) = self.slots.get_mut(slot) else {
            return;
        };
        match &mut conn.kind {
            Kind::Socketcand { decoder, .. } => {
                decoder.push(bytes);
                self.socketcand_messages(slot, now);
            }
            Kind::Console { drive, .. } => {
                let drive = *drive;
                self.console_bytes(slot, drive, bytes, now);
            }
            Kind::Modbus { drive } => {
                let drive = *drive;
                let t = cell_time(self.origin, now);
                let verdict = match self.modbus_links.get_mut(drive) {
                    Some(link) => link.receive(At::on_clock(t), bytes),
                    None => Verdict::Pass,
                };
                // Otherwise lost, or held by the server's link until its time.
                if verdict == Verdict::Pass {
                    self.modbus_request(slot, drive, bytes, t);
                }
            }
        }
    }

    /// A reply: written at once when nothing waits before it, so that each reply is a
    /// write of its own.
    pub(super) fn send_text(&mut self, slot: usize, bytes: &[u8]) {
        let Some(Some(conn)) = self.slots.get_mut(slot) else {
            return;
        };
        if let Some(sent) = send_buffer(&mut conn.kind, &mut self.modbus_links) {
            sent.push(bytes);
        }
        self.write_pending(slot);
    }

    pub(super) fn mark_dirty(&mut self, slot: usize) {
        if !self.dirty.contains(&slot) {
            self.dirty.push(slot);
        }
    }

    pub(super) fn flush_dirty(&mut self) {
        while let Some(slot) = self.dirty.pop() {
            self.write_pending(slot);
        }
    }

    /// Writes what the socket takes; registers for writability while some is left; drops a
    /// client that leaves more than [`MAX_PENDING`] unread.
    pub(super) fn write_pending(&mut self, slot: usize) {
        let Some(Some(conn)) = self.slots.get_mut(slot) else {
            return;
        };
        let Some(pending) = send_buffer(&mut conn.kind, &mut self.modbus_links) else {
            return;
        };
        let mut written = 0;
        let mut failed = false;
        while written < pending.len() {
            match conn
                .stream
                .write(pending.bytes().get(written..).unwrap_or(&[]))
            {
                Ok(0) => {
                    failed = true;
                    break;
                }
                Ok(n) => written += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) => {
                    tracing::debug!(peer = %conn.peer, error = %e, "write failed");
                    failed = true;
                    break;
                }
            }
        }
        pending.consume(written);
        let (left, empty) = (pending.len(), pending.is_empty());
        if failed {
            self.close(slot, modbus::CloseReason::Peer);
            return;
        }
        if left > MAX_PENDING {
            tracing::warn!(peer = %conn.peer, "client does not read its data: dropped");
            self.close(slot, modbus::CloseReason::Transport);
            return;
        }
        if empty && conn.closing {
            let _ = conn.stream.shutdown(std::net::Shutdown::Both);
            self.remove(slot);
            return;
        }
        let want = !empty;
        if want != conn.wants_write {
            let interest = if want {
                Interest::READABLE | Interest::WRITABLE
            } else {
                Interest::READABLE
            };
            let token = Token(FIRST_DYNAMIC + self.listeners.len() + slot);
            if let Err(e) = self
                .poll
                .registry()
                .reregister(&mut conn.stream, token, interest)
            {
                tracing::debug!(error = %e, "reregister failed");
            }
            conn.wants_write = want;
        }
    }
}

/// The kernel's send buffer of a client connection, bounded: what a client leaves unread
/// waits in its own [`MAX_PENDING`] buffer, where the loop sees it, instead of megabytes of
/// autotuned kernel buffer that would hide a client that never reads.
pub(super) fn limit_send_buffer(stream: &TcpStream, peer: SocketAddr) {
    use std::os::fd::AsFd;
    const SEND_BUFFER: u32 = 64 * 1024;
    if let Err(e) = crate::sys::tcp::set_send_buffer(stream.as_fd(), SEND_BUFFER) {
        tracing::debug!(%peer, error = %e, "could not bound SO_SNDBUF");
    }
}

/// Whether the client has closed its end (end of file waiting, nothing else).
pub(super) fn peer_has_closed(stream: &TcpStream) -> bool {
    let mut byte = [0u8; 1];
    match stream.peek(&mut byte) {
        Ok(n) => n == 0,
        Err(e) => !matches!(
            e.kind(),
            io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
        ),
    }
}
