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
//! reaches the other stations of its segment (`SegmentBus::deliver`), the interface, the trace and every client.
//!
//! The loop is the cell's EtherCAT segments as well: a frame from a master on a chain's
//! network interface passes the chain's slaves in order and goes back out at once; a slave
//! whose drive is a CANopen drive of the cell (`allow_unreal_interfaces`) reaches the very
//! drive the CANopen node serves, so a value written over CoE is the one SDO reads.
//!
//! Each front end is one link to its peer ([`crate::cell::link::FrontLink`]): a socketcand
//! client's, a Modbus server's, an EtherCAT chain's. Its faults and its trace wrap it
//! ([`FrontFaultInjector`], [`Tracer`]), and a TCP connection's send buffer is its innermost
//! link; the loop reads the sockets, offers each link what came and writes what waits in
//! its send buffer.
//!
//! Slow clients: what a client has not taken waits in its link's send buffer, bounded by
//! [`MAX_PENDING`]; a client whose buffer would grow beyond it is dropped, so a client that
//! does not read never delays the others, nor the drives.
//!
//! The loop is where the cell meets its transports: it uses both, and neither uses it (the
//! transports reach the drives through [`crate::cell`]'s types and their own traits, such as
//! [`crate::ecat::chain::BusDrives`] and [`crate::serial::LineDrives`]).
//!
//! Sockets are registered for readability only; a client whose socket does not take all of an
//! answer is registered for writability until its buffer is empty (no wake-up per `ACK`).
//!
//! One `impl CellLoop` per concern, each in its own file: this one runs the loop (its
//! tokens, its wait, the timers due); `connections` accepts, reads and writes the TCP
//! connections; `socketcand`, `console` and `modbus_drives` serve what arrives on them;
//! `can_bus` carries a frame to every node of a bus; `ethercat_chains` passes frames
//! through the chains; `serial` serves the serial lines; `handle` the control handle's
//! requests and samples; `wire` the wire faults, traces and taps.

use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use canopen::CanFrame;
use mio::net::{TcpListener, TcpStream};
use mio::{Events, Interest, Poll, Token, Waker};

use crate::can::socketcand::client_link::ClientStream;
use crate::can::socketcand::session::{Effect, Totals};
use crate::can::socketcand::{Decoder, ServerConfig};
use crate::cell::can_cell::CanCell;
use crate::cell::control::{Command, ControlHandle, DriveViews, PlantSample};
use crate::cell::front_fault_injector::{Arrivals, FrontFaultInjector};
use crate::cell::link::{Link, SendBuffer};
use crate::cell::param_saver::ParamSaver;
use crate::cell::stations::StationId;
use crate::cell::tracer::Tracer;
use crate::ecat::chain::{FrameTap, SlaveChain};
use crate::modbus_tcp::cell_drive::ModbusDrive;
use crate::trace::TraceWriter;
use wake_up::{ChainPace, WakeUp};

mod can_bus;
mod connections;
mod console;
pub use console::{NewTerminal, Terminal, TerminalPort, Typed};
mod ethercat_chains;
mod ethercat_line;
mod fine_timer;
mod handle;
mod modbus_drives;
mod plans;
mod serial;
mod socketcand;
pub mod turn_log;
pub mod virtual_clock;
mod wake_up;
mod wire;

/// Bytes a client may leave unread before it is dropped.
pub const MAX_PENDING: usize = 256 * 1024;

/// Reads of 4 KiB one connection gets per turn of the loop: a client that floods the bus
/// does not keep the loop from the others.
const READS_PER_TURN: usize = 16;

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

