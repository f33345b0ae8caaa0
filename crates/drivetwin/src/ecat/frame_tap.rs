//! The frames a chain sees, copied for the trace (`--trace`, a pcap).

/// A copy of a frame for the trace, with the wall-clock time it was seen.
#[derive(Debug, Clone)]
pub struct TracedFrame {
    pub at: std::time::SystemTime,
    pub frame: Vec<u8>,
}

/// Where the runtime sends the frames it sees (`--trace`): each request as it came in and
/// each processed frame as it went back. A full queue drops the copy, never the frame.
pub type FrameTap = std::sync::mpsc::SyncSender<TracedFrame>;

/// A chain's frames copied to the trace's queue: the copy is stamped with the wall clock when
/// it is taken (read only while tracing), as the pcap beside other captures wants.
impl crate::cell::tracer::TraceSink<[u8]> for Option<FrameTap> {
    fn write(&mut self, _: crate::cell::link::At, frame: &[u8]) {
        if let Some(tap) = self {
            let copy = TracedFrame {
                at: std::time::SystemTime::now(),
                frame: frame.to_vec(),
            };
            if tap.try_send(copy).is_err() {
                tracing::warn!("trace queue full, a frame copy is lost");
            }
        }
    }
}
