//! The Enhanced Festo Parameter Channel (EFPC), CMMO-ST manual App. C: the 8 bytes that follow
//! the FHPP Standard telegram (I/O bytes 9…16) when the profile is "FHPP Standard + FPC".
//!
//! This module is the wire codec of both directions, for the drive and for a master (the
//! drive's state machine is [`server`]):
//! - [`Request`] (PLC → drive, FPCC first): [`Request::decode`] on the drive,
//!   [`Request::encode`] on a master;
//! - [`Response`] (drive → PLC, FPCS first): [`Response::encode`] on the drive,
//!   [`Response::decode`] on a master.
//!
//! Byte 1 (FPCC / FPCS): bits 7…4 the transfer mode (Tab. C.3: `0001` parameter, `0100`
//! file), bits 3…0 the request ID (Tab. C.4) or response ID (Tab. C.5).
//!
//! **Parameter mode** (Tab. C.6): byte 2 subindex, bytes 3–4 PNU, bytes 5–8 PWE (value or,
//! with response ID 7, the Tab. C.7 error code).
//! *Byte order of PNU and PWE: big-endian (most significant byte first).* The manual gives no
//! fixed order for them; C.2.1 says words and double words follow the bus master's convention
//! ("Intel/Motorola") and names Modbus as "big endian" (also §4.3.2: "Byte order always big
//! endian"). The manual's own example (English edition Fig. C.1: write PNU 440:2 = 4660 →
//! PNU bytes `01 B8`, PWE `00 00 12 34`) and a frame derived from its tables in the manual's
//! extract kept beside the project (`16 01 04 11` = PNU 1041) print MSB first, and IO-Link is
//! big-endian as well. So both fields are big-endian here.
//!
//! **File mode** (Tab. C.8/C.9): byte 2 the packet ID (3 control/status bits, 5-bit sequence
//! number), bytes 3–8 six bytes of user data. *User data is little-endian* (C.4.3: "the LSB of
//! the user data is in byte 3"), even on Modbus: the start packet's file size is a `u32` LE in
//! bytes 3–6 (the EMCA manual's A.4.4 reads it from bytes 3–4; a `u32` LE agrees for every
//! size below 64 KiB), and an error packet's code is byte 3.

use core::fmt;

pub mod server;

pub use server::{execute, Context, ParameterChannel};

/// Bits 7…4 of FPCC/FPCS: parameter mode, transfer of one PNU (Tab. C.3).
pub const MODE_PARAMETER: u8 = 0x1;
/// Bits 7…4 of FPCC/FPCS: file mode, transfer of the parameter file (Tab. C.3).
pub const MODE_FILE: u8 = 0x4;

/// Request IDs, FPCC bits 3…0 (Tab. C.4).
pub mod req_id {
    /// No task ("zero request", C.3.2).
    pub const NO_TASK: u8 = 0;
    /// Upload the parameter file (drive → PLC), file mode.
    pub const UPLOAD: u8 = 4;
    /// Download the parameter file (PLC → drive), file mode.
    pub const DOWNLOAD: u8 = 5;
    /// Request a parameter value (array), parameter mode.
    pub const READ: u8 = 6;
    /// Change a parameter value (double-word array), parameter mode.
    pub const WRITE: u8 = 8;
}

/// Response IDs, FPCS bits 3…0 (Tab. C.5).
pub mod res_id {
    /// No response.
    pub const NONE: u8 = 0;
    /// Parameter-file transfer active (file mode).
    pub const FILE_ACTIVE: u8 = 3;
    /// Parameter transferred (array, double word), parameter mode.
    pub const VALUE: u8 = 5;
    /// Task cannot be executed; error number in the user data (both modes).
    pub const ERROR: u8 = 7;
}

/// FPCC / FPCS byte from mode and ID.
pub const fn control_byte(mode: u8, id: u8) -> u8 {
    (mode << 4) | (id & 0x0F)
}

