//! socketcand wire codec: framing of `< ... >` messages, parsing and formatting. No I/O.
//!
//! Framing follows socketcand's `receive_command`: bytes before the first `<` are garbage and
//! dropped, a message runs from that `<` to the first `>` after it, messages may be
//! concatenated and there are no newlines. Parsing is total: every byte string yields either a
//! [`Message`] or a [`CodecError`], never a panic.
//!
//! Both directions are covered, so the same codec serves the server (parsing `send`, `open`,
//! ...) and a client or test (parsing `hi`, `ok`, `frame`, ...).

use std::fmt::{self, Write as _};
use std::time::Duration;

use canopen::CanFrame;

/// Longest accepted message, `<` and `>` included. socketcand itself uses 4 KiB buffers; the
/// longest legal classic-CAN message (`< send 1FFFFFFF 8 FF FF FF FF FF FF FF FF >`) is 44.
pub const MAX_MESSAGE_LEN: usize = 1024;

/// Longest bus (channel) name socketcand accepts.
pub const MAX_CHANNEL_LEN: usize = 16;

/// The session modes a client can switch to after `open`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Broadcast manager mode, the default after `open`.
    Bcm,
    /// Every frame on the bus is forwarded; `send` puts frames on the bus.
    Raw,
    /// ISO-TP (ISO 15765-2) transport mode.
    Isotp,
    /// Statistics mode.
    Control,
}

impl Mode {
    fn keyword(self) -> &'static str {
        match self {
            Mode::Bcm => "bcmmode",
            Mode::Raw => "rawmode",
            Mode::Isotp => "isotpmode",
            Mode::Control => "controlmode",
        }
    }
}

/// Arguments of the `< CHANNEL B ... >` bit-timing configuration command, in wire order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BitTiming {
    pub bitrate: u32,
    pub sample_point: u32,
    pub tq: u32,
    pub prop_seg: u32,
    pub phase_seg1: u32,
    pub phase_seg2: u32,
    pub sjw: u32,
    pub brp: u32,
}

/// One socketcand message, either direction.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Message {
    /// `< hi >`, the server's greeting.
    Hi,
    /// `< ok >`
    Ok,
    /// `< error TEXT >`. When formatting, `<`, `>` and control characters in TEXT become `?`.
    Error(String),
    /// `< echo >`, answered with itself.
    Echo,
    /// `< open CHANNEL >`
    Open(String),
    /// `< CHANNEL B bitrate sample_point tq prop_seg phase_seg1 phase_seg2 sjw brp >`
    BitTiming { channel: String, timing: BitTiming },
    /// `< CHANNEL C listen_only loopback three_samples >`
    ControlModes {
        channel: String,
        listen_only: bool,
        loopback: bool,
        three_samples: bool,
    },
    /// `< rawmode >`, `< bcmmode >`, `< isotpmode >`, `< controlmode >`
    Mode(Mode),
    /// `< send ID DLC B0 .. >`: put one frame on the bus.
    ///
    /// `< send ID N >` with `N > 0` and no data bytes is read as a remote frame requesting `N`
    /// bytes: that is what python-can emits for an RTR message (it sends `dlc` and the empty
    /// data). socketcand would reject it; we keep the request instead.
    Send(CanFrame),
    /// `< frame ID SEC.USEC HEXDATA >`: a frame seen on the bus (remote frames are sent with
    /// no data, which is all the protocol can express).
    Frame {
        frame: CanFrame,
        timestamp: Duration,
    },
    /// `< statistics MS >` (control mode): report statistics every MS milliseconds, 0 = off.
    Statistics { interval_ms: u32 },
    /// `< stat rbytes rpackets tbytes tpackets >`
    Stat {
        rbytes: u64,
        rpackets: u64,
        tbytes: u64,
        tpackets: u64,
    },
    /// A known socketcand command this implementation does not provide (BCM jobs, ISO-TP,
    /// CAN FD). Holds the command word.
    Unsupported(&'static str),
}

/// Why bytes are not a valid message. The `Display` texts are fixed ASCII without `<` or `>`,
/// so they can go into an `< error ... >` reply as they are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum CodecError {
    #[error("message too long")]
    TooLong,
    #[error("message is not printable ASCII")]
    NotAscii,
    #[error("empty message")]
    Empty,
    #[error("unknown command")]
    UnknownCommand,
    #[error("wrong arguments for {0}")]
    Arguments(&'static str),
    #[error("bus name too long")]
    ChannelTooLong,
    #[error("invalid CAN identifier")]
    BadId,
    #[error("CAN identifier out of range")]
    IdOutOfRange,
    #[error("invalid DLC")]
    BadDlc,
    #[error("invalid data byte")]
    BadDataByte,
    #[error("DLC does not match the number of data bytes")]
    DlcMismatch,
    #[error("invalid frame data")]
    BadFrameData,
    #[error("invalid timestamp")]
    BadTimestamp,
    #[error("invalid number")]
    BadNumber,
}

