//! The parameter-file transfer of the EFPC (manual C.4.5–C.4.7): upload (drive → PLC) and
//! download (PLC → drive) of the [`parameter_file`](super::parameter_file) in 6-byte packets.
//!
//! The sequence, as decided from C.4.5 (its figures C.3–C.8 are missing from the manual):
//! 1. The PLC sends FPCC 44h (upload) or 45h (download) with the start packet `001 00000`;
//!    a download's start carries the file size (u32 LE). The drive answers FPCS 43h with
//!    the same packet ID and, for an upload, the size of its file.
//! 2. Data packets with sequence numbers 1, 2, … 31, 0, 1, …; the drive acknowledges each
//!    with the same packet ID (an upload's acknowledgement carries the next 6 bytes, the
//!    last zero-padded; a download's carries no data). No "no task" in between.
//! 3. The PLC ends with a stop packet (`010`, sequence not checked); a download is checked
//!    and stored then. Then "no task" again.
//!
//! Errors: type 1 in FPCS (response ID 7, code in byte 3: 11h "not in this state", 65h
//! "ReqID not supported"), type 2 as an error packet `011` with the code in byte 3
//! ([`FileError`]). Aborting errors (Tab. C.12) end the transfer and discard what was
//! received; the caller raises diagnostic 27h for them ("E27", C.4.7).
//!
//! Decisions where the manual says nothing:
//! - **Timeout between two packets: [`PACKET_TIMEOUT_MS`] = 1000 ms.** The manual names the
//!   error (Tab. C.11 code 02h) but no time. One second is ten times the shortest Modbus
//!   watchdog the CMMO-ST accepts (100 ms, §4.3.4), so a master that keeps the connection
//!   alive also keeps a transfer alive, while a stalled transfer does not lock the other
//!   file functions for long. A repeated (unchanged) telegram is not a new packet.
//! - **Downloads less than 3 s apart** are refused with the type-1 error 11h (the PLC may
//!   retry): diagnostic 38h says "the interval between two parameter-file downloads must not
//!   be less than 3 s" ([`DOWNLOAD_INTERVAL_MS`]).
//! - A data or stop packet, or a PLC error packet, with no transfer running, and a packet of
//!   the other direction while one runs ("a download cannot start during an upload"), are
//!   type-1 error 11h; a start while one runs is type-2 04h "wrong command order" (aborts).
//! - A start packet with a sequence number other than 0 is error 01h (wrong order, does not
//!   abort); an upload asked for more packets than the file has is 07h.
//! - A download needs control authority (08h), and no fault present (09h "an error still
//!   needs acknowledging"); so does an upload with a fault present (09h). An upload is a
//!   read and needs no control authority.

use od::DeviceDescription;

use super::parameter_channel::{
    next_sequence, ErrorCode, FileError, FileResponse, Packet, PacketKind,
};
use super::parameter_file::{
    check_header, FileBuffer, PermanentMemory, CAPACITY, CRC_LEN, HEADER_LEN,
};

/// Longest pause between two packets before the drive aborts with error 02h (decided, see
/// the module documentation).
pub const PACKET_TIMEOUT_MS: u64 = 1000;
/// Shortest interval between two downloads (diagnostic 38h).
pub const DOWNLOAD_INTERVAL_MS: u64 = 3000;

/// What the drive knows of itself when a packet comes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TransferContext {
    /// The fieldbus holds control authority (PNU 125 = 1).
    pub control: bool,
    /// A fault is present (SCON.FAULT).
    pub fault: bool,
    /// The device's millisecond clock.
    pub now_ms: u64,
}

/// The drive's answer to one packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reply {
    pub response: FileResponse,
    /// The aborting error, if the packet ended the transfer with one.
    pub aborted: Option<FileError>,
}

impl Reply {
    fn ack(packet: Packet) -> Reply {
        Reply {
            response: FileResponse::Active(packet),
            aborted: None,
        }
    }

