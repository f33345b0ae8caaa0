//! The cell FMU's front ends: each bus's socketcand server, as the cell file sets it, open on
//! the FMU's virtual clock while an importer steps the cell.
//!
//! One thread serves the sockets (`mio`, as the cell loop does). The clock is the importer's:
//! a frame a client sends acts at the clock's time when it arrives (between two steps, the
//! time the last step ended; during a step, it waits for the step's end), so a client that
//! waits for its answers between steps sees the same bus bit for bit on every run. On the
//! instant bus (`bitrate = "instant"`) a drive answers an SDO request at once, so a client's
//! request between steps is answered before the next `doStep`; on a timed bus the answer
//! takes its bit time and crosses in the next step. The frames the drives send during a step go to the clients when the step has ended,
//! stamped with their time on the virtual clock.
//!
//! The socketcand protocol is [`crate::can::socketcand::session`]'s (the cell loop's and the
//! tokio server's): only its RAW stream delay and statistics timers run on real time, since
//! they are the TCP client's, not the bus's.

use std::io::{self, Read, Write};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use canopen::CanFrame;
use mio::net::{TcpListener, TcpStream};
use mio::{Events, Interest, Poll, Token};

use crate::can::socketcand::codec::{emit_frame, FRAME_TEXT_MAX};
use crate::can::socketcand::session::{Effect, Session, Totals};
use crate::can::socketcand::{Decoder, ServerConfig};
use crate::cell::config::CellFile;
use crate::cell_loop::MAX_PENDING;
use crate::scenario::file::Action;
use crate::scenario::runner::Rig;
use crate::scenario::virtual_rig::{Probe, RigPlace, VirtualRig};

use super::serving_thread::{ServingThread, WAKER};
use super::CellFmuError;

/// Bus `b`'s listener has token `FIRST_LISTENER + b`; connections follow the listeners.
const FIRST_LISTENER: usize = 1;
/// Longest wait of the serving thread while a client has bytes it did not take yet.
const WRITE_RETRY: Duration = Duration::from_millis(1);

/// A frame on bus `bus` at `at` on the virtual clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BusFrame {
    pub bus: usize,
    pub at: Duration,
    pub frame: CanFrame,
}

/// What the importer's thread and the serving thread share: the cell, and the frames of its
/// buses the clients have not been given yet.
pub struct Shared {
    pub rig: VirtualRig,
    /// Frames of a step, for the clients (filled only while front ends are open).
    pub outbox: Vec<BusFrame>,
    /// The cell has changed since the outputs were last read (a step, or a client's frame):
    /// they are read anew, all in one pass, at the importer's first get, and not at all when
    /// it gets none.
    pub stale: bool,
    /// Each drive's outputs as last read.
    pub outputs: Vec<Probe>,
}

impl Shared {
    /// The outputs of the drives at `places` read anew.
    pub fn refresh(&mut self, places: &[RigPlace]) {
        for (out, place) in self.outputs.iter_mut().zip(places) {
            if let Some(p) = self.rig.probe_at(place) {
                *out = p;
            }
        }
        self.stale = false;
    }
}

/// The cell behind its lock.
pub type SharedCell = Arc<Mutex<Shared>>;

/// Locks the cell; a thread that panicked holding it left a cell that is still whole (every
/// change is one call into it), so its state is used.
pub fn lock(shared: &SharedCell) -> MutexGuard<'_, Shared> {
    shared
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The serving thread, stopped and joined when dropped.
pub struct FrontEnds {
    thread: ServingThread,
    addresses: Vec<(usize, SocketAddr)>,
}

