//! Function codes (MODBUS Application Protocol V1.1b3 §6) used by this crate.

/// 0x03 Read Holding Registers.
pub const READ_HOLDING_REGISTERS: u8 = 0x03;
/// 0x06 Write Single Register.
pub const WRITE_SINGLE_REGISTER: u8 = 0x06;
/// 0x07 Read Exception Status (serial line only in the standard; the CMMO-ST answers it on
/// Modbus TCP, manual Tab. 4.3).
pub const READ_EXCEPTION_STATUS: u8 = 0x07;
/// 0x10 Write Multiple Registers.
pub const WRITE_MULTIPLE_REGISTERS: u8 = 0x10;
/// 0x17 Read/Write Multiple Registers.
pub const READ_WRITE_MULTIPLE_REGISTERS: u8 = 0x17;
/// 0x2B Encapsulated Interface Transport.
pub const ENCAPSULATED_INTERFACE_TRANSPORT: u8 = 0x2B;
/// MEI type 0x0E of function 0x2B: Read Device Identification.
pub const MEI_READ_DEVICE_IDENTIFICATION: u8 = 0x0E;

/// Quantity limits of the standard (§6.3, §6.12, §6.17).
pub mod limits {
    /// 0x03: 1…125 registers (0x7D).
    pub const MAX_READ_REGISTERS: u16 = 0x7D;
    /// 0x10: 1…123 registers (0x7B).
    pub const MAX_WRITE_REGISTERS: u16 = 0x7B;
    /// 0x17: 1…125 registers read (0x7D).
    pub const MAX_READ_WRITE_READ: u16 = 0x7D;
    /// 0x17: 1…121 registers written (0x79).
    pub const MAX_READ_WRITE_WRITE: u16 = 0x79;
}
