//! The drive's side of the EFPC: one exchange per FHPP cycle. [`ParameterChannel`] decodes
//! the 8 output bytes, keeps the zero-request rule, runs the file transfer, and hands a
//! parameter job to the device, which carries it out with [`execute`] through its own
//! [`ObjectAccess`] (so a written PNU takes effect like any other write).
//!
//! # Decisions
//!
//! - **Zero request (C.3.2).** The drive takes a new job only after a "no task" (request ID 0;
//!   the channel is free at power-on). A job is carried out once, when it arrives; its answer
//!   stays in FPCS while the PLC repeats the same bytes. A *different* job sent without the
//!   "no task" in between is ignored: the drive keeps answering the previous job (whose
//!   subindex and PNU it echoes, so the PLC can see that its new job was not taken) until
//!   the PLC sends "no task". It is not carried out later either. File packets of a running
//!   transfer are exempt: their packet ID changes every telegram (C.4.5).
//! - **"No task"** is answered with response ID 0 and the mode nibble of the request (10h →
//!   10h, 40h → 40h, 00h → 00h), the other bytes 0.
//! - **Checks, in this order**: PNU (00h), subindex (03h; subindex 0 is not an FHPP
//!   subindex), access (read of a write-only 66h, write of a read-only 01h), control
//!   authority for writes (0Bh: FCT or the web server holds control; PNU 125 itself is
//!   exempt, it is how the fieldbus takes control back and answers 11h against FCT),
//!   operating state (11h: an rw2 PNU with the output stage on, [`Context::stage_off_pnus`]),
//!   value (02h: outside the type or the dictionary's limits), then the device's own refusal
//!   (11h).
//! - **PWE** is 32 bits for every type: signed types are sign-extended on read and must fit
//!   the type when written as a signed 32-bit number (so int8 −1 is `FFFF FFFF`, and
//!   `0000 00FF` is 02h "limit exceeded"); unsigned types must fit as unsigned.
//! - A write answers with the value written (English manual Fig. C.1).
//! - A parameter job while a file transfer runs: 11h ("other functions are locked", C.4.6).
//! - A request ID not allowed in its mode: 65h in that mode's layout; a reserved mode: 65h
//!   with the mode echoed and the code in byte 8.

use od::{AbortCode, DataType, DeviceDescription, ObjectAccess, Value};

use super::{
    DecodeError, ErrorCode, FileResponse, ParameterRequest, ParameterResponse, Request, Response,
    MODE_FILE, MODE_PARAMETER,
};
use crate::vendors::festo_cmmo_st::fhpp::parameter_file::PermanentMemory;
use crate::vendors::festo_cmmo_st::fhpp::parameter_file_transfer::{
    FileTransfer, Reply, TransferContext,
};
use crate::vendors::festo_cmmo_st::fhpp::state_machine::Authority;

/// Diagnostic raised for an aborting file-transfer error: "E27" (C.4.7), 27h "save
/// parameters" (App. D).
pub const DIAG_PARAMETER_FILE: u8 = 0x27;

/// PNU 125 "control logic": written to take control back; only 1 is accepted (§3.1.1).
const PNU_CONTROL_LOGIC: u16 = 125;

/// What the device tells the channel every cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Context {
    /// The output stage is switched on (rw2 parameters are locked).
    pub stage_on: bool,
    /// Who holds device control (PNU 125).
    pub authority: Authority,
    /// A fault is present (SCON.FAULT).
    pub fault: bool,
    /// The device's millisecond clock (cycles).
    pub now_ms: u64,
    /// The PNUs with access rw2, writable only with the output stage off (App. B access
    /// column), sorted: the device file's `[device.fhpp] stage_off_pnus`.
    pub stage_off_pnus: &'static [u16],
}

/// Object index of PNU `pnu` (the dictionary's mapping rule, 2000h + PNU); `None` past FFFFh.
pub const fn pnu_object(pnu: u16) -> Option<u16> {
    0x2000u16.checked_add(pnu)
}

