//! SDO request/response over CoE (ETG.1000.6 §5.6.2; spec §6.2–§6.5).
//!
//! ```text
//! CoE header | command | index (u16) | sub | data (4 bytes, or size u32 + data)
//! ```
//!
//! Decisions:
//! * Uploads: a value of 1–4 bytes goes expedited with the size bits set (ethercrab reads
//!   PDO objects with `sdo_read_expedited`, SOEM copies exactly 4 − n bytes; spec §6.3); a
//!   longer one (or a complete-access image, or an empty string) as a normal response when it
//!   fits the send mailbox (SM1 size − 16 bytes), else segmented, with an initiate response of
//!   length 10 carrying only the complete size (works with SOEM, ethercrab and KickCAT,
//!   spec §6.3). Segments carry up to SM1 size − 9 bytes; a segment of fewer than 7 bytes is
//!   padded to mailbox length 10 with the unused count in bits 1–3.
//! * Downloads: expedited (size from bits 2–3, or the entry's size when the size bit is
//!   clear), normal with the complete size and all data in the initiate request, or segmented
//!   when the complete size exceeds the data of the initiate request. Segments: data length =
//!   mailbox length − 3, minus the unused count when that is 7 (as SOEM and ethercrab count).
//!   The entry (access, length) is checked at the initiate request, so a segmented download
//!   of a read-only or too long value is refused before any segment. The value is written
//!   as a whole after the last segment (the dictionary writes whole values only).
//! * Every initiate response and abort echoes index and sub-index (spec §6.3); the download
//!   response is 0x60, with the CA bit echoed (0x70) as SOES does. Segment responses carry
//!   the transfer's toggle bit. A toggle that does not alternate: 0503 0000h; a segment
//!   without a transfer or an unknown command specifier (block transfers do not exist in
//!   CoE): 0504 0001h. A new initiate request ends a transfer in progress (the master gave it
//!   up); an abort from the master ends it without reply.
//! * Complete access (spec §6.4), when [`super::CoeConfig::complete_access`] is on: sub-index
//!   0 or 1 only (else 0601 0000h, as SOES); sub-index 0 is sent as 16 bits (value + pad byte);
//!   entries follow in sub-index order, each in its full size (BOOLEAN as one byte, as the
//!   dictionary stores it); objects with a string or domain entry: 0601 0004h. A VAR is read
//!   and written as its sub-index 0. On read, write-only entries and error history entries
//!   beyond the count read as zeros. On write the data may stop after any whole entry (pysoem
//!   writes `count, pad, n × u16` to 1C12h/1C13h); entries are written in order and sub-index
//!   0 last; when sub-index 0 counts a PDO mapping, it is first set to 0 so the CiA 301
//!   mapping procedure accepts the entries. A non-writable entry written with its current
//!   value is skipped (e.g. the ro "highest sub-index" of a record), with another value it
//!   aborts with 0601 0002h. A CA write is not atomic: entries before a failing one keep their
//!   new values (a PDO mapping then keeps count 0, i.e. stays disabled).
//! * A device whose objects are all ≤ 4 bytes has every transfer end up expedited;
//!   the segmented services are still accepted. Hidden objects ([`super::CoeConfig::hidden`])
//!   answer 0602 0000h.

use crate::field::{u16_at, u32_at};
use od::{AbortCode, Behaviour, DeviceDescription, Entry, ObjectAccess, ObjectKind};

use super::{abort, CoeServer, COE_HEADER_LEN};
use crate::mailbox::{MailboxType, HEADER_LEN};

/// SDO command specifiers (command byte bits 5–7) of requests.
pub mod ccs {
    pub const DOWNLOAD_SEGMENT: u8 = 0;
    pub const INITIATE_DOWNLOAD: u8 = 1;
    pub const INITIATE_UPLOAD: u8 = 2;
    pub const UPLOAD_SEGMENT: u8 = 3;
    pub const ABORT: u8 = 4;
}

/// Command byte bit 4 of an initiate request: complete access.
pub const COMPLETE_ACCESS: u8 = 0x10;
/// Command byte bit 4 of a segment: toggle.
pub const TOGGLE: u8 = 0x10;

