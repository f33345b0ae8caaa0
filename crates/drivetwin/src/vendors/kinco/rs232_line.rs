//! The Kinco telegram protocol on a line (Kinco CD3 / FD3 manual ch. 10, the codec
//! `drive::vendors::kinco::rs232`): bytes become 10-byte telegrams, each answered by the drive it
//! addresses through its object access.
//!
//! Topologies:
//! - point to point (RS232, one drive): the host's telegrams to the drive, its answers back;
//! - ring (RS232_Loop_Enable 6510h:0B = 1, several drives on one RS232 path, §2.1 multi-point):
//!   the host's bytes reach the first drive, each drive's output the next one, the last one's
//!   the host, so the host reads its own telegram, then the answer (KINCO-232-09);
//! - bus (RS485 with RS485_Protocol 6510h:0C = 1): every drive hears the host; the one
//!   addressed answers.
//!
//! Decisions:
//! - A partial telegram is dropped after [`drive::vendors::kinco::rs232::DEFAULT_GAP`] of
//!   silence on the wire (the codec's rule), counted here.
//! - In a ring a drive passes a telegram on when it is whole, not byte by byte: the host
//!   reads the same 20 bytes, 10 character times later than through a real repeater chain.
//! - U2BRG (2FE1h) applies at once (§9.1 item 7): after each answer the line takes the rate
//!   its code gives, for the bytes after the answer.

use drive::vendors::kinco::rs232::{KincoRs232, TelegramCutter, DEFAULT_GAP, TELEGRAM_LEN};
use od::Instant;

use super::baud_of_code;
use crate::cell::stations::StationId;
use crate::serial::line::LineProtocol;
use crate::serial::wire::Wire;
use crate::serial::LineDrives;

/// U2BRG (2FE1h) as a line follows it: its object (the port's `bit_rate_now` in the first
/// drive's device file), the code it had last, and the codes of that file
/// (`serial_bit_rate`).
#[derive(Debug, Clone, Copy)]
pub struct U2brg {
    pub object: u16,
    pub code: u64,
    pub codes: &'static od::SerialBitRateCodes,
}

/// How the drives of a telegram line are wired.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Topology {
    /// One drive, or drives in a ring in this order.
    Ring,
    /// Every drive hears the host (RS485).
    Bus,
}

/// What a telegram line counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TelegramCounters {
    pub answered: u32,
    pub bad_checksum: u32,
    pub other_station: u32,
    /// Partial telegrams dropped after a silence.
    pub partial: u32,
}

pub struct TelegramLine {
    ports: Vec<(StationId, KincoRs232)>,
    topology: Topology,
    cutter: TelegramCutter,
    /// Follow U2BRG (2FE1h) of the first drive: the RS232 port's own rate.
    follow_u2brg: Option<U2brg>,
    partial: u32,
    /// Scratch: what one drive of a ring passes to the next.
    hop: Vec<u8>,
    next: Vec<u8>,
}

impl TelegramLine {
    /// `ports`: each drive with its codec (station, ring flag at power-up).
    pub fn new(
        ports: Vec<(StationId, KincoRs232)>,
        topology: Topology,
        u2brg: Option<U2brg>,
    ) -> Self {
        TelegramLine {
            ports,
            topology,
            cutter: TelegramCutter::new(DEFAULT_GAP),
            follow_u2brg: u2brg,
            partial: 0,
            hop: Vec::with_capacity(64),
            next: Vec::with_capacity(64),
        }
    }

    pub fn counters(&self) -> TelegramCounters {
        let mut c = TelegramCounters {
            partial: self.partial,
            ..TelegramCounters::default()
        };
        for (_, p) in &self.ports {
            let k = p.counters();
            c.answered += k.answered;
            c.bad_checksum += k.bad_checksum;
            c.other_station += k.other_station;
        }
        // In a ring every drive sees every telegram: a bad one counts once.
        if self.topology == Topology::Ring {
            if let Some((_, p)) = self.ports.first() {
                c.bad_checksum = p.counters().bad_checksum;
            }
        }
        c
    }

    /// One byte complete on the wire at `at`.
    pub fn on_byte(&mut self, at: Instant, byte: u8, drives: &mut dyn LineDrives, wire: &mut Wire) {
        let mut dropped = false;
        let t = self.cutter.push(at, byte, &mut dropped);
        if dropped {
            self.partial = self.partial.saturating_add(1);
        }
        if let Some(t) = t {
            self.on_telegram(at, &t, drives, wire);
        }
    }

