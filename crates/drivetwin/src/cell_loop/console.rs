//! Terminals on the loop: a drive's line-based console on a TCP port (the CMMP-AS's CI
//! terminal). The loop owns the connection and reaches the drive; the terminal, a vendor's
//! protocol handed in by whoever builds the [`super::FrontEnds`], cuts the lines and answers
//! them on the drive's objects. Each complete line is answered at once.

use std::time::Instant;

use super::{CellLoop, Connection, Kind};
pub use crate::cell::terminal::{NewTerminal, Terminal, Typed};
use crate::cell::OnBus;

/// A drive's terminal on a TCP port, bound before the loop starts.
pub struct TerminalPort {
    pub listener: std::net::TcpListener,
    /// Its drive.
    pub drive: OnBus,
    /// Its protocol.
    pub terminal: NewTerminal,
}

impl CellLoop {
    /// Bytes typed at a terminal: each complete line is answered by its drive at once.
    pub(super) fn console_bytes(&mut self, slot: usize, drive: OnBus, bytes: &[u8], now: Instant) {
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
                    if let Some(bus) = self.buses.get_mut(drive.bus) {
                        let stations = &mut self.stations;
                        bus.segment
                            .local_access(stations, drive.drive, t, &mut out, &mut |od| {
                                terminal.answer(&line, od, &mut answer);
                                answered = true;
                            });
                    }
                    if !answered {
                        terminal.refuse(&mut answer);
                    }
                    self.drives_sent(drive.bus, now, &mut out);
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
