//! SDO server (CiA 301 §7.2.4): expedited, segmented and block transfers with CRC, one
//! transfer at a time, with a server-side timeout. Sans-IO: request bytes in, response bytes
//! out, a deadline for `poll`.

use core::time::Duration;

use od::{AbortCode, Instant, ObjectAccess};

use crate::sdo_crc::crc16;

/// Largest block size (segments per sub-block) the protocol allows.
const MAX_BLKSIZE: u8 = 127;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Idle,
    /// Segmented download: waiting for the segment with `toggle`.
    DownloadSegments,
    /// Segmented upload: the client asks for each segment.
    UploadSegments,
    /// Block download, inside a sub-block; `next` is the expected sequence number.
    BlockDownload {
        next: u8,
        client_crc: bool,
        gap: bool,
    },
    /// Block download: last segment acknowledged, waiting for the end frame.
    BlockDownloadEnd {
        client_crc: bool,
    },
    /// Block upload: initiate answered, waiting for "start" (A3).
    BlockUploadStart {
        blksize: u8,
    },
    /// Block upload: a sub-block went out, waiting for the client's acknowledgement.
    BlockUploadAck {
        sent: u8,
    },
    /// Block upload: end frame sent, waiting for the client's end response (A1).
    BlockUploadEnd,
}

/// One SDO server channel with an `N`-byte transfer buffer (the largest object it moves).
pub struct SdoServer<const N: usize = 8192> {
    state: State,
    index: u16,
    sub: u8,
    toggle: bool,
    /// Size the client announced for a download, if it did.
    expected: Option<usize>,
    /// Bytes in `buf` (download: received so far; upload: the whole value).
    len: usize,
    /// Block download: bytes received including the last segment's padding.
    received: usize,
    /// Upload: bytes acknowledged / sent so far.
    pos: usize,
    /// Block upload: position at the start of the sub-block in flight.
    block_start: usize,
    timeout: Duration,
    deadline: Option<Instant>,
    buf: [u8; N],
}

impl<const N: usize> Default for SdoServer<N> {
    fn default() -> Self {
        Self::new(Duration::from_millis(1000))
    }
}

/// Bytes of a response frame.
pub type Response = [u8; 8];

fn abort_frame(index: u16, sub: u8, code: AbortCode) -> Response {
    let [il, ih] = index.to_le_bytes();
    let [c0, c1, c2, c3] = code.0.to_le_bytes();
    [0x80, il, ih, sub, c0, c1, c2, c3]
}

fn mux_frame(cs: u8, index: u16, sub: u8, data: [u8; 4]) -> Response {
    let [il, ih] = index.to_le_bytes();
    [cs, il, ih, sub, data[0], data[1], data[2], data[3]]
}

impl<const N: usize> SdoServer<N> {
    /// A server whose transfers abort with 0504 0000h after `timeout` without a client frame
    /// (CiA 301 leaves the value to the device; 1 s as CANopenNode's example).
    pub const fn new(timeout: Duration) -> Self {
        SdoServer {
            state: State::Idle,
            index: 0,
            sub: 0,
            toggle: false,
            expected: None,
            len: 0,
            received: 0,
            pos: 0,
            block_start: 0,
            timeout,
            deadline: None,
            buf: [0; N],
        }
    }

    /// Drops any transfer without a word (NMT Stopped, reset).
    pub fn reset(&mut self) {
        self.state = State::Idle;
        self.deadline = None;
    }

    pub fn is_idle(&self) -> bool {
        self.state == State::Idle
    }

    /// When `poll` must next run.
    pub fn deadline(&self) -> Option<Instant> {
        self.deadline
    }

    /// Aborts a transfer whose client fell silent.
    pub fn poll(&mut self, now: Instant, out: &mut dyn FnMut(Response)) {
        if let Some(d) = self.deadline {
            if now >= d && self.state != State::Idle {
                out(abort_frame(self.index, self.sub, AbortCode::TIMEOUT));
                self.reset();
            }
        }
    }