    fn on_telegram(
        &mut self,
        at: Instant,
        t: &[u8; TELEGRAM_LEN],
        drives: &mut dyn LineDrives,
        wire: &mut Wire,
    ) {
        match self.topology {
            Topology::Bus => {
                for (on_bus, port) in &mut self.ports {
                    let mut answer = [0u8; 2 * TELEGRAM_LEN];
                    let mut n = 0;
                    drives.access(*on_bus, at, &mut |od| {
                        port.on_telegram(t, od, &mut |b| {
                            for &x in b {
                                if let Some(slot) = answer.get_mut(n) {
                                    *slot = x;
                                    n += 1;
                                }
                            }
                        })
                    });
                    wire.send(at, answer.get(..n).unwrap_or(&[]));
                }
            }
            Topology::Ring => {
                self.hop.clear();
                self.hop.extend_from_slice(t);
                for (on_bus, port) in &mut self.ports {
                    self.next.clear();
                    let next = &mut self.next;
                    for block in self.hop.chunks_exact(TELEGRAM_LEN) {
                        let Ok(block) = <&[u8; TELEGRAM_LEN]>::try_from(block) else {
                            continue;
                        };
                        drives.access(*on_bus, at, &mut |od| {
                            port.on_telegram(block, od, &mut |b| next.extend_from_slice(b))
                        });
                    }
                    std::mem::swap(&mut self.hop, &mut self.next);
                }
                wire.send(at, &self.hop);
            }
        }
        if let (Some(last), Some((on_bus, _))) = (self.follow_u2brg, self.ports.first()) {
            let mut code = last.code;
            drives.access(*on_bus, at, &mut |od| {
                let mut b = [0u8; 2];
                if od.read(last.object, 0, &mut b).is_ok() {
                    code = u64::from(u16::from_le_bytes(b));
                }
            });
            if code != last.code {
                self.follow_u2brg = Some(U2brg { code, ..last });
                match baud_of_code(last.codes, code) {
                    Some(baud) => {
                        tracing::info!(code, baud, "RS232: U2BRG applied");
                        wire.set_baud(baud);
                    }
                    None => tracing::warn!(code, "RS232: U2BRG code of no bit rate, ignored"),
                }
            }
        }
    }
}

