//! Modbus RTU (serial line) helpers: the CRC-16 that ends every RTU frame (Modbus over
//! Serial Line V1.02 §6.2.2): polynomial 0xA001 (reflected 0x8005), initial value 0xFFFF,
//! appended low byte first.

use crc::{Crc, CRC_16_MODBUS};

/// Longest RTU frame (Modbus over Serial Line §2.5.1): 256 bytes.
pub const MAX_FRAME: usize = 256;

const MODBUS: Crc<u16> = Crc::<u16>::new(&CRC_16_MODBUS);

/// The CRC-16 of `data`.
pub fn crc16(data: &[u8]) -> u16 {
    MODBUS.checksum(data)
}

/// The two CRC bytes as they go on the wire, low byte first.
pub fn crc_bytes(data: &[u8]) -> [u8; 2] {
    crc16(data).to_le_bytes()
}

/// Whether `frame` (address, PDU, CRC) ends with the right CRC. Frames shorter than 4 bytes
/// (address + function code + CRC) are never valid.
pub fn check_frame(frame: &[u8]) -> bool {
    if frame.len() < 4 {
        return false;
    }
    let (body, crc) = frame.split_at(frame.len() - 2);
    crc == crc_bytes(body)
}

/// The frame without its CRC, if the CRC is right.
pub fn strip_crc(frame: &[u8]) -> Option<&[u8]> {
    if check_frame(frame) {
        frame.get(..frame.len() - 2)
    } else {
        None
    }
}
