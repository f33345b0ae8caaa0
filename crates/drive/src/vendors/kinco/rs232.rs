//! The Kinco RS232 telegram protocol (Kinco CD3 / FD3 manual ch. 10, lines L2170-2310 of its
//! text kept beside the project): every telegram is 10 bytes,
//!
//! ```text
//! byte 0   bytes 1…8                                      byte 9
//! ID       CMD, index LSB, index MSB, sub, D0, D1, D2, D3  CHKS
//! ```
//!
//! The eight data bytes are a CANopen expedited SDO (§10.3): 23h / 2Bh / 2Fh write 4 / 2 / 1
//! bytes and are answered 60h; 40h reads and is answered 43h / 4Bh / 4Fh with 4 / 2 / 1 bytes;
//! 80h answers an error with its cause in bytes 4…7. ID is the station number 100Bh (§10.2).
//! The drive never speaks unasked. It maps onto object access the way the CMMP-AS CI terminal
//! does ([`crate::vendors::festo_cmmp_as::ci_terminal`]): one telegram, one [`ObjectAccess`]
//! read or write.
//!
//! What the manual says, and the decisions where it is silent or wrong:
//! - Checksum: printed "CHKS = SUM(byte0…byte8), low byte" (L2187). Decision: the **negated**
//!   sum, (−Σ byte 0…8) mod 256, so that all ten bytes sum to 0: the four printed telegrams
//!   of §10.4 (L2286-2292) verify only this way (their KINCO-232 vectors).
//! - A wrong checksum or another station's ID: no answer, the telegram is dropped (L2201,
//!   L2215) and counted here.
//! - Ring (RS232_Loop_Enable 6510h:0B = 1, §10.2.2 L2203-2217): every drive passes each
//!   telegram on unchanged, and the addressed one appends its answer, so the host reads its own
//!   telegram and then the answer (KINCO-232-09). Decision: the drive repeats every complete
//!   10-byte block it receives (a bad checksum, another station's telegram or answer too) — a
//!   repeater in a ring does not judge what it passes on.
//! - Write answer bytes 4…7 are "reserved" (L2249). Decision: sent as 00h (KINCO-232-05), as
//!   CiA 301's download response; a read answer's unused bytes are 00h too.
//! - Error causes are not listed (L2249, L2281). Decision: the CiA 301 SDO abort code, little
//!   endian, as an SDO abort carries it (KINCO-232-11: 0602 0000h → `00 00 02 06`). A command
//!   byte the manual does not list is 0504 0001h; a write whose size does not match the object
//!   is what the dictionary says (0607 0010h); a read of an object that is not 1, 2 or 4 bytes
//!   long is 0601 0000h.
//! - Framing: the manual has none beyond "10 bytes". Decision: bytes are gathered into
//!   telegrams, and a partial telegram is dropped when the line has been silent for
//!   [`DEFAULT_GAP`]: a host writes its 10 bytes at once, so a pause inside a telegram means a
//!   lost or stray byte, and the next telegram must start fresh.
//!
//! Sans-IO: bytes and the time come in as arguments; nothing allocates.

use core::time::Duration;

use od::{AbortCode, Instant, ObjectAccess};

/// Every telegram, request or answer, is 10 bytes (§10.2).
pub const TELEGRAM_LEN: usize = 10;

/// One telegram as it goes on the wire.
pub type Telegram = [u8; TELEGRAM_LEN];

/// Silence after which a partial telegram is dropped (decided, see the module doc): 20 ms,
/// more than 10 characters at 9600 bit/s take, less than the 80 ms public drivers wait for an
/// answer.
pub const DEFAULT_GAP: Duration = Duration::from_millis(20);

/// §10.3.1 download (write) command bytes.
pub const WRITE_4: u8 = 0x23;
/// Write 2 bytes.
pub const WRITE_2: u8 = 0x2B;
/// Write 1 byte.
pub const WRITE_1: u8 = 0x2F;
/// §10.3.2 upload (read) command byte.
pub const READ: u8 = 0x40;
/// Answer: write done.
pub const WRITTEN: u8 = 0x60;
/// Answer: 4 bytes read.
pub const READ_4: u8 = 0x43;
/// Answer: 2 bytes read.
pub const READ_2: u8 = 0x4B;
/// Answer: 1 byte read.
pub const READ_1: u8 = 0x4F;
/// Answer: error, cause in bytes 4…7.
pub const ERROR: u8 = 0x80;

