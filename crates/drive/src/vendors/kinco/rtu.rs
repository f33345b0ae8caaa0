//! Kinco's Modbus RTU on RS485 (Kinco CD3 / FD3 manual ch. 12, lines L2530-2640 of its text kept
//! beside the project): registers are a mapping onto the drive's objects, not a second copy. The
//! server is modbus's registers-over-objects ([`modbus::object_registers`]); what is the Kinco's is
//! its table (the device file's `modbus` keys) and how it answers an FC 03h error. What the manual
//! says:
//!
//! - Frame `station, function, data, CRC-16` (low byte first, [`modbus::rtu`]), frames apart by
//!   at least 3.5 character times (L2546); station = ID_Com 100Bh (L2528).
//! - FC 03h read, 06h write one register, 10h write several (L2555-2637). A register address
//!   is a Kinco code, looked up in a table ([`RegisterMapping`], the device file's `modbus`
//!   keys): 3100h controlword 6040h, 3200h statusword 6041h, 6F00h target velocity 60FFh.
//! - A 32-bit object takes two registers, the **low word first**, each word big-endian
//!   (L2630: `55 55 00 08` is 0008 5555h).
//! - Errors are answered with function code 81h for FC 03h ("e.g. a non-existent address",
//!   L2568), 86h for FC 06h and 90h for FC 10h (address out of range, non-existent or
//!   read-only, L2593, L2621). No exception byte is described.
//!
//! Decisions:
//! - FC 03h's error function code: the manual's **81h** ([`ERRORS`], [`ErrorStyle::Read81h`]),
//!   because the programs written for these drives check for it; [`ErrorStyle::Standard`]
//!   answers 83h as MODBUS Application Protocol §7 prescribes. 86h and 90h are both.
//! - Every error reply carries the standard exception byte (02 address, 03 value, 04 device
//!   failure): a Modbus client such as pymodbus needs it to decode the reply.
//! - Two registers read from any object are its 32-bit value, low word first (KINCO-MB-01
//!   reads two registers from the 16-bit statusword): the registers after an object that map
//!   nothing read its sign extension ([`modbus::object_registers`]).

pub use modbus::function_code::WRITE_SINGLE_REGISTER;
pub use modbus::object_registers::{
    from_registers, lookup, to_registers, words, ErrorStyle, Ignored, RegisterMapping,
};
pub use modbus::rtu::MAX_FRAME;

/// The Kinco RTU server of one drive: `station` is its 100Bh at power-up, `map` the device
/// file's `modbus` keys.
pub type KincoRtu<'a> = modbus::object_registers::ObjectRegisters<'a>;

/// How the Kinco answers an FC 03h error: 81h, as the manual prints it (L2568).
pub const ERRORS: ErrorStyle = ErrorStyle::Read81h;