/// A segmented transfer in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Transfer {
    Idle,
    Download {
        index: u16,
        sub: u8,
        ca: bool,
        toggle: bool,
        expected: usize,
        len: usize,
    },
    Upload {
        index: u16,
        sub: u8,
        toggle: bool,
        len: usize,
        pos: usize,
    },
}

impl<const N: usize> CoeServer<N> {
    /// `p`: the mailbox payload (CoE header first), at least 10 bytes.
    pub(crate) fn sdo_request(
        &mut self,
        p: &[u8],
        od: &mut dyn ObjectAccess,
        out: &mut [u8],
    ) -> Option<usize> {
        let cmd = p.get(COE_HEADER_LEN).copied().unwrap_or(0);
        let index = u16_at(p, 3);
        let sub = p.get(5).copied().unwrap_or(0);
        match cmd >> 5 {
            ccs::DOWNLOAD_SEGMENT => self.download_segment(cmd, p, od, out),
            ccs::INITIATE_DOWNLOAD => self.initiate_download(cmd, index, sub, p, od, out),
            ccs::INITIATE_UPLOAD => self.initiate_upload(cmd, index, sub, od, out),
            ccs::UPLOAD_SEGMENT => self.upload_segment(cmd, out),
            ccs::ABORT => {
                self.transfer = Transfer::Idle;
                self.counters.aborts_received = self.counters.aborts_received.saturating_add(1);
                None
            }
            _ => self.abort(out, index, sub, AbortCode::COMMAND_SPECIFIER),
        }
    }

    /// Send an abort and end any transfer.
    pub(crate) fn abort(
        &mut self,
        out: &mut [u8],
        index: u16,
        sub: u8,
        code: AbortCode,
    ) -> Option<usize> {
        self.transfer = Transfer::Idle;
        self.counters.aborts_sent = self.counters.aborts_sent.saturating_add(1);
        self.write_message(out, MailboxType::Coe, |p| {
            abort::encode(p, index, sub, code)
        })
    }

    /// A 10-byte SDO response: command, index, sub, 4 data bytes.
    fn response(
        &mut self,
        out: &mut [u8],
        cmd: u8,
        index: u16,
        sub: u8,
        data: [u8; 4],
    ) -> Option<usize> {
        let [il, ih] = index.to_le_bytes();
        let [d0, d1, d2, d3] = data;
        self.write_message(out, MailboxType::Coe, |p| {
            p.get_mut(..10)?
                .copy_from_slice(&[0x00, 0x30, cmd, il, ih, sub, d0, d1, d2, d3]);
            Some(10)
        })
    }

    fn check_request(&self, index: u16, sub: u8, ca: bool) -> Result<(), AbortCode> {
        if self.config.is_hidden(index) {
            return Err(AbortCode::NO_OBJECT);
        }
        if ca {
            if !self.config.complete_access {
                return Err(abort::CA_NOT_SUPPORTED);
            }
            if sub > 1 {
                return Err(AbortCode::UNSUPPORTED_ACCESS);
            }
        }
        Ok(())
    }

    fn initiate_download(
        &mut self,
        cmd: u8,
        index: u16,
        sub: u8,
        p: &[u8],
        od: &mut dyn ObjectAccess,
        out: &mut [u8],
    ) -> Option<usize> {
        self.transfer = Transfer::Idle;
        let ca = cmd & COMPLETE_ACCESS != 0;
        if let Err(code) = self.check_request(index, sub, ca) {
            return self.abort(out, index, sub, code);
        }
        let done = 0x60 | (cmd & COMPLETE_ACCESS);
        // Data area after command, index and sub-index.
        let area = p.get(COE_HEADER_LEN + 4..).unwrap_or(&[]);
        if cmd & 0x02 != 0 {
            let size = if cmd & 0x01 != 0 {
                4 - usize::from((cmd >> 2) & 0x03)
            } else if ca {
                4
            } else {
                od.entry(index, sub)
                    .ok()
                    .and_then(|e| e.data_type.fixed_size())
                    .filter(|n| *n <= 4)
                    .unwrap_or(4)
            };
            let data = area.get(..size).unwrap_or(area);
            return match write_value(self.desc, od, index, sub, ca, data) {
                Ok(()) => self.response(out, done, index, sub, [0; 4]),
                Err(code) => self.abort(out, index, sub, code),
            };
        }
        let frame = area.get(4..).unwrap_or(&[]);
        let size = if cmd & 0x01 != 0 {
            usize::try_from(u32_at(area, 0)).unwrap_or(usize::MAX)
        } else {
            frame.len()
        };
        if let Some(data) = frame.get(..size) {
            return match write_value(self.desc, od, index, sub, ca, data) {
                Ok(()) => self.response(out, done, index, sub, [0; 4]),
                Err(code) => self.abort(out, index, sub, code),
            };
        }
        // Segmented: check what can be checked now, keep the first part.
        if !ca {
            if let Err(code) = precheck_download(od, index, sub, size) {
                return self.abort(out, index, sub, code);
            }
        }
        if size > N {
            return self.abort(out, index, sub, AbortCode::OUT_OF_MEMORY);
        }
        let first = frame.len();
        match self.buf.get_mut(..first) {
            Some(d) => d.copy_from_slice(frame),
            None => return self.abort(out, index, sub, AbortCode::OUT_OF_MEMORY),
        }
        let n = self.response(out, done, index, sub, [0; 4])?;
        self.transfer = Transfer::Download {
            index,
            sub,
            ca,
            toggle: false,
            expected: size,
            len: first,
        };
        Some(n)
    }

