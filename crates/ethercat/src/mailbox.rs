//! The 6-byte mailbox header and mailbox error replies (spec §5.1, §5.3,
//! §5.5). The ESC's mailbox sync managers are in [`crate::esc`]; CoE comes in a later part.
//!
//! ```text
//! 0–1 length (bytes after the header) | 2–3 address | 4 channel (0–5), priority (6–7)
//! 5 type (0–3), counter (4–6), reserved (7)
//! ```

use crate::frame::WireError;

/// Mailbox header length.
pub const HEADER_LEN: usize = 6;

/// Mailbox protocol (header byte 5 bits 0–3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MailboxType {
    /// 0: mailbox error reply.
    Error,
    Aoe,
    Eoe,
    Coe,
    Foe,
    Soe,
    Voe,
    /// 6–14: reserved.
    Reserved(u8),
}

impl MailboxType {
    pub const fn from_u8(v: u8) -> Self {
        match v & 0x0F {
            0 => MailboxType::Error,
            1 => MailboxType::Aoe,
            2 => MailboxType::Eoe,
            3 => MailboxType::Coe,
            4 => MailboxType::Foe,
            5 => MailboxType::Soe,
            15 => MailboxType::Voe,
            other => MailboxType::Reserved(other),
        }
    }

    pub const fn to_u8(self) -> u8 {
        match self {
            MailboxType::Error => 0,
            MailboxType::Aoe => 1,
            MailboxType::Eoe => 2,
            MailboxType::Coe => 3,
            MailboxType::Foe => 4,
            MailboxType::Soe => 5,
            MailboxType::Voe => 15,
            MailboxType::Reserved(v) => v & 0x0F,
        }
    }
}

/// Mailbox error detail codes (spec §5.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum MailboxErrorDetail {
    Syntax = 0x0001,
    UnsupportedProtocol = 0x0002,
    InvalidChannel = 0x0003,
    ServiceNotSupported = 0x0004,
    InvalidHeader = 0x0005,
    SizeTooShort = 0x0006,
    NoMoreMemory = 0x0007,
    InvalidSize = 0x0008,
}

/// Next mailbox counter: 1 → 2 → … → 7 → 1 (0 means "not used" and is never produced).
pub const fn next_counter(c: u8) -> u8 {
    if c >= 7 {
        1
    } else {
        c + 1
    }
}

/// A view of a mailbox message (header + data).
#[derive(Debug, Clone)]
pub struct Mailbox<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Mailbox<T> {
    pub const fn new_unchecked(buffer: T) -> Self {
        Mailbox { buffer }
    }

    /// A view whose header is complete and whose length field fits the buffer.
    pub fn new_checked(buffer: T) -> Result<Self, WireError> {
        let m = Mailbox { buffer };
        if m.buffer.as_ref().len() < HEADER_LEN + m.length() {
            return Err(WireError::Truncated);
        }
        Ok(m)
    }

    fn byte(&self, i: usize) -> u8 {
        self.buffer.as_ref().get(i).copied().unwrap_or(0)
    }

    /// Bytes after the header.
    pub fn length(&self) -> usize {
        usize::from(u16::from_le_bytes([self.byte(0), self.byte(1)]))
    }

    pub fn address(&self) -> u16 {
        u16::from_le_bytes([self.byte(2), self.byte(3)])
    }

    pub fn channel(&self) -> u8 {
        self.byte(4) & 0x3F
    }

    pub fn priority(&self) -> u8 {
        self.byte(4) >> 6
    }

    pub fn mailbox_type(&self) -> MailboxType {
        MailboxType::from_u8(self.byte(5))
    }

    pub fn counter(&self) -> u8 {
        (self.byte(5) >> 4) & 0x07
    }

    /// The `length()` bytes after the header (cut at the end of the buffer).
    pub fn payload(&self) -> &[u8] {
        let b = self.buffer.as_ref();
        let end = (HEADER_LEN + self.length()).min(b.len());
        b.get(HEADER_LEN..end).unwrap_or(&[])
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Mailbox<T> {
    /// Write the header fields.
    pub fn set_header(&mut self, length: u16, address: u16, kind: MailboxType, counter: u8) {
        if let Some(h) = self.buffer.as_mut().first_chunk_mut::<HEADER_LEN>() {
            let [l0, l1] = length.to_le_bytes();
            let [a0, a1] = address.to_le_bytes();
            *h = [l0, l1, a0, a1, 0, kind.to_u8() | ((counter & 0x07) << 4)];
        }
    }

    pub fn payload_mut(&mut self) -> &mut [u8] {
        let end = (HEADER_LEN + self.length()).min(self.buffer.as_ref().len());
        self.buffer
            .as_mut()
            .get_mut(HEADER_LEN..end)
            .unwrap_or(&mut [])
    }
}

/// Write a mailbox error reply (type 0, length 4, service 0x0001, `detail`) into `buf`;
/// returns its length (10), or `None` if `buf` is shorter.
pub fn write_error_reply(buf: &mut [u8], detail: MailboxErrorDetail, counter: u8) -> Option<usize> {
    let out = buf.get_mut(0..HEADER_LEN + 4)?;
    let mut m = Mailbox::new_unchecked(&mut *out);
    m.set_header(4, 0, MailboxType::Error, counter);
    let p = m.payload_mut();
    p.get_mut(0..2)?.copy_from_slice(&0x0001u16.to_le_bytes());
    p.get_mut(2..4)?
        .copy_from_slice(&(detail as u16).to_le_bytes());
    Some(HEADER_LEN + 4)
}
