//! The master side of the wire, sans-IO: what a minimal master ("enough to check a chain")
//! puts into datagrams and reads back out of them. The frame and datagram views themselves
//! are [`crate::frame`] and [`crate::datagram`]; this module adds the master's conventions:
//!
//! * addressing as SOEM does it (spec §2.8): auto-increment position −n,
//!   configured station address 0x1000 + slave number (1-based);
//! * the SII EEPROM read command (§2.4), the AL control request and the AL status block
//!   0x0130–0x0135 (§4);
//! * finding the reply to a request among the frames that come back (§1.1);
//! * [`sdo`]: the CoE SDO client messages (§6), [`sii_image`]: what a master reads from the
//!   SII image it fetched (§3).

pub mod sdo;
pub mod sii_image;

use crate::al_control::{AlControl, AlState, AlStatus};
use crate::al_status_code::AlStatusCode;
use crate::datagram::Datagram;
use crate::eeprom::{self, SiiCommand};
use crate::frame::{
    EthernetFrame, Frame, ETHERNET_HEADER_LEN, ETHERTYPE_ETHERCAT, HEADER_LEN,
    SOURCE_MAC_RETURN_BIT, TYPE_COMMANDS,
};

/// Source MAC of the master's frames: SOEM's primary MAC 01:01:01:01:01:01. The slave ORs
/// 0x02 into the first byte on the way back (spec §1.1), so the reply is told from the request.
pub const MASTER_MAC: [u8; 6] = [0x01; 6];

/// First configured station address: slave 1 gets 0x1001 (SOEM `ecx_config_init`,
/// spec §2.8 step 19: slave index + 0x1000).
pub const STATION_BASE: u16 = 0x1000;

/// Length of the AL status block read by masters: status 0x0130, reserved, code 0x0134.
pub const AL_STATUS_BLOCK: usize = 6;

/// ADP of an auto-increment datagram addressed to the slave at 0-based `position`
/// (the master writes −position; every slave adds 1, spec §1.4 rule 5).
pub const fn auto_increment(position: u16) -> u16 {
    0u16.wrapping_sub(position)
}

/// The configured station address this master gives to slave `number` (1-based).
pub const fn station_address(number: u16) -> u16 {
    STATION_BASE.wrapping_add(number)
}

/// The 6-byte write at 0x0502 that starts an SII read of `word` (control 0x0100, 32-bit
/// word address; spec §2.4 step 2).
pub fn eeprom_read_command(word: u16) -> [u8; 6] {
    let c = SiiCommand::Read.to_control().to_le_bytes();
    let a = word.to_le_bytes();
    [c[0], c[1], a[0], a[1], 0, 0]
}

/// What the EEPROM control/status word 0x0502 says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EepromStatus {
    Busy,
    /// Idle; reads return 8 bytes (bit 6) or 4.
    Ready {
        read_8: bool,
    },
    /// An error bit (11–14) is set: the raw word.
    Error(u16),
}

impl EepromStatus {
    pub fn from_u16(v: u16) -> Self {
        let errors = eeprom::CHECKSUM_ERROR
            | eeprom::NOT_LOADED
            | eeprom::ACK_ERROR
            | eeprom::WRITE_ENABLE_ERROR;
        if v & eeprom::BUSY != 0 {
            EepromStatus::Busy
        } else if v & errors != 0 {
            EepromStatus::Error(v)
        } else {
            EepromStatus::Ready {
                read_8: v & eeprom::READ_SIZE_8 != 0,
            }
        }
    }
}

/// AL control word requesting `state`, with the error acknowledge bit: SOEM writes its
/// requests so (0x0011 Init, 0x0012 Pre-Op, spec §4.1), and a slave whose error bit is
/// set serves only an acknowledging request (§4.2 step 2).
pub const fn al_request(state: AlState) -> u16 {
    AlControl::new(state, true).to_u16()
}

/// The AL status block 0x0130–0x0135 as read: status word and status code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AlStatusBlock {
    /// Raw AL status (bits 0–3 state, bit 4 error).
    pub raw: u16,
    pub code: AlStatusCode,
}

impl AlStatusBlock {
    /// From the 6 bytes at 0x0130 (or at least the first 2; the code then reads 0).
    pub fn parse(b: &[u8]) -> Option<Self> {
        let raw = u16::from_le_bytes([*b.first()?, *b.get(1)?]);
        let code = match (b.get(4), b.get(5)) {
            (Some(&lo), Some(&hi)) => u16::from_le_bytes([lo, hi]),
            _ => 0,
        };
        Some(AlStatusBlock {
            raw,
            code: AlStatusCode(code),
        })
    }

    /// The state, `None` for a value that is no state (0, 5–7, 9–15).
    pub fn state(&self) -> Option<AlState> {
        AlState::from_u8((self.raw & 0x0F) as u8)
    }

    pub fn error(&self) -> bool {
        AlStatus::from_u16(self.raw).error
    }
}

