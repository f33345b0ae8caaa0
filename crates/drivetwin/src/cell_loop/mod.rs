//! The cell loop: one thread owns the cell's clock and every socket of the cell (the
//! socketcand server and its clients, the SocketCAN interface, the CI terminals, the
//! CMMO-STs' Modbus TCP servers) and the drives themselves. It waits in one `epoll_wait` (mio)
//! for the earliest of a readable socket and the next deadline of a drive or a session, does
//! what is due, and writes the answers before it waits again: a request reaches the drive it
//! addresses, and the answer the socket, on the thread the kernel woke, with no channel and
//! no other task in between (`DESIGN.md`, "The runtime owns the clock and every socket").
//!
//! The loop is the cell's CAN bus as well: a frame from a socketcand client reaches the drives,
//! the SocketCAN interface, the trace and every other client in RAW mode; a frame of a drive
//! reaches the other drives (`Cell::deliver`), the interface, the trace and every client.
//!
//! The loop is the cell's EtherCAT segments as well: a frame from a master on a chain's
//! network interface passes the chain's slaves in order and goes back out at once; a slave
//! whose drive is a CANopen drive of the cell (`allow_unreal_interfaces`) reaches the very
//! drive the CANopen node serves, so a value written over CoE is the one SDO reads.
//!
//! Slow clients: what a client has not taken waits in its own buffer, bounded by
//! [`MAX_PENDING`]; a client whose buffer would grow beyond it is dropped, so a client that
//! does not read never delays the others, nor the drives.
//!
//! The loop is where the cell meets its transports: it uses both, and neither uses it (the
//! transports reach the drives through [`crate::cell`]'s types and their own traits, such as
//! [`crate::ecat::chain::BusDrives`] and [`crate::serial::LineDrives`]).
//!
//! Sockets are registered for readability only; a client whose socket does not take all of an
//! answer is registered for writability until its buffer is empty (no wake-up per `ACK`).

use std::io::{self, Read, Write};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use canopen::CanFrame;
use drive::vendors::festo_cmmp_as::ci_terminal::{self, syntax_error, Cut, LineCutter};
use mio::net::{TcpListener, TcpStream};
use mio::{Events, Interest, Poll, Token, Waker};

use crate::can::socketcand::codec::{emit_frame, FRAME_TEXT_MAX};
use crate::can::socketcand::session::{Effect, Session, Totals};
use crate::can::socketcand::{Decoder, ServerConfig};
use crate::cell::can_drive::CanDrive;
use crate::cell::control::{Command, ControlHandle, PlantSample};
use crate::cell::{Cell, OnBus};
use crate::ecat::chain::{trace_frame, BusDrives, EthercatCell, FrameTap};
use crate::modbus_tcp::cell_drive::ModbusDrive;
use crate::trace::TraceWriter;

mod fine_timer;
mod handle;
mod serial;
pub mod virtual_clock;
mod wire;

/// Bytes a client may leave unread before it is dropped.
pub const MAX_PENDING: usize = 256 * 1024;

/// Reads of 4 KiB one connection gets per turn of the loop: a client that floods the bus
/// does not keep the loop from the others.
const READS_PER_TURN: usize = 16;

/// Frames held for a client while its RAW stream has not started yet.
const MAX_HELD: usize = 64 * 1024;

const WAKER: Token = Token(0);
/// The loop's sub-millisecond timer ([`fine_timer`]).
const TIMER: Token = Token(FIRST_SERIAL - 1);
/// Bus `b` has tokens `1 + 3b` (its socketcand server), `2 + 3b` (its SocketCAN socket) and
/// `3 + 3b` (the socketcand server it joins).
pub const MAX_BUSES: usize = 7;
/// EtherCAT chain `c` has token `FIRST_CHAIN + c`.
const FIRST_CHAIN: usize = 3 * MAX_BUSES + 1;
/// EtherCAT chains (network interfaces) a cell serves at most.
pub const MAX_CHAINS: usize = 4;
/// Tokens from here on: listeners of CI terminals and Modbus servers, then connections.
const FIRST_DYNAMIC: usize = FIRST_CHAIN + MAX_CHAINS;
/// Serial line `i` has token `FIRST_SERIAL + i` (above every connection's).
const FIRST_SERIAL: usize = 1 << 24;
/// EtherCAT frames one chain takes per turn of the loop before the others get their turn.
const FRAMES_PER_TURN: usize = 64;

/// One CAN bus of a cell: the CANopen drives on it and its transports.
pub struct CanBus {
    pub cell: Cell,
    /// The socketcand server and its settings (the bus name it serves).
    pub socketcand: Option<(std::net::TcpListener, ServerConfig)>,
    /// A SocketCAN interface the bus is bridged to.
    pub socketcan: Option<crate::can::socketcan::RawCanSocket>,
    /// Where every frame on the bus is written.
    pub trace: Option<TraceWriter>,
    /// Another socketcand server whose bus this one is (`--socketcand-join`): connected and
    /// in raw mode ([`crate::can::socketcand::join`]).
    pub upstream: Option<std::net::TcpStream>,
}

impl CanBus {
    /// The drives of `cell` on a bus without transports yet.
    pub fn new(cell: Cell) -> CanBus {
        CanBus {
            cell,
            socketcand: None,
            socketcan: None,
            trace: None,
            upstream: None,
        }
    }
}

/// An EtherCAT chain of the cell on one network interface.
pub struct EthercatChain {
    pub chain: EthercatCell,
    pub socket: crate::ecat::link::SlaveSocket,
    /// Where each request and each answer is copied (`--trace`, a pcap).
    pub trace: Option<FrameTap>,
}