/// Commands of socketcand's BCM, ISO-TP and CAN FD modes (and their server-side answers).
const UNSUPPORTED: &[&str] = &[
    "add",
    "update",
    "delete",
    "filter",
    "muxfilter",
    "subscribe",
    "unsubscribe",
    "isotpconf",
    "sendpdu",
    "pdu",
    "fdsend",
    "fdframe",
];

/// Tokens of a message kept on the stack while parsing.
const MAX_TOKENS: usize = 16;

/// Parse the text between `<` and `>` (brackets excluded).
pub fn parse_body(body: &[u8]) -> Result<Message, CodecError> {
    if !body
        .iter()
        .all(|b| b.is_ascii_graphic() || b.is_ascii_whitespace())
    {
        return Err(CodecError::NotAscii);
    }
    let text = std::str::from_utf8(body).map_err(|_| CodecError::NotAscii)?;
    // Up to MAX_TOKENS tokens (a `send` has at most 11) on the stack: the hot path does not
    // allocate; longer messages (an `error` text) are collected.
    let mut on_stack = [""; MAX_TOKENS];
    let mut count = 0;
    let mut words = text.split_ascii_whitespace();
    for (slot, word) in on_stack.iter_mut().zip(&mut words) {
        *slot = word;
        count += 1;
    }
    let collected: Vec<&str>;
    let tokens: &[&str] = if words.next().is_some() {
        collected = text.split_ascii_whitespace().collect();
        &collected
    } else {
        on_stack.get(..count).unwrap_or(&[])
    };
    let Some((&command, args)) = tokens.split_first() else {
        return Err(CodecError::Empty);
    };
    let no_args = |msg: Message, name: &'static str| {
        if args.is_empty() {
            Ok(msg)
        } else {
            Err(CodecError::Arguments(name))
        }
    };
    match command {
        "hi" => no_args(Message::Hi, "hi"),
        "ok" => no_args(Message::Ok, "ok"),
        "echo" => no_args(Message::Echo, "echo"),
        "rawmode" => no_args(Message::Mode(Mode::Raw), "rawmode"),
        "bcmmode" => no_args(Message::Mode(Mode::Bcm), "bcmmode"),
        "isotpmode" => no_args(Message::Mode(Mode::Isotp), "isotpmode"),
        "controlmode" => no_args(Message::Mode(Mode::Control), "controlmode"),
        "error" => Ok(Message::Error(args.join(" "))),
        "open" => match args {
            [channel] => Ok(Message::Open(parse_channel(channel)?)),
            _ => Err(CodecError::Arguments("open")),
        },
        "send" => parse_send(args).map(Message::Send),
        "frame" => parse_frame(args),
        "statistics" => match args {
            [ms] => Ok(Message::Statistics {
                interval_ms: parse_decimal(ms)?,
            }),
            _ => Err(CodecError::Arguments("statistics")),
        },
        "stat" => match args {
            [rb, rp, tb, tp] => Ok(Message::Stat {
                rbytes: parse_decimal(rb)?,
                rpackets: parse_decimal(rp)?,
                tbytes: parse_decimal(tb)?,
                tpackets: parse_decimal(tp)?,
            }),
            _ => Err(CodecError::Arguments("stat")),
        },
        _ => {
            if let Some(&name) = UNSUPPORTED.iter().find(|&&u| u == command) {
                return Ok(Message::Unsupported(name));
            }
            match args {
                ["B", rest @ ..] => parse_bit_timing(command, rest),
                ["C", rest @ ..] => parse_control_modes(command, rest),
                _ => Err(CodecError::UnknownCommand),
            }
        }
    }
}

fn parse_channel(s: &str) -> Result<String, CodecError> {
    if s.len() > MAX_CHANNEL_LEN {
        Err(CodecError::ChannelTooLong)
    } else {
        Ok(s.to_owned())
    }
}

fn parse_bit_timing(channel: &str, args: &[&str]) -> Result<Message, CodecError> {
    let [bitrate, sample_point, tq, prop_seg, phase_seg1, phase_seg2, sjw, brp] = args else {
        return Err(CodecError::Arguments("B"));
    };
    Ok(Message::BitTiming {
        channel: parse_channel(channel)?,
        timing: BitTiming {
            bitrate: parse_decimal(bitrate)?,
            sample_point: parse_decimal(sample_point)?,
            tq: parse_decimal(tq)?,
            prop_seg: parse_decimal(prop_seg)?,
            phase_seg1: parse_decimal(phase_seg1)?,
            phase_seg2: parse_decimal(phase_seg2)?,
            sjw: parse_decimal(sjw)?,
            brp: parse_decimal(brp)?,
        },
    })
}

fn parse_control_modes(channel: &str, args: &[&str]) -> Result<Message, CodecError> {
    let [listen_only, loopback, three_samples] = args else {
        return Err(CodecError::Arguments("C"));
    };
    Ok(Message::ControlModes {
        channel: parse_channel(channel)?,
        listen_only: parse_flag(listen_only)?,
        loopback: parse_flag(loopback)?,
        three_samples: parse_flag(three_samples)?,
    })
}