impl FrontEnds {
    /// Binds the socketcand server of every bus of `file` that has drives and an address,
    /// and serves them on a thread; `None` when no bus has one.
    pub fn open(file: &CellFile, shared: &SharedCell) -> Result<Option<FrontEnds>, CellFmuError> {
        let mut listeners = Vec::new();
        {
            let guard = lock(shared);
            for (b, section) in file.bus.all().iter().enumerate() {
                // A bus without drives (a cell of CMMO-STs only) has no socketcand server.
                if section.socketcand.is_empty() || guard.rig.drives_on(b) == 0 {
                    continue;
                }
                let listener = std::net::TcpListener::bind(&section.socketcand)
                    .and_then(|l| l.set_nonblocking(true).map(|()| l))
                    .map_err(|source| CellFmuError::FrontEnd {
                        what: format!("socketcand on {}", section.socketcand),
                        source,
                    })?;
                let mut config = ServerConfig::new(section.channel.clone());
                if let Some(max) = section.max_clients {
                    config.max_clients = max;
                }
                listeners.push((b, TcpListener::from_std(listener), config));
            }
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
        for (i, (b, l, _)) in listeners.iter_mut().enumerate() {
            poll.registry()
                .register(l, Token(FIRST_LISTENER + i), Interest::READABLE)
                .map_err(front_end)?;
            if let Ok(a) = l.local_addr() {
                tracing::info!(bus = *b, addr = %a, "cell FMU: socketcand server");
                addresses.push((*b, a));
            }
        }
        let shared = Arc::clone(shared);
        let thread = ServingThread::spawn("cell-fmu-front-ends", waker, move |stop| {
            Server {
                poll,
                listeners,
                clients: Vec::new(),
                shared,
                stop,
                effects: Vec::new(),
                seen: Vec::new(),
            }
            .run()
        })
        .map_err(front_end)?;
        Ok(Some(FrontEnds { thread, addresses }))
    }

    /// The addresses the servers listen on, with their bus.
    pub fn addresses(&self) -> &[(usize, SocketAddr)] {
        &self.addresses
    }

    /// The step has left frames in the outbox: the thread gives them to the clients.
    pub fn wake(&self) {
        self.thread.wake();
    }
}

/// One socketcand client.
struct Client {
    stream: TcpStream,
    peer: SocketAddr,
    bus: usize,
    /// Index into [`Server::listeners`] (its server's settings).
    server: usize,
    session: Session,
    decoder: Decoder,
    /// Bytes the client has not taken yet.
    pending: Vec<u8>,
    /// Frames kept while the RAW stream has not started yet.
    held: Vec<u8>,
    closing: bool,
}

struct Server {
    poll: Poll,
    listeners: Vec<(usize, TcpListener, ServerConfig)>,
    clients: Vec<Option<Client>>,
    shared: SharedCell,
    stop: Arc<AtomicBool>,
    effects: Vec<Effect>,
    /// Frames a client's frame put on the bus (itself and the drives' answers).
    seen: Vec<BusFrame>,
}

impl Server {
    fn run(mut self) {
        let mut events = Events::with_capacity(64);
        while !self.stop.load(Ordering::Acquire) {
            let timeout = self.timeout();
            if let Err(e) = self.poll.poll(&mut events, timeout) {
                if e.kind() == io::ErrorKind::Interrupted {
                    continue;
                }
                tracing::error!(error = %e, "cell FMU: front ends stop");
                return;
            }
            for event in events.iter() {
                let t = event.token().0;
                if t == WAKER.0 {
                    continue;
                }
                match t.checked_sub(FIRST_LISTENER) {
                    Some(i) if i < self.listeners.len() => self.accept(i),
                    Some(i) => self.read(i - self.listeners.len()),
                    None => {}
                }
            }
            self.deliver_outbox();
            self.timers();
            self.write_all();
        }
    }

    /// Until the earliest session timer, or a short while when a client has bytes left.
    fn timeout(&self) -> Option<Duration> {
        let now = Instant::now();
        let mut timeout: Option<Duration> = None;
        for c in self.clients.iter().flatten() {
            let t = if !c.pending.is_empty() {
                Some(WRITE_RETRY)
            } else {
                c.session
                    .deadline()
                    .map(|d| d.saturating_duration_since(now))
            };
            timeout = match (timeout, t) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
        }
        timeout
    }

