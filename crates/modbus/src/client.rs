//! The client side, for a master and for tests: request ADUs out, response PDUs in.
//!
//! The encoders refuse requests the standard forbids (quantities out of range), so a
//! well-behaved master cannot send them; tests that need wrong requests write the bytes.

use core::fmt;

use crate::device_identification::ReadDeviceIdCode;
use crate::exception::{Exception, ExceptionResponse};
use crate::function_code::{limits::*, *};
use crate::mbap::{Mbap, MAX_PDU_LEN, MBAP_LEN, PROTOCOL_ID};
use crate::request::Registers;
use crate::writer::{Full, Writer};

/// Why a request could not be encoded or a response not decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ClientError {
    /// The output buffer is too small (give it [`MAX_ADU_LEN`](crate::MAX_ADU_LEN)).
    BufferTooSmall,
    /// A quantity outside the standard's limits.
    InvalidQuantity,
    /// The response is malformed or does not answer the function.
    InvalidResponse,
}

impl fmt::Display for ClientError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ClientError::BufferTooSmall => "buffer too small",
            ClientError::InvalidQuantity => "quantity out of range",
            ClientError::InvalidResponse => "malformed response",
        })
    }
}

impl From<Full> for ClientError {
    fn from(_: Full) -> Self {
        ClientError::BufferTooSmall
    }
}

/// Writes an ADU: MBAP header for `transaction_id` / `unit_id`, then the PDU `body` writes.
fn adu(
    out: &mut [u8],
    transaction_id: u16,
    unit_id: u8,
    body: impl FnOnce(&mut Writer<'_>) -> Result<(), Full>,
) -> Result<usize, ClientError> {
    let (head, rest) = out
        .split_at_mut_checked(MBAP_LEN)
        .ok_or(ClientError::BufferTooSmall)?;
    let limit = rest.len().min(MAX_PDU_LEN);
    let mut w = Writer::new(rest.get_mut(..limit).ok_or(ClientError::BufferTooSmall)?);
    body(&mut w)?;
    let mbap = Mbap {
        transaction_id,
        protocol_id: PROTOCOL_ID,
        length: 1 + w.len() as u16,
        unit_id,
    };
    head.copy_from_slice(&mbap.to_bytes());
    Ok(MBAP_LEN + w.len())
}

fn check(quantity: usize, max: u16) -> Result<u16, ClientError> {
    match u16::try_from(quantity) {
        Ok(q) if (1..=max).contains(&q) => Ok(q),
        _ => Err(ClientError::InvalidQuantity),
    }
}

/// 0x03 request ADU; returns its length.
pub fn read_holding_registers(
    out: &mut [u8],
    transaction_id: u16,
    unit_id: u8,
    address: u16,
    quantity: u16,
) -> Result<usize, ClientError> {
    let quantity = check(usize::from(quantity), MAX_READ_REGISTERS)?;
    adu(out, transaction_id, unit_id, |w| {
        w.u8(READ_HOLDING_REGISTERS)?;
        w.u16(address)?;
        w.u16(quantity)
    })
}

/// 0x07 request ADU.
pub fn read_exception_status(
    out: &mut [u8],
    transaction_id: u16,
    unit_id: u8,
) -> Result<usize, ClientError> {
    adu(out, transaction_id, unit_id, |w| {
        w.u8(READ_EXCEPTION_STATUS)
    })
}

/// 0x10 request ADU.
pub fn write_multiple_registers(
    out: &mut [u8],
    transaction_id: u16,
    unit_id: u8,
    address: u16,
    values: &[u16],
) -> Result<usize, ClientError> {
    let quantity = check(values.len(), MAX_WRITE_REGISTERS)?;
    adu(out, transaction_id, unit_id, |w| {
        w.u8(WRITE_MULTIPLE_REGISTERS)?;
        w.u16(address)?;
        w.u16(quantity)?;
        w.u8((quantity * 2) as u8)?;
        values.iter().try_for_each(|v| w.u16(*v))
    })
}

/// 0x17 request ADU.
pub fn read_write_multiple_registers(
    out: &mut [u8],
    transaction_id: u16,
    unit_id: u8,
    read_address: u16,
    read_quantity: u16,
    write_address: u16,
    values: &[u16],
) -> Result<usize, ClientError> {
    let read_quantity = check(usize::from(read_quantity), MAX_READ_WRITE_READ)?;
    let write_quantity = check(values.len(), MAX_READ_WRITE_WRITE)?;
    adu(out, transaction_id, unit_id, |w| {
        w.u8(READ_WRITE_MULTIPLE_REGISTERS)?;
        w.u16(read_address)?;
        w.u16(read_quantity)?;
        w.u16(write_address)?;
        w.u16(write_quantity)?;
        w.u8((write_quantity * 2) as u8)?;
        values.iter().try_for_each(|v| w.u16(*v))
    })
}

/// 0x2B / 0x0E request ADU.
pub fn read_device_identification(
    out: &mut [u8],
    transaction_id: u16,
    unit_id: u8,
    code: ReadDeviceIdCode,
    object_id: u8,
) -> Result<usize, ClientError> {
    adu(out, transaction_id, unit_id, |w| {
        w.bytes(&[
            ENCAPSULATED_INTERFACE_TRANSPORT,
            MEI_READ_DEVICE_IDENTIFICATION,
            code.code(),
            object_id,
        ])
    })
}

/// The identification objects of a 0x2B / 0x0E response: `(id, value)` pairs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeviceObjects<'a> {
    bytes: &'a [u8],
}

