//! Modbus RTU on an RS485 line (Kinco CD3 / FD3 manual ch. 12, the codecs `modbus::rtu_framing` and
//! `drive::vendors::kinco::rtu`): a frame ends with 3.5 character times of silence at the line's
//! baud rate, and every drive of the line hears it; the one whose station number (= node-ID 100Bh,
//! §12.2) it names answers, once the silence has passed.
//!
//! - A bad CRC or a station no drive of the line has: no answer, counted (KINCO-MB, §12.3).
//! - Station 0 (broadcast): every drive carries out a write; none answers.
//! - FC 03h errors answer 81h as the manual prints (the codec's `ErrorStyle::Read81h`, see its
//!   decision), 86h / 90h for FC 06h / 10h.
//! - The drives do not hear each other's answers (a reply is no request to another station).
//! - **Decision:** a frame ends after 3.5 characters of silence at every baud rate, as the
//!   Kinco manual asks (§12.3: "interval between messages at least 3.5 characters"), not the
//!   standard's fixed 1.75 ms above 19200 bit/s: at 38400 and 115200 bit/s that would demand
//!   a longer gap than the device does and merge frames the device tells apart. The answer
//!   leaves once that silence has passed, the earliest the device can know a frame ended.

use drive::vendors::kinco::rtu::{ErrorStyle, Ignored, KincoRtu, RegisterMapping, MAX_FRAME};
use modbus::rtu_framing::{three_and_a_half_characters, RtuFramer};
use od::Instant;

use crate::cell::stations::StationId;
use crate::serial::line::LineProtocol;
use crate::serial::wire::Wire;
use crate::serial::LineDrives;

/// One drive on an RTU line.
pub struct RtuDrive {
    pub at: StationId,
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
            framer: RtuFramer::with_gap(three_and_a_half_characters(baud)),
            drives,
            errors: ErrorStyle::Read81h,
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

impl LineProtocol for RtuLine {
    fn on_byte(&mut self, at: Instant, byte: u8, drives: &mut dyn LineDrives, wire: &mut Wire) {
        RtuLine::on_byte(self, at, byte, drives, wire);
    }

    fn poll(&mut self, now: Instant, drives: &mut dyn LineDrives, wire: &mut Wire) {
        RtuLine::poll(self, now, drives, wire);
    }