/// Error codes of a parameter transfer, returned in the PWE with response ID 7 (Tab. C.7).
/// The file transfer's type-1 errors (Tab. C.10) are two of them: 0x11 and 0x65.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum ErrorCode {
    /// 0: illegal PNU (no such parameter).
    IllegalPnu = 0x00,
    /// 1: the parameter value cannot be changed (read-only).
    CannotChange = 0x01,
    /// 2: upper or lower limit exceeded.
    LimitExceeded = 0x02,
    /// 3: wrong subindex.
    WrongSubindex = 0x03,
    /// 11: no operator authority (no control right).
    NoAuthority = 0x0B,
    /// 17: the task cannot be executed in the current operating state.
    NotInThisState = 0x11,
    /// 101: Festo: ReqID not supported.
    RequestNotSupported = 0x65,
    /// 102: Festo: the parameter is write-only.
    WriteOnly = 0x66,
}

impl ErrorCode {
    /// Every code, in table order (Tab. C.7).
    pub const ALL: [ErrorCode; 8] = [
        ErrorCode::IllegalPnu,
        ErrorCode::CannotChange,
        ErrorCode::LimitExceeded,
        ErrorCode::WrongSubindex,
        ErrorCode::NoAuthority,
        ErrorCode::NotInThisState,
        ErrorCode::RequestNotSupported,
        ErrorCode::WriteOnly,
    ];

    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The code for a number, `None` for one Tab. C.7 does not list.
    pub fn from_code(code: u32) -> Option<ErrorCode> {
        ErrorCode::ALL
            .into_iter()
            .find(|e| u32::from(e.code()) == code)
    }

    /// The manual's text (Tab. C.7).
    pub const fn text(self) -> &'static str {
        match self {
            ErrorCode::IllegalPnu => "illegal PNU",
            ErrorCode::CannotChange => "parameter value cannot be changed",
            ErrorCode::LimitExceeded => "upper or lower limit exceeded",
            ErrorCode::WrongSubindex => "wrong subindex",
            ErrorCode::NoAuthority => "no operator authority",
            ErrorCode::NotInThisState => "task cannot be executed in the current operating state",
            ErrorCode::RequestNotSupported => "ReqID not supported",
            ErrorCode::WriteOnly => "parameter is write-only",
        }
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (0x{:02X})", self.text(), self.code())
    }
}

/// A parameter-mode job (Tab. C.4 request IDs 6 and 8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ParameterRequest {
    /// ReqID 6: request the value of PNU `pnu`, subindex `subindex`.
    Read { pnu: u16, subindex: u8 },
    /// ReqID 8: change the value; `value` is the 32-bit PWE as sent (sign-extended for
    /// signed types).
    Write { pnu: u16, subindex: u8, value: u32 },
}

impl ParameterRequest {
    pub const fn pnu(&self) -> u16 {
        match *self {
            ParameterRequest::Read { pnu, .. } | ParameterRequest::Write { pnu, .. } => pnu,
        }
    }

    pub const fn subindex(&self) -> u8 {
        match *self {
            ParameterRequest::Read { subindex, .. } | ParameterRequest::Write { subindex, .. } => {
                subindex
            }
        }
    }

    /// The 8 FPC output bytes of this job.
    pub fn encode(&self) -> [u8; 8] {
        Request::Parameter(*self).encode()
    }
}

/// The drive's answer to a parameter-mode job (Tab. C.5 response IDs 5 and 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ParameterResponse {
    /// ResID 5: parameter transferred; `value` is the PWE (for a write: the value written).
    Value { pnu: u16, subindex: u8, value: u32 },
    /// ResID 7: the task cannot be executed, with the Tab. C.7 error code in the PWE.
    Error {
        pnu: u16,
        subindex: u8,
        code: ErrorCode,
    },
}

impl ParameterResponse {
    /// The 8 FPC input bytes.
    pub fn encode(&self) -> [u8; 8] {
        Response::Parameter(*self).encode()
    }

    /// A parameter-mode response from the 8 FPC input bytes; a "no response" or a file-mode
    /// response is [`DecodeError::NotParameterResponse`].
    pub fn decode(bytes: &[u8; 8]) -> Result<ParameterResponse, DecodeError> {
        match Response::decode(bytes)? {
            Response::Parameter(p) => Ok(p),
            _ => Err(DecodeError::NotParameterResponse(bytes[0])),
        }
    }
}