fn parse_flag(s: &str) -> Result<bool, CodecError> {
    match s {
        "0" => Ok(false),
        "1" => Ok(true),
        _ => Err(CodecError::BadNumber),
    }
}

fn parse_decimal<T: std::str::FromStr>(s: &str) -> Result<T, CodecError> {
    // `FromStr` for integers accepts a leading `+`; the protocol does not.
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return Err(CodecError::BadNumber);
    }
    s.parse().map_err(|_| CodecError::BadNumber)
}

fn is_hex(s: &str) -> bool {
    !s.is_empty() && s.bytes().all(|b| b.is_ascii_hexdigit())
}

/// A CAN identifier token: 1 to 8 hex digits.
///
/// Standard or extended? socketcand treats exactly 8 digits as extended; python-can (which
/// always writes 3 or 8 digits) reads "length != 3" as extended. Decision: up to 3 digits is a
/// standard identifier, 4 or more is extended. This agrees with both for 3 and 8 digits, keeps
/// a hand-typed `< send 0 2 1 0 >` a standard NMT frame as socketcand does, and reads the
/// unpadded extended IDs of python-can < 4.2 (e.g. `1234`) as extended.
fn parse_id(s: &str) -> Result<(u32, bool), CodecError> {
    if s.len() > 8 || !is_hex(s) {
        return Err(CodecError::BadId);
    }
    let id = u32::from_str_radix(s, 16).map_err(|_| CodecError::BadId)?;
    let extended = s.len() > 3;
    let max = if extended {
        CanFrame::MAX_EXTENDED_ID
    } else {
        CanFrame::MAX_STANDARD_ID
    };
    if id > max {
        return Err(CodecError::IdOutOfRange);
    }
    Ok((id, extended))
}

/// A DLC token: decimal 0..=8 (python-can writes it as `{:X}`, identical for 0..=8).
fn parse_dlc(s: &str) -> Result<u8, CodecError> {
    if s.len() > 2 || s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return Err(CodecError::BadDlc);
    }
    match s.parse::<u8>() {
        Ok(dlc) if dlc <= 8 => Ok(dlc),
        _ => Err(CodecError::BadDlc),
    }
}

/// A data byte token: 1 or 2 hex digits (python-can writes them lowercase and unpadded).
fn parse_byte(s: &str) -> Result<u8, CodecError> {
    if s.len() > 2 || !is_hex(s) {
        return Err(CodecError::BadDataByte);
    }
    u8::from_str_radix(s, 16).map_err(|_| CodecError::BadDataByte)
}

fn parse_send(args: &[&str]) -> Result<CanFrame, CodecError> {
    let [id, dlc, bytes @ ..] = args else {
        return Err(CodecError::Arguments("send"));
    };
    let (id, extended) = parse_id(id)?;
    let dlc = parse_dlc(dlc)?;
    if bytes.is_empty() && dlc > 0 {
        // python-can's encoding of a remote frame; see `Message::Send`.
        return Ok(CanFrame {
            id,
            extended,
            rtr: true,
            len: dlc,
            data: [0; 8],
        });
    }
    if bytes.len() != usize::from(dlc) {
        return Err(CodecError::DlcMismatch);
    }
    let mut data = [0u8; 8];
    for (slot, tok) in data.iter_mut().zip(bytes.iter()) {
        *slot = parse_byte(tok)?;
    }
    let payload = data.get(..bytes.len()).ok_or(CodecError::DlcMismatch)?;
    CanFrame::with_id(id, extended, payload).map_err(|_| CodecError::IdOutOfRange)
}

fn parse_frame(args: &[&str]) -> Result<Message, CodecError> {
    let (id, ts, hex) = match args {
        [id, ts] => (id, ts, ""),
        [id, ts, hex] => (id, ts, *hex),
        _ => return Err(CodecError::Arguments("frame")),
    };
    let (id, extended) = parse_id(id)?;
    let timestamp = parse_timestamp(ts)?;
    if hex.len() > 16 || hex.len() % 2 == 1 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(CodecError::BadFrameData);
    }
    let mut data = [0u8; 8];
    let mut len = 0;
    for (slot, pair) in data.iter_mut().zip(hex.as_bytes().chunks_exact(2)) {
        let pair = std::str::from_utf8(pair).map_err(|_| CodecError::BadFrameData)?;
        *slot = u8::from_str_radix(pair, 16).map_err(|_| CodecError::BadFrameData)?;
        len += 1;
    }
    let payload = data.get(..len).ok_or(CodecError::BadFrameData)?;
    let frame = CanFrame::with_id(id, extended, payload).map_err(|_| CodecError::IdOutOfRange)?;
    Ok(Message::Frame { frame, timestamp })
}

/// `SEC.FRACTION` (socketcand writes 6 fraction digits; up to 9 are accepted) or `SEC`.
fn parse_timestamp(s: &str) -> Result<Duration, CodecError> {
    let (sec, frac) = s.split_once('.').unwrap_or((s, ""));
    let sec: u64 = parse_decimal(sec).map_err(|_| CodecError::BadTimestamp)?;
    if frac.len() > 9 || !frac.bytes().all(|b| b.is_ascii_digit()) {
        return Err(CodecError::BadTimestamp);
    }
    let mut nanos: u32 = 0;
    for b in frac.bytes().chain(std::iter::repeat(b'0')).take(9) {
        nanos = nanos * 10 + u32::from(b - b'0');
    }
    Ok(Duration::new(sec, nanos))
}