    /// Handles one request frame (any length up to 8: short frames are zero-padded as real
    /// masters send them) and emits the response frames, all with 8 bytes.
    pub fn on_request(
        &mut self,
        now: Instant,
        req: &[u8],
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(Response),
    ) {
        let mut d = [0u8; 8];
        let n = req.len().min(8);
        if let (Some(dst), Some(src)) = (d.get_mut(..n), req.get(..n)) {
            dst.copy_from_slice(src);
        }
        if req.is_empty() {
            out(abort_frame(0, 0, AbortCode::COMMAND_SPECIFIER));
            self.reset();
            return;
        }
        let cs = d[0];
        let in_block_download = matches!(self.state, State::BlockDownload { .. });
        // A client abort ends any transfer silently (CiA 301 §7.2.4.3.17). Inside a block
        // download sub-block 0x80 is a segment (last, seqno 0) instead.
        if cs == 0x80 && !in_block_download {
            self.reset();
            return;
        }
        let result = match self.state {
            State::Idle => self.initiate(&d, od, out),
            State::DownloadSegments => self.download_segment(&d, od, out),
            State::UploadSegments => self.upload_segment(&d, out),
            State::BlockDownload {
                next,
                client_crc,
                gap,
            } => self.block_download_segment(&d, next, client_crc, gap, out),
            State::BlockDownloadEnd { client_crc } => {
                self.block_download_end(&d, client_crc, od, out)
            }
            State::BlockUploadStart { blksize } => {
                if cs == 0xA3 {
                    self.send_sub_block(blksize, out);
                    Ok(())
                } else {
                    Err(AbortCode::COMMAND_SPECIFIER)
                }
            }
            State::BlockUploadAck { sent } => self.block_upload_ack(&d, sent, out),
            State::BlockUploadEnd => {
                if cs & 0xE3 == 0xA1 {
                    self.state = State::Idle;
                    Ok(())
                } else {
                    Err(AbortCode::COMMAND_SPECIFIER)
                }
            }
        };
        if let Err(code) = result {
            out(abort_frame(self.index, self.sub, code));
            self.state = State::Idle;
        }
        self.deadline = (self.state != State::Idle).then(|| now + self.timeout);
    }

    fn initiate(
        &mut self,
        d: &[u8; 8],
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(Response),
    ) -> Result<(), AbortCode> {
        let cs = d[0];
        self.index = u16::from_le_bytes([d[1], d[2]]);
        self.sub = d[3];
        let size_field = u32::from_le_bytes([d[4], d[5], d[6], d[7]]) as usize;
        if cs & 0xE0 == 0x20 {
            // Initiate download.
            let e = od.entry(self.index, self.sub)?;
            if !e.access.writable() {
                return Err(AbortCode::READ_ONLY);
            }
            if cs & 0x02 != 0 {
                // Expedited: 4 − n bytes when the size is indicated, else the object's size.
                let size = if cs & 0x01 != 0 {
                    4 - usize::from((cs >> 2) & 0x03)
                } else {
                    e.data_type.fixed_size().unwrap_or(4).min(4)
                };
                od.write(self.index, self.sub, d.get(4..4 + size).unwrap_or(&[]))?;
                out(mux_frame(0x60, self.index, self.sub, [0; 4]));
                return Ok(());
            }
            self.expected = (cs & 0x01 != 0).then_some(size_field);
            if let Some(size) = self.expected {
                check_size(e, size, N)?;
            }
            self.len = 0;
            self.toggle = false;
            self.state = State::DownloadSegments;
            out(mux_frame(0x60, self.index, self.sub, [0; 4]));
            Ok(())
        } else if cs & 0xE0 == 0x40 {
            // Initiate upload.
            self.read_object(od)?;
            self.upload_initiate_response(out);
            Ok(())
        } else if cs & 0xF9 == 0xC0 {
            // Initiate block download.
            let e = od.entry(self.index, self.sub)?;
            if !e.access.writable() {
                return Err(AbortCode::READ_ONLY);
            }
            self.expected = (cs & 0x02 != 0).then_some(size_field);
            if let Some(size) = self.expected {
                check_size(e, size, N)?;
            }
            self.len = 0;
            self.received = 0;
            self.state = State::BlockDownload {
                next: 1,
                client_crc: cs & 0x04 != 0,
                gap: false,
            };
            // The server always supports CRC (CiA 301 §7.2.4.3.9).
            out(mux_frame(
                0xA4,
                self.index,
                self.sub,
                [MAX_BLKSIZE, 0, 0, 0],
            ));
            Ok(())
        } else if cs & 0xFB == 0xA0 {
            // Initiate block upload.
            let blksize = d[4];
            let pst = usize::from(d[5]);
            if blksize == 0 || blksize > MAX_BLKSIZE {
                return Err(AbortCode::BLOCK_SIZE);
            }
            self.read_object(od)?;
            if pst > 0 && self.len <= pst {
                // Protocol switch threshold (CiA 301 §7.2.4.3.14): answer as a normal upload.
                self.upload_initiate_response(out);
                return Ok(());
            }
            self.pos = 0;
            self.state = State::BlockUploadStart { blksize };
            let size = (self.len as u32).to_le_bytes();
            out(mux_frame(0xC6, self.index, self.sub, size));
            Ok(())
        } else {
            Err(AbortCode::COMMAND_SPECIFIER)
        }
    }

