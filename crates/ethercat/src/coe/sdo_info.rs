//! SDO information service (CoE service 8; ETG.1000.6 §5.6.3; spec §6.6):
//! what pysoem's `slave.od`, SOEM `slaveinfo -sdo`, ethercrab and TwinCAT use to browse
//! the dictionary.
//!
//! ```text
//! CoE header 0x8000 | opcode (bit 7: incomplete) | reserved | fragments left (u16) | data
//! ```
//!
//! Decisions:
//! * OD lists: 1 all objects, 2 objects with an RxPDO-mappable entry (mappable and writable),
//!   3 with a TxPDO-mappable entry (mappable and readable), 4 "stored for device replacement"
//!   = objects with an entry that 1010h saves (`storable`), 5 "start-up parameters" = objects
//!   with a storable writable entry; list 0 gives the five counts. Hidden objects
//!   ([`super::CoeConfig::hidden`]) are in none. A list that does not fit one send mailbox is
//!   split: every fragment but the last has the incomplete bit and the fragments-left count
//!   goes down to 0; the further fragments are posted by [`super::CoeServer::poll`] (and
//!   [`super::pump`]) each time the master has read the previous one, as SOES does.
//! * Object description: data type = the VAR's type, an ARRAY's element type (sub 1), or for
//!   a RECORD the CiA 301 complex type where there is one (0020h PDO communication, 0021h
//!   PDO mapping, 0022h SDO parameter, 0023h identity), else 0000h; max sub-index = the
//!   highest sub-index; object code 7/8/9; the name is cut to fit the mailbox.
//! * Entry description: value-info bits 0–2 (access, category, PDO mapping, which are always
//!   in the fixed part) are echoed; default (0x10), minimum (0x20) and maximum (0x40) are
//!   included for fixed-size types when the description has them (no default for
//!   node-relative defaults: the dictionary knows the node-ID, the description does not), and
//!   their bits echoed only then; the unit type (0x08) is never included (the description's
//!   units are text, not CiA 303-2 codes). Object access: readable in Pre-Op/Safe-Op/Op (bits
//!   0–2); writable in all three (bits 3–5), except the PDO mapping and SM assignment objects
//!   (1600h–17FFh, 1A00h–1BFFh, 1C10h–1C2Fh): Pre-Op only (ETG.1000.6); bit 6 RxPDO and
//!   bit 7 TxPDO mappable as for the lists; bit 8 backup and bit 9 setting as lists 4 and 5.
//!   Data type, bit length (size or capacity × 8; BOOLEAN is 8 bits as the dictionary
//!   stores it), then the optional values, then the name.
//! * Unknown or hidden object: SDO info error 0602 0000h; unknown sub-index 0609 0011h; an
//!   unknown list type 0601 0000h; an unknown opcode 0504 0001h.

use od::{AbortCode, Entry, Object, ObjectAccess, ObjectKind, Value};

use super::{CoeConfig, CoeServer, COE_HEADER_LEN};
use crate::mailbox::{MailboxErrorDetail, MailboxType, HEADER_LEN};

/// SDO info opcodes (info header byte 0 bits 0–6).
pub mod opcode {
    pub const GET_OD_LIST_REQ: u8 = 0x01;
    pub const GET_OD_LIST_RES: u8 = 0x02;
    pub const GET_OBJECT_DESC_REQ: u8 = 0x03;
    pub const GET_OBJECT_DESC_RES: u8 = 0x04;
    pub const GET_ENTRY_DESC_REQ: u8 = 0x05;
    pub const GET_ENTRY_DESC_RES: u8 = 0x06;
    pub const INFO_ERROR: u8 = 0x07;
}

/// Info header byte 0 bit 7: more fragments follow.
pub const INCOMPLETE: u8 = 0x80;

/// OD list types.
pub mod list {
    pub const COUNTS: u16 = 0;
    pub const ALL: u16 = 1;
    pub const RX_PDO: u16 = 2;
    pub const TX_PDO: u16 = 3;
    pub const BACKUP: u16 = 4;
    pub const STARTUP: u16 = 5;
}