/// Write text that must not break the framing: `<`, `>` and control characters become `?`.
fn write_sanitized(f: &mut fmt::Formatter<'_>, s: &str) -> fmt::Result {
    for c in s.chars() {
        let safe = (c.is_ascii_graphic() && c != '<' && c != '>') || c == ' ';
        f.write_char(if safe { c } else { '?' })?;
    }
    Ok(())
}

fn write_id(f: &mut fmt::Formatter<'_>, frame: &CanFrame) -> fmt::Result {
    if frame.extended {
        write!(f, "{:08X}", frame.id & CanFrame::MAX_EXTENDED_ID)
    } else {
        write!(f, "{:03X}", frame.id & CanFrame::MAX_STANDARD_ID)
    }
}

/// Longest `< frame … >` text: extended ID, 20-digit seconds, 8 data bytes.
pub const FRAME_TEXT_MAX: usize = 64;

const HEX: &[u8; 16] = b"0123456789ABCDEF";

/// Writes `< frame ID SEC.USEC HEX >` into `out` without the formatting machinery (the hot
/// path of every frame a client is sent); returns its length. The same text as `Display`.
pub fn emit_frame(frame: &CanFrame, timestamp: Duration, out: &mut [u8; FRAME_TEXT_MAX]) -> usize {
    let mut w = ByteWriter { out, len: 0 };
    w.put(b"< frame ");
    let (id, digits) = if frame.extended {
        (frame.id & CanFrame::MAX_EXTENDED_ID, 8)
    } else {
        (frame.id & CanFrame::MAX_STANDARD_ID, 3)
    };
    for shift in (0..digits).rev() {
        w.hex_digit(id >> (4 * shift));
    }
    w.put(b" ");
    w.decimal(timestamp.as_secs(), 1);
    w.put(b".");
    w.decimal(u64::from(timestamp.subsec_micros()), 6);
    w.put(b" ");
    for b in frame.payload() {
        w.hex_digit(u32::from(*b >> 4));
        w.hex_digit(u32::from(*b));
    }
    // An empty payload leaves two spaces, which python-can needs (three tokens).
    w.put(b" >");
    w.len
}

struct ByteWriter<'a> {
    out: &'a mut [u8; FRAME_TEXT_MAX],
    len: usize,
}

impl ByteWriter<'_> {
    fn put(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if let Some(slot) = self.out.get_mut(self.len) {
                *slot = b;
                self.len += 1;
            }
        }
    }

    fn hex_digit(&mut self, v: u32) {
        let d = HEX.get((v & 0xF) as usize).copied().unwrap_or(b'0');
        self.put(&[d]);
    }

    /// `v` in decimal, at least `width` digits (zero-padded).
    fn decimal(&mut self, mut v: u64, width: usize) {
        let mut digits = [0u8; 20];
        let mut n = 0;
        while (v > 0 || n < width) && n < digits.len() {
            if let Some(d) = digits.get_mut(n) {
                *d = b'0' + (v % 10) as u8;
            }
            v /= 10;
            n += 1;
        }
        for i in (0..n).rev() {
            let d = digits.get(i).copied().unwrap_or(b'0');
            self.put(&[d]);
        }
    }
}

/// Formats the exact wire text, e.g. `< frame 123 1700000000.000100 1A22 >`.
impl fmt::Display for Message {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Message::Hi => f.write_str("< hi >"),
            Message::Ok => f.write_str("< ok >"),
            Message::Echo => f.write_str("< echo >"),
            Message::Error(text) => {
                f.write_str("< error ")?;
                write_sanitized(f, text)?;
                f.write_str(" >")
            }
            Message::Open(channel) => {
                f.write_str("< open ")?;
                write_sanitized(f, channel)?;
                f.write_str(" >")
            }
            Message::BitTiming { channel, timing: t } => {
                f.write_str("< ")?;
                write_sanitized(f, channel)?;
                write!(
                    f,
                    " B {} {} {} {} {} {} {} {} >",
                    t.bitrate,
                    t.sample_point,
                    t.tq,
                    t.prop_seg,
                    t.phase_seg1,
                    t.phase_seg2,
                    t.sjw,
                    t.brp
                )
            }
            Message::ControlModes {
                channel,
                listen_only,
                loopback,
                three_samples,
            } => {
                f.write_str("< ")?;
                write_sanitized(f, channel)?;
                write!(
                    f,
                    " C {} {} {} >",
                    u8::from(*listen_only),
                    u8::from(*loopback),
                    u8::from(*three_samples)
                )
            }
            Message::Mode(mode) => write!(f, "< {} >", mode.keyword()),
            Message::Send(frame) => {
                f.write_str("< send ")?;
                write_id(f, frame)?;
                write!(f, " {}", frame.len.min(8))?;
                for b in frame.payload() {
                    write!(f, " {b:02X}")?;
                }
                f.write_str(" >")
            }
            Message::Frame { frame, timestamp } => {
                let mut buf = [0u8; FRAME_TEXT_MAX];
                let n = emit_frame(frame, *timestamp, &mut buf);
                // `emit_frame` writes ASCII only.
                f.write_str(std::str::from_utf8(buf.get(..n).unwrap_or(&[])).unwrap_or(""))
            }
            Message::Statistics { interval_ms } => write!(f, "< statistics {interval_ms} >"),
            Message::Stat {
                rbytes,
                rpackets,
                tbytes,
                tpackets,
            } => write!(f, "< stat {rbytes} {rpackets} {tbytes} {tpackets} >"),
            Message::Unsupported(command) => write!(f, "< {command} >"),
        }
    }
}

