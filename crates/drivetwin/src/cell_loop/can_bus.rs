//! The cell's CAN bus on the loop: a frame from any node (the drives, a socketcand client, the
//! SocketCAN interface, the server joined) reaches every other node, and the bus's port's
//! trace and taps ([`crate::cell::can_segment::SegmentBus::port`]).

use std::io::{self, Write};
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use canopen::CanFrame;

use super::{cell_time, CellLoop, Kind, Source};
use crate::can::socketcand::client_link::FrameText;
use crate::can::socketcand::session::Session;
use crate::cell::link::{At, FrontLink, Link};
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
        // The bus's port passes every frame; it only traces and taps it.
        if let Some(segment) = self.cell.bus_mut(b) {
            segment.port_mut().cross(at, &frame);
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
                    up.pending.as_vec_mut(),
                    "{}",
                    crate::can::socketcand::Message::Send(frame)
                );
            }
            self.flush_upstream(b);
        }
        if Session::forwards(&frame) {
            // Formatted once for every client: no allocation per frame.
            let text = FrameText::new(&frame, since_epoch);
            let t = At {
                clock: self.now(now),
                stamp: since_epoch,
            };
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
                let Kind::Socketcand { bus, link, .. } = &mut conn.kind else {
                    continue;
                };
                if *bus != b {
                    continue;
                }
                match link.transmit(t, &text) {
                    // In its send buffer, or kept until its stream starts.
                    Verdict::Pass => {}
                    // Lost, held by the client's link until its time, or not the client's.
                    Verdict::Lost | Verdict::Corrupt | Verdict::Delay(_) => continue,
                }
                if !link.inner().session.is_streaming() {
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
            self.cell.on_frame(b, t, &frame, &mut out);
            self.drives_sent(b, now, &mut out);
            self.out = out;
        }
    }
}
