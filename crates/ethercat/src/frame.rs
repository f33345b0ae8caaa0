//! Zero-copy views of the Ethernet frame and the EtherCAT frame header, and a writer that
//! builds frames (for tests and the master side), in the manner of smoltcp's `wire` layer.
//!
//! Layout (spec §1.2): Ethernet header (destination, source, EtherType
//! 0x88A4 big-endian), then the 2-byte EtherCAT header (little-endian: bits 0–10 length of
//! all datagrams that follow, bit 11 reserved, bits 12–15 type; type 1 = EtherCAT commands),
//! then the datagrams ([`crate::datagram`]). Every getter is total: a buffer that is too short
//! reads as zero or an empty slice, never a panic; use `new_checked` to learn that it is short.

use crate::datagram::{self, Command, Datagram};

/// EtherType of EtherCAT frames (IEEE 802.3, 0x88A4).
pub const ETHERTYPE_ETHERCAT: u16 = 0x88A4;
/// Length of the Ethernet II header (no VLAN tag).
pub const ETHERNET_HEADER_LEN: usize = 14;
/// Length of the EtherCAT frame header.
pub const HEADER_LEN: usize = 2;
/// EtherCAT header type 1: EtherCAT commands (DLPDUs).
pub const TYPE_COMMANDS: u8 = 1;
/// Largest value of the 11-bit length field.
pub const MAX_LENGTH: usize = 0x07FF;
/// The bit a slave ORs into the first source-MAC byte of every frame it returns
/// ("locally administered"; spec §1.1: ethercrab ignores replies without it).
pub const SOURCE_MAC_RETURN_BIT: u8 = 0x02;

/// What is wrong with a frame or datagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireError {
    /// The buffer ends before the header, or before the data a length field announces.
    Truncated,
    /// The Ethernet frame does not carry EtherType 0x88A4.
    NotEtherCat,
    /// The EtherCAT header type is not 1 (commands).
    UnsupportedType(u8),
    /// A writer's buffer has no room for what was asked.
    BufferTooSmall,
    /// Datagram data longer than the 11-bit length field allows.
    DataTooLong,
}

fn u16_le(b: &[u8], at: usize) -> u16 {
    match b.get(at..at + 2) {
        Some(&[lo, hi]) => u16::from_le_bytes([lo, hi]),
        _ => 0,
    }
}

/// An Ethernet II frame.
#[derive(Debug, Clone)]
pub struct EthernetFrame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> EthernetFrame<T> {
    pub const fn new_unchecked(buffer: T) -> Self {
        EthernetFrame { buffer }
    }

    /// A view that has at least a whole Ethernet header.
    pub fn new_checked(buffer: T) -> Result<Self, WireError> {
        if buffer.as_ref().len() < ETHERNET_HEADER_LEN {
            return Err(WireError::Truncated);
        }
        Ok(EthernetFrame { buffer })
    }

    pub fn into_inner(self) -> T {
        self.buffer
    }

    pub fn destination(&self) -> [u8; 6] {
        let mut mac = [0; 6];
        if let Some(b) = self.buffer.as_ref().get(0..6) {
            mac.copy_from_slice(b);
        }
        mac
    }

    pub fn source(&self) -> [u8; 6] {
        let mut mac = [0; 6];
        if let Some(b) = self.buffer.as_ref().get(6..12) {
            mac.copy_from_slice(b);
        }
        mac
    }

    /// EtherType (big-endian on the wire).
    pub fn ethertype(&self) -> u16 {
        match self.buffer.as_ref().get(12..14) {
            Some(&[hi, lo]) => u16::from_be_bytes([hi, lo]),
            _ => 0,
        }
    }

