//! The cell FMU's Modbus TCP front ends: the server of each drive the cell serves over
//! Modbus TCP (a CMMO-ST, FHPP), on the address of its `modbus` key (the default
//! `127.0.0.1:1502` without one), open on the FMU's virtual clock while an importer steps the
//! cell.
//!
//! One thread serves the sockets (`mio`). The clock is the importer's, as for the socketcand
//! servers ([`super::front_ends`]): a request a client sends is answered at the clock's time
//! when it arrives (between two steps, the time the last step ended; during a step, at its
//! end: the step holds the cell, the request waits for it). Modbus TCP has no bus time, so the
//! answer goes back at once: a client that waits for its answer between steps gets it before
//! the next `doStep`, and sees the drive as it is at that time.
//!
//! The rules are the cell loop's ([`crate::modbus_tcp::cell_drive`]): one connection at a
//! time (a second one is closed at once without a byte), the watchdog on the clock (a
//! connection silent for longer than `watchdog_ms` of virtual time is closed by the drive, and
//! its socket with it, CMMO-ST manual §4), the ADU handling of `server::answer_all`. The
//! drive's own connection that a timeline's `modbus` steps use, open from 0, is replaced by a
//! client's.

use std::io::{self, Read};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use mio::net::{TcpListener, TcpStream};
use mio::{Events, Interest, Poll, Token};
use modbus::CloseReason;

use super::front_ends::{lock, SharedCell};
use super::serving_thread::ServingThread;
use super::CellFmuError;

/// Drive `i`'s listener has token `FIRST_LISTENER + 2·i`, its connection the next one.
const FIRST_LISTENER: usize = 1;
/// Longest a client may leave answers unread before it is dropped, in bytes.
const MAX_PENDING: usize = 64 * 1024;

/// The serving thread, stopped and joined when dropped.
pub struct ModbusFronts {
    thread: ServingThread,
    addresses: Vec<(usize, SocketAddr)>,
}

impl ModbusFronts {
    /// Binds `servers` (the address of each drive served over Modbus TCP, in the rig's order,
    /// `None` for one without a server) and serves them on a thread; `None` when there is
    /// none.
    pub fn open(
        servers: &[Option<String>],
        shared: &SharedCell,
    ) -> Result<Option<ModbusFronts>, CellFmuError> {
        let mut listeners = Vec::new();
        for (i, addr) in servers.iter().enumerate() {
            let Some(addr) = addr else { continue };
            let listener = std::net::TcpListener::bind(addr)
                .and_then(|l| l.set_nonblocking(true).map(|()| l))
                .map_err(|source| CellFmuError::FrontEnd {
                    what: format!("Modbus TCP on {addr}"),
                    source,
                })?;
            listeners.push(Served {
                drive: i,
                listener: TcpListener::from_std(listener),
                client: None,
            });
        }
        if listeners.is_empty() {
            return Ok(None);
        }
        let front_end = |source: io::Error| CellFmuError::FrontEnd {
            what: "poll".into(),
            source,
        };
        let poll = Poll::new().map_err(front_end)?;
        let waker = ServingThread::waker(&poll).map_err(front_end)?;
        let mut addresses = Vec::new();
        for (k, s) in listeners.iter_mut().enumerate() {
            poll.registry()
                .register(&mut s.listener, listener_token(k), Interest::READABLE)
                .map_err(front_end)?;
            if let Ok(a) = s.listener.local_addr() {
                tracing::info!(drive = s.drive, addr = %a, "cell FMU: Modbus TCP server");
                addresses.push((s.drive, a));
            }
        }
        let shared = Arc::clone(shared);
        let thread = ServingThread::spawn("cell-fmu-modbus", waker, move |stop| {
            Server {
                poll,
                served: listeners,
                shared,
                stop,
            }
            .run()
        })
        .map_err(front_end)?;
        Ok(Some(ModbusFronts { thread, addresses }))
    }

    /// The addresses the servers listen on, with the drive's place among the drives served
    /// over Modbus TCP.
    pub fn addresses(&self) -> &[(usize, SocketAddr)] {
        &self.addresses
    }

    /// A step has ended: the thread closes the sockets of connections the drives closed
    /// meanwhile (the watchdog).
    pub fn wake(&self) {
        self.thread.wake();
    }
}

/// Whether the client has closed its end (a read would give 0 bytes).
fn peer_has_closed(stream: &TcpStream) -> bool {
    let mut byte = [0u8; 1];
    match stream.peek(&mut byte) {
        Ok(n) => n == 0,
        Err(e) => !matches!(
            e.kind(),
            io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
        ),
    }
}

fn listener_token(k: usize) -> Token {
    Token(FIRST_LISTENER + 2 * k)
}

