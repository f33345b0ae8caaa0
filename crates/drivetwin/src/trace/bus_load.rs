//! The bus load beside a CAN trace: `<trace>.load.csv` (`trace.pcap` → `trace.pcap.load.csv`),
//! one line per window of [`LOAD_WINDOW`] (500 ms, as `drivetwin monitor` and the cell's
//! timed bus measure it, [`canbus::bus_load::LoadWindow`]) with the load of the frames the
//! trace holds: each frame's bit time at the bus's bit rate (`canbus::frame_time`, stuff
//! bits included) over the window's length.
//!
//! ```text
//! # drivetwin bus load: bitrate 500000 bit/s, window 500 ms, times in s on the trace's clock
//! end_s,window_s,load_percent,frames
//! 1764290000.500123,0.500000,31.204,1063
//! ```
//!
//! `end_s` is on the trace's own clock (the pcap / candump timestamps), so a reader lines the
//! windows up with the frames; `window_s` is the time the line counts. The windows lie on
//! fixed boundaries from the first frame ([`LoadWindow`]): each line is one window of 500 ms,
//! except a quiet stretch of whole windows without a frame, one line of 0 % over its length.
//!
//! Decisions: a sidecar file, not pcapng comments, so the trace stays the classic pcap that
//! every tool (tshark, python-can, candump's `.log` readers) reads unchanged; a bus without a
//! bit rate (`bitrate` on its `[[bus]]`) has no bit time, so its trace has no load file; a
//! window still running when the trace stops is not written (it would count a part of a
//! window as a whole one).

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

use canbus::bus_load::LoadWindow;
use canbus::frame_time::{bits_to_nanos, frame_bits};
use canopen::CanFrame;
use od::Instant;

use crate::cell::bus_timing::LOAD_WINDOW;

/// The header line naming the columns.
pub const COLUMNS: &str = "end_s,window_s,load_percent,frames";

/// Where the load of the trace at `trace` goes: `trace` with `.load.csv` appended.
pub fn load_path(trace: &Path) -> PathBuf {
    let mut p = trace.as_os_str().to_owned();
    p.push(".load.csv");
    PathBuf::from(p)
}

/// Counts the frames of a trace into windows and writes each closed one.
#[derive(Debug)]
pub struct LoadLog<W: Write> {
    out: W,
    bitrate: u32,
    /// Started at the first frame.
    window: Option<LoadWindow>,
}

impl<W: Write> LoadLog<W> {
    /// Writes the header for a bus at `bitrate` bit/s (at least 1).
    pub fn new(mut out: W, bitrate: u32) -> io::Result<Self> {
        let bitrate = bitrate.max(1);
        writeln!(
            out,
            "# drivetwin bus load: bitrate {bitrate} bit/s, window {} ms, times in s on the \
             trace's clock",
            LOAD_WINDOW.as_millis()
        )?;
        writeln!(out, "{COLUMNS}")?;
        Ok(LoadLog {
            out,
            bitrate,
            window: None,
        })
    }

    /// `frame` in the trace at `since_epoch` (the trace's timestamp).
    pub fn frame(&mut self, since_epoch: Duration, frame: &CanFrame) -> io::Result<()> {
        let now = u64::try_from(since_epoch.as_nanos()).unwrap_or(u64::MAX);
        let window_nanos = u64::try_from(LOAD_WINDOW.as_nanos()).unwrap_or(u64::MAX);
        let w = self
            .window
            .get_or_insert_with(|| LoadWindow::new(window_nanos, Instant::from_nanos(now)));
        let nanos = bits_to_nanos(frame_bits(frame), self.bitrate);
        if let Some(closed) = w.add(Instant::from_nanos(now), nanos) {
            let end = closed.end.as_nanos();
            self.line(end, window_nanos, closed.load_percent, closed.frames)?;
            if closed.quiet > 0 {
                let quiet = closed.quiet.saturating_mul(window_nanos);
                self.line(end.saturating_add(quiet), quiet, 0.0, 0)?;
            }
        }
        Ok(())
    }

    /// One line: the window (or quiet stretch) of `counted` ns that ended at `end`.
    fn line(&mut self, end: u64, counted: u64, percent: f64, frames: u32) -> io::Result<()> {
        writeln!(
            self.out,
            "{}.{:06},{}.{:06},{percent:.3},{frames}",
            end / 1_000_000_000,
            end % 1_000_000_000 / 1000,
            counted / 1_000_000_000,
            counted % 1_000_000_000 / 1000,
        )
    }

    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    pub fn get_ref(&self) -> &W {
        &self.out
    }
}

