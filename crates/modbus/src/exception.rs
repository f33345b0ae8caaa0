//! Exception codes and exception responses (MODBUS Application Protocol V1.1b3 §7).
//!
//! An exception response is the request's function code with bit 7 set, followed by one
//! exception code byte: `83 02` answers a 0x03 request with "illegal data address". The
//! CMMO-ST lists codes 0x01…0x04 for every function code (manual Tab. 4.3); the others are
//! here so that a [`RegisterMap`](crate::RegisterMap) for another device can use them.

use core::fmt;

/// A Modbus exception code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Exception {
    /// 0x01: the function code is not supported (or not in this state).
    IllegalFunction = 0x01,
    /// 0x02: the data address (or address + quantity) is not valid for the server.
    IllegalDataAddress = 0x02,
    /// 0x03: a value in the request is not allowed: quantity, byte count, PDU length.
    IllegalDataValue = 0x03,
    /// 0x04: an unrecoverable error while the server performed the action.
    ServerDeviceFailure = 0x04,
    /// 0x05: accepted, a long-running action is in progress.
    Acknowledge = 0x05,
    /// 0x06: the server is busy with a long-running command; retry later.
    ServerDeviceBusy = 0x06,
    /// 0x08: a memory parity error while reading a record file.
    MemoryParityError = 0x08,
    /// 0x0A: a gateway could not allocate a path.
    GatewayPathUnavailable = 0x0A,
    /// 0x0B: no response from the gateway's target device.
    GatewayTargetFailedToRespond = 0x0B,
}

impl Exception {
    /// The exception code byte.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The exception for a code byte, `None` for codes the standard does not define.
    pub const fn from_code(code: u8) -> Option<Exception> {
        Some(match code {
            0x01 => Exception::IllegalFunction,
            0x02 => Exception::IllegalDataAddress,
            0x03 => Exception::IllegalDataValue,
            0x04 => Exception::ServerDeviceFailure,
            0x05 => Exception::Acknowledge,
            0x06 => Exception::ServerDeviceBusy,
            0x08 => Exception::MemoryParityError,
            0x0A => Exception::GatewayPathUnavailable,
            0x0B => Exception::GatewayTargetFailedToRespond,
            _ => return None,
        })
    }
}

impl fmt::Display for Exception {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = match self {
            Exception::IllegalFunction => "illegal function",
            Exception::IllegalDataAddress => "illegal data address",
            Exception::IllegalDataValue => "illegal data value",
            Exception::ServerDeviceFailure => "server device failure",
            Exception::Acknowledge => "acknowledge",
            Exception::ServerDeviceBusy => "server device busy",
            Exception::MemoryParityError => "memory parity error",
            Exception::GatewayPathUnavailable => "gateway path unavailable",
            Exception::GatewayTargetFailedToRespond => "gateway target device failed to respond",
        };
        write!(f, "{text} ({:02X}h)", self.code())
    }
}

/// An exception response PDU: the request's function code and the exception.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ExceptionResponse {
    /// The function code of the request (without bit 7).
    pub function: u8,
    /// Why the request failed.
    pub exception: Exception,
}

impl ExceptionResponse {
    /// Length of an exception response PDU.
    pub const LEN: usize = 2;

    /// An exception response to `function`.
    pub const fn new(function: u8, exception: Exception) -> ExceptionResponse {
        ExceptionResponse {
            function,
            exception,
        }
    }

    /// The two PDU bytes: function code | 0x80, exception code.
    pub const fn to_bytes(self) -> [u8; 2] {
        [self.function | 0x80, self.exception.code()]
    }
}

impl fmt::Display for ExceptionResponse {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "function {:02X}h: {}", self.function, self.exception)
    }
}