    pub fn payload(&self) -> &[u8] {
        self.buffer
            .as_ref()
            .get(ETHERNET_HEADER_LEN..)
            .unwrap_or(&[])
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> EthernetFrame<T> {
    pub fn set_destination(&mut self, mac: [u8; 6]) {
        if let Some(b) = self.buffer.as_mut().get_mut(0..6) {
            b.copy_from_slice(&mac);
        }
    }

    pub fn set_source(&mut self, mac: [u8; 6]) {
        if let Some(b) = self.buffer.as_mut().get_mut(6..12) {
            b.copy_from_slice(&mac);
        }
    }

    pub fn set_ethertype(&mut self, ethertype: u16) {
        if let Some(b) = self.buffer.as_mut().get_mut(12..14) {
            b.copy_from_slice(&ethertype.to_be_bytes());
        }
    }

    /// OR the locally-administered bit into the first source-MAC byte, as an ESC does on
    /// the way back to the master (spec §1.1).
    pub fn mark_returned(&mut self) {
        if let Some(b) = self.buffer.as_mut().get_mut(6) {
            *b |= SOURCE_MAC_RETURN_BIT;
        }
    }

    pub fn payload_mut(&mut self) -> &mut [u8] {
        self.buffer
            .as_mut()
            .get_mut(ETHERNET_HEADER_LEN..)
            .unwrap_or(&mut [])
    }
}

/// An EtherCAT frame: the 2-byte header and the datagrams after it (padding may follow).
#[derive(Debug, Clone)]
pub struct Frame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Frame<T> {
    pub const fn new_unchecked(buffer: T) -> Self {
        Frame { buffer }
    }

    /// A view with a complete header, whose length field does not run past the buffer.
    pub fn new_checked(buffer: T) -> Result<Self, WireError> {
        let f = Frame { buffer };
        f.check_len()?;
        Ok(f)
    }

    pub fn check_len(&self) -> Result<(), WireError> {
        let len = self.buffer.as_ref().len();
        if len < HEADER_LEN || len < HEADER_LEN + self.length() {
            return Err(WireError::Truncated);
        }
        Ok(())
    }

    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// Length of all datagrams (header bits 0–10).
    pub fn length(&self) -> usize {
        usize::from(u16_le(self.buffer.as_ref(), 0) & 0x07FF)
    }

    /// Frame type (header bits 12–15); 1 = commands.
    pub fn frame_type(&self) -> u8 {
        (u16_le(self.buffer.as_ref(), 0) >> 12) as u8
    }

    /// The datagram area: `length()` bytes after the header, cut at the end of the buffer.
    pub fn payload(&self) -> &[u8] {
        let b = self.buffer.as_ref();
        let end = (HEADER_LEN + self.length()).min(b.len());
        b.get(HEADER_LEN..end).unwrap_or(&[])
    }

    /// Iterate over the datagrams (read-only; for the master side and tests).
    pub fn datagrams(&self) -> Datagrams<'_> {
        Datagrams {
            rest: self.payload(),
            done: false,
        }
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Frame<T> {
    pub fn set_header(&mut self, length: usize, frame_type: u8) {
        let word = (length.min(MAX_LENGTH) as u16) | (u16::from(frame_type & 0x0F) << 12);
        if let Some(b) = self.buffer.as_mut().get_mut(0..2) {
            b.copy_from_slice(&word.to_le_bytes());
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

/// Iterator over the datagrams of a frame; yields one `Err` and stops at the first
/// datagram that runs past the end, and stops after the one whose "more" bit is clear.
#[derive(Debug, Clone)]
pub struct Datagrams<'a> {
    rest: &'a [u8],
    done: bool,
}

impl<'a> Iterator for Datagrams<'a> {
    type Item = Result<Datagram<&'a [u8]>, WireError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let total = match datagram::total_len(self.rest) {
            Some(t) if t <= self.rest.len() => t,
            _ => {
                self.done = true;
                return Some(Err(WireError::Truncated));
            }
        };
        let (this, rest) = self.rest.split_at(total);
        self.rest = rest;
        let dg = Datagram::new_unchecked(this);
        if !dg.more_follows() {
            self.done = true;
        }
        Some(Ok(dg))
    }
}

/// Datagram address as the master writes it: position/configured (ADP, ADO) or logical.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Address {
    /// Auto-increment position (0, −1 = 0xFFFF, …) or configured station address, and the
    /// register/memory offset.
    Physical { adp: u16, ado: u16 },
    /// 32-bit logical address (LRD/LWR/LRW).
    Logical(u32),
}

impl Address {
    /// The 4 address bytes read as one little-endian `u32`.
    pub const fn to_u32(self) -> u32 {
        match self {
            Address::Physical { adp, ado } => (adp as u32) | ((ado as u32) << 16),
            Address::Logical(a) => a,
        }
    }
}

/// Builds an EtherCAT frame in a caller-supplied buffer: Ethernet header (optional), the
/// EtherCAT header, datagrams with the "more" bit chained. No allocation.
#[derive(Debug)]
pub struct FrameWriter<'a> {
    buf: &'a mut [u8],
    /// Offset of the EtherCAT header.
    start: usize,
    pos: usize,
    last: Option<usize>,
}

impl<'a> FrameWriter<'a> {
    /// A frame with an Ethernet header: destination broadcast, the given source MAC,
    /// EtherType 0x88A4.
    pub fn ethernet(buf: &'a mut [u8], source: [u8; 6]) -> Result<Self, WireError> {
        if buf.len() < ETHERNET_HEADER_LEN + HEADER_LEN {
            return Err(WireError::BufferTooSmall);
        }
        let mut eth = EthernetFrame::new_unchecked(&mut *buf);
        eth.set_destination([0xFF; 6]);
        eth.set_source(source);
        eth.set_ethertype(ETHERTYPE_ETHERCAT);
        Ok(FrameWriter {
            buf,
            start: ETHERNET_HEADER_LEN,
            pos: ETHERNET_HEADER_LEN + HEADER_LEN,
            last: None,
        })
    }