/// Splits a byte stream into messages. Feed it with [`push`](Decoder::push), then call
/// [`next_message`](Decoder::next_message) until it returns `None`.
///
/// Memory is bounded: bytes outside `< >` are dropped at once, and an unterminated message
/// longer than the limit is dropped with [`CodecError::TooLong`] (the rest of it, up to the
/// next `<`, is then dropped as garbage).
#[derive(Debug, Clone)]
pub struct Decoder {
    buf: Vec<u8>,
    /// Start of the unread part of `buf`.
    start: usize,
    max_len: usize,
    discarded: u64,
}

impl Default for Decoder {
    fn default() -> Self {
        Decoder::new()
    }
}

impl Decoder {
    pub fn new() -> Decoder {
        Decoder::with_max_len(MAX_MESSAGE_LEN)
    }

    /// A decoder accepting messages of at most `max_len` bytes, brackets included (at least 2).
    pub fn with_max_len(max_len: usize) -> Decoder {
        Decoder {
            buf: Vec::new(),
            start: 0,
            max_len: max_len.max(2),
            discarded: 0,
        }
    }

    /// Append received bytes.
    pub fn push(&mut self, data: &[u8]) {
        if self.start > 0 {
            self.buf.drain(..self.start.min(self.buf.len()));
            self.start = 0;
        }
        self.buf.extend_from_slice(data);
    }

    /// The next complete message, `Some(Err(_))` for a malformed one, `None` when more bytes
    /// are needed.
    pub fn next_message(&mut self) -> Option<Result<Message, CodecError>> {
        let pending = self.buf.get(self.start..).unwrap_or(&[]);
        let Some(open) = pending.iter().position(|&b| b == b'<') else {
            self.discarded += pending.len() as u64;
            self.clear();
            return None;
        };
        self.discarded += open as u64;
        let candidate = pending.get(open..).unwrap_or(&[]);
        match candidate.iter().position(|&b| b == b'>') {
            Some(close) => {
                let total = close + 1;
                let result = if total > self.max_len {
                    Err(CodecError::TooLong)
                } else {
                    parse_body(candidate.get(1..close).unwrap_or(&[]))
                };
                self.start += open + total;
                Some(result)
            }
            None if candidate.len() > self.max_len => {
                self.discarded += candidate.len() as u64;
                self.clear();
                Some(Err(CodecError::TooLong))
            }
            None => {
                self.start += open;
                None
            }
        }
    }

    /// Bytes dropped so far: garbage outside `< >` and over-long messages.
    pub fn discarded(&self) -> u64 {
        self.discarded
    }

    /// Bytes held waiting for the end of a message.
    pub fn pending(&self) -> usize {
        self.buf.len().saturating_sub(self.start)
    }

