//! A trace file as the runtime writes a CAN bus's frames to it: [`TraceWriter`] is the
//! [`FrameLog`] of a bus's `cell::tracer::CanTrace`, which the runtime starts and stops
//! without naming the file's format.

use std::time::Duration;

use canopen::CanFrame;

use crate::cell::tracer::FrameLog;
use crate::trace::TraceWriter;

impl FrameLog for TraceWriter {
    fn write(&mut self, stamp: Duration, frame: &CanFrame) -> std::io::Result<()> {
        TraceWriter::write(self, stamp, frame)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        TraceWriter::flush(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell::link::{At, Link, Wire};
    use crate::cell::tracer::{CanTrace, Tracer};
    use od::Instant;

    #[test]
    fn a_bus_traced_into_a_candump_file() {
        let path = std::env::temp_dir().join(format!("tracer-{}.log", std::process::id()));
        let mut link = Tracer::new(Wire::new(), CanTrace::new(None));
        link.sink_mut()
            .start(Box::new(TraceWriter::create(&path, "vcan0").unwrap()));
        let at = At {
            clock: Instant::from_millis(3),
            stamp: Duration::from_millis(1500),
        };
        link.cross(at, &CanFrame::new(0x181, &[1, 2]).unwrap());
        let mut w = link.sink_mut().stop().unwrap();
        w.flush().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(text, "(0000000001.500000) vcan0 181#0102\n");
    }
}
