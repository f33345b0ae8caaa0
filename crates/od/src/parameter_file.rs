//! The text form of a stored parameter set: one `IIII:SS=HEX` line per entry, little-endian
//! bytes in hex, `#` comments. Readable by people, diffable, and parsed without allocation.

use core::fmt::{self, Write};

use crate::Entry;

/// Writes one entry's line.
pub fn write_line(w: &mut impl Write, e: &Entry, bytes: &[u8]) -> fmt::Result {
    write!(w, "{:04X}:{:02X}=", e.index, e.sub)?;
    for b in bytes {
        write!(w, "{b:02X}")?;
    }
    w.write_char('\n')
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParseError {
    /// No `=` or no `:` between index and sub-index.
    Syntax,
    /// Index, sub-index or data not hexadecimal, or an odd number of hex digits.
    Hex,
    /// More data than the caller's buffer holds.
    TooLong,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ParseError::Syntax => "expected IIII:SS=HEX",
            ParseError::Hex => "not hexadecimal",
            ParseError::TooLong => "value longer than the entry",
        })
    }
}

/// Parses one line into `buf`. Blank lines and comments give `Ok(None)`.
pub fn parse_line(line: &str, buf: &mut [u8]) -> Result<Option<(u16, u8, usize)>, ParseError> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return Ok(None);
    }
    let (key, hex) = line.split_once('=').ok_or(ParseError::Syntax)?;
    let (idx, sub) = key.trim().split_once(':').ok_or(ParseError::Syntax)?;
    let index = u16::from_str_radix(idx, 16).map_err(|_| ParseError::Hex)?;
    let sub = u8::from_str_radix(sub, 16).map_err(|_| ParseError::Hex)?;
    let hex = hex.trim().as_bytes();
    if !hex.len().is_multiple_of(2) {
        return Err(ParseError::Hex);
    }
    let n = hex.len() / 2;
    let out = buf.get_mut(..n).ok_or(ParseError::TooLong)?;
    for (o, pair) in out.iter_mut().zip(hex.chunks_exact(2)) {
        let s = core::str::from_utf8(pair).map_err(|_| ParseError::Hex)?;
        *o = u8::from_str_radix(s, 16).map_err(|_| ParseError::Hex)?;
    }
    Ok(Some((index, sub, n)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_parse_and_bad_lines_are_refused() {
        let mut buf = [0u8; 4];
        assert_eq!(
            parse_line("1017:00=E803", &mut buf),
            Ok(Some((0x1017, 0, 2)))
        );
        assert_eq!(&buf[..2], &[0xE8, 0x03]);
        assert_eq!(parse_line("  # comment", &mut buf), Ok(None));
        assert_eq!(parse_line("1017:00=E80", &mut buf), Err(ParseError::Hex));
        assert_eq!(parse_line("1017=E8", &mut buf), Err(ParseError::Syntax));
        assert_eq!(
            parse_line("1017:00=0102030405", &mut buf),
            Err(ParseError::TooLong)
        );
        assert_eq!(parse_line("10G7:00=00", &mut buf), Err(ParseError::Hex));
    }
}