    fn clear(&mut self) {
        self.buf.clear();
        self.start = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<Message, CodecError> {
        let mut d = Decoder::new();
        d.push(s.as_bytes());
        let r = d.next_message().expect("a complete message");
        assert!(d.next_message().is_none());
        r
    }

    fn std_frame(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(id, data).expect("frame")
    }

    #[test]
    fn handshake_messages() {
        assert_eq!(parse("< hi >"), Ok(Message::Hi));
        assert_eq!(parse("< ok >"), Ok(Message::Ok));
        assert_eq!(parse("< echo >"), Ok(Message::Echo));
        assert_eq!(parse("< open vcan0 >"), Ok(Message::Open("vcan0".into())));
        assert_eq!(parse("<open can1>"), Ok(Message::Open("can1".into())));
        assert_eq!(parse("< rawmode >"), Ok(Message::Mode(Mode::Raw)));
        assert_eq!(parse("< bcmmode >"), Ok(Message::Mode(Mode::Bcm)));
        assert_eq!(parse("< isotpmode >"), Ok(Message::Mode(Mode::Isotp)));
        assert_eq!(parse("< controlmode >"), Ok(Message::Mode(Mode::Control)));
        assert_eq!(
            parse("< error could not open bus >"),
            Ok(Message::Error("could not open bus".into()))
        );
        assert_eq!(
            parse("< statistics 1000 >"),
            Ok(Message::Statistics { interval_ms: 1000 })
        );
        assert_eq!(
            parse("< stat 1 2 3 4 >"),
            Ok(Message::Stat {
                rbytes: 1,
                rpackets: 2,
                tbytes: 3,
                tpackets: 4
            })
        );
        assert_eq!(
            parse("< add 1 0 123 1 00 >"),
            Ok(Message::Unsupported("add"))
        );
        assert_eq!(
            parse("< subscribe 0 0 123 >"),
            Ok(Message::Unsupported("subscribe"))
        );
    }

    #[test]
    fn bus_configuration() {
        assert_eq!(
            parse("< vcan0 B 500000 875 0 0 0 0 1 0 >"),
            Ok(Message::BitTiming {
                channel: "vcan0".into(),
                timing: BitTiming {
                    bitrate: 500000,
                    sample_point: 875,
                    tq: 0,
                    prop_seg: 0,
                    phase_seg1: 0,
                    phase_seg2: 0,
                    sjw: 1,
                    brp: 0
                }
            })
        );
        assert_eq!(
            parse("< vcan0 C 0 1 0 >"),
            Ok(Message::ControlModes {
                channel: "vcan0".into(),
                listen_only: false,
                loopback: true,
                three_samples: false
            })
        );
        assert_eq!(parse("< vcan0 B 500000 >"), Err(CodecError::Arguments("B")));
        assert_eq!(parse("< vcan0 C 0 2 0 >"), Err(CodecError::BadNumber));
        assert_eq!(parse("< vcan0 X 1 >"), Err(CodecError::UnknownCommand));
    }

    #[test]
    fn send_standard_and_extended() {
        assert_eq!(
            parse("< send 605 8 40 18 10 1 0 0 0 0 >"),
            Ok(Message::Send(std_frame(
                0x605,
                &[0x40, 0x18, 0x10, 1, 0, 0, 0, 0]
            )))
        );
        // python-can style: lowercase, unpadded bytes.
        assert_eq!(
            parse("< send 7ff 2 a ff >"),
            Ok(Message::Send(std_frame(0x7FF, &[0x0A, 0xFF])))
        );
        let ext = CanFrame::with_id(0x1234_5678, true, &[1, 2, 3]).expect("frame");
        assert_eq!(parse("< send 12345678 3 1 2 3 >"), Ok(Message::Send(ext)));
        // 8 digits is extended even when the value would fit 11 bits.
        let ext_small = CanFrame::with_id(0x123, true, &[]).expect("frame");
        assert_eq!(parse("< send 00000123 0 >"), Ok(Message::Send(ext_small)));
        // Up to 3 digits: standard.
        assert_eq!(
            parse("< send 0 2 1 5 >"),
            Ok(Message::Send(std_frame(0, &[1, 5])))
        );
        // 4..7 digits: extended.
        let ext4 = CanFrame::with_id(0x1234, true, &[]).expect("frame");
        assert_eq!(parse("< send 1234 0 >"), Ok(Message::Send(ext4)));
    }

    #[test]
    fn send_zero_length_and_remote() {
        // python-canopen's node-guarding request as python-can writes it.
        assert_eq!(
            parse("< send 705 0  >"),
            Ok(Message::Send(std_frame(0x705, &[])))
        );
        let Ok(Message::Send(rtr)) = parse("< send 705 1 >") else {
            panic!("expected a send");
        };
        assert!(rtr.rtr);
        assert_eq!((rtr.id, rtr.len, rtr.extended), (0x705, 1, false));
    }

    #[test]
    fn send_errors() {
        assert_eq!(parse("< send 800 0 >"), Err(CodecError::IdOutOfRange));
        assert_eq!(parse("< send FFF 0 >"), Err(CodecError::IdOutOfRange));
        assert_eq!(parse("< send 20000000 0 >"), Err(CodecError::IdOutOfRange));
        assert_eq!(parse("< send 123456789 0 >"), Err(CodecError::BadId));
        assert_eq!(parse("< send 12g 0 >"), Err(CodecError::BadId));
        assert_eq!(parse("< send +12 0 >"), Err(CodecError::BadId));
        assert_eq!(
            parse("< send 123 9 1 2 3 4 5 6 7 8 9 >"),
            Err(CodecError::BadDlc)
        );
        assert_eq!(parse("< send 123 x >"), Err(CodecError::BadDlc));
        assert_eq!(parse("< send 123 -1 >"), Err(CodecError::BadDlc));
        assert_eq!(parse("< send 123 2 1 >"), Err(CodecError::DlcMismatch));
        assert_eq!(parse("< send 123 1 1 2 >"), Err(CodecError::DlcMismatch));
        assert_eq!(parse("< send 123 0 1 >"), Err(CodecError::DlcMismatch));
        assert_eq!(parse("< send 123 1 100 >"), Err(CodecError::BadDataByte));
        assert_eq!(parse("< send 123 1 zz >"), Err(CodecError::BadDataByte));
        assert_eq!(parse("< send 123 >"), Err(CodecError::Arguments("send")));
        assert_eq!(parse("< send >"), Err(CodecError::Arguments("send")));
        assert_eq!(
            parse("< send 123 8 1 2 3 4 5 6 7 8 9 >"),
            Err(CodecError::DlcMismatch)
        );
    }

    #[test]
    fn frame_formatting() {
        let ts = Duration::new(1_700_000_000, 123_456_789);
        let msg = Message::Frame {
            frame: std_frame(0x123, &[0x1A, 0x22, 0x03, 0x44]),
            timestamp: ts,
        };
        assert_eq!(msg.to_string(), "< frame 123 1700000000.123456 1A220344 >");
        let empty = Message::Frame {
            frame: std_frame(0x5, &[]),
            timestamp: Duration::from_secs(1_700_000_000),
        };
        assert_eq!(empty.to_string(), "< frame 005 1700000000.000000  >");
        let ext = Message::Frame {
            frame: CanFrame::with_id(0xABCDE, true, &[0xFF]).expect("frame"),
            timestamp: Duration::from_micros(1),
        };
        assert_eq!(ext.to_string(), "< frame 000ABCDE 0.000001 FF >");
        let remote = Message::Frame {
            frame: CanFrame::remote(0x701, 1),
            timestamp: Duration::ZERO,
        };
        assert_eq!(remote.to_string(), "< frame 701 0.000000  >");
    }

    #[test]
    fn frame_round_trip() {
        for (text, frame) in [
            (
                "< frame 123 1700000000.123456 1A220344 >",
                std_frame(0x123, &[0x1A, 0x22, 0x03, 0x44]),
            ),
            ("< frame 7FF 1.000000  >", std_frame(0x7FF, &[])),
            (
                "< frame 1FFFFFFF 2.500000 0001020304050607 >",
                CanFrame::with_id(0x1FFF_FFFF, true, &[0, 1, 2, 3, 4, 5, 6, 7]).expect("f"),
            ),
        ] {
            let parsed = parse(text).expect("parses");
            let Message::Frame { frame: got, .. } = &parsed else {
                panic!("not a frame: {parsed:?}");
            };
            assert_eq!(*got, frame);
            assert_eq!(parsed.to_string(), text);
        }
        assert_eq!(
            parse("< frame 123 1.0 ABC >"),
            Err(CodecError::BadFrameData)
        );
        assert_eq!(parse("< frame 123 x.1 AB >"), Err(CodecError::BadTimestamp));
        assert_eq!(
            parse("< frame 123 1.-1 AB >"),
            Err(CodecError::BadTimestamp)
        );
    }

    #[test]
    fn other_formatting() {
        assert_eq!(Message::Hi.to_string(), "< hi >");
        assert_eq!(Message::Ok.to_string(), "< ok >");
        assert_eq!(Message::Mode(Mode::Raw).to_string(), "< rawmode >");
        assert_eq!(
            Message::Error("bad <x> \n".into()).to_string(),
            "< error bad ?x? ? >"
        );
        assert_eq!(
            Message::Send(std_frame(0x605, &[0x40, 0x18])).to_string(),
            "< send 605 2 40 18 >"
        );
        assert_eq!(
            Message::Send(std_frame(0x705, &[])).to_string(),
            "< send 705 0 >"
        );
        assert_eq!(
            Message::Stat {
                rbytes: 1,
                rpackets: 2,
                tbytes: 3,
                tpackets: 4
            }
            .to_string(),
            "< stat 1 2 3 4 >"
        );
        // Every formatted message parses back to itself.
        for m in [
            Message::Hi,
            Message::Ok,
            Message::Echo,
            Message::Open("vcan0".into()),
            Message::Mode(Mode::Control),
            Message::Send(std_frame(0x605, &[0x40, 0x18])),
            Message::Statistics { interval_ms: 5 },
            Message::ControlModes {
                channel: "can0".into(),
                listen_only: true,
                loopback: false,
                three_samples: true,
            },
        ] {
            assert_eq!(parse(&m.to_string()), Ok(m));
        }
    }

    #[test]
    fn bad_messages() {
        assert_eq!(parse("< >"), Err(CodecError::Empty));
        assert_eq!(parse("<>"), Err(CodecError::Empty));
        assert_eq!(parse("< bogus >"), Err(CodecError::UnknownCommand));
        assert_eq!(parse("< hi there >"), Err(CodecError::Arguments("hi")));
        assert_eq!(parse("< open >"), Err(CodecError::Arguments("open")));
        assert_eq!(parse("< open a b >"), Err(CodecError::Arguments("open")));
        assert_eq!(
            parse("< open abcdefghijklmnopq >"),
            Err(CodecError::ChannelTooLong)
        );
        assert_eq!(parse("< open vcan\u{e9} >"), Err(CodecError::NotAscii));
        assert_eq!(parse("< open \x01 >"), Err(CodecError::NotAscii));
        assert_eq!(parse("< statistics -5 >"), Err(CodecError::BadNumber));
        // socketcand takes the first '<' and the first '>': a stray '<' ends up inside.
        assert_eq!(parse("< send 123 <1 >"), Err(CodecError::BadDlc));
    }

    #[test]
    fn framing_concatenated_split_and_garbage() {
        let mut d = Decoder::new();
        d.push(b"junk< hi >< ok >\r\n< open vc");
        assert_eq!(d.next_message(), Some(Ok(Message::Hi)));
        assert_eq!(d.next_message(), Some(Ok(Message::Ok)));
        assert_eq!(d.next_message(), None);
        assert_eq!(d.pending(), "< open vc".len());
        d.push(b"an0 >");
        assert_eq!(d.next_message(), Some(Ok(Message::Open("vcan0".into()))));
        assert_eq!(d.next_message(), None);
        assert_eq!(d.discarded(), 4 + 2);
        // Garbage with no '<' at all is dropped whole.
        d.push(b"\xff\x00 > > garbage");
        assert_eq!(d.next_message(), None);
        assert_eq!(d.pending(), 0);
        // Byte-by-byte delivery.
        for b in b"< send 123 1 ff >" {
            d.push(&[*b]);
            if *b != b'>' {
                assert_eq!(d.next_message(), None);
            }
        }
        assert_eq!(
            d.next_message(),
            Some(Ok(Message::Send(std_frame(0x123, &[0xFF]))))
        );
    }

    #[test]
    fn framing_too_long() {
        let mut d = Decoder::with_max_len(32);
        let mut long = b"< send ".to_vec();
        long.extend_from_slice(&[b'1'; 100]);
        d.push(&long);
        assert_eq!(d.next_message(), Some(Err(CodecError::TooLong)));
        assert_eq!(d.pending(), 0);
        // The tail of the long message is garbage; the next message decodes.
        d.push(b"1111 2 3 >< echo >");
        assert_eq!(d.next_message(), Some(Ok(Message::Echo)));
        // A complete but too long message.
        let mut complete = b"<".to_vec();
        complete.extend_from_slice(&[b' '; 40]);
        complete.extend(b"echo >< ok >");
        d.push(&complete);
        assert_eq!(d.next_message(), Some(Err(CodecError::TooLong)));
        assert_eq!(d.next_message(), Some(Ok(Message::Ok)));
        // Exactly at the limit is fine.
        let mut exact = b"< echo".to_vec();
        exact.extend_from_slice(&[b' '; 32 - 7]);
        exact.push(b'>');
        assert_eq!(exact.len(), 32);
        d.push(&exact);
        assert_eq!(d.next_message(), Some(Ok(Message::Echo)));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig {
            cases: 1024,
            ..proptest::prelude::ProptestConfig::default()
        })]

