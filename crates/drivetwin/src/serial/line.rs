//! A serial line as the cell loop serves it: the port (pty or device), the wire with its
//! timing, and the protocol with its drives. The loop calls [`SerialLine::readable`] when the
//! port has bytes, [`SerialLine::due`] at [`SerialLine::deadline`], and
//! [`SerialLine::writable`] when the port takes bytes again.
//!
//! A host that opens the pty and never reads: the answers wait in the wire's bounded buffer
//! ([`super::wire::MAX_OUT`]), then are dropped and counted, logged once; the line goes on
//! answering, and the drives never wait for it.

use std::path::{Path, PathBuf};

use od::Instant;

use super::pty::{Port, PortError};
use super::wire::{Wire, WireCounters};
use super::{Kind, LineDrives};

/// Bytes read from a port per turn of the loop at most (a flood does not starve the rest).
const READS_PER_TURN: usize = 16;

/// The protocol a line speaks with its drives: a vendor's (the Kinco telegrams, its Modbus
/// RTU), handed in by whoever builds the line. It takes the bytes as they complete on the
/// wire and writes its answers onto the wire.
pub trait LineProtocol: Send {
    /// Byte `byte` has arrived at `at`.
    fn on_byte(&mut self, at: Instant, byte: u8, drives: &mut dyn LineDrives, wire: &mut Wire);
    /// The line's own work at `now` (a frame ended by silence), after the bytes arrived.
    fn poll(&mut self, _now: Instant, _drives: &mut dyn LineDrives, _wire: &mut Wire) {}
    /// When [`LineProtocol::poll`] has work next.
    fn deadline(&self) -> Option<Instant> {
        None
    }
    /// The protocol itself, for what only its own type tells (its counters).
    fn as_any(&self) -> &dyn std::any::Any;
}

/// The protocol a line speaks.
pub type Protocol = Box<dyn LineProtocol>;

/// What a line counted on its wire (its protocol's own counts: [`LineCore::protocol`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LineCounters {
    pub wire: WireCounters,
}

/// A line's wire and protocol with its drives, without a port: what the cell loop's
/// [`SerialLine`] and the virtual clock's [`VirtualLine`] share. Bytes in with
/// [`LineCore::receive`], the line's work at [`LineCore::due`], the crossed answers out with
/// [`LineCore::flush`].
pub struct LineCore {
    wire: Wire,
    protocol: Protocol,
    /// Scratch: bytes complete on the wire, with their times.
    arrived: Vec<(Instant, u8)>,
}

impl LineCore {
    /// A line at `baud` bit/s (0: no timing, a real UART times itself) speaking `protocol`.
    pub fn new(baud: u32, protocol: Protocol) -> Self {
        LineCore {
            wire: Wire::new(baud),
            protocol,
            arrived: Vec::with_capacity(256),
        }
    }

    pub fn counters(&self) -> LineCounters {
        LineCounters {
            wire: self.wire.counters(),
        }
    }

    /// The protocol the line speaks.
    pub fn protocol(&self) -> &dyn LineProtocol {
        &*self.protocol
    }

    /// The host wrote `bytes` at `now`.
    pub fn receive(&mut self, now: Instant, bytes: &[u8]) {
        self.wire.receive(now, bytes);
    }

    /// Whatever is due at `now`: bytes complete on the wire, a frame ended by silence,
    /// answers that have crossed. Returns the answer bytes dropped because the host left
    /// too many unread.
    pub fn due(&mut self, now: Instant, drives: &mut dyn LineDrives) -> u64 {
        self.arrived.clear();
        let arrived = &mut self.arrived;
        self.wire.arrived(now, &mut |at, b| arrived.push((at, b)));
        for &(at, b) in &self.arrived {
            self.protocol.on_byte(at, b, drives, &mut self.wire);
        }
        self.protocol.poll(now, drives, &mut self.wire);
        self.wire.crossed(now)
    }

    /// What has crossed goes to `write`, as much as it takes.
    pub fn flush(&mut self, write: &mut dyn FnMut(&[u8]) -> usize) {
        self.wire.flush(write);
    }