impl<'a> Iterator for DeviceObjects<'a> {
    type Item = (u8, &'a [u8]);

    fn next(&mut self) -> Option<(u8, &'a [u8])> {
        let (&id, rest) = self.bytes.split_first()?;
        let (&len, rest) = rest.split_first()?;
        let value = rest.get(..usize::from(len))?;
        self.bytes = rest.get(usize::from(len)..).unwrap_or(&[]);
        Some((id, value))
    }
}

/// A 0x2B / 0x0E response.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeviceIdentification<'a> {
    /// Read device id code, as requested.
    pub code: u8,
    /// Conformity level byte.
    pub conformity_level: u8,
    /// More objects follow (FFh).
    pub more_follows: bool,
    /// The object to ask for next when more follow.
    pub next_object_id: u8,
    /// The objects.
    pub objects: DeviceObjects<'a>,
}

/// A response PDU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Response<'a> {
    /// 0x03 register values.
    ReadHoldingRegisters(Registers<'a>),
    /// 0x07 status byte.
    ReadExceptionStatus(u8),
    /// 0x10 echo of address and quantity.
    WriteMultipleRegisters {
        /// Start address.
        address: u16,
        /// Registers written.
        quantity: u16,
    },
    /// 0x17 register values read.
    ReadWriteMultipleRegisters(Registers<'a>),
    /// 0x2B / 0x0E.
    ReadDeviceIdentification(DeviceIdentification<'a>),
    /// An exception response to any function.
    Exception(ExceptionResponse),
}

impl<'a> Response<'a> {
    /// Decodes a response PDU.
    pub fn parse(pdu: &'a [u8]) -> Result<Response<'a>, ClientError> {
        let bad = ClientError::InvalidResponse;
        let (&function, data) = pdu.split_first().ok_or(bad)?;
        if function & 0x80 != 0 {
            return match data {
                [code] => Ok(Response::Exception(ExceptionResponse::new(
                    function & 0x7F,
                    Exception::from_code(*code).ok_or(bad)?,
                ))),
                _ => Err(bad),
            };
        }
        let registers = |data: &'a [u8]| -> Result<Registers<'a>, ClientError> {
            let (&count, values) = data.split_first().ok_or(bad)?;
            if usize::from(count) != values.len() {
                return Err(bad);
            }
            Registers::new(values).ok_or(bad)
        };
        match function {
            READ_HOLDING_REGISTERS => Ok(Response::ReadHoldingRegisters(registers(data)?)),
            READ_WRITE_MULTIPLE_REGISTERS => {
                Ok(Response::ReadWriteMultipleRegisters(registers(data)?))
            }
            READ_EXCEPTION_STATUS => match data {
                [status] => Ok(Response::ReadExceptionStatus(*status)),
                _ => Err(bad),
            },
            WRITE_MULTIPLE_REGISTERS => match data {
                [a0, a1, q0, q1] => Ok(Response::WriteMultipleRegisters {
                    address: u16::from_be_bytes([*a0, *a1]),
                    quantity: u16::from_be_bytes([*q0, *q1]),
                }),
                _ => Err(bad),
            },
            ENCAPSULATED_INTERFACE_TRANSPORT => match data {
                [MEI_READ_DEVICE_IDENTIFICATION, code, level, more, next, count, objects @ ..] => {
                    let list = DeviceObjects { bytes: objects };
                    if list.count() != usize::from(*count) {
                        return Err(bad);
                    }
                    Ok(Response::ReadDeviceIdentification(DeviceIdentification {
                        code: *code,
                        conformity_level: *level,
                        more_follows: *more == 0xFF,
                        next_object_id: *next,
                        objects: list,
                    }))
                }
                _ => Err(bad),
            },
            _ => Err(bad),
        }
    }
}
