//! Request PDUs: parsing with the checks of MODBUS Application Protocol V1.1b3 §6.
//!
//! Each function's state diagram in the standard checks, in this order:
//! 1. the function code is supported, else exception 01 (illegal function);
//! 2. the quantities and byte count are in range, else 03 (illegal data value);
//! 3. start address + quantity stays within the 65536 registers, else 02 (illegal data
//!    address);
//! 4. the server performs the request; it answers 02, 03 or 04 when that fails (this is the
//!    [`RegisterMap`](crate::RegisterMap)'s part).
//!
//! A PDU whose length does not fit its function code (missing or extra bytes, a byte count
//! that disagrees with the data) is a wrong value: 03. The standard does not name that case;
//! 03 is what its byte-count rule gives for the one case it does name.

use crate::device_identification::ReadDeviceIdCode;
use crate::exception::{Exception, ExceptionResponse};
use crate::function_code::{limits::*, *};

/// Register values as they are on the wire: big-endian, two bytes each.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Registers<'a>(&'a [u8]);

impl<'a> Registers<'a> {
    /// Wraps wire bytes; `None` when the length is odd.
    pub fn new(bytes: &'a [u8]) -> Option<Registers<'a>> {
        if bytes.len() & 1 == 0 {
            Some(Registers(bytes))
        } else {
            None
        }
    }

    /// Number of registers.
    pub fn len(&self) -> usize {
        self.0.len() / 2
    }

    /// No registers.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Register `i`, `None` past the end.
    pub fn get(&self, i: usize) -> Option<u16> {
        let at = i.checked_mul(2)?;
        match self.0.get(at..at.checked_add(2)?) {
            Some([hi, lo]) => Some(u16::from_be_bytes([*hi, *lo])),
            _ => None,
        }
    }

    /// The register values in order.
    pub fn iter(&self) -> impl Iterator<Item = u16> + 'a {
        self.0.chunks_exact(2).map(|c| match c {
            [hi, lo] => u16::from_be_bytes([*hi, *lo]),
            _ => 0,
        })
    }

    /// The wire bytes.
    pub fn as_bytes(&self) -> &'a [u8] {
        self.0
    }

    /// Decodes into `out`; returns the number of registers written (the shorter of both).
    pub fn decode_into(&self, out: &mut [u16]) -> usize {
        let mut n = 0;
        for (dst, v) in out.iter_mut().zip(self.iter()) {
            *dst = v;
            n += 1;
        }
        n
    }
}

/// A parsed and range-checked request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request<'a> {
    /// 0x03: read `quantity` registers from `address`.
    ReadHoldingRegisters {
        /// Start address.
        address: u16,
        /// 1…125.
        quantity: u16,
    },
    /// 0x07: read the one-byte exception status.
    ReadExceptionStatus,
    /// 0x10: write `values` from `address`.
    WriteMultipleRegisters {
        /// Start address.
        address: u16,
        /// 1…123 registers.
        values: Registers<'a>,
    },
    /// 0x17: write `values` at `write_address`, then read `read_quantity` registers from
    /// `read_address`.
    ReadWriteMultipleRegisters {
        /// Start address of the read.
        read_address: u16,
        /// 1…125.
        read_quantity: u16,
        /// Start address of the write.
        write_address: u16,
        /// 1…121 registers.
        values: Registers<'a>,
    },
    /// 0x2B / 0x0E: read device identification.
    ReadDeviceIdentification {
        /// Which objects and how (stream or individual access).
        code: ReadDeviceIdCode,
        /// First object (stream access) or the object (individual access).
        object_id: u8,
    },
}

fn be16(data: &[u8], at: usize) -> Option<u16> {
    match data.get(at..at.checked_add(2)?) {
        Some([hi, lo]) => Some(u16::from_be_bytes([*hi, *lo])),
        _ => None,
    }
}

/// Start address + quantity must not pass the last register, 0xFFFF.
fn in_address_space(address: u16, quantity: u16) -> bool {
    u32::from(address) + u32::from(quantity) <= 0x1_0000
}