    fn download_segment(
        &mut self,
        cmd: u8,
        p: &[u8],
        od: &mut dyn ObjectAccess,
        out: &mut [u8],
    ) -> Option<usize> {
        let Transfer::Download {
            index,
            sub,
            ca,
            toggle,
            expected,
            len,
        } = self.transfer
        else {
            return self.abort(out, 0, 0, AbortCode::COMMAND_SPECIFIER);
        };
        if (cmd & TOGGLE != 0) != toggle {
            return self.abort(out, index, sub, AbortCode::TOGGLE_BIT);
        }
        let seg = p.get(COE_HEADER_LEN + 1..).unwrap_or(&[]);
        let k = if seg.len() == 7 {
            7 - usize::from((cmd >> 1) & 0x07)
        } else {
            seg.len()
        };
        let data = seg.get(..k).unwrap_or(seg);
        let end = len + data.len();
        if end > expected {
            return self.abort(out, index, sub, AbortCode::LENGTH_TOO_HIGH);
        }
        match self.buf.get_mut(len..end) {
            Some(d) => d.copy_from_slice(data),
            None => return self.abort(out, index, sub, AbortCode::OUT_OF_MEMORY),
        }
        let last = cmd & 0x01 != 0;
        if last {
            if end < expected {
                return self.abort(out, index, sub, AbortCode::LENGTH_TOO_LOW);
            }
            self.transfer = Transfer::Idle;
            let value = self.buf.get(..end).unwrap_or(&[]);
            if let Err(code) = write_value(self.desc, od, index, sub, ca, value) {
                return self.abort(out, index, sub, code);
            }
        } else {
            self.transfer = Transfer::Download {
                index,
                sub,
                ca,
                toggle: !toggle,
                expected,
                len: end,
            };
        }
        let reply = 0x20 | (cmd & TOGGLE);
        self.write_message(out, MailboxType::Coe, |p| {
            let d = p.first_chunk_mut::<10>()?;
            *d = [0, 0x30, reply, 0, 0, 0, 0, 0, 0, 0];
            Some(10)
        })
    }