/// Every socket a cell serves, bound before the loop starts.
#[derive(Default)]
pub struct FrontEnds {
    /// The cell's CAN buses (at most [`MAX_BUSES`]).
    pub buses: Vec<CanBus>,
    /// CI terminals: a listener and its drive.
    pub ci_terminals: Vec<(std::net::TcpListener, OnBus)>,
    /// Drives on Modbus TCP (the CMMO-ST), each with its own listener.
    pub modbus: Vec<ModbusDrive>,
    /// EtherCAT chains (at most [`MAX_CHAINS`]).
    pub ethercat: Vec<EthercatChain>,
    /// Serial lines (RS232, RS485) and the drives on them ([`crate::serial`]).
    pub serial: Vec<crate::serial::line::SerialLine>,
    /// Ask for `SCHED_FIFO` at this priority for the loop's thread (as a drive's firmware
    /// runs its fieldbus task); refused, the loop warns and goes on.
    pub rt_priority: Option<u8>,
    /// Never sleep: poll the sockets without waiting (`--busy-poll`), as a device's fieldbus
    /// hardware is always awake; the lowest round trip, at the price of one CPU kept busy.
    pub busy_poll: bool,
}

/// A bus while the loop runs.
struct BusState {
    cell: Cell,
    socketcand: Option<(TcpListener, ServerConfig)>,
    socketcan: Option<crate::can::socketcan::RawCanSocket>,
    trace: Option<TraceWriter>,
    trace_dirty: bool,
    totals: Totals,
    last_stamp: SystemTime,
    upstream: Option<Upstream>,
}

/// The socketcand server a bus joins: frames from it are on the bus; frames of the bus go to
/// it as `< send >`.
struct Upstream {
    stream: TcpStream,
    decoder: Decoder,
    /// Bytes the server has not taken yet.
    pending: Vec<u8>,
    wants_write: bool,
}

/// Stops a running loop from another thread.
#[derive(Clone)]
pub struct StopHandle {
    waker: Arc<Waker>,
    stop: Arc<AtomicBool>,
}

impl StopHandle {
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Release);
        if let Err(e) = self.waker.wake() {
            tracing::error!(error = %e, "cannot wake the cell loop");
        }
    }
}

/// A cell with its sockets, ready to run.
pub struct CellLoop {
    poll: Poll,
    stop: Arc<AtomicBool>,
    waker: Arc<Waker>,
    /// Wakes the loop between milliseconds; without it (no timerfd) the poll's timeout does.
    timer: Option<fine_timer::FineTimer>,
    /// How late the loop serves due timers.
    lateness: Arc<crate::cell::lateness::Lateness>,
    buses: Vec<BusState>,
    /// The cell clock's zero.
    origin: Instant,
    /// Listeners by token - FIRST_DYNAMIC; connections after them.
    listeners: Vec<Listener>,
    slots: Vec<Option<Connection>>,
    modbus: Vec<ModbusDrive>,
    chains: Vec<EthercatChain>,
    serial: Vec<crate::serial::line::SerialLine>,
    /// Scratch: frames the drives sent while a serial line reached them, with their bus.
    serial_sent: Vec<(usize, CanFrame)>,
    /// Chains that had more frames waiting than one turn takes.
    chains_to_read: Vec<usize>,
    /// Scratch: one Ethernet frame.
    frame: Vec<u8>,
    rt_priority: Option<u8>,
    busy_poll: bool,
    /// Connections that had more to read than one turn takes.
    more_to_read: Vec<usize>,
    /// Connections with bytes to write before the loop waits again.
    dirty: Vec<usize>,
    /// Scratch: frames the drives sent.
    out: Vec<CanFrame>,
    /// Scratch: one frame as socketcand text.
    text: Vec<u8>,
    effects: Vec<Effect>,
    control_tx: std::sync::mpsc::Sender<Command>,
    control_rx: std::sync::mpsc::Receiver<Command>,
    subscriptions: Vec<Subscription>,
    /// Faults on the Modbus and EtherCAT front ends (a bus's are its cell's).
    front_faults: Vec<(
        crate::cell::wire_faults::FrontEnd,
        crate::cell::wire_faults::WireFaults,
    )>,
    /// Receivers of every frame of a bus ([`crate::cell::wire_faults::WireRequest::Tap`]).
    taps: Vec<(usize, std::sync::mpsc::SyncSender<(Duration, CanFrame)>)>,
    /// Modbus requests and EtherCAT frames a `delay` fault holds back.
    held: Vec<wire::Held>,
}

/// A subscriber to a drive's samples: the plant alone, or the plant with named objects.
struct Subscription {
    drive: usize,
    every: Duration,
    next: Instant,
    /// Read with each sample (at most [`crate::cell::control::MAX_SAMPLED_OBJECTS`]); only
    /// for a [`SampleSink::Objects`].
    objects: Vec<(u16, u8)>,
    sink: SampleSink,
}

/// Where a subscription's samples go.
enum SampleSink {
    Plant(std::sync::mpsc::SyncSender<PlantSample>),
    Objects(std::sync::mpsc::SyncSender<crate::cell::control::ObjectsSample>),
}

enum Listener {
    Console { listener: TcpListener, drive: OnBus },
    Modbus { listener: TcpListener, drive: usize },
}

/// Where a frame on the cell's bus came from (it is not sent back there).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Source {
    Drives,
    Client(usize),
    SocketCan,
    /// The socketcand server the bus joins.
    Upstream,
}

