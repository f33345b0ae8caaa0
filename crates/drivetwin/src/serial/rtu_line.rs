//! Modbus RTU on an RS485 line (`spec/kinco-fd-cd.md` §2.3, the codecs
//! `modbus::rtu_framing` and `modbus::kinco_rtu`): a frame ends with 3.5 character times of
//! silence at the line's baud rate, and every drive of the line hears it; the one whose
//! station number (= node-ID 100Bh, §12.2) it names answers, once the silence has passed.
//!
//! - A bad CRC or a station no drive of the line has: no answer, counted (KINCO-MB, §12.3).
//! - Station 0 (broadcast): every drive carries out a write; none answers.
//! - FC 03h errors answer 81h as the manual prints (the codec's `ErrorStyle::Manual`, see its
//!   decision), 86h / 90h for FC 06h / 10h.
//! - The drives do not hear each other's answers (a reply is no request to another station).

use modbus::kinco_rtu::{ErrorStyle, Ignored, KincoRtu, RegisterMapping, MAX_FRAME};
use modbus::rtu_framing::RtuFramer;
use od::Instant;

use super::wire::Wire;
use super::LineDrives;
use crate::cell::poll_loop::OnBus;

/// One drive on an RTU line.
pub struct RtuDrive {
    pub at: OnBus,
    pub station: u8,
    pub map: Vec<RegisterMapping>,
}

/// What an RTU line counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RtuCounters {
    pub answered: u32,
    pub bad_crc: u32,
    pub other_station: u32,
    pub broadcast: u32,
    /// Frames longer than 256 bytes.
    pub too_long: u32,
}

pub struct RtuLine {
    framer: RtuFramer,
    drives: Vec<RtuDrive>,
    errors: ErrorStyle,
    counters: RtuCounters,
    /// Scratch: one frame.
    frame: Vec<u8>,
}

impl RtuLine {
    pub fn new(baud: u32, drives: Vec<RtuDrive>) -> Self {
        RtuLine {
            framer: RtuFramer::new(baud),
            drives,
            errors: ErrorStyle::Manual,
            counters: RtuCounters::default(),
            frame: Vec::with_capacity(MAX_FRAME),
        }
    }

    pub fn counters(&self) -> RtuCounters {
        RtuCounters {
            too_long: self.framer.dropped().too_long,
            ..self.counters
        }
    }

    /// One byte complete on the wire at `at`.
    pub fn on_byte(&mut self, at: Instant, byte: u8, drives: &mut dyn LineDrives, wire: &mut Wire) {
        // The frame before ended with its silence, not with this byte.
        self.poll(at, drives, wire);
        self.framer.on_bytes(at, &[byte], &mut |_| {});
    }

    /// Hands a frame the silence has ended by `now` to the drives.
    pub fn poll(&mut self, now: Instant, drives: &mut dyn LineDrives, wire: &mut Wire) {
        let Some(end) = self.framer.deadline().filter(|d| *d <= now) else {
            return;
        };
        self.frame.clear();
        let frame = &mut self.frame;
        self.framer.poll(end, &mut |f| frame.extend_from_slice(f));
        if self.frame.is_empty() {
            return;
        }
        self.on_frame(end, drives, wire);
    }

    pub fn deadline(&self) -> Option<Instant> {
        self.framer.deadline()
    }

    fn on_frame(&mut self, at: Instant, drives: &mut dyn LineDrives, wire: &mut Wire) {
        if modbus::rtu::strip_crc(&self.frame).is_none() {
            self.counters.bad_crc += 1;
            return;
        }
        let station = self.frame.first().copied().unwrap_or(0);
        let mut addressed = false;
        for d in &self.drives {
            if station != 0 && station != d.station {
                continue;
            }
            addressed = true;
            let server = KincoRtu {
                station: d.station,
                map: &d.map,
                errors: self.errors,
            };
            let mut out = [0u8; MAX_FRAME];
            let mut result = Err(Ignored::OtherStation);
            let frame = &self.frame;
            drives.access(d.at, at, &mut |od| {
                result = server.handle_frame(frame, od, &mut out);
            });
            match result {
                Ok(n) => {
                    self.counters.answered += 1;
                    wire.send(at, out.get(..n).unwrap_or(&[]));
                }
                Err(Ignored::Broadcast) => {}
                Err(Ignored::Crc) => self.counters.bad_crc += 1,
                Err(Ignored::OtherStation) => self.counters.other_station += 1,
            }
        }
        if station == 0 {
            self.counters.broadcast += 1;
        } else if !addressed {
            self.counters.other_station += 1;
        }
    }
}