/// CHKS of bytes 0…8: (−Σ) mod 256 (the decision in the module doc).
pub fn checksum(bytes: &[u8]) -> u8 {
    bytes
        .iter()
        .fold(0u8, |acc, &b| acc.wrapping_add(b))
        .wrapping_neg()
}

/// Whether the ten bytes sum to 0 mod 256.
pub fn checksum_ok(t: &Telegram) -> bool {
    t.iter().fold(0u8, |acc, &b| acc.wrapping_add(b)) == 0
}

/// Why a telegram got no answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ignored {
    /// The ten bytes do not sum to 0.
    Checksum,
    /// Byte 0 is another station's ID.
    OtherStation,
}

/// A request, parsed from bytes 1…8.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// 23h / 2Bh / 2Fh: `data[..len]` little-endian.
    Write {
        index: u16,
        sub: u8,
        data: [u8; 4],
        len: usize,
    },
    /// 40h.
    Read { index: u16, sub: u8 },
    /// A command byte the manual does not list.
    Unknown { command: u8, index: u16, sub: u8 },
}

impl Request {
    /// The request of a telegram to `station`, or why it is ignored.
    pub fn parse(t: &Telegram, station: u8) -> Result<Request, Ignored> {
        if !checksum_ok(t) {
            return Err(Ignored::Checksum);
        }
        let [id, command, lo, hi, sub, d0, d1, d2, d3, _] = *t;
        if id != station {
            return Err(Ignored::OtherStation);
        }
        let index = u16::from_le_bytes([lo, hi]);
        let data = [d0, d1, d2, d3];
        Ok(match command {
            WRITE_4 => Request::Write {
                index,
                sub,
                data,
                len: 4,
            },
            WRITE_2 => Request::Write {
                index,
                sub,
                data,
                len: 2,
            },
            WRITE_1 => Request::Write {
                index,
                sub,
                data,
                len: 1,
            },
            READ => Request::Read { index, sub },
            command => Request::Unknown {
                command,
                index,
                sub,
            },
        })
    }

    /// The telegram of this request to `station` (the master side).
    pub fn emit(&self, station: u8) -> Telegram {
        let (command, index, sub, data) = match *self {
            Request::Write {
                index,
                sub,
                data,
                len,
            } => {
                let command = match len {
                    1 => WRITE_1,
                    2 => WRITE_2,
                    _ => WRITE_4,
                };
                let mut d = [0u8; 4];
                for (i, b) in d.iter_mut().enumerate().take(len.min(4)) {
                    *b = data.get(i).copied().unwrap_or(0);
                }
                (command, index, sub, d)
            }
            Request::Read { index, sub } => (READ, index, sub, [0; 4]),
            Request::Unknown {
                command,
                index,
                sub,
            } => (command, index, sub, [0; 4]),
        };
        telegram(station, command, index, sub, data)
    }

    pub fn index(&self) -> (u16, u8) {
        match *self {
            Request::Write { index, sub, .. }
            | Request::Read { index, sub }
            | Request::Unknown { index, sub, .. } => (index, sub),
        }
    }
}

/// An answer, as the drive sends it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Response {
    /// 60h.
    Written { index: u16, sub: u8 },
    /// 43h / 4Bh / 4Fh: `data[..len]` little-endian.
    Read {
        index: u16,
        sub: u8,
        data: [u8; 4],
        len: usize,
    },
    /// 80h and the abort code.
    Error {
        index: u16,
        sub: u8,
        code: AbortCode,
    },
}

impl Response {
    pub fn emit(&self, station: u8) -> Telegram {
        match *self {
            Response::Written { index, sub } => telegram(station, WRITTEN, index, sub, [0; 4]),
            Response::Read {
                index,
                sub,
                data,
                len,
            } => {
                let command = match len {
                    1 => READ_1,
                    2 => READ_2,
                    _ => READ_4,
                };
                let mut d = [0u8; 4];
                for (i, b) in d.iter_mut().enumerate().take(len.min(4)) {
                    *b = data.get(i).copied().unwrap_or(0);
                }
                telegram(station, command, index, sub, d)
            }
            Response::Error { index, sub, code } => {
                telegram(station, ERROR, index, sub, code.0.to_le_bytes())
            }
        }
    }

