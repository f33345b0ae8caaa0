//! Fieldbus memory management units: logical → physical mapping (spec §2.5,
//! §7.4, §7.5).
//!
//! A mapping covers `(length − 1) × 8 + (stop bit − start bit + 1)` bits; logical bit `i` lies
//! at byte `logical_start + (start_bit + i) / 8`, bit `(start_bit + i) % 8`, and physical bit
//! `i` at byte `physical_start + (physical_start_bit + i) / 8`, bit
//! `(physical_start_bit + i) % 8`. Byte-aligned mappings (start bit 0, stop bit 7, physical
//! bit 0) reduce to a byte copy ([`Fmmu::byte_window`]); the others are served bit by bit
//! ([`Fmmu::bit_window`]), which is exact but slower.

/// Bytes per FMMU register block.
pub const FMMU_LEN: usize = 16;

/// One FMMU entry as stored at 0x0600 + 16·n.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Fmmu {
    pub logical_start: u32,
    /// Logical bytes touched, counting partial first and last bytes.
    pub length: u16,
    pub logical_start_bit: u8,
    pub logical_stop_bit: u8,
    pub physical_start: u16,
    pub physical_start_bit: u8,
    /// Type bit 0: used by reads (LRD, LRW): inputs, slave → master.
    pub read_enable: bool,
    /// Type bit 1: used by writes (LWR, LRW): outputs, master → slave.
    pub write_enable: bool,
    /// Activate bit 0.
    pub enable: bool,
}

/// Byte-aligned intersection of a datagram with a mapping.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ByteWindow {
    /// Offset in the datagram data.
    pub datagram_offset: usize,
    /// Physical address of the first byte.
    pub physical: u32,
    pub len: usize,
}

/// Bit-granular intersection: mapped bits `first..end` (indices into the mapping) fall into
/// the datagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BitWindow {
    pub first: u32,
    pub end: u32,
}

impl Fmmu {
    pub fn from_bytes(b: &[u8; FMMU_LEN]) -> Self {
        Fmmu {
            logical_start: u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            length: u16::from_le_bytes([b[4], b[5]]),
            logical_start_bit: b[6] & 0x07,
            logical_stop_bit: b[7] & 0x07,
            physical_start: u16::from_le_bytes([b[8], b[9]]),
            physical_start_bit: b[10] & 0x07,
            read_enable: b[11] & 0x01 != 0,
            write_enable: b[11] & 0x02 != 0,
            enable: b[12] & 0x01 != 0,
        }
    }

    pub fn to_bytes(&self) -> [u8; FMMU_LEN] {
        let mut b = [0u8; FMMU_LEN];
        b[0..4].copy_from_slice(&self.logical_start.to_le_bytes());
        b[4..6].copy_from_slice(&self.length.to_le_bytes());
        b[6] = self.logical_start_bit;
        b[7] = self.logical_stop_bit;
        b[8..10].copy_from_slice(&self.physical_start.to_le_bytes());
        b[10] = self.physical_start_bit;
        b[11] = u8::from(self.read_enable) | (u8::from(self.write_enable) << 1);
        b[12] = u8::from(self.enable);
        b
    }

    /// A byte-aligned mapping of `length` bytes.
    pub fn bytes(
        logical_start: u32,
        length: u16,
        physical_start: u16,
        read: bool,
        write: bool,
    ) -> Self {
        Fmmu {
            logical_start,
            length,
            logical_start_bit: 0,
            logical_stop_bit: 7,
            physical_start,
            physical_start_bit: 0,
            read_enable: read,
            write_enable: write,
            enable: true,
        }
    }

    /// Active and mapping at least one bit.
    pub fn is_active(&self) -> bool {
        self.enable && self.length > 0 && (self.read_enable || self.write_enable)
    }

    pub fn is_byte_aligned(&self) -> bool {
        self.logical_start_bit == 0 && self.logical_stop_bit == 7 && self.physical_start_bit == 0
    }

    /// Number of mapped bits; 0 if the entry is inconsistent (one byte with stop < start).
    pub fn bit_count(&self) -> u32 {
        if self.length == 0 {
            return 0;
        }
        let whole = (u32::from(self.length) - 1) * 8;
        let last = i32::from(self.logical_stop_bit) - i32::from(self.logical_start_bit) + 1;
        let n = whole as i64 + i64::from(last);
        if n <= 0 {
            0
        } else {
            n as u32
        }
    }

    /// For a byte-aligned mapping: the part of the datagram `[addr, addr + len)` it covers.
    pub fn byte_window(&self, addr: u32, len: usize) -> Option<ByteWindow> {
        let l0 = u64::from(self.logical_start);
        let l1 = l0 + u64::from(self.length);
        let d0 = u64::from(addr);
        let d1 = d0 + len as u64;
        let lo = l0.max(d0);
        let hi = l1.min(d1);
        if lo >= hi {
            return None;
        }
        let physical = u64::from(self.physical_start) + (lo - l0);
        Some(ByteWindow {
            datagram_offset: (lo - d0) as usize,
            physical: u32::try_from(physical).ok()?,
            len: (hi - lo) as usize,
        })
    }

    /// The mapped bits that fall inside the datagram `[addr, addr + len)`.
    pub fn bit_window(&self, addr: u32, len: usize) -> Option<BitWindow> {
        let bits = i64::from(self.bit_count());
        if bits == 0 || len == 0 {
            return None;
        }
        let start = i64::from(self.logical_start_bit);
        // Bit i lies at logical byte L + (start + i) / 8; it is in the datagram when
        // addr ≤ that byte < addr + len, i.e. (addr − L)·8 − start ≤ i < (addr + len − L)·8 − start.
        let rel0 = i64::from(addr) - i64::from(self.logical_start);
        let rel1 = rel0 + len as i64;
        let first = (rel0 * 8 - start).max(0);
        let end = (rel1 * 8 - start).min(bits);
        if first >= end {
            return None;
        }
        Some(BitWindow {
            first: first as u32,
            end: end as u32,
        })
    }

    /// Logical position (byte offset from `addr`, bit) of mapped bit `i` inside a datagram
    /// that starts at logical address `addr`.
    pub fn logical_bit(&self, addr: u32, i: u32) -> (i64, u8) {
        let pos = u64::from(self.logical_start_bit) + u64::from(i);
        let byte = i64::from(self.logical_start) + (pos / 8) as i64 - i64::from(addr);
        (byte, (pos % 8) as u8)
    }

    /// Physical position (address, bit) of mapped bit `i`.
    pub fn physical_bit(&self, i: u32) -> (u32, u8) {
        let pos = u32::from(self.physical_start_bit) + i;
        (u32::from(self.physical_start) + pos / 8, (pos % 8) as u8)
    }
}
