//! The CRC of SDO block transfers: CRC-16/XMODEM (polynomial 1021h, initial 0, no
//! reflection), CiA 301 §7.2.4.3.16.

use crc::{Crc, CRC_16_XMODEM};

const XMODEM: Crc<u16> = Crc::<u16>::new(&CRC_16_XMODEM);

pub fn crc16(data: &[u8]) -> u16 {
    XMODEM.checksum(data)
}

#[cfg(test)]
mod tests {
    use super::crc16;

    // Test values of the CiA 301 / 305 notes kept beside the project, §1.5.
    #[test]
    fn crc_matches_the_published_check_values() {
        assert_eq!(crc16(b"123456789"), 0x31C3);
        assert_eq!(crc16(&[0]), 0x0000);
        assert_eq!(crc16(b"CANopenDemoPIC32"), 0x43F3);
        assert_eq!(crc16(b"Tiny Node - Mega Domains !"), 0xE140);
    }
}
