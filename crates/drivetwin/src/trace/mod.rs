//! Bus traces: pcap (LINKTYPE_CAN_SOCKETCAN) or candump `.log`, chosen by the file name, with
//! the bus load beside them (`bus_load`: `<trace>.load.csv` for a bus with a bit rate), and the
//! candump reader that feeds scripted frames to a virtual-clock run.

pub mod bus_load;
pub mod pcap;
pub mod tracer;

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::time::Duration;

use canopen::CanFrame;

use crate::trace::bus_load::LoadLog;
use crate::trace::pcap::{CandumpWriter, PcapWriter};

/// A trace file being written, and its bus-load file.
pub struct TraceWriter {
    file: TraceFile,
    load: Option<LoadLog<BufWriter<File>>>,
}

enum TraceFile {
    Pcap(PcapWriter<BufWriter<File>>),
    Candump(CandumpWriter<BufWriter<File>>),
}

impl TraceWriter {
    /// `*.log` is candump format, anything else pcap.
    pub fn create(path: &Path, channel: &str) -> std::io::Result<Self> {
        let f = BufWriter::new(File::create(path)?);
        let file = if path.extension().is_some_and(|e| e == "log") {
            TraceFile::Candump(CandumpWriter::new(f, channel))
        } else {
            TraceFile::Pcap(PcapWriter::new(f)?)
        };
        Ok(TraceWriter { file, load: None })
    }

    /// As [`TraceWriter::create`], for a bus at `bitrate` bit/s: with a bit rate its load per
    /// window goes to [`bus_load::load_path`] of `path` as well.
    pub fn create_for_bus(
        path: &Path,
        channel: &str,
        bitrate: Option<u32>,
    ) -> std::io::Result<Self> {
        let mut w = Self::create(path, channel)?;
        if let Some(b) = bitrate {
            let f = BufWriter::new(File::create(bus_load::load_path(path))?);
            w.load = Some(LoadLog::new(f, b)?);
        }
        Ok(w)
    }

    pub fn write(&mut self, since_epoch: Duration, frame: &CanFrame) -> std::io::Result<()> {
        match &mut self.file {
            TraceFile::Pcap(w) => w.write_frame_at(since_epoch, frame)?,
            TraceFile::Candump(w) => w.write_frame_at(since_epoch, frame)?,
        }
        match self.load.as_mut() {
            Some(l) => l.frame(since_epoch, frame),
            None => Ok(()),
        }
    }

    pub fn flush(&mut self) -> std::io::Result<()> {
        match &mut self.file {
            TraceFile::Pcap(w) => w.flush()?,
            TraceFile::Candump(w) => w.flush()?,
        }
        match self.load.as_mut() {
            Some(l) => l.flush(),
            None => Ok(()),
        }
    }
}

#[derive(Debug, thiserror::Error)]
#[error("line {line}: {what}")]
pub struct CandumpParseError {
    pub line: usize,
    pub what: &'static str,
}

/// Parses candump `.log` text: `(SEC.USEC) IFACE ID#DATA` or `ID#R`; blank lines and `#`
/// comments skipped.
pub fn parse_candump(text: &str) -> Result<Vec<(Duration, CanFrame)>, CandumpParseError> {
    Ok(parse_candump_lines(text)?
        .into_iter()
        .map(|l| (l.time, l.frame))
        .collect())
}

/// One frame line of a candump log.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CandumpLine<'a> {
    /// 1-based.
    pub line: usize,
    pub time: Duration,
    pub interface: &'a str,
    pub frame: CanFrame,
}

/// As [`parse_candump`], with each frame's line number and interface.
pub fn parse_candump_lines(text: &str) -> Result<Vec<CandumpLine<'_>>, CandumpParseError> {
    let mut frames = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let err = |what| CandumpParseError { line: i + 1, what };
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut parts = line.split_whitespace();
        let ts = parts
            .next()
            .and_then(|t| t.strip_prefix('('))
            .and_then(|t| t.strip_suffix(')'))
            .ok_or(err("expected (SECONDS)"))?;
        let (sec, usec) = ts.split_once('.').ok_or(err("timestamp needs SEC.USEC"))?;
        let sec: u64 = sec.parse().map_err(|_| err("bad seconds"))?;
        let usec: u32 = usec.parse().map_err(|_| err("bad microseconds"))?;
        if usec >= 1_000_000 || usec.to_string().len() > 6 && usec != 0 {
            return Err(err("bad microseconds"));
        }
        let interface = parts.next().ok_or(err("missing interface"))?;
        let body = parts.next().ok_or(err("missing ID#DATA"))?;
        let frame = parse_candump_frame(body).map_err(err)?;
        frames.push(CandumpLine {
            line: i + 1,
            time: Duration::from_secs(sec) + Duration::from_micros(u64::from(usec)),
            interface,
            frame,
        });
    }
    Ok(frames)
}

/// A frame as candump writes it: `ID#DATA` (hex, 3 digits: standard, 8: extended) or `ID#R`.
pub fn parse_candump_frame(body: &str) -> Result<CanFrame, &'static str> {
    let (id, data) = body.split_once('#').ok_or("expected ID#DATA")?;
    let extended = id.len() != 3;
    let id = u32::from_str_radix(id, 16).map_err(|_| "bad identifier")?;
    if let Some(rest) = data.strip_prefix('R') {
        let len = if rest.is_empty() {
            0
        } else {
            rest.parse::<u8>().map_err(|_| "bad RTR length")?
        };
        let mut f = CanFrame::with_id(id, extended, &[]).map_err(|_| "identifier out of range")?;
        f.rtr = true;
        f.len = len.min(8);
        Ok(f)
    } else {
        let bytes = crate::value_text::parse_hex(data).ok_or("bad data")?;
        CanFrame::with_id(id, extended, &bytes).map_err(|_| "more than 8 bytes or bad identifier")
    }
}

/// Flushes a trace writer, logging instead of failing (a trace must not stop the cell).
pub fn flush_quietly(w: &mut TraceWriter) {
    if let Err(e) = w.flush() {
        tracing::error!(error = %e, "writing the trace failed");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candump_lines_parse_and_bad_lines_are_refused() {
        let f =
            parse_candump("(0.100000) vcan0 601#4000100000000000\n(1.5) vcan0 701#R\n").unwrap();
        assert_eq!(f.len(), 2);
        assert_eq!(f[0].0, Duration::from_millis(100));
        assert_eq!(f[0].1.payload(), &[0x40, 0, 0x10, 0, 0, 0, 0, 0]);
        assert!(f[1].1.rtr);
        assert_eq!(parse_candump("(0.1) vcan0 601#4").unwrap_err().line, 1);
        assert!(parse_candump("vcan0 601#40").is_err());
        assert!(parse_candump("(0.1) vcan0 601#000000000000000000").is_err());
    }
}