/// The transports of one CAN bus of a cell (the bus itself, with its stations, is the
/// cell's: [`CanCell::buses`]).
#[derive(Default)]
pub struct CanBus {
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

/// An EtherCAT chain of the cell on one network interface.
pub struct EthercatChain {
    pub chain: SlaveChain,
    pub socket: crate::ecat::link::SlaveSocket,
    /// Where each request and each answer is copied (`--trace`, a pcap).
    pub trace: Option<FrameTap>,
}

/// An EtherCAT chain's link: its network interface, the faults on the master's frames as
/// they come in, and outermost its trace (`--trace`), which sees every frame the master sent
/// and every answer.
type ChainLink = Tracer<FrontFaultInjector<crate::ecat::link::SlaveSocket>, Option<FrameTap>>;

/// A Modbus TCP server's link: its connection's send buffer (one connection at a time), and
/// the faults on the requests, which outlast a connection.
type ModbusLink = FrontFaultInjector<SendBuffer>;

/// A socketcand client's link: its session and send buffer, and the faults on it alone
/// ([`crate::cell::wire_faults::FrontEnd::Client`]), on its frames to the bus (in) and the
/// bus's frames to it (out).
type ClientLink = FrontFaultInjector<ClientStream>;

/// An EtherCAT chain while the loop runs.
struct ChainState {
    chain: SlaveChain,
    link: ChainLink,
    /// The master's frames and the devices' exchange after the last one
    /// ([`SlaveChain::exchange_with`]), when the loop defers it.
    pace: ChainPace,
    /// The 1010h saves its slaves asked for, written beside the loop
    /// ([`CellLoop::hand_off_saves`]).
    saver: ParamSaver<usize>,
}

impl ChainState {
    /// The network interface the chain is on.
    fn interface(&self) -> &str {
        self.link.inner().inner().interface()
    }