    /// A frame that starts with the EtherCAT header (e.g. EtherCAT over UDP).
    pub fn raw(buf: &'a mut [u8]) -> Result<Self, WireError> {
        if buf.len() < HEADER_LEN {
            return Err(WireError::BufferTooSmall);
        }
        Ok(FrameWriter {
            buf,
            start: 0,
            pos: HEADER_LEN,
            last: None,
        })
    }

    /// Append a datagram with `data` (for reads: zeros of the wanted length). Returns the
    /// datagram's offset in the buffer.
    pub fn push(
        &mut self,
        command: Command,
        index: u8,
        address: Address,
        data: &[u8],
    ) -> Result<usize, WireError> {
        if data.len() > datagram::MAX_DATA_LEN {
            return Err(WireError::DataTooLong);
        }
        let total = datagram::HEADER_LEN + data.len() + datagram::WKC_LEN;
        let at = self.pos;
        if at + total - self.start - HEADER_LEN > MAX_LENGTH {
            return Err(WireError::DataTooLong);
        }
        let Some(slot) = self.buf.get_mut(at..at + total) else {
            return Err(WireError::BufferTooSmall);
        };
        slot.fill(0);
        let mut dg = Datagram::new_unchecked(slot);
        dg.set_command(command);
        dg.set_index(index);
        dg.set_address(address.to_u32());
        dg.set_len_flags(data.len(), false, false);
        dg.data_mut().copy_from_slice(data);
        if let Some(prev) = self.last {
            if let Some(p) = self.buf.get_mut(prev..) {
                let mut prev = Datagram::new_unchecked(p);
                prev.set_more_follows(true);
            }
        }
        self.last = Some(at);
        self.pos = at + total;
        Ok(at)
    }

    /// Append a read datagram of `len` zero bytes.
    pub fn push_read(
        &mut self,
        command: Command,
        index: u8,
        address: Address,
        len: usize,
    ) -> Result<usize, WireError> {
        const ZEROS: [u8; datagram::MAX_DATA_LEN] = [0; datagram::MAX_DATA_LEN];
        let data = ZEROS.get(..len).ok_or(WireError::DataTooLong)?;
        self.push(command, index, address, data)
    }

    /// Write the EtherCAT header and return the frame length (padding not added: masters
    /// send unpadded frames, spec §1.1).
    pub fn finish(self) -> usize {
        let length = self.pos - self.start - HEADER_LEN;
        if let Some(b) = self.buf.get_mut(self.start..) {
            Frame::new_unchecked(b).set_header(length, TYPE_COMMANDS);
        }
        self.pos
    }
}
