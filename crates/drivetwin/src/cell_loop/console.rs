//! Terminals on the loop: a drive's line-based console on a TCP port (the CMMP-AS's CI
//! terminal). The loop owns the connection and reaches the drive; the terminal, a vendor's
//! protocol handed in by whoever builds the [`super::FrontEnds`], cuts the lines and answers
//! them on the drive's objects. Each complete line is answered at once.

use std::time::Instant;

use super::{CellLoop, Connection, Kind};
use crate::cell::stations::StationId;
pub use crate::cell::terminal::{NewTerminal, Terminal, Typed};

/// A drive's terminal on a TCP port, bound before the loop starts.
pub struct TerminalPort {
    pub listener: std::net::TcpListener,
    /// Its drive's station in the cell.
    pub drive: StationId,
    /// Its protocol.
    pub terminal: NewTerminal,
}

impl CellLoop {
    /// Bytes typed at a terminal: each complete line is answered by its drive at once.
    pub(super) fn console_bytes(
        &mut self,
        slot: usize,
        drive: StationId,
        bytes: &[u8],
        now: Instant,
    ) {
        let t = self.now(now);
        for &b in bytes {
            let Some(Some(Connection {
                kind: Kind::Console { terminal, .. },
                ..
            })) = self.slots.get_mut(slot)
            else {
                return;
            };
            let mut answer = Vec::new();
            match terminal.push(b) {
                None => continue,
                Some(Typed::TooLong) => terminal.refuse(&mut answer),
                Some(Typed::Line(line)) => {
                    let mut out = std::mem::take(&mut self.out);
                    let mut answered = false;
                    let bus = self.cell.local_access(drive, t, &mut out, &mut |od| {
                        terminal.answer(&line, od, &mut answer);
                        answered = true;
                    });
                    if !answered {
                        terminal.refuse(&mut answer);
                    }
                    match bus {
                        Some(b) => self.drives_sent(b, now, &mut out),
                        None => out.clear(),
                    }
                    self.out = out;
                }
            }
            if let Some(Some(Connection {
                kind: Kind::Console { sent, .. },
                ..
            })) = self.slots.get_mut(slot)
            {
                sent.push(&answer);
            }
        }
        self.mark_dirty(slot);
    }
}