    fn initiate_upload(
        &mut self,
        cmd: u8,
        index: u16,
        sub: u8,
        od: &mut dyn ObjectAccess,
        out: &mut [u8],
    ) -> Option<usize> {
        self.transfer = Transfer::Idle;
        let ca = cmd & COMPLETE_ACCESS != 0;
        if let Err(code) = self.check_request(index, sub, ca) {
            return self.abort(out, index, sub, code);
        }
        let read = if ca {
            read_complete(self.desc, od, index, sub, &mut self.buf)
        } else {
            od.read(index, sub, &mut self.buf)
        };
        let n = match read {
            Ok(n) => n.min(N),
            Err(code) => return self.abort(out, index, sub, code),
        };
        if !ca && (1..=4).contains(&n) {
            let mut d = [0u8; 4];
            if let (Some(dst), Some(src)) = (d.get_mut(..n), self.buf.get(..n)) {
                dst.copy_from_slice(src);
            }
            let size_bits = u8::try_from(4 - n).unwrap_or(0) << 2;
            return self.response(out, 0x43 | size_bits, index, sub, d);
        }
        let cmd = 0x41 | (cmd & COMPLETE_ACCESS);
        let [il, ih] = index.to_le_bytes();
        let size = u32::try_from(n).unwrap_or(u32::MAX).to_le_bytes();
        let p = out.get_mut(HEADER_LEN..HEADER_LEN + 10)?;
        p.copy_from_slice(&[
            0x00, 0x30, cmd, il, ih, sub, size[0], size[1], size[2], size[3],
        ]);
        let fits = out
            .get_mut(HEADER_LEN + 10..HEADER_LEN + 10 + n)
            .zip(self.buf.get(..n));
        match fits {
            Some((dst, src)) => {
                dst.copy_from_slice(src);
                self.finish(out, MailboxType::Coe, 10 + n)
            }
            None => {
                if out.len() <= HEADER_LEN + COE_HEADER_LEN + 1 {
                    return self.abort(out, index, sub, abort::LENGTH_EXCEEDS_MAILBOX);
                }
                let r = self.finish(out, MailboxType::Coe, 10)?;
                self.transfer = Transfer::Upload {
                    index,
                    sub,
                    toggle: false,
                    len: n,
                    pos: 0,
                };
                Some(r)
            }
        }
    }

    fn upload_segment(&mut self, cmd: u8, out: &mut [u8]) -> Option<usize> {
        let Transfer::Upload {
            index,
            sub,
            toggle,
            len,
            pos,
        } = self.transfer
        else {
            return self.abort(out, 0, 0, AbortCode::COMMAND_SPECIFIER);
        };
        if (cmd & TOGGLE != 0) != toggle {
            return self.abort(out, index, sub, AbortCode::TOGGLE_BIT);
        }
        let room = out.len().saturating_sub(HEADER_LEN + COE_HEADER_LEN + 1);
        let k = len.saturating_sub(pos).min(room);
        let end = pos + k;
        let last = end >= len;
        let unused = if k < 7 {
            u8::try_from(7 - k).unwrap_or(0) << 1
        } else {
            0
        };
        let reply = (cmd & TOGGLE) | u8::from(last) | unused;
        let n = (COE_HEADER_LEN + 1 + k).max(10);
        let src = self.buf.get(pos..end)?;
        let p = out.get_mut(HEADER_LEN..HEADER_LEN + n)?;
        p.fill(0);
        p.get_mut(1..3)?.copy_from_slice(&[0x30, reply]);
        p.get_mut(3..3 + k)?.copy_from_slice(src);
        let r = self.finish(out, MailboxType::Coe, n)?;
        self.transfer = if last {
            Transfer::Idle
        } else {
            Transfer::Upload {
                index,
                sub,
                toggle: !toggle,
                len,
                pos: end,
            }
        };
        Some(r)
    }
}

/// Checks a segmented download can succeed in size and access before taking segments.
fn precheck_download(
    od: &dyn ObjectAccess,
    index: u16,
    sub: u8,
    size: usize,
) -> Result<(), AbortCode> {
    let e = od.entry(index, sub)?;
    if !e.access.writable() {
        return Err(AbortCode::READ_ONLY);
    }
    match e.data_type.fixed_size() {
        Some(n) if size > n => Err(AbortCode::LENGTH_TOO_HIGH),
        Some(n) if size < n => Err(AbortCode::LENGTH_TOO_LOW),
        None if size > e.capacity as usize => Err(AbortCode::LENGTH_TOO_HIGH),
        _ => Ok(()),
    }
}

fn write_value(
    desc: &DeviceDescription,
    od: &mut dyn ObjectAccess,
    index: u16,
    sub: u8,
    ca: bool,
    data: &[u8],
) -> Result<(), AbortCode> {
    if ca {
        write_complete(desc, od, index, sub, data)
    } else {
        od.write(index, sub, data)
    }
}

/// Bytes an entry takes in a complete-access image: sub-index 0 of an ARRAY/RECORD is padded
/// to 16 bits.
fn ca_width(kind: ObjectKind, e: &Entry) -> usize {
    let size = e.data_type.fixed_size().unwrap_or(0);
    if kind != ObjectKind::Var && e.sub == 0 && size == 1 {
        2
    } else {
        size
    }
}