/// Value-info bits of the entry description.
pub mod value_info {
    pub const ACCESS: u8 = 0x01;
    pub const CATEGORY: u8 = 0x02;
    pub const PDO_MAPPING: u8 = 0x04;
    pub const UNIT: u8 = 0x08;
    pub const DEFAULT: u8 = 0x10;
    pub const MINIMUM: u8 = 0x20;
    pub const MAXIMUM: u8 = 0x40;
}

/// Info header: CoE header + opcode, reserved, fragments left.
const INFO_HEADER: usize = COE_HEADER_LEN + 4;

/// A fragmented OD list reply in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ListFragments {
    list: u16,
    /// Position in the description's object table to continue from.
    next: usize,
    /// Fragments after the one to send next.
    left: u16,
    first: bool,
    /// Indices per fragment after the first.
    per_fragment: usize,
}

fn rx_mappable(e: &Entry) -> bool {
    e.pdo_mappable && e.access.writable()
}

fn tx_mappable(e: &Entry) -> bool {
    e.pdo_mappable && e.access.readable()
}

fn setting(e: &Entry) -> bool {
    e.storable && e.access.writable()
}

fn in_list(config: &CoeConfig, o: &Object, list_type: u16) -> bool {
    if config.is_hidden(o.index) {
        return false;
    }
    let any = |f: fn(&Entry) -> bool| o.entries.iter().any(f);
    match list_type {
        list::ALL => true,
        list::RX_PDO => any(rx_mappable),
        list::TX_PDO => any(tx_mappable),
        list::BACKUP => any(|e| e.storable),
        list::STARTUP => any(setting),
        _ => false,
    }
}

fn record_type(index: u16) -> u16 {
    match index {
        0x1018 => 0x0023,
        0x1200..=0x12FF => 0x0022,
        0x1400..=0x15FF | 0x1800..=0x19FF => 0x0020,
        0x1600..=0x17FF | 0x1A00..=0x1BFF => 0x0021,
        _ => 0x0000,
    }
}

fn object_data_type(o: &Object) -> u16 {
    match o.kind {
        ObjectKind::Var => o.entries.first().map_or(0, |e| e.data_type.code()),
        ObjectKind::Array => o
            .entries
            .iter()
            .find(|e| e.sub != 0)
            .map_or(0, |e| e.data_type.code()),
        ObjectKind::Record => record_type(o.index),
    }
}

/// Object access word of an entry description.
fn object_access(e: &Entry) -> u16 {
    let mut a = 0u16;
    if e.access.readable() {
        a |= 0x0007;
    }
    if e.access.writable() {
        a |= match e.index {
            0x1600..=0x17FF | 0x1A00..=0x1BFF | 0x1C10..=0x1C2F => 0x0008,
            _ => 0x0038,
        };
    }
    if rx_mappable(e) {
        a |= 0x0040;
    }
    if tx_mappable(e) {
        a |= 0x0080;
    }
    if e.storable {
        a |= 0x0100;
    }
    if setting(e) {
        a |= 0x0200;
    }
    a
}

/// Small cursor over an output slice: every write is bounds-checked.
struct Cursor<'a> {
    buf: &'a mut [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn new(buf: &'a mut [u8]) -> Self {
        Cursor { buf, pos: 0 }
    }
    fn put(&mut self, b: &[u8]) -> Option<()> {
        self.buf
            .get_mut(self.pos..self.pos + b.len())?
            .copy_from_slice(b);
        self.pos += b.len();
        Some(())
    }
    fn u16(&mut self, v: u16) -> Option<()> {
        self.put(&v.to_le_bytes())
    }
    fn room(&self) -> usize {
        self.buf.len().saturating_sub(self.pos)
    }
    /// As much of `s` as fits.
    fn put_cut(&mut self, s: &[u8]) -> Option<()> {
        let n = s.len().min(self.room());
        self.put(s.get(..n)?)
    }
}

fn info_header(c: &mut Cursor<'_>, op: u8, left: u16) -> Option<()> {
    c.put(&[0x00, super::service::SDO_INFO << 4, op, 0x00])?;
    c.u16(left)
}