    fn rejected(packet_id: u8, code: ErrorCode) -> Reply {
        Reply {
            response: FileResponse::Rejected { packet_id, code },
            aborted: None,
        }
    }
}

/// Which transfer runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    Idle,
    /// `sent` bytes of the stored file are out; `next` is the expected sequence number.
    Upload {
        sent: usize,
        next: u8,
        last_ms: u64,
    },
    /// `size` bytes announced; the received ones are in the buffer.
    Download {
        size: usize,
        next: u8,
        last_ms: u64,
        header_checked: bool,
    },
}

/// The transfer state machine with its receive buffer.
#[derive(Clone)]
pub struct FileTransfer {
    phase: Phase,
    rx: FileBuffer,
    last_download_ms: Option<u64>,
}

impl Default for FileTransfer {
    fn default() -> Self {
        FileTransfer {
            phase: Phase::Idle,
            rx: FileBuffer::new(),
            last_download_ms: None,
        }
    }
}

impl FileTransfer {
    pub fn phase(&self) -> Phase {
        self.phase
    }

    pub fn is_active(&self) -> bool {
        self.phase != Phase::Idle
    }

    /// Ends the transfer and forgets what was received (Tab. C.12 "aborts").
    fn abort(&mut self) {
        self.phase = Phase::Idle;
        self.rx.clear();
    }

    /// A type-2 error answered in an error packet; aborting ones end the transfer.
    fn error(&mut self, sequence: u8, e: FileError) -> Reply {
        let aborted = e.aborts().then(|| {
            self.abort();
            e
        });
        Reply {
            response: FileResponse::Active(Packet::error(sequence, e.code())),
            aborted,
        }
    }

    /// Every cycle: the timeout between two packets (error 02h, aborts).
    pub fn poll_timeout(&mut self, now_ms: u64) -> Option<Reply> {
        let (last, next) = match self.phase {
            Phase::Idle => return None,
            Phase::Upload { last_ms, next, .. } | Phase::Download { last_ms, next, .. } => {
                (last_ms, next)
            }
        };
        (now_ms.saturating_sub(last) > PACKET_TIMEOUT_MS)
            .then(|| self.error(next, FileError::Timeout))
    }

    /// A packet with the reserved control bits `1xx`: error 03h "invalid telegram format"
    /// (does not abort).
    pub fn bad_format(&mut self, packet_id: u8) -> Reply {
        self.error(packet_id & 0x1F, FileError::Format)
    }

