//! A link that copies every frame crossing it to a sink, then passes it to the link it
//! wraps: as smoltcp's `phy::Tracer`, a link that wraps a link ([`crate::cell::link`]), a
//! bus's ([`Link`]) or a front end's ([`FrontLink`]). On a front end's link a frame that
//! comes in is copied before the link it wraps judges it, and one that goes out once the link
//! it wraps has it (the copy is not on the frame's path out); outermost, the tracer shows
//! every frame the peer sent and the cell sent, whatever faults inside make of them. A
//! CAN bus's sink is [`CanTrace`]: its trace file (pcap or candump), which can start and
//! stop while the cell runs, and its taps, each lasting until its receiver is dropped. An
//! EtherCAT chain's is the queue to the thread that writes its pcap
//! (`crate::ecat::chain::FrameTap`).

use std::sync::mpsc::{SyncSender, TrySendError};
use std::time::Duration;

use canopen::CanFrame;
use od::Instant;

use crate::cell::link::{At, FrontLink, Link};
use crate::cell::wire_faults::{Sender, Verdict};
use crate::trace::TraceWriter;

/// Where a [`Tracer`] copies the frames that cross its link.
pub trait TraceSink<F: ?Sized> {
    /// A copy of `frame`, crossing at `at`. A sink that cannot write logs it and stops; a
    /// trace never stops the cell.
    fn write(&mut self, at: At, frame: &F);

    /// Whether it holds written frames not yet flushed out.
    fn unflushed(&self) -> bool {
        false
    }

    /// Writes out what it buffers.
    fn flush(&mut self) {}
}

/// A link traced into a sink.
pub struct Tracer<L, S> {
    inner: L,
    sink: S,
}

impl<L, S> Tracer<L, S> {
    /// `inner`, traced into `sink`.
    pub fn new(inner: L, sink: S) -> Self {
        Tracer { inner, sink }
    }

    /// Where the frames go (to start or stop a trace, add a tap).
    pub fn sink_mut(&mut self) -> &mut S {
        &mut self.sink
    }

    /// The link it wraps.
    pub fn inner(&self) -> &L {
        &self.inner
    }

    /// The link it wraps.
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }
}

impl<L: Link, S: TraceSink<L::Frame>> Link for Tracer<L, S> {
    type Frame = L::Frame;

    fn cross(&mut self, at: At, frame: &L::Frame) -> Verdict {
        self.sink.write(at, frame);
        self.inner.cross(at, frame)
    }

    fn cut_off(&self, at: Instant, who: Sender) -> bool {
        self.inner.cut_off(at, who)
    }

    fn deadline(&self) -> Option<Instant> {
        self.inner.deadline()
    }

    fn unflushed(&self) -> bool {
        self.sink.unflushed() || self.inner.unflushed()
    }

    fn flush(&mut self) {
        self.sink.flush();
        self.inner.flush();
    }
}

impl<L, S> FrontLink for Tracer<L, S>
where
    L: FrontLink,
    S: TraceSink<L::In> + TraceSink<L::Out>,
{
    type In = L::In;
    type Out = L::Out;

    fn receive(&mut self, at: At, frame: &L::In) -> Verdict {
        <S as TraceSink<L::In>>::write(&mut self.sink, at, frame);
        self.inner.receive(at, frame)
    }

    fn transmit(&mut self, at: At, frame: &L::Out) -> Verdict {
        let verdict = self.inner.transmit(at, frame);
        <S as TraceSink<L::Out>>::write(&mut self.sink, at, frame);
        verdict
    }

    fn transmit_held(&mut self, at: At, frame: &L::Out) {
        self.inner.transmit_held(at, frame);
    }

    fn deadline(&self) -> Option<Instant> {
        self.inner.deadline()
    }
}

/// A receiver of every frame of a CAN bus, with its time on the cell's clock.
pub type Tap = SyncSender<(Duration, CanFrame)>;

/// A CAN bus's trace: its trace file while one runs, and its taps.
#[derive(Default)]
pub struct CanTrace {
    file: Option<TraceWriter>,
    /// Frames written to the file since its last flush.
    unflushed: bool,
    taps: Vec<Tap>,
}

impl CanTrace {
    /// Traced into `file` (none: until [`CanTrace::start`]).
    pub fn new(file: Option<TraceWriter>) -> Self {
        CanTrace {
            file,
            unflushed: false,
            taps: Vec::new(),
        }
    }

    pub fn is_tracing(&self) -> bool {
        self.file.is_some()
    }

    /// Traces from now on into `file`.
    pub fn start(&mut self, file: TraceWriter) {
        self.file = Some(file);
    }

    /// Stops the trace and gives its file back, not yet flushed.
    pub fn stop(&mut self) -> Option<TraceWriter> {
        self.unflushed = false;
        self.file.take()
    }

    /// Every frame from now on goes to `tap` as well; a tap that falls behind loses frames
    /// (the bus never waits).
    pub fn tap(&mut self, tap: Tap) {
        self.taps.push(tap);
    }
}

impl TraceSink<CanFrame> for CanTrace {
    fn write(&mut self, at: At, frame: &CanFrame) {
        if !self.taps.is_empty() {
            let t = Duration::from_nanos(at.clock.as_nanos());
            // A tap gone is forgotten; a full one loses the frame.
            self.taps.retain(|tx| {
                !matches!(tx.try_send((t, *frame)), Err(TrySendError::Disconnected(_)))
            });
        }
        if let Some(w) = self.file.as_mut() {
            if let Err(e) = w.write(at.stamp, frame) {
                tracing::error!(error = %e, "writing the trace failed; trace stopped");
                self.file = None;
            }
            self.unflushed = true;
        }
    }

    fn unflushed(&self) -> bool {
        self.unflushed
    }

    fn flush(&mut self) {
        if let Some(w) = self.file.as_mut() {
            crate::trace::flush_quietly(w);
        }
        self.unflushed = false;
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
        let mut link = Tracer::new(Wire::new(), CanTrace::new(None));
        let (tx, rx) = std::sync::mpsc::sync_channel(8);
        link.sink_mut().tap(tx);
        let (gone, _) = std::sync::mpsc::sync_channel(1);
        link.sink_mut().tap(gone);
        link.sink_mut()
            .start(TraceWriter::create(&path, "vcan0").unwrap());
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
        assert_eq!(link.sink.taps.len(), 1);
        assert_eq!(
            rx.try_recv().unwrap(),
            (Duration::from_millis(3), frame(0x181, &[1, 2]))
        );
        let mut w = link.sink_mut().stop().unwrap();
        w.flush().unwrap();
        assert!(!link.sink.is_tracing());
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(text, "(0000000001.500000) vcan0 181#0102\n");
    }
}