fn ca_object(
    desc: &DeviceDescription,
    od: &dyn ObjectAccess,
    index: u16,
) -> Result<&'static od::Object, AbortCode> {
    let obj = desc.object(index).ok_or(AbortCode::NO_OBJECT)?;
    od.entry(index, 0)?;
    if obj.entries.iter().any(|e| e.is_variable()) {
        return Err(super::abort::CA_NOT_SUPPORTED);
    }
    Ok(obj)
}

/// Read every entry from `sub` (0 or 1) on into `buf` (spec §6.4).
pub(crate) fn read_complete(
    desc: &DeviceDescription,
    od: &dyn ObjectAccess,
    index: u16,
    sub: u8,
    buf: &mut [u8],
) -> Result<usize, AbortCode> {
    let obj = ca_object(desc, od, index)?;
    if obj.kind == ObjectKind::Var {
        return od.read(index, 0, buf);
    }
    let mut pos = 0;
    for e in obj.entries.iter().filter(|e| e.sub >= sub) {
        let size = e.data_type.fixed_size().unwrap_or(0);
        let width = ca_width(obj.kind, e);
        let dst = buf
            .get_mut(pos..pos + width)
            .ok_or(AbortCode::OUT_OF_MEMORY)?;
        dst.fill(0);
        let value = dst.get_mut(..size).unwrap_or(&mut []);
        match od.read(index, e.sub, value) {
            Ok(_) => {}
            Err(c) if c == AbortCode::WRITE_ONLY || c == AbortCode::NO_DATA => value.fill(0),
            Err(c) => return Err(c),
        }
        pos += width;
    }
    Ok(pos)
}

/// Write a complete-access image starting at `sub` (0 or 1); see the module notes.
pub(crate) fn write_complete(
    desc: &DeviceDescription,
    od: &mut dyn ObjectAccess,
    index: u16,
    sub: u8,
    data: &[u8],
) -> Result<(), AbortCode> {
    let obj = ca_object(desc, od, index)?;
    if obj.kind == ObjectKind::Var {
        return od.write(index, 0, data);
    }
    // Layout pass: the data must end on an entry boundary, within the object.
    let mut pos = 0;
    for e in obj.entries.iter().filter(|e| e.sub >= sub) {
        if pos >= data.len() {
            break;
        }
        let width = ca_width(obj.kind, e);
        if pos + width > data.len() {
            return Err(AbortCode::LENGTH_MISMATCH);
        }
        pos += width;
    }
    if pos < data.len() {
        return Err(AbortCode::LENGTH_TOO_HIGH);
    }
    if data.is_empty() {
        return Err(AbortCode::LENGTH_TOO_LOW);
    }
    let value = |e: &Entry, at: usize| -> &[u8] {
        let size = e.data_type.fixed_size().unwrap_or(0);
        data.get(at..at + size).unwrap_or(&[])
    };
    let sub0 = obj.entries.first().filter(|e| e.sub == 0 && sub == 0);
    if let Some(e0) = sub0 {
        if e0.behaviour == Behaviour::PdoMapCount {
            // CiA 301 mapping procedure: count 0, entries, count.
            od.write(index, 0, &[0])?;
        }
    }
    let mut pos = 0;
    for e in obj.entries.iter().filter(|e| e.sub >= sub) {
        if pos >= data.len() {
            break;
        }
        if e.sub != 0 {
            write_entry(od, index, e.sub, value(e, pos))?;
        }
        pos += ca_width(obj.kind, e);
    }
    if let Some(e0) = sub0 {
        write_entry(od, index, 0, value(e0, 0))?;
    }
    Ok(())
}

/// One entry of a CA write: a non-writable entry given its current value is skipped.
fn write_entry(od: &mut dyn ObjectAccess, index: u16, sub: u8, v: &[u8]) -> Result<(), AbortCode> {
    match od.write(index, sub, v) {
        Err(AbortCode::READ_ONLY) => {
            let mut cur = [0u8; 8];
            match od.read(index, sub, &mut cur) {
                Ok(n) if cur.get(..n) == Some(v) => Ok(()),
                _ => Err(AbortCode::READ_ONLY),
            }
        }
        r => r,
    }
}
