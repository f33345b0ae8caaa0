//! A CAN link that copies every frame crossing it to a trace file ([`TraceWriter`]) and to
//! taps (channels of frames with their time on the cell's clock), then passes it to the link
//! it wraps: as smoltcp's `phy::Tracer`, a link that wraps a link
//! ([`crate::cell::link`]). A trace can start and stop while the cell runs; a tap lasts
//! until its receiver is dropped.

use std::sync::mpsc::{SyncSender, TrySendError};
use std::time::Duration;

use canopen::CanFrame;
use od::Instant;

use crate::cell::link::{At, Link};
use crate::cell::wire_faults::{Sender, Verdict};
use crate::trace::TraceWriter;

/// A receiver of every frame of a link, with its time on the cell's clock.
pub type Tap = SyncSender<(Duration, CanFrame)>;

/// A CAN link traced.
pub struct Tracer<L> {
    inner: L,
    trace: Option<TraceWriter>,
    /// Frames written to the trace since its last flush.
    unflushed: bool,
    taps: Vec<Tap>,
}

impl<L: Link<Frame = CanFrame>> Tracer<L> {
    /// `inner`, traced into `trace` (none: until [`Tracer::start`]).
    pub fn new(inner: L, trace: Option<TraceWriter>) -> Self {
        Tracer {
            inner,
            trace,
            unflushed: false,
            taps: Vec::new(),
        }
    }

    pub fn is_tracing(&self) -> bool {
        self.trace.is_some()
    }

    /// Traces from now on into `trace`.
    pub fn start(&mut self, trace: TraceWriter) {
        self.trace = Some(trace);
    }

    /// Stops the trace and gives it back, not yet flushed.
    pub fn stop(&mut self) -> Option<TraceWriter> {
        self.unflushed = false;
        self.trace.take()
    }

    /// Every frame from now on goes to `tap` as well; a tap that falls behind loses frames
    /// (the link never waits).
    pub fn tap(&mut self, tap: Tap) {
        self.taps.push(tap);
    }

    /// The link it wraps.
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }
}

impl<L: Link<Frame = CanFrame>> Link for Tracer<L> {
    type Frame = CanFrame;

    fn cross(&mut self, at: At, frame: &CanFrame) -> Verdict {
        if !self.taps.is_empty() {
            let t = Duration::from_nanos(at.clock.as_nanos());
            // A tap gone is forgotten; a full one loses the frame.
            self.taps.retain(|tx| {
                !matches!(tx.try_send((t, *frame)), Err(TrySendError::Disconnected(_)))
            });
        }
        if let Some(w) = self.trace.as_mut() {
            if let Err(e) = w.write(at.stamp, frame) {
                tracing::error!(error = %e, "writing the trace failed; trace stopped");
                self.trace = None;
            }
            self.unflushed = true;
        }
        self.inner.cross(at, frame)
    }

    fn cut_off(&self, at: Instant, who: Sender) -> bool {
        self.inner.cut_off(at, who)
    }

    fn deadline(&self) -> Option<Instant> {
        self.inner.deadline()
    }

    fn unflushed(&self) -> bool {
        self.unflushed || self.inner.unflushed()
    }

    fn flush(&mut self) {
        if let Some(w) = self.trace.as_mut() {
            crate::trace::flush_quietly(w);
        }
        self.unflushed = false;
        self.inner.flush();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell::link::Wire;

    fn frame(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(id, data).unwrap()
    }

    #[test]
    fn taps_and_the_trace_see_every_frame_and_the_inner_link_decides() {
        let path = std::env::temp_dir().join(format!("tracer-{}.log", std::process::id()));
        let mut link = Tracer::new(Wire::new(), None);
        let (tx, rx) = std::sync::mpsc::sync_channel(8);
        link.tap(tx);
        let (gone, _) = std::sync::mpsc::sync_channel(1);
        link.tap(gone);
        link.start(TraceWriter::create(&path, "vcan0").unwrap());
        assert!(!link.unflushed());
        let at = At {
            clock: Instant::from_millis(3),
            stamp: Duration::from_millis(1500),
        };
        assert_eq!(link.cross(at, &frame(0x181, &[1, 2])), Verdict::Pass);
        assert!(link.unflushed());
        link.flush();
        assert!(!link.unflushed());
        // The tap whose receiver is gone is forgotten at the first frame.
        assert_eq!(link.taps.len(), 1);
        assert_eq!(
            rx.try_recv().unwrap(),
            (Duration::from_millis(3), frame(0x181, &[1, 2]))
        );
        let mut w = link.stop().unwrap();
        w.flush().unwrap();
        assert!(!link.is_tracing());
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(text, "(0000000001.500000) vcan0 181#0102\n");
    }
}