/// Control/status bits 7…5 of the packet ID (Tab. C.9).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum PacketKind {
    /// `000`: data transfer active; a user data packet.
    Data = 0b000,
    /// `001`: start data transfer; user data = file size in bytes.
    Start = 0b001,
    /// `010`: stop data transfer; no data.
    Stop = 0b010,
    /// `011`: error; user data byte 3 = error code (Tab. C.11) from the drive, none from the
    /// PLC.
    Error = 0b011,
}

impl PacketKind {
    const fn from_bits(bits: u8) -> Option<PacketKind> {
        match bits {
            0b000 => Some(PacketKind::Data),
            0b001 => Some(PacketKind::Start),
            0b010 => Some(PacketKind::Stop),
            0b011 => Some(PacketKind::Error),
            _ => None,
        }
    }
}

/// Largest sequence number; the next after 31 is 0 (C.4.5).
pub const SEQUENCE_MAX: u8 = 31;

/// The sequence number after `seq` (1…31, then 0; C.4.5).
pub const fn next_sequence(seq: u8) -> u8 {
    if seq >= SEQUENCE_MAX {
        0
    } else {
        seq + 1
    }
}

/// One file-mode packet: packet ID (kind + sequence number) and six bytes of user data
/// (Tab. C.8, little-endian, zero-padded).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Packet {
    pub kind: PacketKind,
    /// 5-bit sequence number (0…31).
    pub sequence: u8,
    pub data: [u8; 6],
}

impl Packet {
    /// A packet with no user data.
    pub const fn empty(kind: PacketKind, sequence: u8) -> Packet {
        Packet {
            kind,
            sequence: sequence & 0x1F,
            data: [0; 6],
        }
    }

    /// The start packet (sequence 0) announcing `size` bytes (u32 LE in bytes 3–6).
    pub fn start(size: u32) -> Packet {
        let mut data = [0u8; 6];
        data[..4].copy_from_slice(&size.to_le_bytes());
        Packet {
            kind: PacketKind::Start,
            sequence: 0,
            data,
        }
    }

    /// A data packet.
    pub const fn data(sequence: u8, data: [u8; 6]) -> Packet {
        Packet {
            kind: PacketKind::Data,
            sequence: sequence & 0x1F,
            data,
        }
    }

    /// An error packet with `code` in byte 3 (Tab. C.11; the PLC sends 0, "no error number").
    pub const fn error(sequence: u8, code: u8) -> Packet {
        Packet {
            kind: PacketKind::Error,
            sequence: sequence & 0x1F,
            data: [code, 0, 0, 0, 0, 0],
        }
    }

    /// Byte 2: control/status bits and sequence number.
    pub const fn id(&self) -> u8 {
        ((self.kind as u8) << 5) | (self.sequence & 0x1F)
    }

    /// The packet for a packet-ID byte and its user data; `None` for the reserved control
    /// bits `1xx`.
    pub const fn from_id(id: u8, data: [u8; 6]) -> Option<Packet> {
        match PacketKind::from_bits(id >> 5) {
            Some(kind) => Some(Packet {
                kind,
                sequence: id & 0x1F,
                data,
            }),
            None => None,
        }
    }

    /// The file size of a start packet (bytes 3–6, LE).
    pub const fn size(&self) -> u32 {
        u32::from_le_bytes([self.data[0], self.data[1], self.data[2], self.data[3]])
    }

    /// The error code of an error packet (byte 3).
    pub const fn error_code(&self) -> u8 {
        self.data[0]
    }
}

/// Which way a file job moves the parameter file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FileDirection {
    /// ReqID 4: the drive sends its file (the values in the permanent memory).
    Upload,
    /// ReqID 5: the PLC sends a file to the drive.
    Download,
}

impl FileDirection {
    const fn req_id(self) -> u8 {
        match self {
            FileDirection::Upload => req_id::UPLOAD,
            FileDirection::Download => req_id::DOWNLOAD,
        }
    }
}