/// How a dictionary refusal reads on the parameter channel (Tab. C.7). Anything else is
/// 11h, "cannot be executed in the current operating state".
const ABORT_TO_ERROR: &[(AbortCode, ErrorCode)] = &[
    (AbortCode::NO_OBJECT, ErrorCode::IllegalPnu),
    (AbortCode::NO_SUB_INDEX, ErrorCode::WrongSubindex),
    (AbortCode::READ_ONLY, ErrorCode::CannotChange),
    (AbortCode::WRITE_ONLY, ErrorCode::WriteOnly),
    (AbortCode::VALUE_TOO_HIGH, ErrorCode::LimitExceeded),
    (AbortCode::VALUE_TOO_LOW, ErrorCode::LimitExceeded),
    (AbortCode::INVALID_VALUE, ErrorCode::LimitExceeded),
    (AbortCode::LENGTH_MISMATCH, ErrorCode::LimitExceeded),
    (AbortCode::LENGTH_TOO_HIGH, ErrorCode::LimitExceeded),
    (AbortCode::LENGTH_TOO_LOW, ErrorCode::LimitExceeded),
    (AbortCode::LOCAL_CONTROL, ErrorCode::NoAuthority),
];

/// The Tab. C.7 code for a dictionary abort code.
pub fn error_for(abort: AbortCode) -> ErrorCode {
    ABORT_TO_ERROR
        .iter()
        .find(|(a, _)| *a == abort)
        .map_or(ErrorCode::NotInThisState, |(_, e)| *e)
}

/// A stored value (little-endian, as the dictionary holds it) as the 32-bit PWE.
fn to_pwe(ty: DataType, bytes: &[u8]) -> Result<u32, ErrorCode> {
    match Value::decode(ty, bytes) {
        Some(Value::Signed(v)) => i32::try_from(v)
            .map(|v| v as u32)
            .map_err(|_| ErrorCode::IllegalPnu),
        Some(Value::Unsigned(v)) => u32::try_from(v).map_err(|_| ErrorCode::IllegalPnu),
        Some(Value::Bool(b)) => Ok(u32::from(b)),
        // A REAL or a string has no FHPP representation: not a PNU the channel carries.
        _ => Err(ErrorCode::IllegalPnu),
    }
}

/// The 32-bit PWE as the entry's little-endian bytes; 02h if it does not fit the type.
fn from_pwe(ty: DataType, pwe: u32, out: &mut [u8; 8]) -> Result<usize, ErrorCode> {
    let v = if ty.is_signed() {
        Value::Signed(i64::from(pwe as i32))
    } else {
        Value::Unsigned(u64::from(pwe))
    };
    match ty {
        DataType::Real32 | DataType::Real64 => Err(ErrorCode::IllegalPnu),
        _ if ty.fixed_size().is_none() => Err(ErrorCode::IllegalPnu),
        _ => v.encode(ty, out).ok_or(ErrorCode::LimitExceeded),
    }
}

/// Carries out a parameter job on the device (see the module documentation for the order of
/// the checks). Returns the PWE to answer with.
pub fn execute<A: ObjectAccess + ?Sized>(
    job: ParameterRequest,
    dev: &mut A,
    ctx: &Context,
) -> Result<u32, ErrorCode> {
    let pnu = job.pnu();
    let sub = job.subindex();
    let index = pnu_object(pnu).ok_or(ErrorCode::IllegalPnu)?;
    let e = dev.entry(index, sub).map_err(error_for)?;
    if sub == 0 {
        return Err(ErrorCode::WrongSubindex);
    }
    match job {
        ParameterRequest::Read { .. } => {
            if !e.access.readable() {
                return Err(ErrorCode::WriteOnly);
            }
            let mut buf = [0u8; 8];
            let n = dev.read(index, sub, &mut buf).map_err(error_for)?;
            to_pwe(e.data_type, buf.get(..n).unwrap_or(&[]))
        }
        ParameterRequest::Write { value, .. } => {
            if !e.access.writable() {
                return Err(ErrorCode::CannotChange);
            }
            if ctx.authority != Authority::Fieldbus && pnu != PNU_CONTROL_LOGIC {
                return Err(ErrorCode::NoAuthority);
            }
            if ctx.stage_on && ctx.stage_off_pnus.binary_search(&pnu).is_ok() {
                return Err(ErrorCode::NotInThisState);
            }
            let mut buf = [0u8; 8];
            let n = from_pwe(e.data_type, value, &mut buf)?;
            if pnu == PNU_CONTROL_LOGIC && value != 1 {
                return Err(ErrorCode::LimitExceeded);
            }
            dev.write(index, sub, buf.get(..n).unwrap_or(&[]))
                .map_err(error_for)?;
            Ok(value)
        }
    }
}