    fn read_object(&mut self, od: &mut dyn ObjectAccess) -> Result<(), AbortCode> {
        self.len = od.read(self.index, self.sub, &mut self.buf)?;
        Ok(())
    }

    fn upload_initiate_response(&mut self, out: &mut dyn FnMut(Response)) {
        let n = self.len;
        if (1..=4).contains(&n) {
            let mut data = [0u8; 4];
            if let (Some(dst), Some(src)) = (data.get_mut(..n), self.buf.get(..n)) {
                dst.copy_from_slice(src);
            }
            let cs = 0x43 | (((4 - n) as u8) << 2);
            out(mux_frame(cs, self.index, self.sub, data));
        } else {
            self.pos = 0;
            self.toggle = false;
            self.state = State::UploadSegments;
            out(mux_frame(
                0x41,
                self.index,
                self.sub,
                (n as u32).to_le_bytes(),
            ));
        }
    }

    fn download_segment(
        &mut self,
        d: &[u8; 8],
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(Response),
    ) -> Result<(), AbortCode> {
        let cs = d[0];
        if cs & 0xE0 != 0 {
            return Err(AbortCode::COMMAND_SPECIFIER);
        }
        let t = cs & 0x10 != 0;
        if t != self.toggle {
            return Err(AbortCode::TOGGLE_BIT);
        }
        let count = 7 - usize::from((cs >> 1) & 0x07);
        let limit = self.expected.unwrap_or(N).min(N);
        if self.len + count > limit {
            return Err(AbortCode::LENGTH_TOO_HIGH);
        }
        let dst = self
            .buf
            .get_mut(self.len..self.len + count)
            .ok_or(AbortCode::OUT_OF_MEMORY)?;
        dst.copy_from_slice(d.get(1..1 + count).unwrap_or(&[]));
        self.len += count;
        self.toggle = !t;
        if cs & 0x01 != 0 {
            if let Some(size) = self.expected {
                if self.len < size {
                    return Err(AbortCode::LENGTH_TOO_LOW);
                }
            }
            od.write(
                self.index,
                self.sub,
                self.buf.get(..self.len).unwrap_or(&[]),
            )?;
            self.state = State::Idle;
        }
        out([0x20 | ((t as u8) << 4), 0, 0, 0, 0, 0, 0, 0]);
        Ok(())
    }

    fn upload_segment(
        &mut self,
        d: &[u8; 8],
        out: &mut dyn FnMut(Response),
    ) -> Result<(), AbortCode> {
        let cs = d[0];
        if cs & 0xEF != 0x60 {
            return Err(AbortCode::COMMAND_SPECIFIER);
        }
        let t = cs & 0x10 != 0;
        if t != self.toggle {
            return Err(AbortCode::TOGGLE_BIT);
        }
        let remaining = self.len.saturating_sub(self.pos);
        let count = remaining.min(7);
        let last = remaining <= 7;
        let mut r = [0u8; 8];
        r[0] = ((t as u8) << 4) | (((7 - count) as u8) << 1) | last as u8;
        if let (Some(dst), Some(src)) = (
            r.get_mut(1..1 + count),
            self.buf.get(self.pos..self.pos + count),
        ) {
            dst.copy_from_slice(src);
        }
        self.pos += count;
        self.toggle = !t;
        if last {
            self.state = State::Idle;
        }
        out(r);
        Ok(())
    }

    fn block_download_segment(
        &mut self,
        d: &[u8; 8],
        next: u8,
        client_crc: bool,
        gap: bool,
        out: &mut dyn FnMut(Response),
    ) -> Result<(), AbortCode> {
        let seqno = d[0] & 0x7F;
        let last = d[0] & 0x80 != 0;
        if seqno == 0 || seqno > MAX_BLKSIZE {
            return Err(AbortCode::SEQUENCE_NUMBER);
        }
        if gap && seqno != 1 {
            // After an early acknowledgement the rest of the broken sub-block is still
            // arriving: ignore it until the client restarts at 1.
            return Ok(());
        }
        let next = if gap { 1 } else { next };
        if seqno < next {
            return Ok(()); // duplicate
        }
        if seqno > next {
            // A segment was lost: acknowledge what arrived in sequence so the client repeats
            // the rest (CiA 301 §7.2.4.3.10).
            out([0xA2, next - 1, MAX_BLKSIZE, 0, 0, 0, 0, 0]);
            self.state = State::BlockDownload {
                next: 1,
                client_crc,
                gap: true,
            };
            return Ok(());
        }
        // Keep at most N bytes; anything past N can only be padding of a value that fits,
        // which the end frame tells apart (`received` counts it all).
        let room = N.saturating_sub(self.len).min(7);
        if let (Some(dst), Some(src)) = (
            self.buf.get_mut(self.len..self.len + room),
            d.get(1..1 + room),
        ) {
            dst.copy_from_slice(src);
        }
        self.len += room;
        self.received += 7;
        if last || seqno == MAX_BLKSIZE {
            out([0xA2, seqno, MAX_BLKSIZE, 0, 0, 0, 0, 0]);
            self.state = if last {
                State::BlockDownloadEnd { client_crc }
            } else {
                State::BlockDownload {
                    next: 1,
                    client_crc,
                    gap: false,
                }
            };
        } else {
            self.state = State::BlockDownload {
                next: seqno + 1,
                client_crc,
                gap: false,
            };
        }
        Ok(())
    }