/// Name of a state as masters print it (SOEM `ec_state` names).
pub const fn state_name(state: AlState) -> &'static str {
    match state {
        AlState::Init => "INIT",
        AlState::PreOp => "PREOP",
        AlState::Bootstrap => "BOOT",
        AlState::SafeOp => "SAFEOP",
        AlState::Op => "OP",
    }
}

/// If `frame` (a whole Ethernet frame) is a reply to the request whose first datagram has
/// index `index`, its first datagram: EtherType 0x88A4, the source-MAC bit a slave sets on
/// the way back (spec §1.1), a complete EtherCAT header and datagram. Anything else (our
/// own request seen again, another master's traffic, a stale retry) gives `None`.
pub fn reply_datagram(frame: &[u8], index: u8) -> Option<Datagram<&[u8]>> {
    let eth = EthernetFrame::new_checked(frame).ok()?;
    if eth.ethertype() != ETHERTYPE_ETHERCAT || eth.source()[0] & SOURCE_MAC_RETURN_BIT == 0 {
        return None;
    }
    let bytes = frame.get(ETHERNET_HEADER_LEN..)?;
    let ecat = Frame::new_checked(bytes).ok()?;
    if ecat.frame_type() != TYPE_COMMANDS {
        return None;
    }
    let first = bytes.get(HEADER_LEN..HEADER_LEN + ecat.length())?;
    let dg = Datagram::new_checked(first).ok()?;
    (dg.index() == index).then_some(dg)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::datagram::Command;
    use crate::frame::{Address, FrameWriter};
    use crate::Esc;

    #[test]
    fn addressing_follows_soem() {
        assert_eq!(auto_increment(0), 0x0000);
        assert_eq!(auto_increment(1), 0xFFFF);
        assert_eq!(auto_increment(2), 0xFFFE);
        assert_eq!(station_address(1), 0x1001);
        assert_eq!(station_address(2), 0x1002);
    }

    #[test]
    fn eeprom_read_command_is_control_then_word_address() {
        // spec §2.4 step 2: `00 01 | addr_lo addr_hi | 00 00`.
        assert_eq!(eeprom_read_command(0x0008), [0x00, 0x01, 0x08, 0x00, 0, 0]);
        assert_eq!(eeprom_read_command(0x1234), [0x00, 0x01, 0x34, 0x12, 0, 0]);
    }

    #[test]
    fn eeprom_status_decodes_busy_errors_and_read_size() {
        assert_eq!(
            EepromStatus::from_u16(0x0040),
            EepromStatus::Ready { read_8: true }
        );
        assert_eq!(
            EepromStatus::from_u16(0x0000),
            EepromStatus::Ready { read_8: false }
        );
        assert_eq!(EepromStatus::from_u16(0x8140), EepromStatus::Busy);
        assert_eq!(EepromStatus::from_u16(0x2040), EepromStatus::Error(0x2040));
    }

    #[test]
    fn al_requests_carry_the_acknowledge_bit() {
        // spec §4.1: 0x0011 Init + ack, 0x0012 Pre-Op + ack.
        assert_eq!(al_request(AlState::Init), 0x0011);
        assert_eq!(al_request(AlState::PreOp), 0x0012);
        assert_eq!(al_request(AlState::SafeOp), 0x0014);
        assert_eq!(al_request(AlState::Op), 0x0018);
    }

    #[test]
    fn al_status_block_parses_state_error_and_code() {
        let b = AlStatusBlock::parse(&[0x12, 0x00, 0, 0, 0x16, 0x00]).expect("6 bytes");
        assert_eq!(b.state(), Some(AlState::PreOp));
        assert!(b.error());
        assert_eq!(b.code, AlStatusCode::INVALID_MAILBOX_CONFIGURATION);
        let b = AlStatusBlock::parse(&[0x08, 0x00]).expect("2 bytes");
        assert_eq!(
            (b.state(), b.error(), b.code.0),
            (Some(AlState::Op), false, 0)
        );
        assert!(AlStatusBlock::parse(&[0x01]).is_none());
        assert_eq!(AlStatusBlock::parse(&[0, 0]).and_then(|b| b.state()), None);
    }

    /// A BRD built with the frame writer, through two emulated ESCs, is found as the reply
    /// by its index with a working counter of 2; the request itself is not a reply.
    #[test]
    fn reply_is_found_by_index_after_a_chain() {
        let mut buf = [0u8; 64];
        let mut w = FrameWriter::ethernet(&mut buf, MASTER_MAC).expect("room");
        w.push_read(Command::Brd, 0x5A, Address::Physical { adp: 0, ado: 0 }, 2)
            .expect("datagram");
        let len = w.finish();
        let frame = &mut buf[..len];
        assert!(reply_datagram(frame, 0x5A).is_none(), "not returned yet");
        let mut escs = [Esc::with_sii(&[]), Esc::with_sii(&[])];
        let _ = crate::process_chain(&mut escs, od::Instant::from_nanos(0), frame);
        let dg = reply_datagram(frame, 0x5A).expect("reply");
        assert_eq!(dg.wkc(), 2);
        assert!(reply_datagram(frame, 0x5B).is_none(), "other index");
        assert!(reply_datagram(&frame[..20], 0x5A).is_none(), "truncated");
    }
}