    /// An answer telegram from `station` (the master side); `None` if the checksum is wrong,
    /// the ID is another's or the command byte is none of the answers.
    pub fn parse(t: &Telegram, station: u8) -> Option<Response> {
        if !checksum_ok(t) {
            return None;
        }
        let [id, command, lo, hi, sub, d0, d1, d2, d3, _] = *t;
        if id != station {
            return None;
        }
        let index = u16::from_le_bytes([lo, hi]);
        let data = [d0, d1, d2, d3];
        let read = |len| Response::Read {
            index,
            sub,
            data,
            len,
        };
        Some(match command {
            WRITTEN => Response::Written { index, sub },
            READ_4 => read(4),
            READ_2 => read(2),
            READ_1 => read(1),
            ERROR => Response::Error {
                index,
                sub,
                code: AbortCode(u32::from_le_bytes(data)),
            },
            _ => return None,
        })
    }
}

fn telegram(station: u8, command: u8, index: u16, sub: u8, data: [u8; 4]) -> Telegram {
    let [lo, hi] = index.to_le_bytes();
    let [d0, d1, d2, d3] = data;
    let mut t = [station, command, lo, hi, sub, d0, d1, d2, d3, 0];
    t[9] = checksum(&t[..9]);
    t
}

/// Carries out one request on `od`.
pub fn run(request: Request, od: &mut dyn ObjectAccess) -> Response {
    let (index, sub) = request.index();
    let result = match request {
        Request::Write {
            index,
            sub,
            data,
            len,
        } => od
            .write(index, sub, data.get(..len).unwrap_or(&[]))
            .map(|()| Response::Written { index, sub }),
        Request::Read { index, sub } => read(index, sub, od),
        Request::Unknown { .. } => Err(AbortCode::COMMAND_SPECIFIER),
    };
    result.unwrap_or_else(|code| Response::Error { index, sub, code })
}

fn read(index: u16, sub: u8, od: &mut dyn ObjectAccess) -> Result<Response, AbortCode> {
    let e = od.entry(index, sub)?;
    // Only the three expedited sizes have an answer byte (decided, see the module doc).
    if !matches!(e.data_type.fixed_size(), Some(1 | 2 | 4)) {
        return Err(AbortCode::UNSUPPORTED_ACCESS);
    }
    let mut data = [0u8; 4];
    let len = od.read(index, sub, &mut data)?;
    Ok(Response::Read {
        index,
        sub,
        data,
        len,
    })
}

/// Gathers a byte stream into telegrams; a partial one is dropped after a silence of `gap`.
#[derive(Debug, Clone)]
pub struct TelegramCutter {
    buf: Telegram,
    len: usize,
    last: Option<Instant>,
    gap: Duration,
}

impl TelegramCutter {
    pub const fn new(gap: Duration) -> Self {
        TelegramCutter {
            buf: [0; TELEGRAM_LEN],
            len: 0,
            last: None,
            gap,
        }
    }

    /// Adds one byte received at `now`; a telegram when it was the tenth. `dropped` is set
    /// when a partial telegram was thrown away first.
    pub fn push(&mut self, now: Instant, byte: u8, dropped: &mut bool) -> Option<Telegram> {
        if self.len > 0
            && self
                .last
                .is_some_and(|t| now.saturating_since(t) > self.gap)
        {
            self.len = 0;
            *dropped = true;
        }
        self.last = Some(now);
        if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = byte;
            self.len += 1;
        }
        if self.len == TELEGRAM_LEN {
            self.len = 0;
            Some(self.buf)
        } else {
            None
        }
    }

    /// Bytes of a partial telegram waiting.
    pub fn pending(&self) -> usize {
        self.len
    }

    /// When a partial telegram will be dropped, if one waits.
    pub fn deadline(&self) -> Option<Instant> {
        (self.len > 0)
            .then(|| self.last.map(|t| t + self.gap))
            .flatten()
    }
}

/// What the server counted: the telegrams it answered and, by cause, those it dropped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    pub answered: u32,
    pub bad_checksum: u32,
    pub other_station: u32,
    /// Partial telegrams dropped after a silence.
    pub partial: u32,
}

/// The drive's RS232 port: bytes in, telegrams out.
#[derive(Debug, Clone)]
pub struct KincoRs232 {
    station: u8,
    ring: bool,
    cutter: TelegramCutter,
    counters: Counters,
}

impl KincoRs232 {
    /// A port answering as `station` (100Bh at power-up; a new ID takes effect after save and
    /// reboot, §9.5 d5.01); `ring` is RS232_Loop_Enable 6510h:0B = 1 at power-up.
    pub const fn new(station: u8, ring: bool) -> Self {
        KincoRs232 {
            station,
            ring,
            cutter: TelegramCutter::new(DEFAULT_GAP),
            counters: Counters {
                answered: 0,
                bad_checksum: 0,
                other_station: 0,
                partial: 0,
            },
        }
    }

