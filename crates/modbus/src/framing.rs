//! Splitting a Modbus TCP byte stream into ADUs.
//!
//! TCP delivers bytes, not ADUs: one read may hold half an ADU or several. The MBAP length
//! field (bytes 5–6) says how long each ADU is. It counts unit id + PDU, so it is 2…254 for
//! any ADU; any other value means the stream is not (or no longer) Modbus TCP, and the
//! receiver cannot find the next ADU. [`Framer`] reports that as [`FrameError`], and a
//! server drops the connection.
//!
//! [`adu_len`] is the rule alone, for a caller with its own buffer; [`Framer`] adds a fixed
//! buffer of two maximal ADUs, so nothing is allocated and a client cannot make it grow.

use core::fmt;

use crate::mbap::{LENGTH_FIELD_END, MAX_ADU_LEN, MAX_LENGTH_FIELD, MIN_LENGTH_FIELD};

/// The stream is not Modbus TCP.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FrameError {
    /// A length field outside 2…254.
    InvalidLength(u16),
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameError::InvalidLength(n) => write!(
                f,
                "MBAP length {n} outside {MIN_LENGTH_FIELD}…{MAX_LENGTH_FIELD}"
            ),
        }
    }
}

/// The length of the ADU at the start of `buf`: `Ok(None)` while its header or body is
/// incomplete, `Ok(Some(n))` once `buf` holds all `n` bytes.
pub fn adu_len(buf: &[u8]) -> Result<Option<usize>, FrameError> {
    let Some([hi, lo]) = buf.get(4..LENGTH_FIELD_END) else {
        return Ok(None);
    };
    let length = u16::from_be_bytes([*hi, *lo]);
    if !(MIN_LENGTH_FIELD..=MAX_LENGTH_FIELD).contains(&length) {
        return Err(FrameError::InvalidLength(length));
    }
    let n = LENGTH_FIELD_END + usize::from(length);
    Ok((buf.len() >= n).then_some(n))
}

/// Buffer size of a [`Framer`]: one complete ADU and most of the next.
pub const FRAMER_CAPACITY: usize = 2 * MAX_ADU_LEN;

/// A bounded reassembly buffer for one Modbus TCP connection.
///
/// ```
/// # use modbus::Framer;
/// let mut framer = Framer::new();
/// let mut input: &[u8] = &[0, 1, 0, 0, 0, 2, 0, 7, 0, 2, 0, 0, 0, 2, 0];
/// let mut adus = 0;
/// while !input.is_empty() {
///     let taken = framer.push(input);
///     input = &input[taken..];
///     while let Some(adu) = framer.next_adu().expect("valid stream") {
///         assert_eq!(adu.len(), 8);
///         adus += 1;
///     }
/// }
/// assert_eq!((adus, framer.buffered()), (1, 7));
/// ```
#[derive(Clone)]
pub struct Framer {
    buf: [u8; FRAMER_CAPACITY],
    start: usize,
    end: usize,
}

impl Default for Framer {
    fn default() -> Self {
        Framer::new()
    }
}

impl fmt::Debug for Framer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Framer")
            .field("buffered", &self.buffered())
            .finish()
    }
}

impl Framer {
    /// An empty framer.
    pub const fn new() -> Framer {
        Framer {
            buf: [0; FRAMER_CAPACITY],
            start: 0,
            end: 0,
        }
    }

    /// Appends as much of `data` as fits and returns how many bytes were taken. Take the
    /// complete ADUs out with [`next_adu`](Self::next_adu) and push the rest: once the
    /// complete ADUs are out, there is always room for more.
    pub fn push(&mut self, data: &[u8]) -> usize {
        if self.start > 0 {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        let free = self.buf.get_mut(self.end..).unwrap_or(&mut []);
        let n = free.len().min(data.len());
        if let (Some(dst), Some(src)) = (free.get_mut(..n), data.get(..n)) {
            dst.copy_from_slice(src);
            self.end += n;
            n
        } else {
            0
        }
    }

    /// The next complete ADU, removed from the buffer; `Ok(None)` until one is complete. An
    /// error stays until [`clear`](Self::clear).
    pub fn next_adu(&mut self) -> Result<Option<&[u8]>, FrameError> {
        let pending = self.buf.get(self.start..self.end).unwrap_or(&[]);
        match adu_len(pending)? {
            Some(n) => {
                let at = self.start;
                self.start += n;
                if self.start == self.end {
                    self.start = 0;
                    self.end = 0;
                }
                Ok(self.buf.get(at..at + n))
            }
            None => Ok(None),
        }
    }

    /// Bytes buffered that are not yet a complete ADU (or not yet taken).
    pub fn buffered(&self) -> usize {
        self.end - self.start
    }

    /// Forgets everything buffered.
    pub fn clear(&mut self) {
        self.start = 0;
        self.end = 0;
    }
}