impl<const N: usize> CoeServer<N> {
    /// `p`: the mailbox payload (CoE header first).
    pub(crate) fn sdo_info_request(
        &mut self,
        p: &[u8],
        od: &mut dyn ObjectAccess,
        out: &mut [u8],
    ) -> Option<usize> {
        self.info = None;
        let Some(op) = p.get(2).map(|b| b & 0x7F) else {
            return self.mailbox_error(out, MailboxErrorDetail::InvalidSize);
        };
        let body = p.get(INFO_HEADER..).unwrap_or(&[]);
        let need = match op {
            opcode::GET_OD_LIST_REQ | opcode::GET_OBJECT_DESC_REQ => 2,
            opcode::GET_ENTRY_DESC_REQ => 4,
            _ => 0,
        };
        if p.len() < INFO_HEADER || body.len() < need {
            return self.mailbox_error(out, MailboxErrorDetail::InvalidSize);
        }
        let w = |i: usize| {
            u16::from_le_bytes([
                body.get(i).copied().unwrap_or(0),
                body.get(i + 1).copied().unwrap_or(0),
            ])
        };
        match op {
            opcode::GET_OD_LIST_REQ => self.od_list(w(0), out),
            opcode::GET_OBJECT_DESC_REQ => self.object_description(w(0), out),
            opcode::GET_ENTRY_DESC_REQ => {
                let sub = body.get(2).copied().unwrap_or(0);
                let vi = body.get(3).copied().unwrap_or(0);
                self.entry_description(w(0), sub, vi, od, out)
            }
            _ => self.info_error(out, AbortCode::COMMAND_SPECIFIER),
        }
    }

    fn info_error(&mut self, out: &mut [u8], code: AbortCode) -> Option<usize> {
        self.counters.info_errors = self.counters.info_errors.saturating_add(1);
        self.write_message(out, MailboxType::Coe, |p| {
            let mut c = Cursor::new(p);
            info_header(&mut c, opcode::INFO_ERROR, 0)?;
            c.put(&code.0.to_le_bytes())?;
            Some(c.pos)
        })
    }

    fn count(&self, list_type: u16) -> usize {
        let config = self.config;
        self.desc
            .objects
            .iter()
            .filter(|o| in_list(&config, o, list_type))
            .count()
    }

    fn od_list(&mut self, list_type: u16, out: &mut [u8]) -> Option<usize> {
        if list_type == list::COUNTS {
            let counts = [
                list::ALL,
                list::RX_PDO,
                list::TX_PDO,
                list::BACKUP,
                list::STARTUP,
            ]
            .map(|l| u16::try_from(self.count(l)).unwrap_or(u16::MAX));
            return self.write_message(out, MailboxType::Coe, |p| {
                let mut c = Cursor::new(p);
                info_header(&mut c, opcode::GET_OD_LIST_RES, 0)?;
                c.u16(list::COUNTS)?;
                for n in counts {
                    c.u16(n)?;
                }
                Some(c.pos)
            });
        }
        if !(list::ALL..=list::STARTUP).contains(&list_type) {
            return self.info_error(out, AbortCode::UNSUPPORTED_ACCESS);
        }
        let room = out.len().saturating_sub(HEADER_LEN + INFO_HEADER);
        let first = room.saturating_sub(2) / 2;
        let per_fragment = room / 2;
        if first == 0 {
            return self.info_error(out, super::abort::LENGTH_EXCEEDS_MAILBOX);
        }
        let total = self.count(list_type);
        let rest = total.saturating_sub(first);
        let left = rest.div_ceil(per_fragment);
        self.info = Some(ListFragments {
            list: list_type,
            next: 0,
            left: u16::try_from(left).unwrap_or(u16::MAX),
            first: true,
            per_fragment,
        });
        self.next_list_fragment(out)
    }

