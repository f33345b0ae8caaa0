//! A link that copies every frame crossing it to a sink, then passes it to the link it
//! wraps: as smoltcp's `phy::Tracer`, a link that wraps a link ([`crate::cell::link`]), a
//! bus's ([`Link`]) or a front end's ([`FrontLink`]). On a front end's link a frame that
//! comes in is copied before the link it wraps judges it, and one that goes out once the link
//! it wraps has it (the copy is not on the frame's path out); outermost, the tracer shows
//! every frame the peer sent and the cell sent, whatever faults inside make of them. A
//! CAN bus's sink is [`CanTrace`]: its trace file (pcap or candump), which can start and
//! stop while the cell runs, and its taps, each lasting until its receiver is dropped. An
//! EtherCAT chain's is the queue to the thread that writes its pcap
//! (`ecat::chain::FrameTap`).
//!
//! A CAN bus's trace is its bus's own: the [`super::can_segment::SegmentBus`] holds the link
//! its front ends see, a `Tracer<Wire<CanFrame>, CanTrace>`, beside the faulty wire between its
//! stations, so neither the cell loop nor the scenario rig keeps a trace of its own. The file
//! is a [`FrameLog`] (the pcap or candump writer of `trace`), which the runtime does not name.

use std::sync::mpsc::{SyncSender, TrySendError};
use std::time::Duration;

use canopen::CanFrame;
use od::Instant;

use super::link::{At, FrontLink, Link};
use super::wire_faults::{Sender, Verdict};

/// A file a CAN bus's frames are written to (a pcap or candump file and its bus load).
pub trait FrameLog: Send {
    /// `frame`, stamped `stamp` (since the Unix epoch, or since the virtual clock's zero).
    fn write(&mut self, stamp: Duration, frame: &CanFrame) -> std::io::Result<()>;
    /// Writes out what it buffers.
    fn flush(&mut self) -> std::io::Result<()>;
}

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
    file: Option<Box<dyn FrameLog>>,
    /// Frames written to the file since its last flush.
    unflushed: bool,
    taps: Vec<Tap>,
}

impl CanTrace {
    /// Traced into `file` (none: until [`CanTrace::start`]).
    pub fn new(file: Option<Box<dyn FrameLog>>) -> Self {
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
    pub fn start(&mut self, file: Box<dyn FrameLog>) {
        self.file = Some(file);
    }

    /// Stops the trace and gives its file back, not yet flushed.
    pub fn stop(&mut self) -> Option<Box<dyn FrameLog>> {
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
            if let Err(e) = w.flush() {
                tracing::error!(error = %e, "writing the trace failed");
            }
        }
        self.unflushed = false;
    }
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use super::*;
    use crate::cell::link::Wire;

    fn frame(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(id, data).unwrap()
    }

    /// What a [`Memory`] keeps: the frames with their stamps, and how often it was flushed.
    type Kept = (Vec<(Duration, CanFrame)>, u32);

    /// Keeps what is written, and how often it was flushed.
    #[derive(Clone, Default)]
    struct Memory(Arc<Mutex<Kept>>);

    impl FrameLog for Memory {
        fn write(&mut self, stamp: Duration, frame: &CanFrame) -> std::io::Result<()> {
            self.0.lock().unwrap().0.push((stamp, *frame));
            Ok(())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            self.0.lock().unwrap().1 += 1;
            Ok(())
        }
    }

    #[test]
    fn taps_and_the_trace_see_every_frame_and_the_inner_link_decides() {
        let mut link = Tracer::new(Wire::new(), CanTrace::new(None));
        let (tx, rx) = std::sync::mpsc::sync_channel(8);
        link.sink_mut().tap(tx);
        let (gone, _) = std::sync::mpsc::sync_channel(1);
        link.sink_mut().tap(gone);
        let file = Memory::default();
        link.sink_mut().start(Box::new(file.clone()));
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
        assert!(link.sink_mut().stop().is_some());
        assert!(!link.sink.is_tracing());
        let (written, flushes) = file.0.lock().unwrap().clone();
        assert_eq!(
            written,
            [(Duration::from_millis(1500), frame(0x181, &[1, 2]))]
        );
        assert_eq!(flushes, 1);
    }
}