/// Type-2 errors of a file transfer, in the packet ID `011xxxxx` with the code in byte 3
/// (Tab. C.11), and whether they abort the transfer (Tab. C.12).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum FileError {
    /// 0: error message sent by the PLC.
    FromPlc = 0x00,
    /// 1: wrong packet order (sequence number).
    Sequence = 0x01,
    /// 2: timeout between two packets.
    Timeout = 0x02,
    /// 3: invalid telegram format.
    Format = 0x03,
    /// 4: wrong command order, e.g. a restart without a stop in between.
    CommandOrder = 0x04,
    /// 5: read error (invalid file length or wrong transfer state).
    Read = 0x05,
    /// 6: error writing the parameter file.
    Write = 0x06,
    /// 7: amount of data received or sent differs from the expected one.
    Amount = 0x07,
    /// 8: parameter-file access error, e.g. no control authority.
    Access = 0x08,
    /// 9: parameter-file access timeout, e.g. an error still needs acknowledging.
    AccessTimeout = 0x09,
}

impl FileError {
    /// Every code, in table order (Tab. C.11).
    pub const ALL: [FileError; 10] = [
        FileError::FromPlc,
        FileError::Sequence,
        FileError::Timeout,
        FileError::Format,
        FileError::CommandOrder,
        FileError::Read,
        FileError::Write,
        FileError::Amount,
        FileError::Access,
        FileError::AccessTimeout,
    ];

    pub const fn code(self) -> u8 {
        self as u8
    }

    pub fn from_code(code: u8) -> Option<FileError> {
        FileError::ALL.into_iter().find(|e| e.code() == code)
    }

    /// Whether the error ends the transfer and discards what was received (Tab. C.12).
    /// Only 0x01 and 0x03 let it continue. 0x04 is missing from Tab. C.12; decided: it aborts
    /// (a start without a stop in between cannot be resumed).
    pub const fn aborts(self) -> bool {
        !matches!(self, FileError::Sequence | FileError::Format)
    }

    pub const fn text(self) -> &'static str {
        match self {
            FileError::FromPlc => "error message sent by the PLC",
            FileError::Sequence => "wrong packet order",
            FileError::Timeout => "timeout between two packets",
            FileError::Format => "invalid telegram format",
            FileError::CommandOrder => "wrong command order",
            FileError::Read => "read error",
            FileError::Write => "error writing the parameter file",
            FileError::Amount => "amount of data differs from the expected one",
            FileError::Access => "parameter-file access error",
            FileError::AccessTimeout => "parameter-file access timeout",
        }
    }
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (0x{:02X})", self.text(), self.code())
    }
}

/// One FPC output telegram (PLC → drive).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Request {
    /// ReqID 0, "no task" (the zero request). `mode` is FPCC bits 7…4 as sent (1, 4 or 0:
    /// the manual does not say which mode accompanies ID 0, so any is accepted).
    NoTask { mode: u8 },
    /// Parameter mode, ReqID 6 or 8.
    Parameter(ParameterRequest),
    /// File mode, ReqID 4 or 5, with one packet.
    File {
        direction: FileDirection,
        packet: Packet,
    },
}

/// Why 8 FPC bytes are not a request or response this channel knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DecodeError {
    /// FPCC/FPCS bits 7…4 name a reserved transfer mode (Tab. C.3).
    ReservedMode { mode: u8, id: u8 },
    /// The request/response ID is reserved or not allowed in this mode (Tab. C.4/C.5); the
    /// drive answers error 0x65 "ReqID not supported".
    UnsupportedId { mode: u8, id: u8 },
    /// A file packet with the reserved control bits `1xx` (Tab. C.9).
    ReservedPacketId(u8),
    /// A parameter error response whose PWE is no Tab. C.7 code.
    UnknownErrorCode(u32),
    /// FPCS is valid but not a parameter-mode response ([`ParameterResponse::decode`]).
    NotParameterResponse(u8),
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::ReservedMode { mode, .. } => {
                write!(f, "reserved transfer mode {mode:04b}")
            }
            DecodeError::UnsupportedId { mode, id } => {
                write!(f, "ID {id} not supported in mode {mode:04b}")
            }
            DecodeError::ReservedPacketId(id) => write!(f, "reserved packet ID {id:08b}"),
            DecodeError::UnknownErrorCode(c) => write!(f, "unknown FPC error code 0x{c:X}"),
            DecodeError::NotParameterResponse(b) => {
                write!(f, "FPCS 0x{b:02X} is not a parameter response")
            }
        }
    }
}

fn pnu_of(b: &[u8; 8]) -> u16 {
    u16::from_be_bytes([b[2], b[3]])
}

