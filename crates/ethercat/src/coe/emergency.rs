//! CoE emergency (CoE service 1, spec §6.7): the 8-byte CiA 301 EMCY payload
//! after the CoE header, mailbox length 10.
//!
//! ```text
//! CoE header 0x1000 | error code (u16) | error register (1001h) | 5 manufacturer bytes
//! ```
//!
//! Bytes 3–7 are the device's (a drive may fill them with zeros); the device decides.
//! Emergencies are queued by the device ([`super::CoeServer::queue_emergency`]) and posted only when the send
//! mailbox is empty and no SDO transfer or SDO info reply is in progress: ethercrab panics on
//! an emergency where it expects an SDO response (spec §5.6).

use super::service;

/// One emergency message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Emergency {
    /// CiA 301 / CiA 402 error code (0000h: error reset / no error).
    pub code: u16,
    /// Error register (object 1001h).
    pub register: u8,
    /// Manufacturer-specific bytes.
    pub data: [u8; 5],
}

impl Emergency {
    pub const fn new(code: u16, register: u8, data: [u8; 5]) -> Self {
        Emergency {
            code,
            register,
            data,
        }
    }

    /// The 8 EMCY bytes.
    pub fn to_bytes(&self) -> [u8; 8] {
        let [c0, c1] = self.code.to_le_bytes();
        let [d0, d1, d2, d3, d4] = self.data;
        [c0, c1, self.register, d0, d1, d2, d3, d4]
    }

    /// The CoE part (10 bytes: CoE header + EMCY) into `p`.
    pub fn encode(&self, p: &mut [u8]) -> Option<usize> {
        let dst = p.get_mut(..10)?;
        let (hdr, body) = dst.split_at_mut(2);
        hdr.copy_from_slice(&[0x00, service::EMERGENCY << 4]);
        body.copy_from_slice(&self.to_bytes());
        Some(10)
    }
}
