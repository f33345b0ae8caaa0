//! The SII EEPROM interface of the ESC, registers 0x0500–0x050F (spec §2.4).
//! The image itself (its words and categories) is [`crate::sii`]'s business; this module is
//! the control/status word and the storage the ESC reads commands from.

/// Control bit 0: write enable (must be set in the same write as a write command).
pub const WRITE_ENABLE: u16 = 0x0001;
/// Status bit 5: EEPROM emulated by the PDI (reported 0).
pub const EMULATION: u16 = 0x0020;
/// Status bit 6: a read returns 8 bytes (0: 4 bytes). This ESC always offers 8-byte reads.
pub const READ_SIZE_8: u16 = 0x0040;
/// Status bit 7: two address bytes (EEPROM > 16 kbit).
pub const ADDRESS_2_BYTES: u16 = 0x0080;
/// Command bits 8–10.
pub const COMMAND_MASK: u16 = 0x0700;
/// Status bit 11: checksum error in the ESC configuration area (never set here).
pub const CHECKSUM_ERROR: u16 = 0x0800;
/// Status bit 12: device information not loaded (never set here).
pub const NOT_LOADED: u16 = 0x1000;
/// Status bit 13: missing EEPROM acknowledge / invalid command.
pub const ACK_ERROR: u16 = 0x2000;
/// Status bit 14: write command without write enable.
pub const WRITE_ENABLE_ERROR: u16 = 0x4000;
/// Status bit 15: busy.
pub const BUSY: u16 = 0x8000;
/// Error bits a NOP clears.
pub const ERROR_BITS: u16 = ACK_ERROR | WRITE_ENABLE_ERROR;

/// EEPROM commands (control bits 8–10).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SiiCommand {
    /// 000: idle / clear errors.
    Nop,
    /// 001: read 4 or 8 bytes from the word address.
    Read,
    /// 010: write one word from 0x0508.
    Write,
    /// 100: reload the ESC configuration area.
    Reload,
    /// Anything else (SOEM 1.4's "reload" constant 0x0300 lands here): command error.
    Invalid(u8),
}

impl SiiCommand {
    pub const fn from_control(control: u16) -> Self {
        match (control & COMMAND_MASK) >> 8 {
            0 => SiiCommand::Nop,
            1 => SiiCommand::Read,
            2 => SiiCommand::Write,
            4 => SiiCommand::Reload,
            other => SiiCommand::Invalid(other as u8),
        }
    }

    pub const fn to_control(self) -> u16 {
        let c: u16 = match self {
            SiiCommand::Nop => 0,
            SiiCommand::Read => 1,
            SiiCommand::Write => 2,
            SiiCommand::Reload => 4,
            SiiCommand::Invalid(v) => v as u16 & 0x07,
        };
        c << 8
    }
}

/// The EEPROM behind the interface: a byte image (little-endian words), read-only (e.g. a
/// `&'static` image generated at build time) or writable (then SII write commands change it).
#[derive(Debug)]
pub enum Eeprom<'a> {
    /// No EEPROM: every word reads 0xFFFF (erased).
    None,
    ReadOnly(&'a [u8]),
    Writable(&'a mut [u8]),
}

impl Eeprom<'_> {
    pub fn bytes(&self) -> &[u8] {
        match self {
            Eeprom::None => &[],
            Eeprom::ReadOnly(b) => b,
            Eeprom::Writable(b) => b,
        }
    }

    /// Word `addr`; 0xFFFF beyond the image (an erased EEPROM, spec §2.4).
    pub fn word(&self, addr: u32) -> u16 {
        let at = (addr as usize).saturating_mul(2);
        match self.bytes().get(at..at.saturating_add(2)) {
            Some(&[lo, hi]) => u16::from_le_bytes([lo, hi]),
            _ => 0xFFFF,
        }
    }

    /// Write word `addr`; false if the image is read-only or too short.
    pub fn write_word(&mut self, addr: u32, value: u16) -> bool {
        let Eeprom::Writable(b) = self else {
            return false;
        };
        let at = (addr as usize).saturating_mul(2);
        match b.get_mut(at..at.saturating_add(2)) {
            Some(w) => {
                w.copy_from_slice(&value.to_le_bytes());
                true
            }
            None => false,
        }
    }
}