impl<'a> Request<'a> {
    /// Parses a request PDU (function code + data) and checks it, or gives the exception
    /// response the standard prescribes. An empty PDU is answered as illegal function 00h.
    pub fn parse(pdu: &'a [u8]) -> Result<Request<'a>, ExceptionResponse> {
        let Some((&function, data)) = pdu.split_first() else {
            return Err(ExceptionResponse::new(0, Exception::IllegalFunction));
        };
        let fail = |e| ExceptionResponse::new(function, e);
        let value = fail(Exception::IllegalDataValue);
        let address = fail(Exception::IllegalDataAddress);
        match function {
            READ_HOLDING_REGISTERS => {
                if data.len() != 4 {
                    return Err(value);
                }
                let start = be16(data, 0).ok_or(value)?;
                let quantity = be16(data, 2).ok_or(value)?;
                if !(1..=MAX_READ_REGISTERS).contains(&quantity) {
                    return Err(value);
                }
                if !in_address_space(start, quantity) {
                    return Err(address);
                }
                Ok(Request::ReadHoldingRegisters {
                    address: start,
                    quantity,
                })
            }
            READ_EXCEPTION_STATUS => {
                if !data.is_empty() {
                    return Err(value);
                }
                Ok(Request::ReadExceptionStatus)
            }
            WRITE_MULTIPLE_REGISTERS => {
                let start = be16(data, 0).ok_or(value)?;
                let quantity = be16(data, 2).ok_or(value)?;
                let byte_count = data.get(4).copied().ok_or(value)?;
                if !(1..=MAX_WRITE_REGISTERS).contains(&quantity)
                    || u32::from(byte_count) != u32::from(quantity) * 2
                {
                    return Err(value);
                }
                let bytes = data.get(5..).ok_or(value)?;
                if bytes.len() != usize::from(byte_count) {
                    return Err(value);
                }
                if !in_address_space(start, quantity) {
                    return Err(address);
                }
                Ok(Request::WriteMultipleRegisters {
                    address: start,
                    values: Registers::new(bytes).ok_or(value)?,
                })
            }
            READ_WRITE_MULTIPLE_REGISTERS => {
                let read_start = be16(data, 0).ok_or(value)?;
                let read_quantity = be16(data, 2).ok_or(value)?;
                let write_start = be16(data, 4).ok_or(value)?;
                let write_quantity = be16(data, 6).ok_or(value)?;
                let byte_count = data.get(8).copied().ok_or(value)?;
                if !(1..=MAX_READ_WRITE_READ).contains(&read_quantity)
                    || !(1..=MAX_READ_WRITE_WRITE).contains(&write_quantity)
                    || u32::from(byte_count) != u32::from(write_quantity) * 2
                {
                    return Err(value);
                }
                let bytes = data.get(9..).ok_or(value)?;
                if bytes.len() != usize::from(byte_count) {
                    return Err(value);
                }
                if !in_address_space(read_start, read_quantity)
                    || !in_address_space(write_start, write_quantity)
                {
                    return Err(address);
                }
                Ok(Request::ReadWriteMultipleRegisters {
                    read_address: read_start,
                    read_quantity,
                    write_address: write_start,
                    values: Registers::new(bytes).ok_or(value)?,
                })
            }
            ENCAPSULATED_INTERFACE_TRANSPORT => {
                let Some((&mei, rest)) = data.split_first() else {
                    return Err(value);
                };
                if mei != MEI_READ_DEVICE_IDENTIFICATION {
                    // Only MEI 0x0E is implemented (0x0D, CANopen general reference, is not).
                    return Err(fail(Exception::IllegalFunction));
                }
                match rest {
                    [code, object_id] => Ok(Request::ReadDeviceIdentification {
                        code: ReadDeviceIdCode::from_code(*code).ok_or(value)?,
                        object_id: *object_id,
                    }),
                    _ => Err(value),
                }
            }
            _ => Err(fail(Exception::IllegalFunction)),
        }
    }

    /// The function code.
    pub fn function(&self) -> u8 {
        match self {
            Request::ReadHoldingRegisters { .. } => READ_HOLDING_REGISTERS,
            Request::ReadExceptionStatus => READ_EXCEPTION_STATUS,
            Request::WriteMultipleRegisters { .. } => WRITE_MULTIPLE_REGISTERS,
            Request::ReadWriteMultipleRegisters { .. } => READ_WRITE_MULTIPLE_REGISTERS,
            Request::ReadDeviceIdentification { .. } => ENCAPSULATED_INTERFACE_TRANSPORT,
        }
    }
}
