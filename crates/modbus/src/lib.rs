//! Modbus application protocol, sans-IO and `no_std`: request bytes in, response bytes out.
//!
//! The crate is the server side of MODBUS Application Protocol Specification V1.1b3 and of
//! MODBUS Messaging on TCP/IP Implementation Guide V1.0b for these function codes (those of
//! the FHPP device, manual GDCP-CMMO-ST-LK-C-HP-ZH §4.3.2, Tab. 4.3):
//!
//! | FC | Name | Module |
//! |---|---|---|
//! | 0x03 | Read Holding Registers | [`request`] |
//! | 0x07 | Read Exception Status | [`request`] |
//! | 0x10 | Write Multiple Registers | [`request`] |
//! | 0x17 | Read/Write Multiple Registers | [`request`] |
//! | 0x2B / 0x0E | Read Device Identification | [`device_identification`] |
//!
//! Layers, each usable alone:
//! - [`framing`]: splits a TCP byte stream into ADUs by the MBAP length field, in a bounded
//!   buffer; a length field no ADU can have is an error (drop the connection).
//! - [`adu`] / [`mbap`]: the MBAP header and its checks (protocol id, length, size).
//! - [`request`]: parsing and validating a request PDU, with the exception the standard
//!   prescribes for each wrong request (and encoding, for a client).
//! - [`server`]: the [`RegisterMap`] a device implements, [`handle_pdu`] and [`handle_adu`].
//! - [`watchdog`]: the CMMO-ST connection monitoring ("Node Guard / Timeout", §4.3.4).
//! - [`rtu`]: the Modbus RTU CRC-16 for serial transports.
//! - [`rtu_framing`]: RTU frames cut from a serial byte stream by the 3.5-character silence.
//! - [`object_registers`]: an RTU server (FC 03h / 06h / 10h) whose holding registers are a
//!   table mapping them onto a device's objects.
//!
//! Nothing here allocates, panics on wire data, reads a clock or touches a socket.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod adu;
pub mod client;
pub mod device_identification;
pub mod exception;
pub mod framing;
pub mod function_code;
pub mod mbap;
pub mod object_registers;
pub mod request;
pub mod rtu;
pub mod rtu_framing;
pub mod server;
pub mod watchdog;

mod writer;

pub use adu::{Adu, AduError};
pub use device_identification::{ConformityLevel, ReadDeviceIdCode};
pub use exception::{Exception, ExceptionResponse};
pub use framing::{FrameError, Framer};
pub use mbap::{Mbap, MAX_ADU_LEN, MAX_PDU_LEN, MBAP_LEN};
pub use request::{Registers, Request};
pub use server::{handle_adu, handle_pdu, CloseReason, ConnectionEvent, PduError, RegisterMap};
pub use watchdog::Watchdog;
