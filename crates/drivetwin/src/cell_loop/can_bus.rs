//! The cell's CAN bus on the loop: a frame from any node (the drives, a socketcand client, the
//! SocketCAN interface, the server joined) reaches every other node, and its link's trace and
//! taps.

use std::io::{self, Write};
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use canopen::CanFrame;

use super::{cell_time, CellLoop, Kind, Source, MAX_HELD};
use crate::can::socketcand::codec::{emit_frame, FRAME_TEXT_MAX};
use crate::can::socketcand::session::Session;
use crate::cell::link::{At, Link};
use crate::cell::wire_faults::Verdict;

impl CellLoop {
    pub(super) fn read_socketcan(&mut self, b: usize, now: Instant) {
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
    pub(super) fn drives_sent(&mut self, b: usize, now: Instant, out: &mut Vec<CanFrame>) {
        for f in out.drain(..) {
            self.bus(b, f, Source::Drives, now);
        }
    }

    /// One frame on bus `b`: to every node of it but its source.
    pub(super) fn bus(&mut self, b: usize, frame: CanFrame, source: Source, now: Instant) {
        let Some(bus) = self.buses.get_mut(b) else {
            return;
        };
        let stamp = SystemTime::now().max(bus.last_stamp);
        bus.last_stamp = stamp;
        bus.totals.frames += 1;
        bus.totals.bytes += frame.payload().len() as u64;
        let since_epoch = stamp.duration_since(UNIX_EPOCH).unwrap_or_default();
        let at = At {
            clock: cell_time(self.origin, now),
            stamp: since_epoch,
        };
        // The loop's bus passes every frame; its link only traces and taps it.
        bus.link.cross(at, &frame);
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
            let t = self.now(now);
            for slot in 0..self.slots.len() {
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
                    session,
                    held,
                    bus,
                    faults,
                    ..
                } = &mut conn.kind
                else {
                    continue;
                };
                if *bus != b {
                    continue;
                }
                match faults.cross_out(t, frame.id, &mut self.arrivals, || self.text.clone()) {
                    Verdict::Pass => {}
                    // Lost, or held by the client's link until its time.
                    Verdict::Lost | Verdict::Corrupt | Verdict::Delay(_) => continue,
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
                bus.segment.on_frame(t, &frame, &mut out);
            }
            self.drives_sent(b, now, &mut out);
            self.out = out;
        }
    }
}