    /// The chain's network interface, its link's innermost.
    fn socket(&mut self) -> &mut crate::ecat::link::SlaveSocket {
        self.link.inner_mut().inner_mut()
    }
}

/// Every socket a cell serves, bound before the loop starts.
#[derive(Default)]
pub struct FrontEnds {
    /// The transports of the cell's CAN buses, by bus (`buses[b]` is those of the cell's
    /// bus `b`; a bus without an entry has none).
    pub buses: Vec<CanBus>,
    /// Terminals of drives (the CMMP-AS's CI terminal): a listener, its drive and its
    /// protocol.
    pub ci_terminals: Vec<TerminalPort>,
    /// Drives on Modbus TCP (the CMMO-ST), each with its own listener.
    pub modbus: Vec<ModbusDrive>,
    /// EtherCAT chains (at most [`MAX_CHAINS`]).
    pub ethercat: Vec<EthercatChain>,
    /// Serial lines (RS232, RS485) and the drives on them ([`crate::serial`]).
    pub serial: Vec<crate::serial::line::SerialLine>,
    /// Ask for `SCHED_FIFO` at this priority for the loop's thread (as a drive's firmware
    /// runs its fieldbus task); refused, [`CellLoop::run`] fails with the reason
    /// ([`crate::cell::realtime`]).
    pub rt_priority: Option<u8>,
    /// Ask for this time slice under the fair scheduler for the loop's thread instead
    /// (`--sched-slice-us`); refused or not kept, [`CellLoop::run`] fails with the reason.
    pub sched_slice: Option<Duration>,
    /// Never sleep: poll the sockets without waiting (`--busy-poll`), as a device's fieldbus
    /// hardware is always awake; the lowest round trip, at the price of one CPU kept busy.
    pub busy_poll: bool,
    /// What only the drives' vendors tell (the display a drive has).
    pub views: DriveViews,
    /// What the cell file plans for the drives outside the CAN buses (a CMMO-ST on Modbus
    /// TCP, an EtherCAT chain's own drive), which join the cell as the loop starts: put on
    /// the cell's timeline then, by the id each has (the CAN stations' are on it already).
    pub plans: Vec<crate::cell::planned::OutsidePlans>,
    /// The faults the cell file plans for the EtherCAT lines (`[[ethercat_line]]`): carried
    /// out by the loop at their times on its clock.
    pub line_plans: Vec<crate::cell::ethercat_line::TimedLineAction>,
}

/// A bus's transports while the loop runs (the bus itself is the cell's; its port,
/// [`crate::cell::can_segment::SegmentBus::port`], traces and taps every frame the loop
/// carries on it).
struct BusState {
    socketcand: Option<(TcpListener, ServerConfig)>,
    socketcan: Option<crate::can::socketcan::RawCanSocket>,
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
    pending: SendBuffer,
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
    /// The longest turns and what the loop did in them ([`turn_log`]).
    turns: turn_log::TurnLog,
    /// The transports of each of the cell's CAN buses (bus `b`'s: `buses[b]`).
    buses: Vec<BusState>,
    /// The cell: every station (the buses' in bus order, then the EtherCAT chains' own in
    /// chain and wire order) and the CAN buses, which name them by id as the chains do.
    cell: CanCell,
    /// The cell clock's zero.
    origin: Instant,
    /// Listeners by token - FIRST_DYNAMIC; connections after them.
    listeners: Vec<Listener>,
    slots: Vec<Option<Connection>>,
    modbus: Vec<ModbusDrive>,
    chains: Vec<ChainState>,
    serial: Vec<crate::serial::line::SerialLine>,
    /// Scratch: frames the drives sent while a serial line reached them, with their bus.
    serial_sent: Vec<(usize, CanFrame)>,
    /// Chains that had more frames waiting than one turn takes, bit `c` for chain `c`: a set
    /// of bits, not a `Vec` taken and dropped each turn, so that a master sending back to
    /// back (a burst after a stall) costs no allocation on the frame's path.
    chains_to_read: u32,
    /// Scratch: one Ethernet frame.
    frame: Vec<u8>,
    scheduling: crate::cell::realtime::LoopScheduling,
    busy_poll: bool,
    views: DriveViews,
    /// Connections that had more to read than one turn takes.
    more_to_read: Vec<usize>,
    /// Connections with bytes to write before the loop waits again.
    dirty: Vec<usize>,
    /// Scratch: frames the drives sent.
    out: Vec<CanFrame>,
    effects: Vec<Effect>,
    control_tx: std::sync::mpsc::Sender<Command>,
    control_rx: std::sync::mpsc::Receiver<Command>,
    /// The turn the loop sleeps until, for the control handles' requests to ride on.
    next_turn: Arc<crate::cell::next_turn::NextTurn>,
    subscriptions: Vec<Subscription>,
    /// Each Modbus drive's server's link, by drive (a chain's is in its [`ChainState`], a
    /// socketcand client's in its connection, a bus's faults in its cell).
    modbus_links: Vec<ModbusLink>,
    /// The order in which the front ends' faults held their frames, over all of them: what
    /// is due at one turn is released in that order ([`Arrivals`]).
    arrivals: Arrivals,
    /// The faults the cell file plans for the EtherCAT lines: (chain, action) ([`plans`]);
    /// the drives' plans are the cell's.
    line_plans: crate::cell::planned::Timeline<(usize, crate::cell::ethercat_line::LineAction)>,
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
    Console {
        listener: TcpListener,
        drive: StationId,
        terminal: NewTerminal,
    },
    Modbus {
        listener: TcpListener,
        drive: usize,
    },
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

/// A TCP connection; the bytes it has not taken yet are in its link's send buffer
/// ([`connections::send_buffer`]).
struct Connection {
    stream: TcpStream,
    peer: SocketAddr,
    kind: Kind,
    /// Registered for writability too (while its send buffer is not empty).
    wants_write: bool,
    /// Close once its send buffer is written.
    closing: bool,
}

enum Kind {
    Socketcand {
        bus: usize,
        decoder: Decoder,
        /// What it may put on the bus (the bus's frame rate).
        budget: crate::can::frame_budget::FrameBudget,
        link: Box<ClientLink>,
    },
    Console {
        drive: StationId,
        terminal: Box<dyn Terminal>,
        sent: SendBuffer,
    },
    /// Its send buffer is its drive's server's link's.
    Modbus { drive: usize },
}

impl CellLoop {
    /// `cell` with the sockets of `front`: the transports of its CAN buses (`front.buses`,
    /// by bus) and its other front ends.
    pub fn new(mut cell: CanCell, mut front: FrontEnds) -> io::Result<CellLoop> {
        if cell.buses.len() > MAX_BUSES || front.buses.len() > cell.buses.len() {
            return Err(io::Error::other(format!(
                "{} CAN buses ({} with transports): a cell has at most {MAX_BUSES}",
                cell.buses.len(),
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
        let mut transports = std::mem::take(&mut front.buses).into_iter();
        for b in 0..cell.buses.len() {
            let bus = transports.next().unwrap_or_default();
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
                        pending: SendBuffer::default(),
                        wants_write: false,
                    })
                }
                None => None,
            };
            if let (Some(trace), Some(segment)) = (bus.trace, cell.bus_mut(b)) {
                segment.port_mut().sink_mut().start(Box::new(trace));
            }
            buses.push(BusState {
                upstream,
                socketcand,
                socketcan: bus.socketcan,
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
        for chain in &mut front.ethercat {
            // The chain's own drives join the cell's list, and its slaves name every drive
            // by id there.
            chain.chain.join_cell(&mut cell);
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
        for port in front.ci_terminals {
            port.listener.set_nonblocking(true)?;
            listeners.push(Listener::Console {
                listener: TcpListener::from_std(port.listener),
                drive: port.drive,
                terminal: port.terminal,
            });
        }
        for (drive, m) in front.modbus.iter_mut().enumerate() {
            // The drive becomes a station of the cell; its front end reaches it by its id.
            m.join(&mut cell.stations);
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
        let arrivals = Arrivals::default();
        let chains: Vec<ChainState> = front
            .ethercat
            .into_iter()
            .map(|c| ChainState {
                chain: c.chain,
                link: Tracer::new(
                    FrontFaultInjector::inbound(c.socket, arrivals.clone()),
                    c.trace,
                ),
                pace: ChainPace::new(Instant::now()),
                saver: ParamSaver::default(),
            })
            .collect();
        plans::plan_outside(&mut cell, front.plans, &chains, &front.modbus);
        let line_plans = plans::line_timeline(front.line_plans, &chains);
        Ok(CellLoop {
            control_tx,
            control_rx,
            next_turn: Arc::default(),
            subscriptions: Vec::new(),
            modbus_links: front
                .modbus
                .iter()
                .map(|_| {
                    FrontFaultInjector::inbound(SendBuffer::with_capacity(1024), arrivals.clone())
                })
                .collect(),
            poll,
            stop: Arc::new(AtomicBool::new(false)),
            waker,
            timer,
            lateness: Arc::default(),
            turns: turn_log::TurnLog::new(Instant::now()),
            buses,
            cell,
            origin: Instant::now(),
            listeners,
            slots: Vec::new(),
            modbus: front.modbus,
            chains,
            arrivals,
            line_plans,
            serial: front.serial,
            serial_sent: Vec::new(),
            chains_to_read: 0,
            frame: vec![0; crate::ecat::MAX_FRAME],
            scheduling: crate::cell::realtime::LoopScheduling {
                rt_priority: front.rt_priority,
                slice: front.sched_slice,
            },
            busy_poll: front.busy_poll,
            views: front.views,
            more_to_read: Vec::new(),
            dirty: Vec::new(),
            out: Vec::with_capacity(256),
            effects: Vec::new(),
        })
    }

    /// How late the loop serves its timers, readable while it runs and after.
    pub fn lateness(&self) -> Arc<crate::cell::lateness::Lateness> {
        Arc::clone(&self.lateness)
    }

    /// The loop's longest turns, filled in when it stops.
    pub fn turn_report(&self) -> Arc<std::sync::Mutex<turn_log::TurnReport>> {
        self.turns.report()
    }

    pub fn stop_handle(&self) -> StopHandle {
        StopHandle {
            waker: Arc::clone(&self.waker),
            stop: Arc::clone(&self.stop),
        }
    }

    /// A handle to the cell while it runs (see [`crate::cell::control`]).
    pub fn control_handle(&self) -> ControlHandle {
        ControlHandle::new(
            self.control_tx.clone(),
            Arc::clone(&self.waker),
            Arc::clone(&self.next_turn),
        )
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

    /// Runs the cell in real time until [`StopHandle::stop`]; gives the cell back (its
    /// stations and buses, the transports closed). A drive's load FMU that fails ends the run with its error
    /// ([`crate::cosim::FmuLoadError`] inside the `io::Error`).
    pub fn run(mut self) -> io::Result<CanCell> {
        // The thread that answers the frames, alone: what it starts begins at normal
        // priority (`sys::sched`), the console's threads run batch.
        self.scheduling.apply().map_err(io::Error::other)?;
        let mut events = Events::with_capacity(256);
        let start = Instant::now();
        let mut out = std::mem::take(&mut self.out);
        for b in 0..self.buses.len() {
            let t = self.now(start);
            self.cell.boot(b, t, &mut out);
            self.drives_sent(b, start, &mut out);
        }
        self.out = out;
        let t = self.now(start);
        for chain in &mut self.chains {
            chain.chain.boot_with(t, &mut self.cell);
        }
        self.flush_dirty();
        self.turns.start(self.sync0_total());
        let mut load_failure = None;
        // The wake-up a turn that answered frames alone found already ([`Self::frames_only`]),
        // for its wait: nothing changed since.
        let mut planned: Option<Option<WakeUp>> = None;
        while !self.stop.load(Ordering::Acquire) {
            let reuse = planned.take();
            if self.busy_poll {
                // A master's frame, answered from the ring before the turn's poll.
                let spin_end = Instant::now() + ethercat_chains::RING_SPIN;
                let until = self.deadline().map_or(spin_end, |d| d.min(spin_end));
                self.spin_on_rings(until);
            }
            let timeout =
                if self.busy_poll || !self.more_to_read.is_empty() || self.chains_to_read != 0 {
                    self.next_turn.publish(None);
                    Some(Duration::ZERO)
                } else {
                    let now = Instant::now();
                    let wake = match reuse {
                        Some(wake) => wake,
                        None => self.wake_up(now),
                    };
                    let deadline = wake.map(|w| w.at);
                    // A request that came in after this turn's `control` is served at once.
                    let pending = self.next_turn.publish(deadline);
                    let wait = deadline
                        .map(|d| d.saturating_duration_since(now))
                        .filter(|_| !pending)
                        .or(pending.then_some(Duration::ZERO));
                    self.turns.waits_until(deadline.filter(|_| wait.is_some()));
                    match (wake, wait, &mut self.timer) {
                        (Some(wake), Some(w), Some(timer)) if !w.is_zero() => {
                            timer.arm(wake, w);
                            // The timerfd wakes the loop by then: epoll's own millisecond timer,
                            // armed and cancelled at every wait, would only lengthen the wake-up
                            // of a frame that comes first.
                            if timer.serves(wake) {
                                // A timer kept within the wake-up's stretch is what the loop
                                // waits for (the turn log's "woke late").
                                self.turns.waits_until(timer.armed());
                                None
                            } else {
                                wait
                            }
                        }
                        _ => wait,
                    }
                };
            if let Err(e) = self.poll.poll(&mut events, timeout) {
                if e.kind() == io::ErrorKind::Interrupted {
                    continue;
                }
                return Err(e);
            }
            let now = Instant::now();
            self.turns.begin(now);
            // A master's EtherCAT frames before anything else: each is answered before the
            // drives step and the other sockets are served ([`ethercat_chains`]).
            self.answer_frames(&events);
            self.turns.mark(turn_log::Part::Pass);
            // A turn that had frames to answer and nothing else to do sleeps again at once:
            // the devices' exchange after them waits for the loop's next wake-up, so that a
            // master on the same CPU gets it back with its answer. Any other turn runs the
            // exchange first.
            planned = self.frames_only(&events, now);
            let frames_only = planned.is_some();
            if !frames_only {
                self.settle_chains();
                self.turns.mark(turn_log::Part::Exchange);
                self.turn(&events, now);
                // Frames a flooded chain left for this turn: exchanged before the samples.
                self.settle_chains();
                self.turns.mark(turn_log::Part::Exchange);
            }
            if self.control(now) {
                planned = None;
            }
            if !frames_only {
                self.samples(now);
            }
            self.flush_dirty();
            if events.is_empty() {
                for bus in self.cell.buses.iter_mut().filter(|b| b.port().unflushed()) {
                    bus.port_mut().flush();
                }
            }
            self.turns.mark(turn_log::Part::Rest);
            // A frame's turn ends with its master waiting for the loop to sleep: the thread's
            // usage (two system calls) is read at the next turn that is not one.
            self.turns
                .end(Instant::now(), self.sync0_total(), !frames_only);
            if let Some(e) = self.load_failure() {
                load_failure = Some(e);
                break;
            }
        }
        self.turns.publish();
        self.settle_chains();
        for m in &mut self.modbus {
            m.close_connection();
        }
        if let Some(e) = load_failure {
            for bus in &mut self.cell.buses {
                bus.port_mut().flush();
            }
            return Err(io::Error::other(e));
        }
        for bus in &mut self.cell.buses {
            bus.port_mut().flush();
        }
        Ok(self.cell)
    }

    /// Whether this turn answered frames and has nothing else to do: every event is a
    /// chain's, nothing is due and no socket has more to read. If so, the loop's next
    /// wake-up, which told it: the wait after the turn takes it rather than go over every
    /// slave's deadline again on the frame's path.
    fn frames_only(&self, events: &Events, now: Instant) -> Option<Option<WakeUp>> {
        let answered_alone = self.chains.iter().any(|c| c.pace.pending())
            && events
                .iter()
                .all(|e| (FIRST_CHAIN..FIRST_DYNAMIC).contains(&e.token().0))
            && self.chains_to_read == 0
            && self.more_to_read.is_empty();
        if !answered_alone {
            return None;
        }
        let wake = self.wake_up(now);
        (!matches!(wake, Some(w) if w.at <= now)).then_some(wake)
    }

    /// The timers due and every socket's event of a turn but the chains' (answered first).
    fn turn(&mut self, events: &Events, now: Instant) {
        // Then the timers: an answer on the other front ends shows the drive as of now.
        self.timers(now);
        self.turns.mark(turn_log::Part::Timers);
        for event in events {
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
                // Answered first, above.
                Token(t) if (FIRST_CHAIN..FIRST_DYNAMIC).contains(&t) => {}
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
        let to_read = std::mem::take(&mut self.chains_to_read);
        for c in 0..self.chains.len() {
            if to_read & ethercat_chains::chain_bit(c) != 0 {
                self.read_ethercat(c);
            }
        }
        for slot in std::mem::take(&mut self.more_to_read) {
            // No event comes for what waits: read on to would-block or end of file.
            self.read(slot, now, true);
        }
        self.turns.mark(turn_log::Part::Sockets);
    }

    /// Why a drive's load FMU stopped the cell, once one has: any station of the cell (on a
    /// CAN bus or a chain's own) or drive served over Modbus TCP (the CMMO-ST).
    fn load_failure(&mut self) -> Option<crate::cosim::FmuLoadError> {
        self.cell
            .load_failure()
            .or_else(|| self.chains.iter().find_map(|c| c.chain.load_failure()))
            .cloned()
            .or_else(|| {
                let stations = &mut self.cell.stations;
                self.modbus.iter_mut().find_map(|m| {
                    m.device_mut(stations)
                        .and_then(|d| d.load_failure().cloned())
                })
            })
    }

    /// The earliest time something is due: a drive, a session's timer, a Modbus cycle, a
    /// planned change, or a trace to flush.
    fn deadline(&self) -> Option<Instant> {
        self.wake_up(Instant::now()).map(|w| w.at)
    }

    /// When the loop wakes next ([`deadline`](Self::deadline)), and by when a timer armed
    /// already wakes it as well ([`wake_up`]).
    fn wake_up(&self, now: Instant) -> Option<WakeUp> {
        let mut at: Option<Instant> = None;
        let mut take = |d: Option<Instant>| at = od::time::earliest(at, d);
        for (b, bus) in self.cell.buses.iter().enumerate() {
            take(self.cell.deadline_of(b).map(|d| self.wall(d)));
            if bus.port().unflushed() {
                take(Some(now + Duration::from_millis(20)));
            }
        }
        for c in self.slots.iter().flatten() {
            if let Kind::Socketcand { link, .. } = &c.kind {
                take(link.inner().session.deadline());
            }
        }
        for m in &self.modbus {
            take(m.next_cycle(&self.cell.stations).map(|d| self.wall(d)));
        }
        let mut exchanges = None;
        for c in &self.chains {
            take(c.chain.wake_by().map(|d| self.wall(d)));
            exchanges = WakeUp::first(exchanges, c.pace.wake_up(now));
        }
        for l in &self.serial {
            take(l.deadline().map(|d| self.wall(d)));
        }
        take(self.held_deadline());
        take(self.plans_deadline().map(|d| self.wall(d)));
        let wake = WakeUp::first(at.map(WakeUp::exact), exchanges);
        let sample = self.subscriptions.iter().map(|s| s.next).min();
        handle::with_samples(wake.map(|w| w.at), sample).map(|at| match wake {
            Some(w) if w.at == at => w,
            _ => WakeUp::exact(at),
        })
    }

    fn timers(&mut self, now: Instant) {
        let t = self.now(now);
        if let Some(due) = self.plans_deadline().filter(|d| *d <= t) {
            self.lateness.record(t.saturating_since(due));
            self.carry_out_plans(now);
        }
        for b in 0..self.buses.len() {
            if let Some(due) = self.cell.deadline_of(b).filter(|d| *d <= t) {
                self.lateness.record(t.saturating_since(due));
                let mut out = std::mem::take(&mut self.out);
                self.cell.poll(b, t, &mut out);
                self.drives_sent(b, now, &mut out);
                self.out = out;
            }
        }
        for chain in &mut self.chains {
            if let Some(due) = chain.chain.deadline().filter(|d| *d <= t) {
                // Late only past the chain's wake-up (a step's grace).
                let by = chain.chain.wake_by().unwrap_or(due);
                self.lateness.record(t.saturating_since(by));
                chain.chain.poll_with(t, &mut self.cell);
                self.turns.poll();
                Self::hand_off_saves(chain, &mut self.cell);
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
                    let stations = &mut self.cell.stations;
                    if let Some(due) = m.next_cycle(stations).filter(|due| *due <= t) {
                        self.lateness.record(t.saturating_since(due));
                    }
                    m.cycle(t, stations)
                }
                None => false,
            };
            if closed {
                self.close_modbus_of(drive);
            }
        }
    }
}

/// `at` on the cell's clock, whose zero is `origin`.
fn cell_time(origin: Instant, at: Instant) -> od::Instant {
    od::Instant::from_nanos(
        u64::try_from(at.saturating_duration_since(origin).as_nanos()).unwrap_or(u64::MAX),
    )
}
