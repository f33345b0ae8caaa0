//! A complete Modbus TCP ADU: MBAP header + PDU, with the header checks.
//!
//! A request that fails these checks has no trustworthy transaction id or extent, so it
//! cannot be answered with an exception; the Implementation Guide (§4.4.1.2) discards it. A
//! server on a byte stream should drop the connection, since it can no longer tell where the
//! next ADU starts.

use core::fmt;

use crate::mbap::{Mbap, MAX_ADU_LEN, MBAP_LEN, PROTOCOL_ID};

/// Why bytes are not a valid ADU (or a response could not be written).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AduError {
    /// Fewer bytes than MBAP header + function code (8).
    TooShort {
        /// Bytes given.
        len: usize,
    },
    /// More bytes than the longest ADU (260).
    TooLong {
        /// Bytes given.
        len: usize,
    },
    /// The protocol identifier is not 0.
    ProtocolId(u16),
    /// The MBAP length field does not count the bytes that follow it.
    LengthMismatch {
        /// The length field.
        declared: u16,
        /// Bytes actually after the length field.
        actual: usize,
    },
    /// The response buffer cannot hold the response ADU (give it [`MAX_ADU_LEN`] bytes).
    ResponseBufferTooSmall,
}

impl fmt::Display for AduError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AduError::TooShort { len } => {
                write!(f, "ADU of {len} bytes is shorter than MBAP + function code")
            }
            AduError::TooLong { len } => {
                write!(f, "ADU of {len} bytes is longer than {MAX_ADU_LEN}")
            }
            AduError::ProtocolId(id) => write!(f, "protocol identifier {id:04X}h is not 0"),
            AduError::LengthMismatch { declared, actual } => write!(
                f,
                "MBAP length {declared} does not match the {actual} bytes that follow it"
            ),
            AduError::ResponseBufferTooSmall => write!(f, "response buffer too small"),
        }
    }
}

/// A checked ADU borrowed from a byte buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Adu<'a> {
    /// The MBAP header.
    pub header: Mbap,
    /// The PDU: function code and data, at least one byte.
    pub pdu: &'a [u8],
}

impl<'a> Adu<'a> {
    /// Parses one complete ADU, checking in this order: at least MBAP + function code, at
    /// most [`MAX_ADU_LEN`], protocol identifier 0, length field = bytes after it.
    pub fn parse(bytes: &'a [u8]) -> Result<Adu<'a>, AduError> {
        let len = bytes.len();
        if len < MBAP_LEN + 1 {
            return Err(AduError::TooShort { len });
        }
        if len > MAX_ADU_LEN {
            return Err(AduError::TooLong { len });
        }
        let header = Mbap::parse(bytes).ok_or(AduError::TooShort { len })?;
        if header.protocol_id != PROTOCOL_ID {
            return Err(AduError::ProtocolId(header.protocol_id));
        }
        if header.adu_len() != len {
            return Err(AduError::LengthMismatch {
                declared: header.length,
                actual: len.saturating_sub(6),
            });
        }
        let pdu = bytes.get(MBAP_LEN..).ok_or(AduError::TooShort { len })?;
        Ok(Adu { header, pdu })
    }
}