    /// One new packet of an upload (`upload`) or a download.
    pub fn packet(
        &mut self,
        upload: bool,
        packet: Packet,
        ctx: &TransferContext,
        memory: &mut PermanentMemory,
        desc: &'static DeviceDescription,
    ) -> Reply {
        let seq = packet.sequence;
        match (packet.kind, self.phase) {
            (PacketKind::Error, Phase::Idle)
            | (PacketKind::Data | PacketKind::Stop, Phase::Idle) => {
                Reply::rejected(packet.id(), ErrorCode::NotInThisState)
            }
            (PacketKind::Error, _) => {
                // The PLC aborts; it sends no error number (Tab. C.11 code 00h).
                self.error(seq, FileError::FromPlc)
            }
            (PacketKind::Start, Phase::Idle) => self.start(upload, packet, ctx, memory, desc),
            // C.4.6: "a download cannot start during an upload, and vice versa".
            (_, Phase::Upload { .. }) if !upload => {
                Reply::rejected(packet.id(), ErrorCode::NotInThisState)
            }
            (_, Phase::Download { .. }) if upload => {
                Reply::rejected(packet.id(), ErrorCode::NotInThisState)
            }
            (PacketKind::Start, _) => self.error(seq, FileError::CommandOrder),
            (PacketKind::Data, Phase::Upload { sent, next, .. }) => {
                if seq != next {
                    return self.error(seq, FileError::Sequence);
                }
                let Ok(file) = memory.file(desc) else {
                    return self.error(seq, FileError::Read);
                };
                let Some(rest) = file.get(sent..).filter(|r| !r.is_empty()) else {
                    return self.error(seq, FileError::Amount);
                };
                let mut data = [0u8; 6];
                for (d, s) in data.iter_mut().zip(rest) {
                    *d = *s;
                }
                self.phase = Phase::Upload {
                    sent: sent + 6,
                    next: next_sequence(next),
                    last_ms: ctx.now_ms,
                };
                Reply::ack(Packet::data(seq, data))
            }
            (
                PacketKind::Data,
                Phase::Download {
                    size,
                    next,
                    header_checked,
                    ..
                },
            ) => {
                if seq != next {
                    return self.error(seq, FileError::Sequence);
                }
                let have = self.rx.len();
                if have >= size {
                    return self.error(seq, FileError::Amount);
                }
                // C.4.3: the size sent at the start says how much of the last packet counts.
                let take = (size - have).min(packet.data.len());
                let bytes = packet.data.get(..take).unwrap_or(&[]);
                if self.rx.extend_from_slice(bytes).is_err() {
                    return self.error(seq, FileError::Write);
                }
                let mut checked = header_checked;
                if !checked && self.rx.len() >= HEADER_LEN {
                    // C.4.4: the compatibility check directly after the header.
                    match check_header(desc, &self.rx) {
                        Ok(h) if h.file_len() == size => checked = true,
                        Ok(_) => return self.error(seq, FileError::Amount),
                        Err(e) => return self.error(seq, e.transfer_error()),
                    }
                }
                self.phase = Phase::Download {
                    size,
                    next: next_sequence(next),
                    last_ms: ctx.now_ms,
                    header_checked: checked,
                };
                Reply::ack(Packet::empty(PacketKind::Data, seq))
            }
            (PacketKind::Stop, Phase::Upload { .. }) => {
                self.phase = Phase::Idle;
                Reply::ack(Packet::empty(PacketKind::Stop, seq))
            }
            (PacketKind::Stop, Phase::Download { size, .. }) => {
                if self.rx.len() != size {
                    return self.error(seq, FileError::Amount);
                }
                // C.4.4: checked again, then stored; the previous file is deleted. The active
                // values stay until PNU 127:4 = 10h or a restart.
                if let Err(e) = memory.replace(desc, &self.rx) {
                    return self.error(seq, e.transfer_error());
                }
                self.abort();
                self.last_download_ms = Some(ctx.now_ms);
                Reply::ack(Packet::empty(PacketKind::Stop, seq))
            }
        }
    }

    fn start(
        &mut self,
        upload: bool,
        packet: Packet,
        ctx: &TransferContext,
        memory: &mut PermanentMemory,
        desc: &'static DeviceDescription,
    ) -> Reply {
        let seq = packet.sequence;
        if seq != 0 {
            // C.4.5: "the sequence number starts with 0".
            return self.error(seq, FileError::Sequence);
        }
        if !upload && !ctx.control {
            return self.error(seq, FileError::Access);
        }
        if ctx.fault {
            return self.error(seq, FileError::AccessTimeout);
        }
        if upload {
            let Ok(file) = memory.file(desc) else {
                return self.error(seq, FileError::Read);
            };
            let size = file.len() as u32;
            self.rx.clear();
            self.phase = Phase::Upload {
                sent: 0,
                next: 1,
                last_ms: ctx.now_ms,
            };
            return Reply::ack(Packet::start(size));
        }
        if let Some(t) = self.last_download_ms {
            if ctx.now_ms.saturating_sub(t) < DOWNLOAD_INTERVAL_MS {
                return Reply::rejected(packet.id(), ErrorCode::NotInThisState);
            }
        }
        let size = packet.size() as usize;
        if !(HEADER_LEN + CRC_LEN..=CAPACITY).contains(&size) {
            return self.error(seq, FileError::Read);
        }
        self.rx.clear();
        self.phase = Phase::Download {
            size,
            next: 1,
            last_ms: ctx.now_ms,
            header_checked: false,
        };
        Reply::ack(Packet::start(size as u32))
    }
}
