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
use super::rs232_line::{TelegramCounters, TelegramLine};
use super::rtu_line::{RtuCounters, RtuLine};
use super::wire::{Wire, WireCounters};
use super::{Kind, LineDrives};

/// Bytes read from a port per turn of the loop at most (a flood does not starve the rest).
const READS_PER_TURN: usize = 16;

/// The protocol a line speaks.
pub enum Protocol {
    Telegrams(TelegramLine),
    Rtu(Box<RtuLine>),
}

/// Everything a line counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LineCounters {
    pub wire: WireCounters,
    pub telegrams: Option<TelegramCounters>,
    pub rtu: Option<RtuCounters>,
}

pub struct SerialLine {
    kind: Kind,
    path: PathBuf,
    port: Port,
    wire: Wire,
    protocol: Protocol,
    /// Bytes the host did not read were dropped: said once.
    warned: bool,
    /// Scratch: bytes complete on the wire, with their times.
    arrived: Vec<(Instant, u8)>,
}

impl SerialLine {
    /// Opens `path` (a pty link, or a device) for a line at `baud` bit/s speaking `protocol`.
    pub fn open(kind: Kind, path: &Path, baud: u32, protocol: Protocol) -> Result<Self, PortError> {
        let port = Port::open(path, baud)?;
        // A real UART times the line itself.
        let wire = Wire::new(if port.is_pty() { baud } else { 0 });
        Ok(SerialLine {
            kind,
            path: path.to_path_buf(),
            port,
            wire,
            protocol,
            warned: false,
            arrived: Vec::with_capacity(256),
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
        LineCounters {
            wire: self.wire.counters(),
            telegrams: match &self.protocol {
                Protocol::Telegrams(t) => Some(t.counters()),
                Protocol::Rtu(_) => None,
            },
            rtu: match &self.protocol {
                Protocol::Rtu(r) => Some(r.counters()),
                Protocol::Telegrams(_) => None,
            },
        }
    }

    /// The port has bytes (read at `now`).
    pub fn readable(&mut self, now: Instant, drives: &mut dyn LineDrives) {
        let mut buf = [0u8; 1024];
        for _ in 0..READS_PER_TURN {
            match self.port.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => self.wire.receive(now, buf.get(..n).unwrap_or(&[])),
                Err(e) => {
                    // EIO while a pty has no reader: nothing to read.
                    tracing::debug!(path = %self.path.display(), error = %e, "serial read");
                    break;
                }
            }
        }
        self.due(now, drives);
    }

    /// Whatever is due at `now`: bytes complete on the wire, a frame ended by silence,
    /// answers that have crossed.
    pub fn due(&mut self, now: Instant, drives: &mut dyn LineDrives) {
        self.arrived.clear();
        let arrived = &mut self.arrived;
        self.wire.arrived(now, &mut |at, b| arrived.push((at, b)));
        for &(at, b) in &self.arrived {
            match &mut self.protocol {
                Protocol::Telegrams(t) => t.on_byte(at, b, drives, &mut self.wire),
                Protocol::Rtu(r) => r.on_byte(at, b, drives, &mut self.wire),
            }
        }
        if let Protocol::Rtu(r) = &mut self.protocol {
            r.poll(now, drives, &mut self.wire);
        }
        if self.wire.crossed(now) > 0 && !self.warned {
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
        self.wire.flush(&mut |b| port.write(b));
    }

    pub fn deadline(&self) -> Option<Instant> {
        let protocol = match &self.protocol {
            Protocol::Rtu(r) => r.deadline(),
            Protocol::Telegrams(_) => None,
        };
        od::time::earliest(self.wire.deadline(), protocol)
    }
}