struct Connection {
    stream: TcpStream,
    peer: SocketAddr,
    kind: Kind,
    /// Bytes the socket has not taken yet.
    pending: Vec<u8>,
    /// Registered for writability too (while `pending` is not empty).
    wants_write: bool,
    /// Close once `pending` is written.
    closing: bool,
}

enum Kind {
    Socketcand {
        bus: usize,
        session: Session,
        decoder: Decoder,
        /// Frames kept during the stream delay after `rawmode`.
        held: Vec<u8>,
        /// What it may put on the bus (the bus's frame rate).
        budget: crate::can::frame_budget::FrameBudget,
    },
    Console {
        drive: OnBus,
        lines: LineCutter,
    },
    Modbus {
        drive: usize,
    },
}

impl CellLoop {
    /// A cell of one CAN bus, `cell`, with the transports of `front` (whose own `buses` come
    /// after it).
    pub fn new(cell: Cell, front: FrontEnds) -> io::Result<CellLoop> {
        let mut front = front;
        front.buses.insert(0, CanBus::new(cell));
        CellLoop::with_buses(front)
    }

    /// A cell of several buses, `front.buses`, and the other front ends of `front`.
    pub fn with_buses(mut front: FrontEnds) -> io::Result<CellLoop> {
        if front.buses.len() > MAX_BUSES {
            return Err(io::Error::other(format!(
                "{} CAN buses: a cell has at most {MAX_BUSES}",
                front.buses.len()
            )));
        }
        let poll = Poll::new()?;
        let waker = Arc::new(Waker::new(poll.registry(), WAKER)?);
        let timer = fine_timer::FineTimer::new(poll.registry(), TIMER)
            .map_err(
                |e| tracing::warn!(error = %e, "no timerfd: the loop wakes on whole milliseconds"),
            )
            .ok();
        let mut buses = Vec::new();
        for (b, bus) in std::mem::take(&mut front.buses).into_iter().enumerate() {
            let mut socketcand = None;
            if let Some((l, config)) = bus.socketcand {
                l.set_nonblocking(true)?;
                let mut l = TcpListener::from_std(l);
                poll.registry()
                    .register(&mut l, Token(1 + 3 * b), Interest::READABLE)?;
                socketcand = Some((l, config));
            }
            if let Some(s) = &bus.socketcan {
                poll.registry().register(
                    &mut mio::unix::SourceFd(&s.as_raw_fd()),
                    Token(2 + 3 * b),
                    Interest::READABLE,
                )?;
            }
            let upstream = match bus.upstream {
                Some(s) => {
                    s.set_nonblocking(true)?;
                    let mut stream = TcpStream::from_std(s);
                    poll.registry()
                        .register(&mut stream, Token(3 + 3 * b), Interest::READABLE)?;
                    Some(Upstream {
                        stream,
                        decoder: Decoder::new(),
                        pending: Vec::new(),
                        wants_write: false,
                    })
                }
                None => None,
            };
            buses.push(BusState {
                upstream,
                cell: bus.cell,
                socketcand,
                socketcan: bus.socketcan,
                trace: bus.trace,
                trace_dirty: false,
                totals: Totals::default(),
                last_stamp: UNIX_EPOCH,
            });
        }
        if front.ethercat.len() > MAX_CHAINS {
            return Err(io::Error::other(format!(
                "{} EtherCAT chains: a cell has at most {MAX_CHAINS}",
                front.ethercat.len()
            )));
        }
        for (c, chain) in front.ethercat.iter().enumerate() {
            use std::os::fd::AsRawFd;
            poll.registry().register(
                &mut mio::unix::SourceFd(&chain.socket.as_raw_fd()),
                Token(FIRST_CHAIN + c),
                Interest::READABLE,
            )?;
        }
        for (i, line) in front.serial.iter().enumerate() {
            poll.registry().register(
                &mut mio::unix::SourceFd(&line.port().raw_fd()),
                Token(FIRST_SERIAL + i),
                Interest::READABLE | Interest::WRITABLE,
            )?;
        }
        let mut listeners = Vec::new();
        for (l, drive) in front.ci_terminals {
            l.set_nonblocking(true)?;
            listeners.push(Listener::Console {
                listener: TcpListener::from_std(l),
                drive,
            });
        }
        for (drive, m) in front.modbus.iter_mut().enumerate() {
            let l = m.take_listener()?;
            listeners.push(Listener::Modbus { listener: l, drive });
        }
        for (i, l) in listeners.iter_mut().enumerate() {
            let listener = match l {
                Listener::Console { listener, .. } | Listener::Modbus { listener, .. } => listener,
            };
            poll.registry()
                .register(listener, Token(FIRST_DYNAMIC + i), Interest::READABLE)?;
        }
        let (control_tx, control_rx) = std::sync::mpsc::channel();
        Ok(CellLoop {
            control_tx,
            control_rx,
            subscriptions: Vec::new(),
            front_faults: Vec::new(),
            taps: Vec::new(),
            held: Vec::new(),
            poll,
            stop: Arc::new(AtomicBool::new(false)),
            waker,
            timer,
            lateness: Arc::default(),
            buses,
            origin: Instant::now(),
            listeners,
            slots: Vec::new(),
            modbus: front.modbus,
            chains: front.ethercat,
            serial: front.serial,
            serial_sent: Vec::new(),
            chains_to_read: Vec::new(),
            frame: vec![0; crate::ecat::MAX_FRAME],
            rt_priority: front.rt_priority,
            busy_poll: front.busy_poll,
            more_to_read: Vec::new(),
            dirty: Vec::new(),
            out: Vec::with_capacity(256),
            text: Vec::with_capacity(64),
            effects: Vec::new(),
        })
    }