        /// Any bytes, mostly protocol characters, pushed in any pieces: no panic, the
        /// decoder's buffer stays bounded, and anything it accepts formats to something that
        /// parses again.
        #[test]
        fn never_panics_on_arbitrary_bytes(
            pieces in proptest::collection::vec(
                proptest::collection::vec(
                    proptest::prop_oneof![
                        3 => proptest::sample::select(
                            b"<> sendframe0123456789abcdefABCDEFxo.-+\x00\xff\n".to_vec()
                        ),
                        1 => proptest::prelude::any::<u8>(),
                    ],
                    0..40,
                ),
                1..40,
            )
        ) {
            let mut d = Decoder::with_max_len(64);
            for piece in &pieces {
                d.push(piece);
                while let Some(r) = d.next_message() {
                    if let Ok(m) = r {
                        let text = m.to_string();
                        let mut d2 = Decoder::new();
                        d2.push(text.as_bytes());
                        proptest::prop_assert!(matches!(d2.next_message(), Some(Ok(_))), "{}", text);
                    }
                }
                proptest::prop_assert!(d.pending() <= 64 + 1);
            }
        }
    }

    /// The same text the formatting machinery gives, for standard and extended IDs, empty and
    /// full payloads, and seconds of any width.
    #[test]
    fn emit_frame_matches_the_reference_text() {
        let reference = |f: &CanFrame, t: Duration| {
            let id = if f.extended {
                format!("{:08X}", f.id)
            } else {
                format!("{:03X}", f.id)
            };
            let hex: String = f.payload().iter().map(|b| format!("{b:02X}")).collect();
            format!(
                "< frame {id} {}.{:06} {hex} >",
                t.as_secs(),
                t.subsec_micros()
            )
        };
        let frames = [
            CanFrame::new(0x581, &[0x43, 0, 0x10, 0, 0x92, 1, 2, 0]).expect("f"),
            CanFrame::new(0x7, &[]).expect("f"),
            CanFrame::with_id(0x1ABC_DEF0, true, &[0xFF]).expect("f"),
        ];
        for f in &frames {
            for t in [
                Duration::ZERO,
                Duration::from_micros(1_700_000_000_000_100),
                Duration::new(u64::MAX / 2, 999_999_000),
            ] {
                let mut buf = [0u8; FRAME_TEXT_MAX];
                let n = emit_frame(f, t, &mut buf);
                assert_eq!(
                    std::str::from_utf8(&buf[..n]).expect("ascii"),
                    reference(f, t)
                );
            }
        }
    }
}