    fn accept(&mut self, server: usize) {
        loop {
            let Some((bus, listener, config)) = self.listeners.get(server) else {
                return;
            };
            let bus = *bus;
            match listener.accept() {
                Ok((mut stream, peer)) => {
                    let clients = self
                        .clients
                        .iter()
                        .flatten()
                        .filter(|c| c.server == server)
                        .count();
                    if clients >= config.max_clients {
                        tracing::warn!(%peer, "socketcand: too many clients, refusing");
                        // Best effort, never blocks the thread.
                        let _ = stream.write(b"< error too many clients >");
                        continue;
                    }
                    let slot = self
                        .clients
                        .iter()
                        .position(Option::is_none)
                        .unwrap_or(self.clients.len());
                    let token = Token(FIRST_LISTENER + self.listeners.len() + slot);
                    if let Err(e) =
                        self.poll
                            .registry()
                            .register(&mut stream, token, Interest::READABLE)
                    {
                        tracing::warn!(%peer, error = %e, "socketcand: client not registered");
                        continue;
                    }
                    let _ = stream.set_nodelay(true);
                    let max_len = config.max_message_len;
                    let client = Client {
                        stream,
                        peer,
                        bus,
                        server,
                        session: Session::new(),
                        decoder: Decoder::with_max_len(max_len),
                        pending: Session::HELLO.to_string().into_bytes(),
                        held: Vec::new(),
                        closing: false,
                    };
                    tracing::info!(%peer, "cell FMU: socketcand client connected");
                    match self.clients.get_mut(slot) {
                        Some(s) => *s = Some(client),
                        None => self.clients.push(Some(client)),
                    }
                    self.write(slot);
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    tracing::warn!(error = %e, "socketcand: accept failed");
                    return;
                }
            }
        }
    }

    fn read(&mut self, slot: usize) {
        let mut buf = [0u8; 4096];
        let mut closed = false;
        if let Some(Some(c)) = self.clients.get_mut(slot) {
            loop {
                match c.stream.read(&mut buf) {
                    Ok(0) => {
                        closed = true;
                        break;
                    }
                    Ok(n) => c.decoder.push(buf.get(..n).unwrap_or(&[])),
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(_) => {
                        closed = true;
                        break;
                    }
                }
            }
        }
        self.messages(slot);
        if closed {
            self.close(slot);
        }
    }

    /// The client's complete messages, in order.
    fn messages(&mut self, slot: usize) {
        loop {
            let Some(Some(c)) = self.clients.get_mut(slot) else {
                return;
            };
            let Some(message) = c.decoder.next_message() else {
                return;
            };
            let Some((_, _, config)) = self.listeners.get(c.server) else {
                return;
            };
            let effects = &mut self.effects;
            c.session
                .on_message(config, Instant::now(), message, &mut |e| effects.push(e));
            self.carry_out(slot);
        }
    }

    /// What the session asked for.
    fn carry_out(&mut self, slot: usize) {
        let mut effects = std::mem::take(&mut self.effects);
        for effect in effects.drain(..) {
            let Some(Some(c)) = self.clients.get_mut(slot) else {
                break;
            };
            match effect {
                Effect::Reply(m) => c.pending.extend_from_slice(m.to_string().as_bytes()),
                Effect::Open => {}
                Effect::SkipPending => c.held.clear(),
                Effect::Close => c.closing = true,
                Effect::Send(frame) => {
                    let bus = c.bus;
                    self.put_on_bus(slot, bus, frame);
                }
            }
        }
        self.effects = effects;
    }