    /// The next fragment of the OD list in progress.
    pub(crate) fn next_list_fragment(&mut self, out: &mut [u8]) -> Option<usize> {
        let st = self.info?;
        let config = self.config;
        let objects = self.desc.objects;
        let op = opcode::GET_OD_LIST_RES | if st.left > 0 { INCOMPLETE } else { 0 };
        let mut next = st.next;
        let n = {
            let p = out.get_mut(HEADER_LEN..)?;
            let mut c = Cursor::new(p);
            info_header(&mut c, op, st.left)?;
            let cap = if st.first {
                c.u16(st.list)?;
                c.room() / 2
            } else {
                (c.room() / 2).min(st.per_fragment)
            };
            let mut k = 0;
            while k < cap {
                let Some(o) = objects.get(next) else { break };
                next += 1;
                if in_list(&config, o, st.list) {
                    c.u16(o.index)?;
                    k += 1;
                }
            }
            c.pos
        };
        let r = self.finish(out, MailboxType::Coe, n)?;
        self.info = if st.left == 0 {
            None
        } else {
            Some(ListFragments {
                next,
                left: st.left - 1,
                first: false,
                ..st
            })
        };
        Some(r)
    }

    fn object_description(&mut self, index: u16, out: &mut [u8]) -> Option<usize> {
        let obj = match self.desc.object(index) {
            Some(o) if !self.config.is_hidden(index) => o,
            _ => return self.info_error(out, AbortCode::NO_OBJECT),
        };
        let [il, ih] = index.to_le_bytes();
        let [tl, th] = object_data_type(obj).to_le_bytes();
        let max_sub = obj.entries.last().map_or(0, |e| e.sub);
        let code = obj.kind.object_code();
        self.write_message(out, MailboxType::Coe, |p| {
            let mut c = Cursor::new(p);
            info_header(&mut c, opcode::GET_OBJECT_DESC_RES, 0)?;
            c.put(&[il, ih, tl, th, max_sub, code])?;
            c.put_cut(obj.name.as_bytes())?;
            Some(c.pos)
        })
    }

    fn entry_description(
        &mut self,
        index: u16,
        sub: u8,
        vi: u8,
        od: &mut dyn ObjectAccess,
        out: &mut [u8],
    ) -> Option<usize> {
        let obj = match self.desc.object(index) {
            Some(o) if !self.config.is_hidden(index) => o,
            _ => return self.info_error(out, AbortCode::NO_OBJECT),
        };
        let Some(e) = obj.entry(sub) else {
            return self.info_error(out, AbortCode::NO_SUB_INDEX);
        };
        if let Err(code) = od.entry(index, sub) {
            return self.info_error(out, code);
        }
        let bits = e
            .data_type
            .fixed_size()
            .map_or(e.bit_len(), |n| u32::try_from(n * 8).unwrap_or(0));
        let bits = u16::try_from(bits).unwrap_or(u16::MAX);
        // Optional values, each in the entry's size.
        let mut opt = [[0u8; 8]; 3];
        let mut included =
            vi & (value_info::ACCESS | value_info::CATEGORY | value_info::PDO_MAPPING);
        let size = e.data_type.fixed_size().unwrap_or(0);
        if size > 0 {
            if vi & value_info::DEFAULT != 0 && !e.default_plus_node_id {
                let n = e.default.len().min(size);
                if let (Some(d), Some(s)) = (opt[0].get_mut(..n), e.default.get(..n)) {
                    d.copy_from_slice(s);
                    included |= value_info::DEFAULT;
                }
            }
            for (bit, slot, limit) in [
                (value_info::MINIMUM, 1, e.min),
                (value_info::MAXIMUM, 2, e.max),
            ] {
                if vi & bit == 0 {
                    continue;
                }
                if let (Some(l), Some(dst)) = (limit, opt.get_mut(slot)) {
                    if Value::from_limit(l).encode(e.data_type, dst).is_some() {
                        included |= bit;
                    }
                }
            }
        }
        let [il, ih] = index.to_le_bytes();
        let access = object_access(e);
        self.write_message(out, MailboxType::Coe, |p| {
            let mut c = Cursor::new(p);
            info_header(&mut c, opcode::GET_ENTRY_DESC_RES, 0)?;
            c.put(&[il, ih, sub, included])?;
            c.u16(e.data_type.code())?;
            c.u16(bits)?;
            c.u16(access)?;
            for (bit, slot) in [
                (value_info::DEFAULT, 0usize),
                (value_info::MINIMUM, 1),
                (value_info::MAXIMUM, 2),
            ] {
                if included & bit != 0 {
                    c.put(opt.get(slot)?.get(..size)?)?;
                }
            }
            c.put_cut(e.name.as_bytes())?;
            Some(c.pos)
        })
    }
}
