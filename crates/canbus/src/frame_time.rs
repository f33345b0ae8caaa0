//! How long a classic CAN frame occupies the bus (ISO 11898-1): the exact number of bits of
//! one frame, stuff bits included, and the worst case the schedulability analysis uses
//! (Davis, Burns, Bril, Lukkien 2007). A frame is on the wire as
//!
//! ```text
//! SOF | identifier | RTR (SRR IDE id17..0 RTR) | IDE r0 (r1 r0) | DLC | data | CRC-15   ← stuffed
//! CRC delimiter | ACK slot | ACK delimiter | EOF ×7 | intermission ×3              ← fixed form
//! ```
//!
//! In the stuffed part a bit of the opposite level follows every five equal bits (and counts
//! toward the next five). The CRC is CAN's CRC-15 (x¹⁵ + x¹⁴ + x¹⁰ + x⁸ + x⁷ + x⁴ + x³ + 1),
//! computed over the bits from SOF to the data; it is written here because it runs over a
//! bit string that is not a whole number of bytes, which byte-wise CRC crates cannot take.

use crate::CanFrame;

/// Bits after the CRC that are never stuffed: CRC delimiter, ACK slot and delimiter, EOF,
/// intermission.
pub const FIXED_TAIL_BITS: u32 = 1 + 2 + 7 + 3;

/// Up to 19 + 20 + 64 + 15 bits: an extended frame with 8 bytes, CRC included.
const MAX_STUFFED_BITS: usize = 1 + 11 + 1 + 1 + 18 + 1 + 2 + 4 + 64 + 15;

/// The bits of the stuffed part of a frame, before stuffing, MSB first.
struct BitString {
    bits: [bool; MAX_STUFFED_BITS],
    len: usize,
}

impl BitString {
    fn push(&mut self, value: u64, width: u32) {
        for i in (0..width).rev() {
            if let Some(slot) = self.bits.get_mut(self.len) {
                *slot = (value >> i) & 1 == 1;
                self.len += 1;
            }
        }
    }

    fn as_slice(&self) -> &[bool] {
        self.bits.get(..self.len).unwrap_or(&[])
    }
}

/// CAN's CRC-15 over a bit string.
pub fn crc15(bits: &[bool]) -> u16 {
    const POLY: u16 = 0x4599;
    let mut crc: u16 = 0;
    for &bit in bits {
        let top = (crc >> 14) & 1 == 1;
        crc = (crc << 1) & 0x7FFF;
        if top != bit {
            crc ^= POLY;
        }
    }
    crc
}

/// The stuff bits ISO 11898-1 inserts into `bits`.
pub fn stuff_bits(bits: &[bool]) -> u32 {
    let mut count = 0;
    let mut run = 0;
    let mut last = None;
    for &bit in bits {
        if Some(bit) == last {
            run += 1;
        } else {
            run = 1;
            last = Some(bit);
        }
        if run == 5 {
            count += 1;
            // The stuff bit is the opposite level and starts the next run.
            last = Some(!bit);
            run = 1;
        }
    }
    count
}

fn stuffed_part(frame: &CanFrame) -> BitString {
    let mut s = BitString {
        bits: [false; MAX_STUFFED_BITS],
        len: 0,
    };
    let dlc = u64::from(frame.len.min(15));
    let data_len = if frame.rtr {
        0
    } else {
        usize::from(frame.len.min(8))
    };
    s.push(0, 1); // SOF
    if frame.extended {
        s.push(u64::from(frame.id >> 18) & 0x7FF, 11);
        s.push(1, 1); // SRR
        s.push(1, 1); // IDE
        s.push(u64::from(frame.id) & 0x3FFFF, 18);
        s.push(u64::from(frame.rtr), 1);
        s.push(0, 2); // r1 r0
    } else {
        s.push(u64::from(frame.id) & 0x7FF, 11);
        s.push(u64::from(frame.rtr), 1);
        s.push(0, 2); // IDE r0
    }
    s.push(dlc, 4);
    for byte in frame.data.iter().take(data_len) {
        s.push(u64::from(*byte), 8);
    }
    let crc = crc15(s.as_slice());
    s.push(u64::from(crc), 15);
    s
}

/// The bits `frame` occupies on the bus, stuff bits and intermission included.
pub fn frame_bits(frame: &CanFrame) -> u32 {
    let s = stuffed_part(frame);
    s.len as u32 + stuff_bits(s.as_slice()) + FIXED_TAIL_BITS
}