fn pwe_of(b: &[u8; 8]) -> u32 {
    u32::from_be_bytes([b[4], b[5], b[6], b[7]])
}

fn user_data(b: &[u8; 8]) -> [u8; 6] {
    [b[2], b[3], b[4], b[5], b[6], b[7]]
}

fn parameter_bytes(control: u8, subindex: u8, pnu: u16, pwe: u32) -> [u8; 8] {
    let p = pnu.to_be_bytes();
    let v = pwe.to_be_bytes();
    [control, subindex, p[0], p[1], v[0], v[1], v[2], v[3]]
}

fn file_bytes(control: u8, packet_id: u8, data: [u8; 6]) -> [u8; 8] {
    [
        control, packet_id, data[0], data[1], data[2], data[3], data[4], data[5],
    ]
}

impl Request {
    /// The 8 FPC output bytes (what a master writes to I/O bytes 9…16).
    pub fn encode(&self) -> [u8; 8] {
        match *self {
            Request::NoTask { mode } => [control_byte(mode, req_id::NO_TASK), 0, 0, 0, 0, 0, 0, 0],
            Request::Parameter(ParameterRequest::Read { pnu, subindex }) => {
                parameter_bytes(control_byte(MODE_PARAMETER, req_id::READ), subindex, pnu, 0)
            }
            Request::Parameter(ParameterRequest::Write {
                pnu,
                subindex,
                value,
            }) => parameter_bytes(
                control_byte(MODE_PARAMETER, req_id::WRITE),
                subindex,
                pnu,
                value,
            ),
            Request::File { direction, packet } => file_bytes(
                control_byte(MODE_FILE, direction.req_id()),
                packet.id(),
                packet.data,
            ),
        }
    }

    /// The request in 8 FPC output bytes (what the drive receives).
    pub fn decode(b: &[u8; 8]) -> Result<Request, DecodeError> {
        let mode = b[0] >> 4;
        let id = b[0] & 0x0F;
        if id == req_id::NO_TASK && matches!(mode, 0 | MODE_PARAMETER | MODE_FILE) {
            return Ok(Request::NoTask { mode });
        }
        match (mode, id) {
            (MODE_PARAMETER, req_id::READ) => Ok(Request::Parameter(ParameterRequest::Read {
                pnu: pnu_of(b),
                subindex: b[1],
            })),
            (MODE_PARAMETER, req_id::WRITE) => Ok(Request::Parameter(ParameterRequest::Write {
                pnu: pnu_of(b),
                subindex: b[1],
                value: pwe_of(b),
            })),
            (MODE_FILE, req_id::UPLOAD | req_id::DOWNLOAD) => {
                let direction = if id == req_id::UPLOAD {
                    FileDirection::Upload
                } else {
                    FileDirection::Download
                };
                let packet = Packet::from_id(b[1], user_data(b))
                    .ok_or(DecodeError::ReservedPacketId(b[1]))?;
                Ok(Request::File { direction, packet })
            }
            (MODE_PARAMETER | MODE_FILE, _) => Err(DecodeError::UnsupportedId { mode, id }),
            _ => Err(DecodeError::ReservedMode { mode, id }),
        }
    }
}

/// The drive's answer in a file-mode job.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FileResponse {
    /// ResID 3, "parameter-file transfer active", with the acknowledged packet: the same
    /// packet ID as the PLC's (the handshake, C.4.5); an upload's data and start packets
    /// carry data and size, a type-2 error is a packet of kind [`PacketKind::Error`].
    Active(Packet),
    /// ResID 7, type-1 error (Tab. C.10) with the code in byte 3; byte 2 echoes the packet ID.
    Rejected { packet_id: u8, code: ErrorCode },
}

/// One FPC input telegram (drive → PLC).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Response {
    /// ResID 0 "no response"; `mode` is FPCS bits 7…4 (the drive echoes the mode of the "no
    /// task" it answers).
    NoResponse { mode: u8 },
    /// Parameter mode, ResID 5 or 7.
    Parameter(ParameterResponse),
    /// File mode, ResID 3 or 7.
    File(FileResponse),
    /// ResID 7 in a reserved mode: the drive could not decode the request (error 0x65, or
    /// another code) and echoes the mode it got. `mode` is FPCS bits 7…4.
    Unsupported { mode: u8, code: ErrorCode },
}