/// The EFPC server state: the last request, the answer shown, the zero-request latch, the
/// file transfer and the permanent memory it reads and writes.
#[derive(Default, Clone)]
pub struct ParameterChannel {
    last: [u8; 8],
    response: [u8; 8],
    /// A job was answered; the next one needs a "no task" first (C.3.2).
    held: bool,
    transfer: FileTransfer,
    memory: PermanentMemory,
    diagnostic: Option<u8>,
}

impl ParameterChannel {
    /// The 8 FPC input bytes to send (FPCS first).
    pub fn response(&self) -> [u8; 8] {
        self.response
    }

    /// The permanent memory (PNU 127 commands, the uploaded file).
    pub fn memory(&self) -> &PermanentMemory {
        &self.memory
    }

    pub fn memory_mut(&mut self) -> &mut PermanentMemory {
        &mut self.memory
    }

    pub fn transfer(&self) -> &FileTransfer {
        &self.transfer
    }

    /// The diagnostic to raise (27h after an aborting file error), once.
    pub fn take_diagnostic(&mut self) -> Option<u8> {
        self.diagnostic.take()
    }

    fn answer(&mut self, r: Response) {
        self.response = r.encode();
    }

    fn answer_file(&mut self, reply: Reply) {
        if reply.aborted.is_some() {
            self.diagnostic = Some(DIAG_PARAMETER_FILE);
        }
        self.answer(Response::File(reply.response));
    }

    /// One cycle: takes the output bytes; returns the parameter job the device must carry
    /// out now with [`execute`] and report with [`Self::complete`].
    pub fn receive(
        &mut self,
        out: &[u8; 8],
        ctx: &Context,
        desc: &'static DeviceDescription,
    ) -> Option<ParameterRequest> {
        if let Some(reply) = self.transfer.poll_timeout(ctx.now_ms) {
            self.answer_file(reply);
        }
        if *out == self.last {
            return None;
        }
        self.last = *out;
        let request = Request::decode(out);
        if let Ok(Request::NoTask { mode }) = request {
            self.held = false;
            self.answer(Response::NoResponse { mode });
            return None;
        }
        if self.held && !self.transfer.is_active() {
            // C.3.2: no new job without a "no task" in between (see the module docs).
            return None;
        }
        self.held = true;
        match request {
            Ok(Request::NoTask { .. }) => None,
            Ok(Request::Parameter(job)) => {
                if self.transfer.is_active() {
                    self.complete(job, Err(ErrorCode::NotInThisState));
                    return None;
                }
                Some(job)
            }
            Ok(Request::File { direction, packet }) => {
                let tctx = TransferContext {
                    control: ctx.authority == Authority::Fieldbus,
                    fault: ctx.fault,
                    now_ms: ctx.now_ms,
                };
                let upload = direction == super::FileDirection::Upload;
                let reply = self
                    .transfer
                    .packet(upload, packet, &tctx, &mut self.memory, desc);
                self.answer_file(reply);
                None
            }
            Err(DecodeError::ReservedPacketId(id)) => {
                let reply = self.transfer.bad_format(id);
                self.answer_file(reply);
                None
            }
            Err(DecodeError::UnsupportedId {
                mode: MODE_PARAMETER,
                ..
            }) => {
                let pnu = u16::from_be_bytes([out[2], out[3]]);
                self.answer(Response::Parameter(ParameterResponse::Error {
                    pnu,
                    subindex: out[1],
                    code: ErrorCode::RequestNotSupported,
                }));
                None
            }
            Err(DecodeError::UnsupportedId {
                mode: MODE_FILE, ..
            }) => {
                self.answer(Response::File(FileResponse::Rejected {
                    packet_id: out[1],
                    code: ErrorCode::RequestNotSupported,
                }));
                None
            }
            Err(_) => {
                self.answer(Response::Unsupported {
                    mode: out[0] >> 4,
                    code: ErrorCode::RequestNotSupported,
                });
                None
            }
        }
    }

    /// The device's result for the job [`Self::receive`] returned.
    pub fn complete(&mut self, job: ParameterRequest, result: Result<u32, ErrorCode>) {
        let (pnu, subindex) = (job.pnu(), job.subindex());
        self.answer(Response::Parameter(match result {
            Ok(value) => ParameterResponse::Value {
                pnu,
                subindex,
                value,
            },
            Err(code) => ParameterResponse::Error {
                pnu,
                subindex,
                code,
            },
        }));
    }
}
