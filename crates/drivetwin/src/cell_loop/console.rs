//! CI terminals on the loop: each complete line typed is answered by its drive at once.

use std::time::Instant;

use drive::vendors::festo_cmmp_as::ci_terminal::{self, syntax_error, Cut};

use super::{CellLoop, Connection, Kind};
use crate::cell::OnBus;

impl CellLoop {
    /// Bytes typed at a CI terminal: each complete line is answered by its drive at once.
    pub(super) fn console_bytes(&mut self, slot: usize, drive: OnBus, bytes: &[u8], now: Instant) {
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
}