/// The most bits a frame of this format and data length can take: `g + 8n + 13 +
/// ⌊(g + 8n − 1) / 4⌋` with g = 34 (standard) or 54 (extended) stuffable bits.
pub const fn worst_case_bits(extended: bool, data_len: u8) -> u32 {
    let g = if extended { 54 } else { 34 };
    let n = if data_len > 8 { 8 } else { data_len as u32 };
    g + 8 * n + FIXED_TAIL_BITS + (g + 8 * n - 1) / 4
}

/// The fewest bits: no stuff bit at all.
pub const fn best_case_bits(extended: bool, data_len: u8) -> u32 {
    let g = if extended { 54 } else { 34 };
    let n = if data_len > 8 { 8 } else { data_len as u32 };
    g + 8 * n + FIXED_TAIL_BITS
}

/// Nanoseconds `bits` take at `bitrate` bit/s (rounded up; 0 for a bit rate of 0).
pub const fn bits_to_nanos(bits: u32, bitrate: u32) -> u64 {
    if bitrate == 0 {
        return 0;
    }
    (bits as u64 * 1_000_000_000).div_ceil(bitrate as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bits_of(text: &[u8]) -> [bool; 72] {
        let mut out = [false; 72];
        for (i, byte) in text.iter().enumerate() {
            for b in 0..8 {
                out[i * 8 + b] = (byte >> (7 - b)) & 1 == 1;
            }
        }
        out
    }

    #[test]
    fn crc15_check_value() {
        // The CRC catalogue's check value of CRC-15/CAN over "123456789".
        assert_eq!(crc15(&bits_of(b"123456789")), 0x059E);
    }

    #[test]
    fn stuffing_counts_runs_of_five_and_the_stuff_bit_starts_the_next_run() {
        let b = |s: &str| {
            s.bytes()
                .map(|c| c == b'1')
                .collect::<heapless::Vec<bool, 64>>()
        };
        assert_eq!(stuff_bits(&b("0000")), 0);
        assert_eq!(stuff_bits(&b("00000")), 1);
        assert_eq!(stuff_bits(&b("000000000")), 1, "00000[1]0000");
        assert_eq!(stuff_bits(&b("0000000000")), 2, "00000[1]00000[1]");
        assert_eq!(
            stuff_bits(&b("0000011110")),
            2,
            "00000[1]1111 → the stuff bit + 4 ones"
        );
        assert_eq!(stuff_bits(&b("0101010101")), 0);
    }

    #[test]
    fn every_length_lies_between_best_and_worst_case() {
        for extended in [false, true] {
            for n in 0..=8u8 {
                for pattern in [0x00u8, 0xFF, 0x55, 0x0F, 0xE1] {
                    for id in [0u32, 0x7FF, 0x555, 0x1FF] {
                        let data = [pattern; 8];
                        let f = CanFrame::with_id(id, extended, &data[..usize::from(n)]);
                        let Ok(f) = f else { continue };
                        let bits = frame_bits(&f);
                        assert!(bits >= best_case_bits(extended, n), "{f:?}: {bits}");
                        assert!(bits <= worst_case_bits(extended, n), "{f:?}: {bits}");
                    }
                }
            }
        }
    }

    #[test]
    fn worst_case_formula() {
        // 8 data bytes, standard: 34 + 64 + 13 + ⌊97 / 4⌋ = 135 bits.
        assert_eq!(worst_case_bits(false, 8), 135);
        assert_eq!(best_case_bits(false, 8), 111);
        assert_eq!(worst_case_bits(false, 0), 55);
        assert_eq!(worst_case_bits(true, 8), 160);
        // A heartbeat (1 byte): 55…65 bits, 440…520 µs at 125 kbit/s.
        assert_eq!(best_case_bits(false, 1), 55);
        assert_eq!(worst_case_bits(false, 1), 65);
        assert_eq!(bits_to_nanos(55, 125_000), 440_000);
    }

    #[test]
    fn all_zero_identifier_and_data_stuff_heavily() {
        let f = CanFrame::new(0, &[0; 8]).expect("a frame");
        let bits = frame_bits(&f);
        // SOF + 11 zero id bits + RTR + IDE + r0 + DLC 1000 + 64 zeros: long zero runs.
        assert!(bits >= best_case_bits(false, 8) + 15, "{bits}");
    }
}
