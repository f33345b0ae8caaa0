//! The server side: a device implements [`RegisterMap`]; [`handle_adu`] (Modbus TCP) or
//! [`handle_pdu`] (any transport) turns one request into one response.
//!
//! Every request that parses as an ADU gets a response: the function's answer or an
//! exception response. Only a broken MBAP header (see [`Adu::parse`]) gets none.

use core::fmt;

use crate::adu::{Adu, AduError};
use crate::device_identification::{self, ConformityLevel, ReadDeviceIdCode};
use crate::exception::{Exception, ExceptionResponse};
use crate::function_code::limits::{MAX_READ_REGISTERS, MAX_WRITE_REGISTERS};
use crate::mbap::{MAX_ADU_LEN, MAX_PDU_LEN, MBAP_LEN};
use crate::request::Request;
use crate::writer::Writer;

/// What happened to the Modbus TCP connection, reported to the map by the transport.
///
/// The CMMO-ST has one Modbus connection at a time (manual §4) and monitors it (§4.3.4): a
/// client silent for the configured timeout triggers "Timeout MODBUS TCP/IP", diagnostic 47h
/// "Modbus connection with master control" when Modbus held control authority, else 48h
/// "Modbus connection without master control" (Appendix D: "the Modbus connection to the
/// controller is interrupted"; as a warning it clears when the client reconnects).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ConnectionEvent {
    /// A client connected (and is now the one Modbus connection).
    Opened,
    /// The connection ended.
    Closed(CloseReason),
}

/// Why a connection ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CloseReason {
    /// The client closed it (or reset it).
    Peer,
    /// No request within the watchdog timeout; the server closed it (manual §4: the
    /// connection "is closed only on a controller error, on timeout, or by the remote peer").
    WatchdogExpired,
    /// The client sent bytes that are no Modbus TCP stream (bad MBAP header); the server
    /// closed it.
    ProtocolError,
    /// The transport failed (write timeout, I/O error).
    Transport,
    /// The server was told to close it (shutdown, controller error).
    Server,
}

impl CloseReason {
    /// Whether this is the manual's "Timeout MODBUS TCP/IP" (diagnostic 47h / 48h).
    pub const fn is_timeout(self) -> bool {
        matches!(self, CloseReason::WatchdogExpired)
    }
}

impl fmt::Display for CloseReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            CloseReason::Peer => "closed by the client",
            CloseReason::WatchdogExpired => "watchdog expired (Timeout MODBUS TCP/IP)",
            CloseReason::ProtocolError => "not a Modbus TCP stream",
            CloseReason::Transport => "transport error",
            CloseReason::Server => "closed by the server",
        })
    }
}

/// A device's registers as Modbus sees them. Addresses are the PDU's (0-based); the request
/// has been checked against the standard's quantity limits and the 65536-register address
/// space before a method is called. Return the exception the device gives: 02 for addresses
/// it does not have, 03 for values (or quantities) it does not take, 04 when it fails.
pub trait RegisterMap {
    /// 0x03: fill `out` (1…125 registers, zeroed) from `address` on.
    fn read(&mut self, address: u16, out: &mut [u16]) -> Result<(), Exception>;

    /// 0x10: write `values` (1…123 registers) from `address` on.
    fn write(&mut self, address: u16, values: &[u16]) -> Result<(), Exception>;

    /// 0x17: write, then read (the standard: "the write operation is performed before the
    /// read"). The default calls [`write`](Self::write) then [`read`](Self::read); override
    /// it to make the exchange one step, or to check both ranges before writing.
    fn read_write(
        &mut self,
        read_address: u16,
        out: &mut [u16],
        write_address: u16,
        values: &[u16],
    ) -> Result<(), Exception> {
        self.write(write_address, values)?;
        self.read(read_address, out)
    }

    /// 0x07: the exception status byte. The default answers 01 (not supported).
    fn exception_status(&mut self) -> Result<u8, Exception> {
        Err(Exception::IllegalFunction)
    }

    /// 0x2B / 0x0E: the value of identification object `object`, `None` if there is none.
    /// The default has none, so read device identification answers 02.
    fn device_id(&self, object: u8) -> Option<&[u8]> {
        let _ = object;
        None
    }

    /// 0x2B / 0x0E: the conformity level reported in answer to `requested`. The default is
    /// the standard's: the highest category that has objects, with individual access
    /// ([`ConformityLevel::from_objects`]).
    fn conformity_level(&self, requested: ReadDeviceIdCode) -> ConformityLevel {
        let _ = requested;
        ConformityLevel::from_objects(self)
    }

    /// The transport reports a connection event. The default ignores it.
    fn connection_event(&mut self, event: ConnectionEvent) {
        let _ = event;
    }
}

impl<M: RegisterMap + ?Sized> RegisterMap for &mut M {
    fn read(&mut self, address: u16, out: &mut [u16]) -> Result<(), Exception> {
        (**self).read(address, out)
    }
    fn write(&mut self, address: u16, values: &[u16]) -> Result<(), Exception> {
        (**self).write(address, values)
    }
    fn read_write(
        &mut self,
        read_address: u16,
        out: &mut [u16],
        write_address: u16,
        values: &[u16],
    ) -> Result<(), Exception> {
        (**self).read_write(read_address, out, write_address, values)
    }
    fn exception_status(&mut self) -> Result<u8, Exception> {
        (**self).exception_status()
    }
    fn device_id(&self, object: u8) -> Option<&[u8]> {
        (**self).device_id(object)
    }
    fn conformity_level(&self, requested: ReadDeviceIdCode) -> ConformityLevel {
        (**self).conformity_level(requested)
    }
    fn connection_event(&mut self, event: ConnectionEvent) {
        (**self).connection_event(event)
    }
}