    /// A client's frame acts on the cell at the clock's time; it and the drives' answers go
    /// to the bus's other clients (the sender does not get its own frame back, as socketcand).
    fn put_on_bus(&mut self, from: usize, bus: usize, frame: CanFrame) {
        self.seen.clear();
        let earlier = {
            let mut guard = lock(&self.shared);
            let shared = &mut *guard;
            // Frames the last step left come first: they are earlier on the bus.
            let earlier = std::mem::take(&mut shared.outbox);
            let seen = &mut self.seen;
            let result = shared.rig.act(
                &Action::Frame { bus, frame },
                &mut |b: usize, at: Duration, f: &CanFrame| {
                    seen.push(BusFrame {
                        bus: b,
                        at,
                        frame: *f,
                    })
                },
            );
            shared.stale = true;
            if let Err(e) = result {
                tracing::warn!(bus, error = %e, "cell FMU: client frame refused");
            }
            earlier
        };
        for f in &earlier {
            self.forward(f, None);
        }
        let mut own = Some(frame);
        let seen = std::mem::take(&mut self.seen);
        for f in &seen {
            let sender = if f.bus == bus && own == Some(f.frame) {
                own = None;
                Some(from)
            } else {
                None
            };
            self.forward(f, sender);
        }
        self.seen = seen;
    }

    /// The frames the last step left, to the clients.
    fn deliver_outbox(&mut self) {
        let frames = std::mem::take(&mut lock(&self.shared).outbox);
        for f in &frames {
            self.forward(f, None);
        }
    }

    /// A bus frame to every client of its bus in RAW mode but `except`.
    fn forward(&mut self, f: &BusFrame, except: Option<usize>) {
        if !Session::forwards(&f.frame) {
            return;
        }
        let mut text = [0u8; FRAME_TEXT_MAX];
        let n = emit_frame(&f.frame, f.at, &mut text);
        let text = text.get(..n).unwrap_or(&[]);
        for (slot, c) in self.clients.iter_mut().enumerate() {
            let Some(c) = c else { continue };
            if c.bus != f.bus || Some(slot) == except || !c.session.wants_frames() {
                continue;
            }
            if c.session.is_streaming() {
                c.pending.extend_from_slice(text);
            } else if c.held.len() < MAX_PENDING {
                c.held.extend_from_slice(text);
            }
        }
    }

    fn timers(&mut self) {
        let now = Instant::now();
        for slot in 0..self.clients.len() {
            let Some(Some(c)) = self.clients.get_mut(slot) else {
                continue;
            };
            if c.session.deadline().is_none_or(|d| d > now) {
                continue;
            }
            let was_streaming = c.session.is_streaming();
            let effects = &mut self.effects;
            c.session
                .poll(now, Totals::default(), &mut |e| effects.push(e));
            if c.session.is_streaming() && !was_streaming {
                let held = std::mem::take(&mut c.held);
                c.pending.extend_from_slice(&held);
            }
            self.carry_out(slot);
        }
    }

    fn write_all(&mut self) {
        for slot in 0..self.clients.len() {
            self.write(slot);
        }
    }

    /// Writes what the client has not taken; a client that leaves more than
    /// [`MAX_PENDING`] bytes is dropped, so it never holds the others up.
    fn write(&mut self, slot: usize) {
        let mut failed = false;
        let Some(Some(c)) = self.clients.get_mut(slot) else {
            return;
        };
        if !super::serving_thread::flush(&mut c.stream, &mut c.pending) {
            failed = true;
        }
        if c.pending.len() > MAX_PENDING {
            tracing::warn!(peer = %c.peer, "socketcand client does not read: dropped");
            failed = true;
        }
        if failed || (c.closing && c.pending.is_empty()) {
            self.close(slot);
        }
    }

    fn close(&mut self, slot: usize) {
        if let Some(s) = self.clients.get_mut(slot) {
            if let Some(mut c) = s.take() {
                let _ = self.poll.registry().deregister(&mut c.stream);
                tracing::info!(peer = %c.peer, "cell FMU: socketcand client left");
            }
        }
    }
}