    /// How late the loop serves its timers, readable while it runs and after.
    pub fn lateness(&self) -> Arc<crate::cell::lateness::Lateness> {
        Arc::clone(&self.lateness)
    }

    pub fn stop_handle(&self) -> StopHandle {
        StopHandle {
            waker: Arc::clone(&self.waker),
            stop: Arc::clone(&self.stop),
        }
    }

    /// A handle to the cell while it runs (see [`crate::cell::control`]).
    pub fn control_handle(&self) -> ControlHandle {
        ControlHandle::new(self.control_tx.clone(), Arc::clone(&self.waker))
    }

    /// The address the socketcand server of bus `bus` listens on.
    pub fn socketcand_addr(&self, bus: usize) -> Option<SocketAddr> {
        self.buses
            .get(bus)?
            .socketcand
            .as_ref()
            .and_then(|(l, _)| l.local_addr().ok())
    }

    fn now(&self, at: Instant) -> od::Instant {
        cell_time(self.origin, at)
    }

    fn wall(&self, at: od::Instant) -> Instant {
        self.origin + Duration::from_nanos(at.as_nanos())
    }

    /// Runs the cell in real time until [`StopHandle::stop`]; gives the drives of its buses
    /// back.
    pub fn run(mut self) -> io::Result<Vec<Cell>> {
        if let Some(p) = self.rt_priority {
            if let Err(e) = crate::cell::realtime::set_fifo_priority(p) {
                tracing::warn!(priority = p, error = %e, "SCHED_FIFO refused; running at normal priority");
            }
        }
        let mut events = Events::with_capacity(256);
        let start = Instant::now();
        let mut out = std::mem::take(&mut self.out);
        for b in 0..self.buses.len() {
            let t = self.now(start);
            if let Some(bus) = self.buses.get_mut(b) {
                bus.cell.boot(t, &mut out);
            }
            self.drives_sent(b, start, &mut out);
        }
        self.out = out;
        let t = self.now(start);
        for chain in &mut self.chains {
            chain.chain.boot_with(t, &mut Buses(&mut self.buses));
        }
        self.flush_dirty();
        while !self.stop.load(Ordering::Acquire) {
            let timeout = if self.busy_poll
                || !self.more_to_read.is_empty()
                || !self.chains_to_read.is_empty()
            {
                Some(Duration::ZERO)
            } else {
                let deadline = self.deadline();
                let wait = deadline.map(|d| d.saturating_duration_since(Instant::now()));
                if let (Some(d), Some(w), Some(timer)) = (deadline, wait, &mut self.timer) {
                    timer.arm(d, w);
                }
                wait
            };
            if let Err(e) = self.poll.poll(&mut events, timeout) {
                if e.kind() == io::ErrorKind::Interrupted {
                    continue;
                }
                return Err(e);
            }
            let now = Instant::now();
            // Timers first: an answer shows the drive as of now.
            self.timers(now);
            for event in &events {
                match event.token() {
                    WAKER => {}
                    TIMER => {
                        if let Some(timer) = &mut self.timer {
                            timer.clear();
                        }
                    }
                    Token(t) if t >= FIRST_SERIAL => {
                        self.serial_event(t - FIRST_SERIAL, now, event.is_readable());
                    }
                    Token(t) if (FIRST_CHAIN..FIRST_DYNAMIC).contains(&t) => {
                        self.read_ethercat(t - FIRST_CHAIN);
                    }
                    Token(t) if t < FIRST_DYNAMIC => {
                        let b = (t - 1) / 3;
                        match (t - 1) % 3 {
                            0 => self.accept_socketcand(b),
                            1 => self.read_socketcan(b, now),
                            _ => {
                                if event.is_writable() {
                                    self.flush_upstream(b);
                                }
                                if event.is_readable() || event.is_read_closed() {
                                    self.read_upstream(b, now);
                                }
                            }
                        }
                    }
                    Token(t) => {
                        let i = t - FIRST_DYNAMIC;
                        if i < self.listeners.len() {
                            self.accept(i);
                        } else {
                            let slot = i - self.listeners.len();
                            if event.is_writable() {
                                self.write_pending(slot);
                            }
                            if event.is_readable() || event.is_read_closed() || event.is_error() {
                                let closed = event.is_read_closed() || event.is_error();
                                self.read(slot, now, closed);
                            }
                        }
                    }
                }
            }
            for c in std::mem::take(&mut self.chains_to_read) {
                self.read_ethercat(c);
            }
            for slot in std::mem::take(&mut self.more_to_read) {
                // No event comes for what waits: read on to would-block or end of file.
                self.read(slot, now, true);
            }
            self.control(now);
            self.samples(now);
            self.flush_dirty();
            if events.is_empty() {
                for bus in self.buses.iter_mut().filter(|b| b.trace_dirty) {
                    if let Some(w) = bus.trace.as_mut() {
                        crate::trace::flush_quietly(w);
                    }
                    bus.trace_dirty = false;
                }
            }
        }
        for m in &mut self.modbus {
            m.close_connection();
        }
        Ok(self
            .buses
            .into_iter()
            .map(|mut b| {
                if let Some(w) = b.trace.as_mut() {
                    crate::trace::flush_quietly(w);
                }
                b.cell
            })
            .collect())
    }

