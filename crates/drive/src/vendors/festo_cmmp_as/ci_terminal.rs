//! SDO simulation over the CMMP-AS CI terminal (the RS232 debug console of the
//! parameterisation software; CMMP-AS manual §3.2.3). ASCII lines, typed without spaces:
//!
//! * `?XXXXSU` reads index `XXXX`, sub-index `SU`; the answer is `=XXXXSU:` followed by the
//!   value in 2, 4 or 8 hex digits for an 8-, 16- or 32-bit object.
//! * `=XXXXSU:WW`, `=XXXXSU:WWWW`, `=XXXXSU:WWWWWWWW` write 8, 16 or 32 bits; the answer echoes
//!   the command.
//! * Any failure answers `!` and the 32-bit SDO abort code F3F2F1F0, e.g. `!06010002`.
//!
//! Sans-IO: [`LineCutter`] cuts a byte stream into lines, [`execute`] answers one line from an
//! [`ObjectAccess`]. The manual says the syntax is for tests only and may change; the twin
//! accepts lower-case hex digits and answers in upper case.
//!
//! **Decision:** §3.2.3 prints no line ends. A request ends at CR, LF or CR LF (the empty line
//! between CR and LF gets no answer); an answer ends with CR alone ([`ANSWER_END`]), as the
//! device sends it: programs written for the CMMP-AS send `?606100` CR and read the answer up
//! to CR, and an LF after it would start their next answer.

use core::fmt::Write as _;

use heapless::String;
use od::{AbortCode, ObjectAccess};

/// Longest command: `=XXXXSU:WWWWWWWW`.
pub const MAX_LINE: usize = 16;

/// An answer line without its terminator: `=XXXXSU:WWWWWWWW` at most.
pub type Reply = String<MAX_LINE>;

/// What ends every answer on the wire: CR alone (see the module's decision).
pub const ANSWER_END: u8 = b'\r';

/// One parsed command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    Read {
        index: u16,
        sub: u8,
    },
    /// `data[..len]` little-endian, as an SDO download carries it.
    Write {
        index: u16,
        sub: u8,
        data: [u8; 4],
        len: usize,
    },
}

impl Command {
    pub fn index(&self) -> (u16, u8) {
        match *self {
            Command::Read { index, sub } | Command::Write { index, sub, .. } => (index, sub),
        }
    }
}

fn hex_digit(c: u8) -> Option<u32> {
    (c as char).to_digit(16)
}

fn hex(s: &[u8]) -> Option<u32> {
    s.iter()
        .try_fold(0u32, |acc, &c| Some(acc << 4 | hex_digit(c)?))
}

/// Parses one line (without its terminator). A line that is not one of the manual's forms is
/// answered like an unknown SDO command specifier, 0504 0001h: the manual prints no error
/// for bad syntax (decided here).
pub fn parse(line: &[u8]) -> Result<Command, AbortCode> {
    let bad = AbortCode::COMMAND_SPECIFIER;
    let (op, rest) = line.split_first().ok_or(bad)?;
    let address = rest.get(..6).ok_or(bad)?;
    if !address.iter().all(|&c| hex_digit(c).is_some()) {
        return Err(bad);
    }
    let a = hex(address).ok_or(bad)?;
    let (index, sub) = ((a >> 8) as u16, a as u8);
    match (op, rest.get(6..)) {
        (b'?', Some([])) => Ok(Command::Read { index, sub }),
        (b'=', Some([b':', digits @ ..])) if matches!(digits.len(), 2 | 4 | 8) => {
            let value = hex(digits).ok_or(bad)?;
            let len = digits.len() / 2;
            Ok(Command::Write {
                index,
                sub,
                data: value.to_le_bytes(),
                len,
            })
        }
        _ => Err(bad),
    }
}

fn value_reply(index: u16, sub: u8, data: &[u8]) -> Reply {
    let mut r = Reply::new();
    // Cannot overflow: 8 characters of address and at most 8 hex digits.
    let _ = write!(r, "={index:04X}{sub:02X}:");
    for b in data.iter().rev() {
        let _ = write!(r, "{b:02X}");
    }
    r
}

fn error_reply(code: AbortCode) -> Reply {
    let mut r = Reply::new();
    let _ = write!(r, "!{:08X}", code.0);
    r
}

/// Carries out one command on `od`.
pub fn run(cmd: Command, od: &mut dyn ObjectAccess) -> Result<Reply, AbortCode> {
    match cmd {
        Command::Read { index, sub } => {
            let e = od.entry(index, sub)?;
            // Only the three sizes the syntax has; a string or a 64-bit value has no CI form
            // (decided: "unsupported access").
            if !matches!(e.data_type.fixed_size(), Some(1 | 2 | 4)) {
                return Err(AbortCode::UNSUPPORTED_ACCESS);
            }
            let mut buf = [0u8; 4];
            let n = od.read(index, sub, &mut buf)?;
            Ok(value_reply(index, sub, buf.get(..n).unwrap_or(&[])))
        }
        Command::Write {
            index,
            sub,
            data,
            len,
        } => {
            let bytes = data.get(..len).unwrap_or(&[]);
            od.write(index, sub, bytes)?;
            Ok(value_reply(index, sub, bytes))
        }
    }
}

/// Parses and runs one line: the answer, a value or `!` and the abort code.
pub fn execute(line: &[u8], od: &mut dyn ObjectAccess) -> Reply {
    match parse(line).and_then(|cmd| run(cmd, od)) {
        Ok(r) => r,
        Err(code) => error_reply(code),
    }
}

/// The answer to a line that is none of the manual's forms (see [`parse`]).
pub fn syntax_error() -> Reply {
    error_reply(AbortCode::COMMAND_SPECIFIER)
}

/// A line as [`LineCutter`] hands it out.
pub type LineBuf = heapless::Vec<u8, MAX_LINE>;

/// What a line end completed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Cut {
    Line(LineBuf),
    /// The line was longer than any command; its bytes are gone.
    TooLong,
}

/// Cuts a byte stream into lines at CR or LF; empty lines are skipped, so CR LF ends one line. A line longer than any
/// command is dropped whole and reported at its end as [`Cut::TooLong`].
#[derive(Debug, Default)]
pub struct LineCutter {
    line: LineBuf,
    overflow: bool,
}

impl LineCutter {
    pub fn push(&mut self, byte: u8) -> Option<Cut> {
        if byte != b'\r' && byte != b'\n' {
            if self.line.push(byte).is_err() {
                self.overflow = true;
            }
            return None;
        }
        let line = core::mem::take(&mut self.line);
        if core::mem::take(&mut self.overflow) {
            Some(Cut::TooLong)
        } else if line.is_empty() {
            None
        } else {
            Some(Cut::Line(line))
        }
    }
}

/// The console on one dictionary: bytes in, one answer per line.
#[derive(Debug, Default)]
pub struct CiTerminal {
    lines: LineCutter,
}

impl CiTerminal {
    pub fn on_byte(&mut self, byte: u8, od: &mut dyn ObjectAccess) -> Option<Reply> {
        match self.lines.push(byte)? {
            Cut::Line(line) => Some(execute(&line, od)),
            Cut::TooLong => Some(syntax_error()),
        }
    }
}