    pub fn deadline(&self) -> Option<Instant> {
        od::time::earliest(self.wire.deadline(), self.protocol.deadline())
    }
}

pub struct SerialLine {
    kind: Kind,
    path: PathBuf,
    port: Port,
    core: LineCore,
    /// Bytes the host did not read were dropped: said once.
    warned: bool,
}

impl SerialLine {
    /// Opens `path` (a pty link, or a device) for a line at `baud` bit/s speaking `protocol`.
    pub fn open(kind: Kind, path: &Path, baud: u32, protocol: Protocol) -> Result<Self, PortError> {
        let port = Port::open(path, baud)?;
        // A real UART times the line itself.
        let core = LineCore::new(if port.is_pty() { baud } else { 0 }, protocol);
        Ok(SerialLine {
            kind,
            path: path.to_path_buf(),
            port,
            core,
            warned: false,
        })
    }

    pub fn kind(&self) -> Kind {
        self.kind
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn port(&self) -> &Port {
        &self.port
    }

    pub fn counters(&self) -> LineCounters {
        self.core.counters()
    }

    /// The protocol the line speaks.
    pub fn protocol(&self) -> &dyn LineProtocol {
        self.core.protocol()
    }

    /// The port has bytes (read at `now`).
    pub fn readable(&mut self, now: Instant, drives: &mut dyn LineDrives) {
        let mut buf = [0u8; 1024];
        for _ in 0..READS_PER_TURN {
            match self.port.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => self.core.receive(now, buf.get(..n).unwrap_or(&[])),
                Err(e) => {
                    // EIO while a pty has no reader: nothing to read.
                    tracing::debug!(path = %self.path.display(), error = %e, "serial read");
                    break;
                }
            }
        }
        self.due(now, drives);
    }

    /// Whatever is due at `now` ([`LineCore::due`]), then out to the port.
    pub fn due(&mut self, now: Instant, drives: &mut dyn LineDrives) {
        if self.core.due(now, drives) > 0 && !self.warned {
            self.warned = true;
            tracing::warn!(
                path = %self.path.display(),
                "serial host does not read its answers: dropped (counted; said once)"
            );
        }
        self.writable();
    }

    /// The port takes bytes again: what has crossed goes out.
    pub fn writable(&mut self) {
        let port = &self.port;
        self.core.flush(&mut |b| port.write(b));
    }

    pub fn deadline(&self) -> Option<Instant> {
        self.core.deadline()
    }
}

/// A line of the virtual clock ([`crate::cell_loop::virtual_clock::run_virtual_lines`]): the same wire
/// timing and protocol as a port's line, its host's bytes given as inputs at their virtual
/// times and its answers taken as outputs when they have crossed, so that two runs give the
/// same bytes at the same times.
pub struct VirtualLine {
    kind: Kind,
    core: LineCore,
}

impl VirtualLine {
    /// A line at `baud` bit/s (timed as a pty's) speaking `protocol`.
    pub fn new(kind: Kind, baud: u32, protocol: Protocol) -> Self {
        VirtualLine {
            kind,
            core: LineCore::new(baud, protocol),
        }
    }

    pub fn kind(&self) -> Kind {
        self.kind
    }

    pub fn counters(&self) -> LineCounters {
        self.core.counters()
    }

    /// The protocol the line speaks.
    pub fn protocol(&self) -> &dyn LineProtocol {
        self.core.protocol()
    }

    /// The host writes `bytes` at `now`.
    pub fn input(&mut self, now: Instant, bytes: &[u8]) {
        self.core.receive(now, bytes);
    }

    /// The line's work at `now`; the answers that have crossed by then are appended to `out`.
    pub fn due(&mut self, now: Instant, drives: &mut dyn LineDrives, out: &mut Vec<u8>) {
        self.core.due(now, drives);
        self.core.flush(&mut |b| {
            out.extend_from_slice(b);
            b.len()
        });
    }

    pub fn deadline(&self) -> Option<Instant> {
        self.core.deadline()
    }
}