fn client_token(k: usize) -> Token {
    Token(FIRST_LISTENER + 2 * k + 1)
}

/// One drive's server and its one connection.
struct Served {
    /// The drive's place among the rig's drives served over Modbus TCP.
    drive: usize,
    listener: TcpListener,
    client: Option<Client>,
}

struct Client {
    stream: TcpStream,
    peer: SocketAddr,
    /// Answers the client has not taken yet.
    pending: Vec<u8>,
}

struct Server {
    poll: Poll,
    served: Vec<Served>,
    shared: SharedCell,
    stop: Arc<AtomicBool>,
}

impl Server {
    fn run(mut self) {
        let mut events = Events::with_capacity(64);
        while !self.stop.load(Ordering::Acquire) {
            if let Err(e) = self.poll.poll(&mut events, None) {
                if e.kind() == io::ErrorKind::Interrupted {
                    continue;
                }
                tracing::error!(error = %e, "cell FMU: Modbus front ends stop");
                return;
            }
            for event in events.iter() {
                let Some(t) = event.token().0.checked_sub(FIRST_LISTENER) else {
                    continue;
                };
                let k = t / 2;
                if t % 2 == 0 {
                    self.accept(k);
                } else {
                    if event.is_readable() || event.is_read_closed() {
                        self.read(k);
                    }
                    if event.is_writable() {
                        self.write(k);
                    }
                }
            }
            self.drop_closed();
        }
    }

