//! Zero-copy view of one EtherCAT datagram (DLPDU) and the command codes
//! (spec §1.3, §1.4; ETG.1000.4).
//!
//! ```text
//! 0      1      2          4          6                  8      10       10+n
//! | cmd  | idx  | ADP/log  | ADO/log  | len|res|C|M       | IRQ  | data…  | WKC |
//! ```
//! All fields little-endian; len is bits 0–10, C (circulating) bit 14, M (more) bit 15.
//! Getters never panic: a short buffer reads as zeros / an empty slice.

use crate::frame::WireError;

/// Datagram header length.
pub const HEADER_LEN: usize = 10;
/// Working counter length.
pub const WKC_LEN: usize = 2;
/// Largest data length the 11-bit field can express.
pub const MAX_DATA_LEN: usize = 0x07FF;

const LEN_MASK: u16 = 0x07FF;
const CIRCULATING: u16 = 1 << 14;
const MORE: u16 = 1 << 15;

mod field {
    pub const CMD: usize = 0;
    pub const IDX: usize = 1;
    pub const ADP: usize = 2;
    pub const ADO: usize = 4;
    pub const LEN: usize = 6;
    pub const IRQ: usize = 8;
}

/// Datagram command (ETG.1000.4 table; spec §1.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Command {
    Nop,
    Aprd,
    Apwr,
    Aprw,
    Fprd,
    Fpwr,
    Fprw,
    Brd,
    Bwr,
    Brw,
    Lrd,
    Lwr,
    Lrw,
    Armw,
    Frmw,
    /// 0x0F and up: reserved; an ESC leaves such a datagram untouched.
    Unknown(u8),
}

/// How a command selects the slaves that act on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Addressing {
    None,
    /// ADP = −position; the slave that sees 0 acts; every slave increments ADP.
    AutoIncrement,
    /// ADP = configured station address (0x0010) or alias (0x0012).
    Configured,
    /// Every slave; every slave increments ADP.
    Broadcast,
    /// 32-bit logical address through the FMMUs.
    Logical,
}

impl Command {
    pub const fn from_u8(v: u8) -> Self {
        match v {
            0x00 => Command::Nop,
            0x01 => Command::Aprd,
            0x02 => Command::Apwr,
            0x03 => Command::Aprw,
            0x04 => Command::Fprd,
            0x05 => Command::Fpwr,
            0x06 => Command::Fprw,
            0x07 => Command::Brd,
            0x08 => Command::Bwr,
            0x09 => Command::Brw,
            0x0A => Command::Lrd,
            0x0B => Command::Lwr,
            0x0C => Command::Lrw,
            0x0D => Command::Armw,
            0x0E => Command::Frmw,
            other => Command::Unknown(other),
        }
    }

    pub const fn to_u8(self) -> u8 {
        match self {
            Command::Nop => 0x00,
            Command::Aprd => 0x01,
            Command::Apwr => 0x02,
            Command::Aprw => 0x03,
            Command::Fprd => 0x04,
            Command::Fpwr => 0x05,
            Command::Fprw => 0x06,
            Command::Brd => 0x07,
            Command::Bwr => 0x08,
            Command::Brw => 0x09,
            Command::Lrd => 0x0A,
            Command::Lwr => 0x0B,
            Command::Lrw => 0x0C,
            Command::Armw => 0x0D,
            Command::Frmw => 0x0E,
            Command::Unknown(v) => v,
        }
    }

    pub const fn addressing(self) -> Addressing {
        match self {
            Command::Aprd | Command::Apwr | Command::Aprw | Command::Armw => {
                Addressing::AutoIncrement
            }
            Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw => Addressing::Configured,
            Command::Brd | Command::Bwr | Command::Brw => Addressing::Broadcast,
            Command::Lrd | Command::Lwr | Command::Lrw => Addressing::Logical,
            Command::Nop | Command::Unknown(_) => Addressing::None,
        }
    }
}

impl From<u8> for Command {
    fn from(v: u8) -> Self {
        Command::from_u8(v)
    }
}

impl From<Command> for u8 {
    fn from(c: Command) -> u8 {
        c.to_u8()
    }
}

fn u16_le(b: &[u8], at: usize) -> u16 {
    match b.get(at..at + 2) {
        Some(&[lo, hi]) => u16::from_le_bytes([lo, hi]),
        _ => 0,
    }
}

fn put_u16_le(b: &mut [u8], at: usize, v: u16) {
    if let Some(s) = b.get_mut(at..at + 2) {
        s.copy_from_slice(&v.to_le_bytes());
    }
}

/// Total length (header + data + WKC) of the datagram starting at `buf`, from its length
/// field; `None` if even the header is incomplete.
pub fn total_len(buf: &[u8]) -> Option<usize> {
    if buf.len() < HEADER_LEN {
        return None;
    }
    Some(HEADER_LEN + usize::from(u16_le(buf, field::LEN) & LEN_MASK) + WKC_LEN)
}