impl LineProtocol for TelegramLine {
    fn on_byte(&mut self, at: Instant, byte: u8, drives: &mut dyn LineDrives, wire: &mut Wire) {
        TelegramLine::on_byte(self, at, byte, drives, wire);
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::test_drives::{on, Dictionaries};

    fn hex(s: &str) -> Vec<u8> {
        s.split_whitespace()
            .filter_map(|b| u8::from_str_radix(b, 16).ok())
            .collect()
    }

    /// Kinco FD3s on one telegram line at `baud`: station `i + 1` on drive `i`, each port
    /// echoing in a ring where `echo` says so.
    struct Rig {
        drives: Dictionaries,
        wire: Wire,
        line: TelegramLine,
    }

    impl Rig {
        fn new(
            baud: u32,
            stations: u8,
            echo: bool,
            topology: Topology,
            u2brg: Option<u64>,
        ) -> Self {
            let ports = (0..stations)
                .map(|i| (on(usize::from(i)), KincoRs232::new(i + 1, echo)))
                .collect();
            Rig {
                drives: Dictionaries::fd3(stations),
                wire: Wire::new(baud),
                line: TelegramLine::new(
                    ports,
                    topology,
                    u2brg.map(|code| U2brg {
                        object: od::SerialPort::find(devices::KINCO_FD3.serial_ports, "rs232")
                            .and_then(|p| p.bit_rate_now)
                            .expect("the FD3's RS232 bit_rate_now"),
                        code,
                        codes: devices::KINCO_FD3
                            .serial_bit_rate
                            .as_ref()
                            .expect("the FD3's serial_bit_rate"),
                    }),
                ),
            }
        }

        /// Feeds `bytes` written at `at` through the wire to the line; what the host reads by
        /// `until`.
        fn exchange(&mut self, at: Instant, bytes: &[u8], until: Instant) -> Vec<u8> {
            self.wire.receive(at, bytes);
            let mut arrived = Vec::new();
            self.wire.arrived(until, &mut |t, b| arrived.push((t, b)));
            for (t, b) in arrived {
                self.line.on_byte(t, b, &mut self.drives, &mut self.wire);
            }
            self.wire.crossed(until);
            let mut got = Vec::new();
            self.wire.flush(&mut |b| {
                got.extend_from_slice(b);
                b.len()
            });
            got
        }
    }

    /// A telegram writing the 16-bit `value` to `index`:0 of `station`.
    fn write16(station: u8, index: u16, value: u16) -> [u8; TELEGRAM_LEN] {
        let [lo, hi] = value.to_le_bytes();
        drive::vendors::kinco::rs232::Request::Write {
            index,
            sub: 0,
            data: [lo, hi, 0, 0],
            len: 2,
        }
        .emit(station)
    }

    /// KINCO-232-01 and KINCO-232-05 through the line: the answer is read when its 10 bytes
    /// have crossed after the request's 10, 20 character times at 38400 bit/s (5.2 ms).
    #[test]
    fn kinco_232_01_answer_after_twenty_characters() {
        let mut rig = Rig::new(38_400, 1, false, Topology::Ring, Some(270));
        let t = hex("01 2B 40 60 00 2F 00 00 00 05");
        let early = rig.exchange(Instant::ZERO, &t, Instant::from_nanos(5_208_000));
        assert!(early.is_empty(), "{early:02X?}");
        let got = rig.exchange(
            Instant::from_nanos(5_208_000),
            &[],
            Instant::from_nanos(5_208_320),
        );
        assert_eq!(got, hex("01 60 40 60 00 00 00 00 00 FF"));
        assert_eq!(
            rig.drives.0.first().and_then(|d| d.get_unsigned(0x6040, 0)),
            Some(0x2F)
        );
    }

    /// KINCO-232-07, KINCO-232-08 and garbage: a bad checksum, another ID, short telegrams
    /// and noise get no answer; the next good telegram after a silence is answered.
    #[test]
    fn kinco_232_07_08_bad_input_then_a_good_telegram() {
        let mut rig = Rig::new(115_200, 1, false, Topology::Ring, None);
        let ms = Instant::from_millis;
        let mut got = rig.exchange(
            ms(0),
            &hex("01 2B 40 60 00 2F 00 00 00 06 02 2B 40 60 00 2F 00 00 00 04"),
            ms(10),
        );
        got.extend(rig.exchange(ms(10), &[0x01, 0x40, 0x41], ms(11)));
        let noise: Vec<u8> = (0..=255u8).cycle().take(777).collect();
        got.extend(rig.exchange(ms(100), &noise, ms(200)));
        assert!(got.len() <= 10 * 78, "noise may form telegrams, never more");
        let c = rig.line.counters();
        assert_eq!(c.other_station, 1);
        assert!(c.bad_checksum >= 1);
        assert!(c.partial >= 1);
        let answer = rig.exchange(ms(300), &hex("01 40 41 60 00 00 00 00 00 1E"), ms(310));
        assert_eq!(answer.get(..5), Some(&hex("01 4B 41 60 00")[..]));
    }

    /// KINCO-232-09: two drives in a ring; the host reads its own telegram, then the answer
    /// of the drive addressed, whichever it is.
    #[test]
    fn kinco_232_09_two_drives_in_a_ring() {
        let mut rig = Rig::new(38_400, 2, true, Topology::Ring, None);
        let ms = Instant::from_millis;
        for (i, station) in [1u8, 2].into_iter().enumerate() {
            let t = write16(station, 0x6040, 0x0F);
            let start = ms(100 * i as u64);
            let got = rig.exchange(start, &t, start + std::time::Duration::from_millis(50));
            assert_eq!(got.len(), 20, "{got:02X?}");
            assert_eq!(got.get(..10), Some(&t[..]));
            assert_eq!(got.get(10..12), Some(&[station, 0x60][..]));
        }
        for d in &rig.drives.0 {
            assert_eq!(d.get_unsigned(0x6040, 0), Some(0x0F));
        }
        // A station no drive has: only the echo.
        let t = drive::vendors::kinco::rs232::Request::Read {
            index: 0x6041,
            sub: 0,
        }
        .emit(9);
        let got = rig.exchange(ms(500), &t, ms(550));
        assert_eq!(got, t.to_vec());
    }

    /// RS485 with RS485_Protocol = 1: every drive hears the host, the one addressed answers.
    #[test]
    fn telegrams_on_an_rs485_bus() {
        let mut rig = Rig::new(19_200, 2, false, Topology::Bus, None);
        let t = write16(2, 0x6040, 0x06);
        let got = rig.exchange(Instant::ZERO, &t, Instant::from_millis(50));
        assert_eq!(got.len(), 10);
        assert_eq!(got.get(..2), Some(&[2, 0x60][..]));
        let cw: Vec<_> = rig
            .drives
            .0
            .iter()
            .map(|d| d.get_unsigned(0x6040, 0))
            .collect();
        assert_eq!(cw, [Some(0), Some(6)]);
    }

    /// U2BRG (2FE1h) written over the line applies at once, after the answer.
    #[test]
    fn u2brg_applies_at_once() {
        let mut rig = Rig::new(38_400, 1, false, Topology::Ring, Some(270));
        let t = write16(1, 0x2FE1, 90);
        let got = rig.exchange(Instant::ZERO, &t, Instant::from_millis(20));
        assert_eq!(got.get(1), Some(&0x60));
        assert_eq!(
            rig.wire.char_time(),
            crate::serial::wire::char_time(115_200)
        );
    }
}