    /// CMMO-ST manual §4: one connection at a time; a second one is closed at once without a
    /// byte, unless the first one's client has closed it meanwhile (as the cell loop's server
    /// does).
    fn accept(&mut self, k: usize) {
        loop {
            let Some(s) = self.served.get_mut(k) else {
                return;
            };
            let (stream, peer) = match s.listener.accept() {
                Ok(accepted) => accepted,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    tracing::warn!(error = %e, "Modbus: accept failed");
                    return;
                }
            };
            match s.client.as_ref().map(|c| peer_has_closed(&c.stream)) {
                Some(false) => {
                    tracing::warn!(%peer, "Modbus: one connection at a time, refusing");
                    continue;
                }
                Some(true) => self.close(k, CloseReason::Peer),
                None => {}
            }
            self.connect(k, stream, peer);
        }
    }

    /// `stream` is drive `k`'s connection: it replaces the one a timeline uses.
    fn connect(&mut self, k: usize, mut stream: TcpStream, peer: SocketAddr) {
        let Some(s) = self.served.get_mut(k) else {
            return;
        };
        if let Err(e) = self.poll.registry().register(
            &mut stream,
            client_token(k),
            Interest::READABLE | Interest::WRITABLE,
        ) {
            tracing::warn!(%peer, error = %e, "Modbus: client not registered");
            return;
        }
        let _ = stream.set_nodelay(true);
        {
            let mut guard = lock(&self.shared);
            let rig = &mut guard.rig;
            let now = rig.now();
            if let Some((m, stations)) = rig.modbus_drive_mut(s.drive) {
                m.close_connection_because(CloseReason::Peer, stations);
                m.open_connection(now, stations);
            }
            guard.stale = true;
        }
        tracing::info!(%peer, "cell FMU: Modbus client connected");
        s.client = Some(Client {
            stream,
            peer,
            pending: Vec::new(),
        });
    }

    /// The client's bytes, answered at the clock's time; a broken stream closes the
    /// connection after the answers before it.
    fn read(&mut self, k: usize) {
        let mut buf = [0u8; 4096];
        let mut closed = None;
        let Some(s) = self.served.get_mut(k) else {
            return;
        };
        let Some(c) = s.client.as_mut() else {
            return;
        };
        loop {
            match c.stream.read(&mut buf) {
                Ok(0) => {
                    closed = Some(CloseReason::Peer);
                    break;
                }
                Ok(n) => {
                    let bytes = buf.get(..n).unwrap_or(&[]);
                    let mut guard = lock(&self.shared);
                    let rig = &mut guard.rig;
                    let now = rig.now();
                    let result = match rig.modbus_drive_mut(s.drive) {
                        Some((m, stations)) => m.answer(bytes, now, &mut c.pending, stations),
                        None => Ok(()),
                    };
                    guard.stale = true;
                    if let Err(reason) = result {
                        closed = Some(reason);
                        break;
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(_) => {
                    closed = Some(CloseReason::Transport);
                    break;
                }
            }
        }
        self.write(k);
        if let Some(reason) = closed {
            self.close(k, reason);
        }
    }

    /// Writes what the client has not taken; a client that leaves more than
    /// [`MAX_PENDING`] bytes is dropped.
    fn write(&mut self, k: usize) {
        let Some(c) = self.served.get_mut(k).and_then(|s| s.client.as_mut()) else {
            return;
        };
        let mut failed = false;
        if !super::serving_thread::flush(&mut c.stream, &mut c.pending) {
            failed = true;
        }
        if c.pending.len() > MAX_PENDING {
            tracing::warn!(peer = %c.peer, "Modbus client does not read: dropped");
            failed = true;
        }
        if failed {
            self.close(k, CloseReason::Transport);
        }
    }

    /// The connection ends for `reason`: the drive is told, the socket closed.
    fn close(&mut self, k: usize, reason: CloseReason) {
        let Some(s) = self.served.get_mut(k) else {
            return;
        };
        let Some(mut c) = s.client.take() else {
            return;
        };
        let _ = self.poll.registry().deregister(&mut c.stream);
        let mut guard = lock(&self.shared);
        if let Some((m, stations)) = guard.rig.modbus_drive_mut(s.drive) {
            m.close_connection_because(reason, stations);
        }
        guard.stale = true;
        tracing::info!(peer = %c.peer, "cell FMU: Modbus client left");
    }

    /// Sockets of connections the drive has closed (its watchdog, during a step).
    fn drop_closed(&mut self) {
        let mut guard = lock(&self.shared);
        for s in &mut self.served {
            if s.client.is_none() {
                continue;
            }
            let open = guard
                .rig
                .modbus_drive_mut(s.drive)
                .is_some_and(|(m, _)| m.has_connection());
            if !open {
                if let Some(mut c) = s.client.take() {
                    let _ = self.poll.registry().deregister(&mut c.stream);
                    tracing::info!(peer = %c.peer, "cell FMU: Modbus connection closed by the drive");
                }
            }
        }
    }
}

/// The address of each drive `file` serves over Modbus TCP, in the order the virtual clock's
/// rig serves them (the cell file's): its `modbus` key, else the default `127.0.0.1:1502`,
/// as `drivetwin run` binds it.
pub fn addresses(
    file: &crate::cell::config::CellFile,
    vendors: crate::cell::Vendors,
) -> Result<Vec<Option<String>>, CellFmuError> {
    let specs = file
        .drives(vendors)
        .map_err(|e| CellFmuError::Cell(e.to_string()))?;
    Ok(specs
        .iter()
        .filter_map(|spec| spec.fhpp.as_ref())
        .map(|fhpp| {
            Some(
                fhpp.modbus
                    .clone()
                    .unwrap_or_else(|| crate::modbus_tcp::server::DEFAULT_ADDR.to_string()),
            )
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use std::io::{ErrorKind, Read, Write};
    use std::net::TcpStream;
    use std::time::Duration;

    use crate::cell_fmu::instance::CellInstance;
    use crate::cell_fmu::CELL_FILE;

    #[test]
    fn a_modbus_client_is_answered_between_steps_one_connection_at_a_time() {
        let dir = std::env::temp_dir().join(format!("cell-fmu-modbus-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            dir.join(CELL_FILE),
            "[[bus]]\nsocketcand = \"\"\n[[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n\
             [[drive]]\ndevice = \"cmmo-st\"\nnode = 30\nmodbus = \"127.0.0.1:0\"\n",
        )
        .unwrap();
        let mut cell = CellInstance::from_resources(&dir, crate::vendors::VENDORS.runtime).unwrap();
        let (drive, addr) = cell.modbus_addresses()[0];
        assert_eq!(drive, 0);
        cell.do_step(0.0, 0.01).unwrap();
        let mut client = TcpStream::connect(addr).unwrap();
        client
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        // FC 03h, the 4 registers of the input telegram (transaction 7, unit 1).
        client
            .write_all(&[0, 7, 0, 0, 0, 6, 1, 3, 0, 0, 0, 4])
            .unwrap();
        let mut answer = [0u8; 17];
        client.read_exact(&mut answer).unwrap();
        assert_eq!(answer[..9], [0, 7, 0, 0, 0, 11, 1, 3, 8]);
        // SCON 10h, SPOS 04h: the power-on telegram (FHPP Example 1).
        assert_eq!(answer[9..11], [0x10, 0x04]);
        // A second connection is closed without a byte.
        let mut second = TcpStream::connect(addr).unwrap();
        second
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        let mut byte = [0u8; 1];
        match second.read(&mut byte) {
            Ok(0) => {}
            Err(e) if e.kind() == ErrorKind::ConnectionReset => {}
            other => panic!("{other:?}"),
        }
        drop(client);
        drop(cell);
        assert!(
            TcpStream::connect(addr).is_err(),
            "the server closes with its instance"
        );
        std::fs::remove_dir_all(&dir).ok();
    }
}