    fn deadline(&self) -> Option<Instant> {
        RtuLine::deadline(self)
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::test_drives::{on, Dictionaries};
    use crate::vendors::kinco::serial_lines::register_map;
    use std::time::Duration;

    fn line(n: usize) -> RtuLine {
        let drives = (0..n)
            .map(|i| RtuDrive {
                at: on(i),
                station: u8::try_from(i + 1).unwrap_or(0),
                map: register_map("kinco-fd3"),
            })
            .collect();
        RtuLine::new(19_200, drives)
    }

    /// A line at `baud` bit/s with one FD3 as station 1.
    fn one_drive(baud: u32) -> RtuLine {
        RtuLine::new(
            baud,
            vec![RtuDrive {
                at: on(0),
                station: 1,
                map: register_map("kinco-fd3"),
            }],
        )
    }

    fn exchange(
        line: &mut RtuLine,
        wire: &mut Wire,
        drives: &mut Dictionaries,
        at: Instant,
        bytes: &[u8],
    ) -> (Vec<u8>, Instant) {
        exchange_all(line, wire, drives, &[(at, bytes)])
    }

    /// The host writes each of `writes` at its time; what the line answers, and when the
    /// last answer reached the host.
    fn exchange_all(
        line: &mut RtuLine,
        wire: &mut Wire,
        drives: &mut Dictionaries,
        writes: &[(Instant, &[u8])],
    ) -> (Vec<u8>, Instant) {
        let mut writes = writes.iter().peekable();
        let mut got = Vec::new();
        let mut when = Instant::ZERO;
        // Run the line deadline by deadline, as the cell loop does.
        for _ in 0..1000 {
            let host = writes.peek().map(|(t, _)| *t);
            let next =
                od::time::earliest(od::time::earliest(wire.deadline(), line.deadline()), host);
            let Some(now) = next else {
                break;
            };
            if host == Some(now) {
                if let Some((t, bytes)) = writes.next() {
                    wire.receive(*t, bytes);
                }
                continue;
            }
            let mut arrived = Vec::new();
            wire.arrived(now, &mut |t, b| arrived.push((t, b)));
            for (t, b) in arrived {
                line.on_byte(t, b, drives, wire);
            }
            line.poll(now, drives, wire);
            wire.crossed(now);
            wire.flush(&mut |b| {
                got.extend_from_slice(b);
                when = now;
                b.len()
            });
        }
        (got, when)
    }

    /// KINCO-MB-02 on the line: the echo, once the request (8 characters), the silence
    /// (3.5) and the echo (8) have passed at 19200 bit/s.
    #[test]
    fn kinco_mb_02_echo_after_silence_and_wire_time() {
        let mut drives = Dictionaries::fd3(1);
        let mut wire = Wire::new(19_200);
        let mut l = line(1);
        let request = [0x01, 0x06, 0x31, 0x00, 0x00, 0x0F, 0xC7, 0x32];
        let (got, when) = exchange(&mut l, &mut wire, &mut drives, Instant::ZERO, &request);
        assert_eq!(got, request);
        let char_ns = 1_000_000_000 * 10 / 19_200u64;
        let expected = Duration::from_nanos(16 * char_ns) + modbus::rtu_framing::t3_5(19_200);
        let at = Duration::from_nanos(when.as_nanos());
        assert!(
            at >= expected && at < expected + Duration::from_micros(10),
            "{at:?} vs {expected:?}"
        );
        assert_eq!(
            drives.0.first().and_then(|d| d.get_unsigned(0x6040, 0)),
            Some(0x0F)
        );
    }

    /// At 115200 bit/s a frame ends after 3.5 characters (0.30 ms) of silence, as the Kinco
    /// manual asks (§12.3), not the standard's 1.75 ms: a broadcast write followed 0.5 ms later
    /// by a read are two frames, and the read's answer leaves 3.5 characters after it.
    #[test]
    fn frames_end_after_three_and_a_half_characters_at_115200() {
        let baud = 115_200;
        let mut drives = Dictionaries::fd3(1);
        let mut wire = Wire::new(baud);
        let mut l = one_drive(baud);
        let mut broadcast = vec![0x00, 0x06, 0x31, 0x00, 0x00, 0x06];
        broadcast.extend(modbus::rtu::crc_bytes(&broadcast));
        let read = [0x01, 0x03, 0x32, 0x00, 0x00, 0x02, 0xCA, 0xB3];
        let char_ns = 1_000_000_000 * 10 / u64::from(baud);
        let read_at = Instant::from_nanos(8 * char_ns + 500_000);
        let (got, when) = exchange_all(
            &mut l,
            &mut wire,
            &mut drives,
            &[(Instant::ZERO, &broadcast), (read_at, &read)],
        );
        assert_eq!(got.get(..3), Some(&[0x01, 0x03, 0x04][..]), "{got:02X?}");
        assert_eq!(
            drives.0.first().and_then(|d| d.get_unsigned(0x6040, 0)),
            Some(0x06),
            "the broadcast was carried out"
        );
        let gap = modbus::rtu_framing::three_and_a_half_characters(baud);
        let expected = read_at + Duration::from_nanos((8 + 9) * char_ns) + gap;
        assert!(
            when >= expected && when < expected + Duration::from_micros(10),
            "{when:?} vs {expected:?}"
        );
    }

    /// KINCO-MB-01 and KINCO-MB-03 at two drives of one line: each answers its own station; a
    /// bad CRC and a station none has get no answer.
    #[test]
    fn kinco_mb_two_drives_by_station_bad_crc_and_other_station() {
        let mut drives = Dictionaries::fd3(2);
        let mut wire = Wire::new(19_200);
        let mut l = line(2);
        let ms = Instant::from_millis;
        let mut write = vec![
            0x02, 0x10, 0x6F, 0x00, 0x00, 0x02, 0x04, 0x55, 0x55, 0x00, 0x08,
        ];
        write.extend(modbus::rtu::crc_bytes(&write));
        let (got, _) = exchange(&mut l, &mut wire, &mut drives, ms(0), &write);
        assert_eq!(
            got.get(..6),
            Some(&[0x02, 0x10, 0x6F, 0x00, 0x00, 0x02][..])
        );
        assert_eq!(
            drives.0.get(1).and_then(|d| d.get_unsigned(0x60FF, 0)),
            Some(0x0008_5555)
        );
        assert_eq!(
            drives.0.first().and_then(|d| d.get_unsigned(0x60FF, 0)),
            Some(0)
        );
        let (got, _) = exchange(
            &mut l,
            &mut wire,
            &mut drives,
            ms(100),
            &[0x01, 0x03, 0x32, 0x00, 0x00, 0x02, 0xCA, 0xB3],
        );
        assert_eq!(got.get(..3), Some(&[0x01, 0x03, 0x04][..]));
        let (got, _) = exchange(
            &mut l,
            &mut wire,
            &mut drives,
            ms(200),
            &[0x01, 0x03, 0x32, 0x00, 0x00, 0x02, 0xCA, 0xB4],
        );
        assert!(got.is_empty());
        let mut other = vec![0x07, 0x03, 0x32, 0x00, 0x00, 0x02];
        other.extend(modbus::rtu::crc_bytes(&other));
        let (got, _) = exchange(&mut l, &mut wire, &mut drives, ms(300), &other);
        assert!(got.is_empty());
        let c = l.counters();
        assert_eq!((c.answered, c.bad_crc, c.other_station), (2, 1, 1));
    }

    /// Garbage at every baud rate: no answer the CRC would not allow, and the line answers
    /// the next good frame.
    #[test]
    fn garbage_then_a_good_frame() {
        for baud in [9600, 19_200, 38_400, 115_200] {
            let mut drives = Dictionaries::fd3(1);
            let mut wire = Wire::new(baud);
            let mut l = one_drive(baud);
            let noise: Vec<u8> = (0..600u32).map(|i| (i * 37 % 251) as u8).collect();
            let _ = exchange(&mut l, &mut wire, &mut drives, Instant::ZERO, &noise);
            let (got, _) = exchange(
                &mut l,
                &mut wire,
                &mut drives,
                Instant::from_millis(2000),
                &[0x01, 0x06, 0x31, 0x00, 0x00, 0x0F, 0xC7, 0x32],
            );
            assert_eq!(got.len(), 8, "at {baud} bit/s");
        }
    }
}