/// One line of a load file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadRecord {
    /// The window's end, on the trace's clock.
    pub end: Duration,
    /// The time it counted.
    pub window: Duration,
    pub load_percent: f64,
    pub frames: u32,
}

#[derive(Debug, thiserror::Error)]
#[error("line {line}: {what}")]
pub struct LoadParseError {
    pub line: usize,
    pub what: &'static str,
}

/// Reads a load file back (comment lines with `#` and the column line skipped).
pub fn parse_load(text: &str) -> Result<Vec<LoadRecord>, LoadParseError> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let err = |what| LoadParseError { line: i + 1, what };
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || line == COLUMNS {
            continue;
        }
        let mut f = line.split(',');
        let mut next = |what| f.next().ok_or(err(what));
        let end = seconds(next("end_s")?).ok_or(err("bad end_s"))?;
        let window = seconds(next("window_s")?).ok_or(err("bad window_s"))?;
        let load_percent = next("load_percent")?
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && *v >= 0.0)
            .ok_or(err("bad load_percent"))?;
        let frames = next("frames")?.parse().map_err(|_| err("bad frames"))?;
        out.push(LoadRecord {
            end,
            window,
            load_percent,
            frames,
        });
    }
    Ok(out)
}

/// `SEC.USEC` (six digits after the point, as written) exactly.
fn seconds(text: &str) -> Option<Duration> {
    let (s, us) = text.split_once('.')?;
    if us.len() != 6 {
        return None;
    }
    Some(Duration::from_secs(s.parse().ok()?) + Duration::from_micros(us.parse().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SYNCs (id 80h, no data: 47 bits and 4 stuff bits, at 125 kbit/s 408 µs) every 10 ms:
    /// 4.08 % in each 500 ms window, 50 frames a window; read back as written.
    #[test]
    fn windows_of_sync_frames_read_back() {
        let sync = CanFrame::new(0x080, &[]).expect("a frame");
        assert_eq!(frame_bits(&sync), 51);
        let mut log = LoadLog::new(Vec::new(), 125_000).expect("header");
        let t0 = Duration::from_secs(1_000);
        for n in 0..=150u32 {
            log.frame(t0 + Duration::from_millis(10) * n, &sync)
                .expect("line");
        }
        let text = String::from_utf8(log.get_ref().clone()).expect("utf-8");
        assert!(text.starts_with("# drivetwin bus load: bitrate 125000 bit/s, window 500 ms"));
        let rows = parse_load(&text).expect("parses");
        assert_eq!(rows.len(), 3, "{text}");
        for (k, r) in rows.iter().enumerate() {
            assert_eq!(r.frames, 50);
            assert!((r.load_percent - 4.08).abs() < 1e-3, "{r:?}");
            assert_eq!(r.window, Duration::from_millis(500));
            assert_eq!(r.end, t0 + Duration::from_millis(500) * (k as u32 + 1));
        }
        assert!(parse_load("1.000000,0.500000,x,3").is_err());
        assert!(parse_load("1.000000,0.500000").is_err());
        assert!(parse_load("1.0,0.500000,1.0,3").is_err(), "six digits");
    }

    /// Heartbeats (id 701h, one byte) at 0, 1 and 3.2 s: one line per window on fixed
    /// boundaries from the first frame, and a quiet stretch of whole windows as one line.
    #[test]
    fn a_quiet_stretch_is_one_line_of_its_length() {
        let beat = CanFrame::new(0x701, &[0x7F]).expect("a frame");
        let mut log = LoadLog::new(Vec::new(), 125_000).expect("header");
        let t0 = Duration::from_secs(1_000);
        for ms in [0, 1000, 3200] {
            log.frame(t0 + Duration::from_millis(ms), &beat)
                .expect("line");
        }
        let text = String::from_utf8(log.get_ref().clone()).expect("utf-8");
        let rows = parse_load(&text).expect("parses");
        let got: Vec<_> = rows
            .iter()
            .map(|r| (r.end - t0, r.window, r.frames, r.load_percent > 0.0))
            .collect();
        let ms = Duration::from_millis;
        assert_eq!(
            got,
            [
                (ms(500), ms(500), 1, true),
                (ms(1000), ms(500), 0, false),
                (ms(1500), ms(500), 1, true),
                (ms(3000), ms(1500), 0, false),
            ],
            "{text}"
        );
    }

    #[test]
    fn the_load_file_sits_beside_the_trace() {
        assert_eq!(
            load_path(Path::new("/tmp/bus0.pcap")),
            PathBuf::from("/tmp/bus0.pcap.load.csv")
        );
    }
}