    fn block_download_end(
        &mut self,
        d: &[u8; 8],
        client_crc: bool,
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(Response),
    ) -> Result<(), AbortCode> {
        let cs = d[0];
        if cs & 0xE3 != 0xC1 {
            return Err(AbortCode::COMMAND_SPECIFIER);
        }
        let pad = usize::from((cs >> 2) & 0x07);
        let total = self.received.saturating_sub(pad);
        if total > N {
            return Err(AbortCode::OUT_OF_MEMORY);
        }
        if let Some(size) = self.expected {
            if total > size {
                return Err(AbortCode::LENGTH_TOO_HIGH);
            }
            if total < size {
                return Err(AbortCode::LENGTH_TOO_LOW);
            }
        }
        let data = self.buf.get(..total).unwrap_or(&[]);
        if client_crc && crc16(data) != u16::from_le_bytes([d[1], d[2]]) {
            return Err(AbortCode::CRC);
        }
        od.write(self.index, self.sub, data)?;
        self.state = State::Idle;
        out([0xA1, 0, 0, 0, 0, 0, 0, 0]);
        Ok(())
    }

    /// Sends up to `blksize` segments from `pos`; the one holding the last byte gets bit 7.
    fn send_sub_block(&mut self, blksize: u8, out: &mut dyn FnMut(Response)) {
        self.block_start = self.pos;
        let mut sent = 0u8;
        let mut pos = self.pos;
        while sent < blksize {
            let remaining = self.len.saturating_sub(pos);
            let count = remaining.min(7);
            let last = remaining <= 7;
            sent += 1;
            let mut r = [0u8; 8];
            r[0] = sent | if last { 0x80 } else { 0 };
            if let (Some(dst), Some(src)) =
                (r.get_mut(1..1 + count), self.buf.get(pos..pos + count))
            {
                dst.copy_from_slice(src);
            }
            pos += count;
            out(r);
            if last {
                break;
            }
        }
        self.state = State::BlockUploadAck { sent };
    }

    fn block_upload_ack(
        &mut self,
        d: &[u8; 8],
        sent: u8,
        out: &mut dyn FnMut(Response),
    ) -> Result<(), AbortCode> {
        if d[0] & 0xE3 != 0xA2 {
            return Err(AbortCode::COMMAND_SPECIFIER);
        }
        let ackseq = d[1];
        let blksize = d[2];
        if blksize == 0 || blksize > MAX_BLKSIZE {
            return Err(AbortCode::BLOCK_SIZE);
        }
        if ackseq > sent {
            return Err(AbortCode::SEQUENCE_NUMBER);
        }
        self.pos = (self.block_start + usize::from(ackseq) * 7).min(self.len);
        let all_sent_acked = ackseq == sent && self.pos >= self.len;
        if all_sent_acked {
            // Bytes in the last segment: 1…7 (0 only for an empty value, sent as one segment).
            let tail = if self.len == 0 {
                0
            } else {
                (self.len - 1) % 7 + 1
            };
            let pad = (7 - tail) as u8;
            let [c0, c1] = crc16(self.buf.get(..self.len).unwrap_or(&[])).to_le_bytes();
            out([0xC1 | (pad << 2), c0, c1, 0, 0, 0, 0, 0]);
            self.state = State::BlockUploadEnd;
        } else {
            self.send_sub_block(blksize, out);
        }
        Ok(())
    }
}

/// Checks an announced download size against the entry and the transfer buffer.
fn check_size(e: &od::Entry, size: usize, buffer: usize) -> Result<(), AbortCode> {
    match e.data_type.fixed_size() {
        Some(n) if size > n => Err(AbortCode::LENGTH_TOO_HIGH),
        Some(n) if size < n => Err(AbortCode::LENGTH_TOO_LOW),
        None if size > e.capacity as usize => Err(AbortCode::LENGTH_TOO_HIGH),
        _ if size > buffer => Err(AbortCode::OUT_OF_MEMORY),
        _ => Ok(()),
    }
}