    pub fn station(&self) -> u8 {
        self.station
    }

    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// When a partial telegram will be dropped (for the runtime's timer).
    pub fn deadline(&self) -> Option<Instant> {
        self.cutter.deadline()
    }

    /// Bytes received at `now`; what the drive sends goes to `out` (in a ring: the telegram
    /// itself, then the answer).
    pub fn on_bytes(
        &mut self,
        now: Instant,
        bytes: &[u8],
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(&[u8]),
    ) {
        for &b in bytes {
            let mut dropped = false;
            let t = self.cutter.push(now, b, &mut dropped);
            if dropped {
                self.counters.partial = self.counters.partial.saturating_add(1);
            }
            if let Some(t) = t {
                self.on_telegram(&t, od, out);
            }
        }
    }

    /// One complete telegram.
    pub fn on_telegram(
        &mut self,
        t: &Telegram,
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(&[u8]),
    ) {
        if self.ring {
            out(t);
        }
        match Request::parse(t, self.station) {
            Ok(request) => {
                let answer = run(request, od).emit(self.station);
                self.counters.answered = self.counters.answered.saturating_add(1);
                out(&answer);
            }
            Err(Ignored::Checksum) => {
                self.counters.bad_checksum = self.counters.bad_checksum.saturating_add(1);
            }
            Err(Ignored::OtherStation) => {
                self.counters.other_station = self.counters.other_station.saturating_add(1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use od::{ObjectDictionary, Value};
    use std::{format, string::String, vec, vec::Vec};

    fn fd3() -> ObjectDictionary<Vec<u8>> {
        let d = &devices::KINCO_FD3;
        ObjectDictionary::new(d, 1, vec![0; d.storage_size]).unwrap()
    }

    fn hex(s: &str) -> Telegram {
        let mut t = [0u8; TELEGRAM_LEN];
        for (slot, b) in t.iter_mut().zip(s.split_whitespace()) {
            *slot = u8::from_str_radix(b, 16).unwrap();
        }
        t
    }

    /// Sends `request` to a point-to-point port of station 1; what comes back.
    fn exchange(od: &mut ObjectDictionary<Vec<u8>>, request: &str) -> Vec<u8> {
        let mut port = KincoRs232::new(1, false);
        let mut out = Vec::new();
        port.on_bytes(Instant::ZERO, &hex(request), od, &mut |b| {
            out.extend_from_slice(b)
        });
        out
    }

    /// The four telegrams of §10.4 (L2286-2292) carry the negated sum.
    #[test]
    fn kinco_232_01_to_04_printed_checksums() {
        for (id, t, chks) in [
            ("KINCO-232-01", "01 2B 40 60 00 2F 00 00 00 05", 0x05),
            ("KINCO-232-02", "01 2F 60 60 00 06 00 00 00 0A", 0x0A),
            ("KINCO-232-03", "01 23 7A 60 00 50 C3 00 00 EF", 0xEF),
            ("KINCO-232-04", "01 40 41 60 00 00 00 00 00 1E", 0x1E),
        ] {
            let t = hex(t);
            assert_eq!(checksum(&t[..9]), chks, "{id}");
            assert!(checksum_ok(&t), "{id}");
        }
    }

    /// KINCO-232-01 and KINCO-232-05: controlword 6040h := 002Fh, answered
    /// `01 60 40 60 00 00 00 00 00 FF`.
    #[test]
    fn kinco_232_01_05_write_controlword() {
        let mut od = fd3();
        let answer = exchange(&mut od, "01 2B 40 60 00 2F 00 00 00 05");
        assert_eq!(answer, hex("01 60 40 60 00 00 00 00 00 FF"));
        assert_eq!(od.get_unsigned(0x6040, 0), Some(0x2F));
    }

    /// KINCO-232-02: Operation_Mode 6060h := 6 (homing), 8 bit.
    #[test]
    fn kinco_232_02_write_operation_mode() {
        let mut od = fd3();
        let answer = exchange(&mut od, "01 2F 60 60 00 06 00 00 00 0A");
        assert_eq!(answer.get(..5), Some(&[0x01, 0x60, 0x60, 0x60, 0x00][..]));
        assert_eq!(od.value(0x6060, 0), Some(Value::Signed(6)));
    }

    /// KINCO-232-03: Target_Position 607Ah := 50000 (C350h), 32 bit.
    #[test]
    fn kinco_232_03_write_target_position() {
        let mut od = fd3();
        let answer = exchange(&mut od, "01 23 7A 60 00 50 C3 00 00 EF");
        assert_eq!(answer.get(..5), Some(&[0x01, 0x60, 0x7A, 0x60, 0x00][..]));
        assert!(checksum_ok(&answer.clone().try_into().unwrap()));
        assert_eq!(od.value(0x607A, 0), Some(Value::Signed(50000)));
    }

    /// KINCO-232-04 and KINCO-232-06: reading the statusword answers 4Bh with the two bytes
    /// in telegram bytes 5-6.
    #[test]
    fn kinco_232_04_06_read_statusword() {
        let mut od = fd3();
        od.write_internal(0x6041, 0, &0x0637u16.to_le_bytes())
            .unwrap();
        let answer = exchange(&mut od, "01 40 41 60 00 00 00 00 00 1E");
        let mut expected = [0x01, 0x4B, 0x41, 0x60, 0x00, 0x37, 0x06, 0x00, 0x00, 0];
        expected[9] = checksum(&expected[..9]);
        assert_eq!(answer, expected);
        // 8- and 32-bit objects answer 4Fh and 43h.
        let a = exchange(
            &mut od,
            &format_request(Request::Read {
                index: 0x6060,
                sub: 0,
            }),
        );
        assert_eq!(a.get(1), Some(&READ_1));
        let a = exchange(
            &mut od,
            &format_request(Request::Read {
                index: 0x607A,
                sub: 0,
            }),
        );
        assert_eq!(a.get(1), Some(&READ_4));
    }

    fn format_request(r: Request) -> String {
        r.emit(1)
            .iter()
            .map(|b| format!("{b:02X}"))
            .collect::<Vec<_>>()
            .join(" ")
    }

    /// KINCO-232-07: a wrong checksum gets no answer, and nothing is written.
    #[test]
    fn kinco_232_07_wrong_checksum_is_dropped() {
        let mut od = fd3();
        let mut port = KincoRs232::new(1, false);
        let mut out = Vec::new();
        port.on_bytes(
            Instant::ZERO,
            &hex("01 2B 40 60 00 2F 00 00 00 06"),
            &mut od,
            &mut |b| out.extend_from_slice(b),
        );
        assert!(out.is_empty());
        assert_eq!(od.get_unsigned(0x6040, 0), Some(0));
        assert_eq!(port.counters().bad_checksum, 1);
    }

    /// KINCO-232-08: station 1 does not answer a telegram to ID 2.
    #[test]
    fn kinco_232_08_other_station_is_ignored() {
        let mut od = fd3();
        let mut port = KincoRs232::new(1, false);
        let mut out = Vec::new();
        port.on_bytes(
            Instant::ZERO,
            &hex("02 2B 40 60 00 2F 00 00 00 04"),
            &mut od,
            &mut |b| out.extend_from_slice(b),
        );
        assert!(out.is_empty());
        assert_eq!(od.get_unsigned(0x6040, 0), Some(0));
        assert_eq!(port.counters().other_station, 1);
    }

    /// KINCO-232-09: in a ring the host reads its own telegram, then the answer (20 bytes);
    /// to a station no drive has, only the echo.
    #[test]
    fn kinco_232_09_ring_echoes_then_answers() {
        let mut od = fd3();
        let mut port = KincoRs232::new(1, true);
        let mut out = Vec::new();
        let t = hex("01 2B 40 60 00 2F 00 00 00 05");
        port.on_bytes(Instant::ZERO, &t, &mut od, &mut |b| {
            out.extend_from_slice(b)
        });
        assert_eq!(out.len(), 20);
        assert_eq!(out.get(..10), Some(&t[..]));
        assert_eq!(
            out.get(10..),
            Some(&hex("01 60 40 60 00 00 00 00 00 FF")[..])
        );
        out.clear();
        let other = hex("02 2B 40 60 00 2F 00 00 00 04");
        port.on_bytes(Instant::ZERO, &other, &mut od, &mut |b| {
            out.extend_from_slice(b)
        });
        assert_eq!(out, other);
        // Two drives in a ring: drive 2 passes on drive 1's echo and answer, then adds nothing.
        let mut od2 = fd3();
        let mut drive2 = KincoRs232::new(2, true);
        let mut host = Vec::new();
        let mut hop = Vec::new();
        KincoRs232::new(1, true).on_bytes(Instant::ZERO, &t, &mut od, &mut |b| {
            hop.extend_from_slice(b)
        });
        drive2.on_bytes(Instant::ZERO, &hop, &mut od2, &mut |b| {
            host.extend_from_slice(b)
        });
        assert_eq!(host, hop);
        assert_eq!(od2.get_unsigned(0x6040, 0), Some(0));
    }

    /// KINCO-232-11: a write to an object the drive does not have answers 80h with the CiA 301
    /// abort code 0602 0000h, little-endian.
    #[test]
    fn kinco_232_11_error_answer() {
        let mut od = fd3();
        let answer = exchange(&mut od, "01 2B 00 99 00 01 00 00 00 3A");
        let mut expected = [0x01, 0x80, 0x00, 0x99, 0x00, 0x00, 0x00, 0x02, 0x06, 0];
        expected[9] = checksum(&expected[..9]);
        assert_eq!(answer, expected);
        assert_eq!(
            Response::parse(&expected, 1),
            Some(Response::Error {
                index: 0x9900,
                sub: 0,
                code: AbortCode::NO_OBJECT
            })
        );
    }

    /// Decisions: a size that does not match the object, a read-only object, an unknown
    /// command byte.
    #[test]
    fn wrong_size_read_only_and_unknown_command() {
        let mut od = fd3();
        let write32_to_16 = Request::Write {
            index: 0x6040,
            sub: 0,
            data: [0x0F, 0, 0, 0],
            len: 4,
        };
        let a = exchange(&mut od, &format_request(write32_to_16));
        let code = |a: &[u8]| u32::from_le_bytes(a[5..9].try_into().unwrap());
        assert_eq!(a[1], ERROR);
        assert_eq!(code(&a), AbortCode::LENGTH_TOO_HIGH.0);
        let ro = Request::Write {
            index: 0x6041,
            sub: 0,
            data: [1, 0, 0, 0],
            len: 2,
        };
        assert_eq!(
            code(&exchange(&mut od, &format_request(ro))),
            AbortCode::READ_ONLY.0
        );
        let unknown = Request::Unknown {
            command: 0x22,
            index: 0x6040,
            sub: 0,
        };
        assert_eq!(
            code(&exchange(&mut od, &format_request(unknown))),
            AbortCode::COMMAND_SPECIFIER.0
        );
    }

    /// Framing: telegrams split over several reads join; a partial telegram followed by
    /// silence is dropped and the next one is answered.
    #[test]
    fn split_telegrams_join_and_stale_bytes_are_dropped() {
        let mut od = fd3();
        let mut port = KincoRs232::new(1, false);
        let mut out = Vec::new();
        let t = hex("01 40 41 60 00 00 00 00 00 1E");
        let ms = Instant::from_millis;
        port.on_bytes(ms(0), &t[..4], &mut od, &mut |b| out.extend_from_slice(b));
        port.on_bytes(ms(1), &t[4..], &mut od, &mut |b| out.extend_from_slice(b));
        assert_eq!(out.len(), 10);
        out.clear();
        port.on_bytes(ms(10), &[0x55, 0x01, 0x02], &mut od, &mut |b| {
            out.extend_from_slice(b)
        });
        assert_eq!(port.deadline(), Some(ms(10) + DEFAULT_GAP));
        port.on_bytes(ms(100), &t, &mut od, &mut |b| out.extend_from_slice(b));
        assert_eq!(out.len(), 10, "answered after the stray bytes were dropped");
        assert_eq!(port.counters().partial, 1);
        assert_eq!(port.counters().answered, 2);
    }

    /// The master side: what `emit` builds, `parse` reads back.
    #[test]
    fn requests_and_answers_round_trip() {
        let w = Request::Write {
            index: 0x607A,
            sub: 0,
            data: 50000u32.to_le_bytes(),
            len: 4,
        };
        assert_eq!(w.emit(1), hex("01 23 7A 60 00 50 C3 00 00 EF"));
        assert_eq!(Request::parse(&w.emit(1), 1), Ok(w));
        let r = Response::Read {
            index: 0x6041,
            sub: 0,
            data: [0x37, 0x06, 0, 0],
            len: 2,
        };
        assert_eq!(Response::parse(&r.emit(1), 1), Some(r));
        assert_eq!(Response::parse(&r.emit(1), 2), None);
    }
}