/// Why [`handle_pdu`] wrote no response.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PduError {
    /// The request PDU has no function code.
    Empty,
    /// The response buffer is shorter than [`MAX_PDU_LEN`].
    ResponseBufferTooSmall,
}

impl fmt::Display for PduError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PduError::Empty => "empty PDU",
            PduError::ResponseBufferTooSmall => "response buffer too small",
        })
    }
}

/// Handles one request PDU: writes the response PDU (the answer or an exception response) to
/// `response`, which must hold [`MAX_PDU_LEN`] bytes, and returns its length.
pub fn handle_pdu<M: RegisterMap + ?Sized>(
    request: &[u8],
    map: &mut M,
    response: &mut [u8],
) -> Result<usize, PduError> {
    if request.is_empty() {
        return Err(PduError::Empty);
    }
    let response = response
        .get_mut(..MAX_PDU_LEN)
        .ok_or(PduError::ResponseBufferTooSmall)?;
    let outcome = match Request::parse(request) {
        Ok(req) => execute(req, map, response),
        Err(e) => Err(e),
    };
    match outcome {
        Ok(n) => Ok(n),
        Err(e) => {
            let bytes = e.to_bytes();
            let dst = response
                .get_mut(..bytes.len())
                .ok_or(PduError::ResponseBufferTooSmall)?;
            dst.copy_from_slice(&bytes);
            Ok(bytes.len())
        }
    }
}

/// Handles one complete Modbus TCP request ADU: checks the MBAP header, handles the PDU and
/// writes the response ADU (same transaction id and unit id) to `response`, which must hold
/// [`MAX_ADU_LEN`] bytes. Returns the response length.
///
/// An `Err` means the request has no valid MBAP header and gets no response (see
/// [`Adu::parse`]).
pub fn handle_adu<M: RegisterMap + ?Sized>(
    request: &[u8],
    map: &mut M,
    response: &mut [u8],
) -> Result<usize, AduError> {
    let adu = Adu::parse(request)?;
    if response.len() < MAX_ADU_LEN {
        return Err(AduError::ResponseBufferTooSmall);
    }
    let (head, pdu_out) = response.split_at_mut(MBAP_LEN);
    let pdu_len =
        handle_pdu(adu.pdu, map, pdu_out).map_err(|_| AduError::ResponseBufferTooSmall)?;
    head.copy_from_slice(&adu.header.response(pdu_len).to_bytes());
    Ok(MBAP_LEN + pdu_len)
}

fn execute<M: RegisterMap + ?Sized>(
    req: Request<'_>,
    map: &mut M,
    out: &mut [u8],
) -> Result<usize, ExceptionResponse> {
    let function = req.function();
    let fail = |e| ExceptionResponse::new(function, e);
    let full = |_| fail(Exception::ServerDeviceFailure);
    match req {
        Request::ReadHoldingRegisters { address, quantity } => {
            let mut regs = [0u16; MAX_READ_REGISTERS as usize];
            let regs = regs
                .get_mut(..usize::from(quantity))
                .ok_or(fail(Exception::IllegalDataValue))?;
            map.read(address, regs).map_err(fail)?;
            write_registers(out, function, regs).map_err(full)
        }
        Request::ReadExceptionStatus => {
            let status = map.exception_status().map_err(fail)?;
            let mut w = Writer::new(out);
            w.u8(function).map_err(full)?;
            w.u8(status).map_err(full)?;
            Ok(w.len())
        }
        Request::WriteMultipleRegisters { address, values } => {
            let mut regs = [0u16; MAX_WRITE_REGISTERS as usize];
            let n = values.decode_into(&mut regs);
            let regs = regs.get(..n).ok_or(fail(Exception::IllegalDataValue))?;
            map.write(address, regs).map_err(fail)?;
            let mut w = Writer::new(out);
            w.u8(function).map_err(full)?;
            w.u16(address).map_err(full)?;
            w.u16(n as u16).map_err(full)?;
            Ok(w.len())
        }
        Request::ReadWriteMultipleRegisters {
            read_address,
            read_quantity,
            write_address,
            values,
        } => {
            let mut written = [0u16; MAX_WRITE_REGISTERS as usize];
            let n = values.decode_into(&mut written);
            let written = written.get(..n).ok_or(fail(Exception::IllegalDataValue))?;
            let mut regs = [0u16; MAX_READ_REGISTERS as usize];
            let regs = regs
                .get_mut(..usize::from(read_quantity))
                .ok_or(fail(Exception::IllegalDataValue))?;
            map.read_write(read_address, regs, write_address, written)
                .map_err(fail)?;
            write_registers(out, function, regs).map_err(full)
        }
        Request::ReadDeviceIdentification { code, object_id } => {
            device_identification::respond(code, object_id, map, out)
        }
    }
}

fn write_registers(
    out: &mut [u8],
    function: u8,
    regs: &[u16],
) -> Result<usize, crate::writer::Full> {
    let mut w = Writer::new(out);
    w.u8(function)?;
    w.u8((regs.len() * 2) as u8)?;
    for r in regs {
        w.u16(*r)?;
    }
    Ok(w.len())
}