impl Response {
    /// The 8 FPC input bytes (what the drive puts in I/O bytes 9…16).
    pub fn encode(&self) -> [u8; 8] {
        match *self {
            Response::NoResponse { mode } => {
                [control_byte(mode, res_id::NONE), 0, 0, 0, 0, 0, 0, 0]
            }
            Response::Parameter(ParameterResponse::Value {
                pnu,
                subindex,
                value,
            }) => parameter_bytes(
                control_byte(MODE_PARAMETER, res_id::VALUE),
                subindex,
                pnu,
                value,
            ),
            Response::Parameter(ParameterResponse::Error {
                pnu,
                subindex,
                code,
            }) => parameter_bytes(
                control_byte(MODE_PARAMETER, res_id::ERROR),
                subindex,
                pnu,
                u32::from(code.code()),
            ),
            Response::File(FileResponse::Active(p)) => {
                file_bytes(control_byte(MODE_FILE, res_id::FILE_ACTIVE), p.id(), p.data)
            }
            Response::File(FileResponse::Rejected { packet_id, code }) => file_bytes(
                control_byte(MODE_FILE, res_id::ERROR),
                packet_id,
                [code.code(), 0, 0, 0, 0, 0],
            ),
            Response::Unsupported { mode, code } => [
                control_byte(mode, res_id::ERROR),
                0,
                0,
                0,
                0,
                0,
                0,
                code.code(),
            ],
        }
    }

    /// The response in 8 FPC input bytes (what a master reads).
    pub fn decode(b: &[u8; 8]) -> Result<Response, DecodeError> {
        let mode = b[0] >> 4;
        let id = b[0] & 0x0F;
        if id == res_id::NONE {
            return Ok(Response::NoResponse { mode });
        }
        match (mode, id) {
            (MODE_PARAMETER, res_id::VALUE) => Ok(Response::Parameter(ParameterResponse::Value {
                pnu: pnu_of(b),
                subindex: b[1],
                value: pwe_of(b),
            })),
            (MODE_PARAMETER, res_id::ERROR) => {
                let raw = pwe_of(b);
                let code = ErrorCode::from_code(raw).ok_or(DecodeError::UnknownErrorCode(raw))?;
                Ok(Response::Parameter(ParameterResponse::Error {
                    pnu: pnu_of(b),
                    subindex: b[1],
                    code,
                }))
            }
            (MODE_FILE, res_id::FILE_ACTIVE) => {
                let packet = Packet::from_id(b[1], user_data(b))
                    .ok_or(DecodeError::ReservedPacketId(b[1]))?;
                Ok(Response::File(FileResponse::Active(packet)))
            }
            (MODE_FILE, res_id::ERROR) => {
                let code = ErrorCode::from_code(u32::from(b[2]))
                    .ok_or(DecodeError::UnknownErrorCode(u32::from(b[2])))?;
                Ok(Response::File(FileResponse::Rejected {
                    packet_id: b[1],
                    code,
                }))
            }
            (MODE_PARAMETER | MODE_FILE, _) => Err(DecodeError::UnsupportedId { mode, id }),
            (_, res_id::ERROR) => {
                let code = ErrorCode::from_code(u32::from(b[7]))
                    .ok_or(DecodeError::UnknownErrorCode(u32::from(b[7])))?;
                Ok(Response::Unsupported { mode, code })
            }
            _ => Err(DecodeError::ReservedMode { mode, id }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manual_example_write_pnu_440_2() {
        // English manual Fig. C.1: write PNU 440:2 = 4660, answered with FPCS 0001 0101.
        let req = ParameterRequest::Write {
            pnu: 440,
            subindex: 2,
            value: 4660,
        };
        assert_eq!(
            req.encode(),
            [0x18, 0x02, 0x01, 0xB8, 0x00, 0x00, 0x12, 0x34]
        );
        let res = ParameterResponse::Value {
            pnu: 440,
            subindex: 2,
            value: 4660,
        };
        assert_eq!(
            res.encode(),
            [0x15, 0x02, 0x01, 0xB8, 0x00, 0x00, 0x12, 0x34]
        );
        assert_eq!(ParameterResponse::decode(&res.encode()), Ok(res));
    }
}