/// A view of one datagram. The buffer may be longer than the datagram (the rest of the
/// frame); [`Datagram::total_len`] tells where it ends.
#[derive(Debug, Clone)]
pub struct Datagram<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Datagram<T> {
    pub const fn new_unchecked(buffer: T) -> Self {
        Datagram { buffer }
    }

    /// A view whose header, data and working counter all lie inside the buffer.
    pub fn new_checked(buffer: T) -> Result<Self, WireError> {
        let d = Datagram { buffer };
        d.check_len()?;
        Ok(d)
    }

    pub fn check_len(&self) -> Result<(), WireError> {
        match total_len(self.buffer.as_ref()) {
            Some(t) if t <= self.buffer.as_ref().len() => Ok(()),
            _ => Err(WireError::Truncated),
        }
    }

    pub fn into_inner(self) -> T {
        self.buffer
    }

    pub fn command(&self) -> Command {
        Command::from_u8(self.command_raw())
    }

    pub fn command_raw(&self) -> u8 {
        self.buffer.as_ref().get(field::CMD).copied().unwrap_or(0)
    }

    pub fn index(&self) -> u8 {
        self.buffer.as_ref().get(field::IDX).copied().unwrap_or(0)
    }

    /// Position / station address (bytes 2–3).
    pub fn adp(&self) -> u16 {
        u16_le(self.buffer.as_ref(), field::ADP)
    }

    /// Register / memory offset (bytes 4–5).
    pub fn ado(&self) -> u16 {
        u16_le(self.buffer.as_ref(), field::ADO)
    }

    /// Bytes 2–5 as one logical address.
    pub fn logical_address(&self) -> u32 {
        u32::from(self.adp()) | (u32::from(self.ado()) << 16)
    }

    pub fn data_len(&self) -> usize {
        usize::from(u16_le(self.buffer.as_ref(), field::LEN) & LEN_MASK)
    }

    /// Circulating-frame bit (14).
    pub fn circulating(&self) -> bool {
        u16_le(self.buffer.as_ref(), field::LEN) & CIRCULATING != 0
    }

    /// "More datagrams follow" bit (15).
    pub fn more_follows(&self) -> bool {
        u16_le(self.buffer.as_ref(), field::LEN) & MORE != 0
    }

    pub fn irq(&self) -> u16 {
        u16_le(self.buffer.as_ref(), field::IRQ)
    }

    pub fn data(&self) -> &[u8] {
        let len = self.data_len();
        self.buffer
            .as_ref()
            .get(HEADER_LEN..HEADER_LEN + len)
            .unwrap_or(&[])
    }

    pub fn wkc(&self) -> u16 {
        u16_le(self.buffer.as_ref(), HEADER_LEN + self.data_len())
    }

    /// Header + data + WKC.
    pub fn total_len(&self) -> usize {
        HEADER_LEN + self.data_len() + WKC_LEN
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Datagram<T> {
    pub fn set_command(&mut self, c: Command) {
        if let Some(b) = self.buffer.as_mut().get_mut(field::CMD) {
            *b = c.to_u8();
        }
    }

    pub fn set_index(&mut self, idx: u8) {
        if let Some(b) = self.buffer.as_mut().get_mut(field::IDX) {
            *b = idx;
        }
    }

    pub fn set_adp(&mut self, v: u16) {
        put_u16_le(self.buffer.as_mut(), field::ADP, v);
    }

    pub fn set_ado(&mut self, v: u16) {
        put_u16_le(self.buffer.as_mut(), field::ADO, v);
    }

    /// Bytes 2–5 (ADP | ADO << 16, or the logical address).
    pub fn set_address(&mut self, v: u32) {
        self.set_adp(v as u16);
        self.set_ado((v >> 16) as u16);
    }

    pub fn set_len_flags(&mut self, len: usize, circulating: bool, more: bool) {
        let mut w = (len.min(MAX_DATA_LEN) as u16) & LEN_MASK;
        if circulating {
            w |= CIRCULATING;
        }
        if more {
            w |= MORE;
        }
        put_u16_le(self.buffer.as_mut(), field::LEN, w);
    }

    pub fn set_more_follows(&mut self, more: bool) {
        let w = u16_le(self.buffer.as_ref(), field::LEN);
        let w = if more { w | MORE } else { w & !MORE };
        put_u16_le(self.buffer.as_mut(), field::LEN, w);
    }

    pub fn set_irq(&mut self, v: u16) {
        put_u16_le(self.buffer.as_mut(), field::IRQ, v);
    }

    pub fn data_mut(&mut self) -> &mut [u8] {
        let len = self.data_len();
        self.buffer
            .as_mut()
            .get_mut(HEADER_LEN..HEADER_LEN + len)
            .unwrap_or(&mut [])
    }

    pub fn set_wkc(&mut self, v: u16) {
        let at = HEADER_LEN + self.data_len();
        put_u16_le(self.buffer.as_mut(), at, v);
    }
}