    /// The earliest time something is due: a drive, a session's timer, a Modbus cycle, or a
    /// trace to flush.
    fn deadline(&self) -> Option<Instant> {
        let mut at: Option<Instant> = None;
        let mut take = |d: Option<Instant>| {
            at = match (at, d) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            }
        };
        for bus in &self.buses {
            take(bus.cell.deadline().map(|d| self.wall(d)));
            if bus.trace_dirty {
                take(Some(Instant::now() + Duration::from_millis(20)));
            }
        }
        for c in self.slots.iter().flatten() {
            if let Kind::Socketcand { session, .. } = &c.kind {
                take(session.deadline());
            }
        }
        for m in &self.modbus {
            take(Some(self.wall(m.next_cycle())));
        }
        for c in &self.chains {
            take(c.chain.deadline().map(|d| self.wall(d)));
        }
        for s in &self.subscriptions {
            take(Some(s.next));
        }
        for l in &self.serial {
            take(l.deadline().map(|d| self.wall(d)));
        }
        take(self.held_deadline());
        at
    }

    fn timers(&mut self, now: Instant) {
        let t = self.now(now);
        for b in 0..self.buses.len() {
            let Some(bus) = self.buses.get_mut(b) else {
                break;
            };
            if let Some(due) = bus.cell.deadline().filter(|d| *d <= t) {
                self.lateness.record(t.saturating_since(due));
                let mut out = std::mem::take(&mut self.out);
                bus.cell.poll(t, &mut out);
                self.drives_sent(b, now, &mut out);
                self.out = out;
            }
        }
        for chain in &mut self.chains {
            if let Some(due) = chain.chain.deadline().filter(|d| *d <= t) {
                self.lateness.record(t.saturating_since(due));
                chain.chain.poll_with(t, &mut Buses(&mut self.buses));
            }
        }
        for slot in 0..self.slots.len() {
            self.session_timers(slot, now);
        }
        self.serial_timers(now);
        self.release_held(now);
        for drive in 0..self.modbus.len() {
            let t = self.now(now);
            let closed = match self.modbus.get_mut(drive) {
                Some(m) => {
                    let due = m.next_cycle();
                    if due <= t {
                        self.lateness.record(t.saturating_since(due));
                    }
                    m.cycle(t)
                }
                None => false,
            };
            if closed {
                self.close_modbus_of(drive);
            }
        }
    }

    fn session_timers(&mut self, slot: usize, now: Instant) {
        let Some(Some(conn)) = self.slots.get_mut(slot) else {
            return;
        };
        let Kind::Socketcand {
            session, held, bus, ..
        } = &mut conn.kind
        else {
            return;
        };
        let totals = self.buses.get(*bus).map(|b| b.totals).unwrap_or_default();
        if session.deadline().is_none_or(|d| d > now) {
            return;
        }
        let was_streaming = session.is_streaming();
        let effects = &mut self.effects;
        session.poll(now, totals, &mut |e| effects.push(e));
        if session.is_streaming() && !was_streaming {
            conn.pending.extend_from_slice(held);
            held.clear();
        }
        self.carry_out(slot, now);
        self.mark_dirty(slot);
    }

    fn accept_socketcand(&mut self, b: usize) {
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
                    let bitrate = self.buses.get(b).map_or(1_000_000, |x| x.cell.bitrate());
                    let kind = Kind::Socketcand {
                        bus: b,
                        session: Session::new(),
                        decoder: Decoder::with_max_len(max_len),
                        held: Vec::new(),
                        budget: crate::can::frame_budget::FrameBudget::for_bitrate(bitrate),
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

    fn accept(&mut self, i: usize) {
        loop {
            let (accepted, console) = match self.listeners.get(i) {
                Some(Listener::Console { listener, drive }) => (listener.accept(), Ok(*drive)),
                Some(Listener::Modbus { listener, drive }) => (listener.accept(), Err(*drive)),
                None => return,
            };
            match accepted {
                Ok((stream, peer)) => match console {
                    Err(modbus) => self.accept_modbus(stream, peer, modbus),
                    Ok(drive) => {
                        tracing::info!(%peer, bus = drive.bus, drive = drive.drive, "CI terminal connected");
                        let kind = Kind::Console {
                            drive,
                            lines: LineCutter::default(),
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

    /// The CMMO-ST serves one connection at a time: a second one is closed at once without a
    /// byte, unless the first has been closed by its client meanwhile
    /// ([`crate::modbus_tcp::server`]).
    fn accept_modbus(&mut self, stream: TcpStream, peer: SocketAddr, drive: usize) {
        let active = self.slots.iter().position(|c| {
            c.as_ref()
                .is_some_and(|c| matches!(c.kind, Kind::Modbus { drive: d } if d == drive))
        });
        if let Some(slot) = active {
            let closed = self
                .slots
                .get(slot)
                .and_then(Option::as_ref)
                .is_some_and(|c| peer_has_closed(&c.stream));
            if !closed {
                tracing::warn!(%peer, "Modbus: one connection at a time, refusing");
                return;
            }
            self.close(slot, modbus::CloseReason::Peer);
        }
        let t = self.now(Instant::now());
        let Some(m) = self.modbus.get_mut(drive) else {
            return;
        };
        m.open_connection(t);
        tracing::info!(%peer, "Modbus client connected");
        self.add(stream, peer, Kind::Modbus { drive });
    }

    fn close_modbus_of(&mut self, drive: usize) {
        let slot = self.slots.iter().position(|c| {
            c.as_ref()
                .is_some_and(|c| matches!(c.kind, Kind::Modbus { drive: d } if d == drive))
        });
        if let Some(slot) = slot {
            // The drive has already seen the close (watchdog, stalled writes).
            self.remove(slot);
        }
    }

    fn add(&mut self, mut stream: TcpStream, peer: SocketAddr, kind: Kind) -> Option<usize> {
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
            pending: Vec::with_capacity(1024),
            wants_write: false,
            closing: false,
        };
        if let Some(s) = self.slots.get_mut(slot) {
            *s = Some(conn);
        }
        Some(slot)
    }

    /// Closes a connection, telling the drive behind a Modbus one why.
    fn close(&mut self, slot: usize, reason: modbus::CloseReason) {
        if let Some(Some(Connection {
            kind: Kind::Modbus { drive },
            ..
        })) = self.slots.get(slot)
        {
            if let Some(m) = self.modbus.get_mut(*drive) {
                m.close_connection_because(reason);
            }
        }
        self.remove(slot);
    }

    fn remove(&mut self, slot: usize) {
        if let Some(s) = self.slots.get_mut(slot) {
            if let Some(mut conn) = s.take() {
                let _ = self.poll.registry().deregister(&mut conn.stream);
                tracing::info!(peer = %conn.peer, "connection closed");
            }
        }
    }

    /// Reads what a connection has sent and acts on it. `closed`: the event said the peer
    /// has closed its end, so the socket is read to its end of file whatever the length of
    /// the read before (an edge-triggered poll reports the close only once).
    fn read(&mut self, slot: usize, now: Instant, closed: bool) {
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

    fn received(&mut self, slot: usize, bytes: &[u8], now: Instant) {
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
                match self.hold_until(crate::cell::wire_faults::FrontEnd::Modbus(drive), t) {
                    None => self.modbus_request(slot, drive, bytes, t),
                    Some(None) => {}
                    Some(Some(at)) => self.held.push(wire::Held::Modbus {
                        slot,
                        drive,
                        bytes: bytes.to_vec(),
                        at,
                    }),
                }
            }
        }
    }

    /// A Modbus request's bytes on connection `slot` of drive `drive`, answered at `t`.
    fn modbus_request(&mut self, slot: usize, drive: usize, bytes: &[u8], t: od::Instant) {
        let Some(Some(conn)) = self.slots.get_mut(slot) else {
            return;
        };
        let result = match self.modbus.get_mut(drive) {
            Some(m) => m.answer(bytes, t, &mut conn.pending),
            None => Ok(()),
        };
        self.mark_dirty(slot);
        if let Err(reason) = result {
            // The answers before a broken stream still go out.
            self.write_pending(slot);
            self.close(slot, reason);
        }
    }

    /// Bytes typed at a CI terminal: each complete line is answered by its drive at once.
    fn console_bytes(&mut self, slot: usize, drive: OnBus, bytes: &[u8], now: Instant) {
        let t = self.now(now);
        for &b in bytes {
            let Some(Some(Connection {
                kind: Kind::Console { lines, .. },
                ..
            })) = self.slots.get_mut(slot)
            else {
                return;
            };
            let reply = match lines.push(b) {
                None => continue,
                Some(Cut::TooLong) => syntax_error(),
                Some(Cut::Line(line)) => {
                    let mut out = std::mem::take(&mut self.out);
                    let reply = self
                        .buses
                        .get_mut(drive.bus)
                        .and_then(|b| b.cell.ci_line(drive.drive, t, &line, &mut out))
                        .unwrap_or_else(syntax_error);
                    self.drives_sent(drive.bus, now, &mut out);
                    self.out = out;
                    reply
                }
            };
            if let Some(Some(conn)) = self.slots.get_mut(slot) {
                conn.pending.extend_from_slice(reply.as_bytes());
                conn.pending.push(ci_terminal::ANSWER_END);
            }
        }
        self.mark_dirty(slot);
    }

    fn socketcand_messages(&mut self, slot: usize, now: Instant) {
        loop {
            let Some(Some(conn)) = self.slots.get_mut(slot) else {
                return;
            };
            let Kind::Socketcand {
                session,
                decoder,
                bus,
                ..
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
            session.on_message(config, now, message, &mut |e| effects.push(e));
            self.carry_out(slot, now);
        }
    }

    /// What a session asked for.
    fn carry_out(&mut self, slot: usize, now: Instant) {
        let mut effects = std::mem::take(&mut self.effects);
        for effect in effects.drain(..) {
            match effect {
                Effect::Reply(m) => self.send_text(slot, m.to_string().as_bytes()),
                Effect::Open => {}
                Effect::SkipPending => {
                    if let Some(Some(Connection {
                        kind: Kind::Socketcand { held, .. },
                        ..
                    })) = self.slots.get_mut(slot)
                    {
                        held.clear();
                    }
                }
                Effect::Send(frame) => {
                    if let Some(Some(Connection {
                        kind: Kind::Socketcand { bus, budget, .. },
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
                        let port = peer.port();
                        if self.client_faults() {
                            let t = self.now(now);
                            let id = frame.id;
                            match self.client_verdict(slot, port, false, id, t) {
                                None => {}
                                Some(None) => continue,
                                Some(Some(at)) => {
                                    self.held.push(wire::Held::FromClient {
                                        slot,
                                        port,
                                        bus,
                                        frame,
                                        at,
                                    });
                                    continue;
                                }
                            }
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

    /// A reply: written at once when nothing waits before it, so that each reply is a
    /// write of its own.
    fn send_text(&mut self, slot: usize, bytes: &[u8]) {
        let Some(Some(conn)) = self.slots.get_mut(slot) else {
            return;
        };
        conn.pending.extend_from_slice(bytes);
        self.write_pending(slot);
    }

    fn mark_dirty(&mut self, slot: usize) {
        if !self.dirty.contains(&slot) {
            self.dirty.push(slot);
        }
    }

    fn flush_dirty(&mut self) {
        while let Some(slot) = self.dirty.pop() {
            self.write_pending(slot);
        }
    }

    /// Writes what the socket takes; registers for writability while some is left; drops a
    /// client that leaves more than [`MAX_PENDING`] unread.
    fn write_pending(&mut self, slot: usize) {
        let Some(Some(conn)) = self.slots.get_mut(slot) else {
            return;
        };
        let mut written = 0;
        let mut failed = false;
        while written < conn.pending.len() {
            match conn
                .stream
                .write(conn.pending.get(written..).unwrap_or(&[]))
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
        conn.pending.drain(..written);
        if failed {
            self.close(slot, modbus::CloseReason::Peer);
            return;
        }
        if conn.pending.len() > MAX_PENDING {
            tracing::warn!(peer = %conn.peer, "client does not read its data: dropped");
            self.close(slot, modbus::CloseReason::Transport);
            return;
        }
        if conn.pending.is_empty() && conn.closing {
            let _ = conn.stream.shutdown(std::net::Shutdown::Both);
            self.remove(slot);
            return;
        }
        let want = !conn.pending.is_empty();
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

    fn read_socketcan(&mut self, b: usize, now: Instant) {
        loop {
            let Some(s) = self.buses.get(b).and_then(|x| x.socketcan.as_ref()) else {
                return;
            };
            match s.try_recv() {
                Ok(Some(frame)) => self.bus(b, frame, Source::SocketCan, now),
                Ok(None) => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => {
                    tracing::error!(error = %e, "SocketCAN receive failed; interface closed");
                    if let Some(x) = self.buses.get_mut(b) {
                        x.socketcan = None;
                    }
                    return;
                }
            }
        }
    }

    /// Frames the drives of bus `b` sent: on the bus.
    fn drives_sent(&mut self, b: usize, now: Instant, out: &mut Vec<CanFrame>) {
        for f in out.drain(..) {
            self.bus(b, f, Source::Drives, now);
        }
    }

    /// One frame on bus `b`: to every node of it but its source.
    fn bus(&mut self, b: usize, frame: CanFrame, source: Source, now: Instant) {
        let Some(bus) = self.buses.get_mut(b) else {
            return;
        };
        let stamp = SystemTime::now().max(bus.last_stamp);
        bus.last_stamp = stamp;
        bus.totals.frames += 1;
        bus.totals.bytes += frame.payload().len() as u64;
        if !self.taps.is_empty() {
            self.tap(b, &frame, now);
        }
        let Some(bus) = self.buses.get_mut(b) else {
            return;
        };
        let since_epoch = stamp.duration_since(UNIX_EPOCH).unwrap_or_default();
        if let Some(w) = bus.trace.as_mut() {
            if let Err(e) = w.write(since_epoch, &frame) {
                tracing::error!(error = %e, "writing the trace failed; trace stopped");
                bus.trace = None;
            }
            bus.trace_dirty = true;
        }
        if source != Source::SocketCan {
            if let Some(s) = &bus.socketcan {
                if let Err(e) = s.try_send(&frame) {
                    tracing::warn!(error = %e, "SocketCAN: frame not sent");
                }
            }
        }
        if source != Source::Upstream {
            if let Some(up) = bus.upstream.as_mut() {
                // Formatted into the buffer: no allocation per frame.
                let _ = write!(
                    up.pending,
                    "{}",
                    crate::can::socketcand::Message::Send(frame)
                );
            }
            self.flush_upstream(b);
        }
        if Session::forwards(&frame) {
            let mut text = [0u8; FRAME_TEXT_MAX];
            let n = emit_frame(&frame, since_epoch, &mut text);
            self.text.clear();
            self.text.extend_from_slice(text.get(..n).unwrap_or(&[]));
            let per_client = self.client_faults();
            let t = self.now(now);
            for slot in 0..self.slots.len() {
                if per_client {
                    let to = match self.slots.get(slot) {
                        Some(Some(c)) if matches!(c.kind, Kind::Socketcand { bus, .. } if bus == b) => {
                            Some(c.peer.port())
                        }
                        _ => None,
                    };
                    if let Some(port) = to.filter(|_| source != Source::Client(slot)) {
                        match self.client_verdict(slot, port, true, frame.id, t) {
                            None => {}
                            Some(None) => continue,
                            Some(Some(at)) => {
                                self.held.push(wire::Held::ToClient {
                                    slot,
                                    port,
                                    text: self.text.clone(),
                                    at,
                                });
                                continue;
                            }
                        }
                    }
                }
                let Some(c) = self.slots.get_mut(slot) else {
                    continue;
                };
                let Some(conn) = c else {
                    continue;
                };
                if source == Source::Client(slot) {
                    continue;
                }
                let Kind::Socketcand {
                    session, held, bus, ..
                } = &mut conn.kind
                else {
                    continue;
                };
                if *bus != b {
                    continue;
                }
                if session.is_streaming() {
                    conn.pending.extend_from_slice(&self.text);
                } else if session.wants_frames() && held.len() + self.text.len() <= MAX_HELD {
                    held.extend_from_slice(&self.text);
                    continue;
                } else {
                    continue;
                }
                if !self.dirty.contains(&slot) {
                    self.dirty.push(slot);
                }
            }
        }
        if source != Source::Drives {
            let mut out = std::mem::take(&mut self.out);
            let t = self.now(now);
            if let Some(bus) = self.buses.get_mut(b) {
                bus.cell.on_frame(t, &frame, &mut out);
            }
            self.drives_sent(b, now, &mut out);
            self.out = out;
        }
    }
}

/// The kernel's send buffer of a client connection, bounded: what a client leaves unread
/// waits in its own [`MAX_PENDING`] buffer, where the loop sees it, instead of megabytes of
/// autotuned kernel buffer that would hide a client that never reads.
fn limit_send_buffer(stream: &TcpStream, peer: SocketAddr) {
    use std::os::fd::AsFd;
    const SEND_BUFFER: u32 = 64 * 1024;
    if let Err(e) = crate::sys::tcp::set_send_buffer(stream.as_fd(), SEND_BUFFER) {
        tracing::debug!(%peer, error = %e, "could not bound SO_SNDBUF");
    }
}

/// Whether the client has closed its end (end of file waiting, nothing else).
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

/// `at` on the cell's clock, whose zero is `origin`.
fn cell_time(origin: Instant, at: Instant) -> od::Instant {
    od::Instant::from_nanos(
        u64::try_from(at.saturating_duration_since(origin).as_nanos()).unwrap_or(u64::MAX),
    )
}

/// The cell's CAN buses as the EtherCAT chains see them: where a slave that is a CANopen
/// drive as well finds its drive.
struct Buses<'a>(&'a mut [BusState]);

impl BusDrives for Buses<'_> {
    fn can_drive(&mut self, at: OnBus) -> Option<&mut CanDrive> {
        self.0.get_mut(at.bus)?.cell.drives.get_mut(at.drive)
    }
}

impl CellLoop {
    /// Reads EtherCAT frames of chain `c` until none waits (at most [`FRAMES_PER_TURN`]):
    /// each passes the chain and goes back out at once, as through a line of real slaves.
    fn read_ethercat(&mut self, c: usize) {
        let mut frame = std::mem::take(&mut self.frame);
        let mut shared = false;
        for turn in 0..=FRAMES_PER_TURN {
            let Some(chain) = self.chains.get_mut(c) else {
                break;
            };
            if turn == FRAMES_PER_TURN {
                // More may wait: read on next turn, after the other sockets.
                self.chains_to_read.push(c);
                break;
            }
            let n = match chain.socket.try_recv(&mut frame) {
                Ok(Some(n)) => n,
                Ok(None) => continue,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    tracing::error!(interface = chain.socket.interface(), error = %e, "EtherCAT receive failed");
                    break;
                }
            };
            let Some(f) = frame.get_mut(..n) else {
                continue;
            };
            trace_frame(chain.trace.as_ref(), f);
            let t = cell_time(self.origin, Instant::now());
            let front = crate::cell::wire_faults::FrontEnd::Ethercat(c);
            match self.hold_until(front, t) {
                None => {}
                Some(None) => continue,
                Some(Some(at)) => {
                    self.held.push(wire::Held::Ethercat {
                        chain: c,
                        frame: f.to_vec(),
                        at,
                    });
                    continue;
                }
            }
            let Some(chain) = self.chains.get_mut(c) else {
                break;
            };
            shared |= chain.chain.has_bus_drives();
            Self::pass_chain(chain, f, t, &mut self.buses);
        }
        self.frame = frame;
        if shared {
            // A value the master wrote may be due in a TPDO (on change): the CANopen side of
            // the chain's shared drives looks at once.
            let now = Instant::now();
            let t = self.now(now);
            for b in 0..self.buses.len() {
                let on_bus = self
                    .chains
                    .get(c)
                    .is_some_and(|ch| ch.chain.has_drives_on_bus(b));
                if !on_bus {
                    continue;
                }
                let mut out = std::mem::take(&mut self.out);
                if let Some(bus) = self.buses.get_mut(b) {
                    bus.cell.poll(t, &mut out);
                }
                self.drives_sent(b, now, &mut out);
                self.out = out;
            }
        }
    }

    /// One frame through chain `chain` and back out on its socket.
    fn pass_chain(chain: &mut EthercatChain, f: &mut [u8], t: od::Instant, buses: &mut [BusState]) {
        if chain.chain.on_frame_with(t, f, &mut Buses(buses)).forward() {
            trace_frame(chain.trace.as_ref(), f);
            match chain.socket.send(f) {
                Ok(()) => {}
                Err(e) if crate::ecat::link::is_queue_full(&e) => {
                    tracing::warn!(
                        interface = chain.socket.interface(),
                        "TX queue full, frame lost"
                    );
                }
                Err(e) => {
                    tracing::error!(interface = chain.socket.interface(), error = %e, "EtherCAT send failed");
                }
            }
        }
    }

    /// A frame a `delay` fault held back arrives at chain `c` at `t`.
    fn ethercat_frame(&mut self, c: usize, mut frame: Vec<u8>, t: od::Instant) {
        if let Some(chain) = self.chains.get_mut(c) {
            Self::pass_chain(chain, &mut frame, t, &mut self.buses);
        }
    }
}

impl CellLoop {
    /// Frames from the socketcand server the bus joins: on the bus as any client's are.
    fn read_upstream(&mut self, b: usize, now: Instant) {
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
    fn flush_upstream(&mut self, b: usize) {
        let Some(up) = self.buses.get_mut(b).and_then(|x| x.upstream.as_mut()) else {
            return;
        };
        let mut failed = false;
        while !up.pending.is_empty() {
            match up.stream.write(&up.pending) {
                Ok(0) => {
                    failed = true;
                    break;
                }
                Ok(n) => {
                    up.pending.drain(..n.min(up.pending.len()));
                }
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
