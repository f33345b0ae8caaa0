//! CoE SDO client messages: the requests a master writes into the receive mailbox (SM0) and
//! the decoding of what the slave posts in the send mailbox (SM1) (ETG.1000.6 §5.6.2;
//! spec §5.1, §6.2–§6.5). The server side is [`crate::coe::sdo_server`].
//!
//! ```text
//! mailbox header (6) | CoE header (2) | command | index (u16) | sub | data (4, or size + data)
//! ```
//!
//! Every builder writes into `out`, the master's copy of the SM0 window: the master writes
//! the whole window so that the write covers its last byte (spec §5.2); `out` must be
//! zeroed beforehand, the builders only write the message. They return the message length
//! (header included), or `None` when `out` is too small.
//!
//! Decisions:
//! * data of 1–4 bytes goes expedited with the size bits (0x23/0x27/0x2B/0x2F); longer data
//!   as a normal download when it fits the window, else an initiate with the first part and
//!   segments (the SOEM way, spec §6.3);
//! * a segment of fewer than 7 bytes is padded to mailbox length 10 with the unused count in
//!   bits 1–3 (spec §6.3), as the server expects;
//! * an abort is accepted with CoE service 2 or 3: the twin (and SOES) send it as an SDO
//!   request (spec §6.5).

use crate::field::{u16_at, u32_at};
use od::AbortCode;

use crate::coe::sdo_server::ccs;
use crate::coe::{service, COE_HEADER_LEN};
use crate::mailbox::{Mailbox, MailboxType, HEADER_LEN};

/// Mailbox header + CoE header + command, index, sub-index + 4 data bytes: the fixed part
/// of an initiate message, and the smallest SDO message.
pub const INITIATE_LEN: usize = HEADER_LEN + COE_HEADER_LEN + 8;
/// Mailbox header + CoE header + command: what precedes segment data.
pub const SEGMENT_HEADER_LEN: usize = HEADER_LEN + COE_HEADER_LEN + 1;
/// A segment carries at least 7 data bytes (padding counted as "unused").
const SEGMENT_MIN_DATA: usize = 7;
/// Command bit 0 of an initiate: size indicated; of a segment: last segment.
const SIZE_OR_LAST: u8 = 0x01;
/// Command bit 1 of an initiate: expedited.
const EXPEDITED: u8 = 0x02;
/// Command bit 4 of a segment: toggle.
const TOGGLE: u8 = 0x10;

/// Server command specifiers (command byte bits 5–7 of responses).
mod scs {
    pub const UPLOAD_SEGMENT: u8 = 0;
    pub const DOWNLOAD_SEGMENT: u8 = 1;
    pub const INITIATE_UPLOAD: u8 = 2;
    pub const INITIATE_DOWNLOAD: u8 = 3;
    pub const ABORT: u8 = 4;
}

/// Writes the mailbox and CoE headers (SDO request) in front of `sdo_len` bytes of SDO data
/// already at `out[8..]`; returns the message length.
fn finish(out: &mut [u8], counter: u8, sdo_len: usize) -> Option<usize> {
    let len = COE_HEADER_LEN + sdo_len;
    if out.len() < HEADER_LEN + len {
        return None;
    }
    let coe = out.get_mut(HEADER_LEN..HEADER_LEN + COE_HEADER_LEN)?;
    coe.copy_from_slice(&[0x00, service::SDO_REQUEST << 4]);
    let mut m = Mailbox::new_unchecked(out.get_mut(..HEADER_LEN)?);
    m.set_header(u16::try_from(len).ok()?, 0, MailboxType::Coe, counter);
    Some(HEADER_LEN + len)
}

/// The SDO part (command byte first) of `out`.
fn sdo_part(out: &mut [u8]) -> Option<&mut [u8]> {
    out.get_mut(HEADER_LEN + COE_HEADER_LEN..)
}

fn initiate(out: &mut [u8], command: u8, index: u16, sub: u8, data: [u8; 4]) -> Option<()> {
    let [il, ih] = index.to_le_bytes();
    let p = sdo_part(out)?.get_mut(..8)?;
    p.copy_from_slice(&[command, il, ih, sub, data[0], data[1], data[2], data[3]]);
    Some(())
}

/// Initiate upload (read) of `index:sub` (0x40; spec §6.3).
pub fn upload(out: &mut [u8], counter: u8, index: u16, sub: u8) -> Option<usize> {
    initiate(out, ccs::INITIATE_UPLOAD << 5, index, sub, [0; 4])?;
    finish(out, counter, 8)
}

/// Upload segment request (0x60 / 0x70 with the toggle bit).
pub fn upload_segment(out: &mut [u8], counter: u8, toggle: bool) -> Option<usize> {
    let cmd = (ccs::UPLOAD_SEGMENT << 5) | if toggle { TOGGLE } else { 0 };
    let p = sdo_part(out)?.get_mut(..8)?;
    p.copy_from_slice(&[cmd, 0, 0, 0, 0, 0, 0, 0]);
    finish(out, counter, 8)
}

/// Initiate download (write) of `data` to `index:sub`: expedited for 1–4 bytes, else normal
/// with the complete size and as much data as fits `out`. Returns the message length and
/// the number of data bytes it carries; the rest goes in [`download_segment`]s.
pub fn download(
    out: &mut [u8],
    counter: u8,
    index: u16,
    sub: u8,
    data: &[u8],
) -> Option<(usize, usize)> {
    if (1..=4).contains(&data.len()) {
        let mut d = [0u8; 4];
        d.get_mut(..data.len())?.copy_from_slice(data);
        let unused = (4 - data.len()) as u8;
        let cmd = (ccs::INITIATE_DOWNLOAD << 5) | (unused << 2) | EXPEDITED | SIZE_OR_LAST;
        initiate(out, cmd, index, sub, d)?;
        return Some((finish(out, counter, 8)?, data.len()));
    }
    let size = u32::try_from(data.len()).ok()?;
    initiate(
        out,
        (ccs::INITIATE_DOWNLOAD << 5) | SIZE_OR_LAST,
        index,
        sub,
        size.to_le_bytes(),
    )?;
    let room = out.len().checked_sub(INITIATE_LEN)?;
    let take = data.len().min(room);
    out.get_mut(INITIATE_LEN..INITIATE_LEN + take)?
        .copy_from_slice(data.get(..take)?);
    Some((finish(out, counter, 8 + take)?, take))
}

/// Download segment with the next part of `rest` (as much as fits `out`); the last-segment
/// bit is set when it takes all of `rest`. Returns the message length and the bytes taken.
pub fn download_segment(
    out: &mut [u8],
    counter: u8,
    toggle: bool,
    rest: &[u8],
) -> Option<(usize, usize)> {
    let room = out.len().checked_sub(SEGMENT_HEADER_LEN)?;
    if room < SEGMENT_MIN_DATA {
        return None;
    }
    let take = rest.len().min(room);
    let last = take == rest.len();
    let unused = SEGMENT_MIN_DATA.saturating_sub(take) as u8;
    let cmd = (ccs::DOWNLOAD_SEGMENT << 5)
        | if toggle { TOGGLE } else { 0 }
        | (unused << 1)
        | if last { SIZE_OR_LAST } else { 0 };
    let p = sdo_part(out)?;
    *p.first_mut()? = cmd;
    p.get_mut(1..1 + take)?.copy_from_slice(rest.get(..take)?);
    let sdo_len = 1 + take.max(SEGMENT_MIN_DATA);
    Some((finish(out, counter, sdo_len)?, take))
}

/// Abort of a transfer by the master (0x80 with the abort code).
pub fn abort(out: &mut [u8], counter: u8, index: u16, sub: u8, code: AbortCode) -> Option<usize> {
    initiate(out, ccs::ABORT << 5, index, sub, code.0.to_le_bytes())?;
    finish(out, counter, 8)
}

/// What the slave answered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Response<'a> {
    /// Expedited upload: the value (1–4 bytes; 4 when the size is not indicated).
    UploadExpedited {
        index: u16,
        sub: u8,
        data: &'a [u8],
    },
    /// Normal upload: the complete size, if indicated, and the data in this message (all of
    /// it, or nothing when segments follow).
    UploadNormal {
        index: u16,
        sub: u8,
        size: Option<u32>,
        data: &'a [u8],
    },
    UploadSegment {
        toggle: bool,
        last: bool,
        data: &'a [u8],
    },
    DownloadInitiate {
        index: u16,
        sub: u8,
    },
    DownloadSegment {
        toggle: bool,
    },
    Abort {
        index: u16,
        sub: u8,
        code: AbortCode,
    },
    /// A CoE emergency (the master skips it and waits on).
    Emergency,
    /// A mailbox error reply (type 0): the detail code (spec §5.5).
    MailboxError(u16),
}

/// Why a message is not an SDO response.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResponseError {
    /// Shorter than its headers or its length field says.
    Truncated,
    /// A mailbox protocol other than CoE (raw type).
    NotCoe(u8),
    /// A CoE service other than SDO response, SDO request (abort) or emergency.
    Service(u8),
    /// A server command specifier that does not exist (raw command byte).
    Command(u8),
}

/// Decodes one message read from the send mailbox (the whole SM1 window may be passed: the
/// mailbox length field bounds it).
pub fn parse_response(msg: &[u8]) -> Result<Response<'_>, ResponseError> {
    let m = Mailbox::new_checked(msg).map_err(|_| ResponseError::Truncated)?;
    let p = msg
        .get(HEADER_LEN..HEADER_LEN + m.length())
        .ok_or(ResponseError::Truncated)?;
    match m.mailbox_type() {
        MailboxType::Error => {
            return match p.get(2..4) {
                Some(_) => Ok(Response::MailboxError(u16_at(p, 2))),
                None => Err(ResponseError::Truncated),
            }
        }
        MailboxType::Coe => {}
        other => return Err(ResponseError::NotCoe(other.to_u8())),
    }
    let svc = p.get(1).ok_or(ResponseError::Truncated)? >> 4;
    if svc == service::EMERGENCY {
        return Ok(Response::Emergency);
    }
    if svc != service::SDO_RESPONSE && svc != service::SDO_REQUEST {
        return Err(ResponseError::Service(svc));
    }
    let sdo = p.get(COE_HEADER_LEN..).ok_or(ResponseError::Truncated)?;
    let cmd = *sdo.first().ok_or(ResponseError::Truncated)?;
    let scs_ = cmd >> 5;
    // A service-2 message from the slave can only be an abort (spec §6.5).
    if svc == service::SDO_REQUEST && scs_ != scs::ABORT {
        return Err(ResponseError::Service(svc));
    }
    if scs_ == scs::UPLOAD_SEGMENT || scs_ == scs::DOWNLOAD_SEGMENT {
        let toggle = cmd & TOGGLE != 0;
        if scs_ == scs::DOWNLOAD_SEGMENT {
            return Ok(Response::DownloadSegment { toggle });
        }
        let rest = sdo.get(1..).unwrap_or(&[]);
        // Up to 7 bytes the unused count says how many are padding (spec §6.3).
        let n = if rest.len() <= SEGMENT_MIN_DATA {
            let unused = usize::from((cmd >> 1) & 0x07);
            rest.len().min(SEGMENT_MIN_DATA - unused)
        } else {
            rest.len()
        };
        return Ok(Response::UploadSegment {
            toggle,
            last: cmd & SIZE_OR_LAST != 0,
            data: rest.get(..n).unwrap_or(&[]),
        });
    }
    if sdo.len() < 8 {
        return Err(ResponseError::Truncated);
    }
    let index = u16_at(sdo, 1);
    let sub = sdo.get(3).copied().unwrap_or(0);
    match scs_ {
        scs::INITIATE_UPLOAD if cmd & EXPEDITED != 0 => {
            let n = if cmd & SIZE_OR_LAST != 0 {
                4 - usize::from((cmd >> 2) & 0x03)
            } else {
                4
            };
            Ok(Response::UploadExpedited {
                index,
                sub,
                data: sdo.get(4..4 + n).ok_or(ResponseError::Truncated)?,
            })
        }
        scs::INITIATE_UPLOAD => Ok(Response::UploadNormal {
            index,
            sub,
            size: (cmd & SIZE_OR_LAST != 0).then(|| u32_at(sdo, 4)),
            data: sdo.get(8..).unwrap_or(&[]),
        }),
        scs::INITIATE_DOWNLOAD => Ok(Response::DownloadInitiate { index, sub }),
        scs::ABORT => Ok(Response::Abort {
            index,
            sub,
            code: AbortCode(u32_at(sdo, 4)),
        }),
        _ => Err(ResponseError::Command(cmd)),
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec;
    use std::vec::Vec;

    use super::*;
    use crate::coe::{CoeConfig, CoeServer};

    #[test]
    fn expedited_upload_request_matches_the_spec_bytes() {
        // spec §6.3: len 10, CoE 0x2000, cmd 0x40, index, sub, 4 zero bytes.
        let mut out = [0u8; 128];
        let n = upload(&mut out, 3, 0x1018, 0x01).expect("fits");
        assert_eq!(n, 16);
        assert_eq!(
            &out[..16],
            &[10, 0, 0, 0, 0, 0x33, 0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]
        );
    }

    #[test]
    fn expedited_download_sets_size_bits() {
        let mut out = [0u8; 128];
        let (n, taken) = download(&mut out, 1, 0x6065, 0, &[0x39, 0x30]).expect("fits");
        assert_eq!((n, taken), (16, 2));
        // 0x2B: expedited, size indicated, 2 unused bytes.
        assert_eq!(
            &out[6..16],
            &[0x00, 0x20, 0x2B, 0x65, 0x60, 0x00, 0x39, 0x30, 0, 0]
        );
        let mut out = [0u8; 128];
        download(&mut out, 1, 0x6065, 0, &[1, 2, 3, 4]).expect("fits");
        assert_eq!(out[8], 0x23);
        download(&mut out, 1, 0x6065, 0, &[1]).expect("fits");
        assert_eq!(out[8], 0x2F);
    }

    #[test]
    fn long_download_is_normal_then_segmented() {
        let data: Vec<u8> = (0..200u8).collect();
        let mut out = [0u8; 128];
        let (n, taken) = download(&mut out, 1, 0x2001, 0, &data).expect("fits");
        // 128-byte window: 16 bytes of headers, 112 data bytes (SOEM: SM0 size − 16).
        assert_eq!((n, taken), (128, 112));
        assert_eq!(out[8], 0x21);
        assert_eq!(&out[12..16], &200u32.to_le_bytes());
        assert_eq!(&out[16..128], &data[..112]);
        let mut out = [0u8; 128];
        let (n, taken) = download_segment(&mut out, 2, false, &data[112..]).expect("fits");
        assert_eq!((n, taken), (9 + 88, 88));
        assert_eq!(out[8], 0x01, "last, toggle 0, no unused bytes");
        let mut out = [0u8; 128];
        let (n, taken) = download_segment(&mut out, 3, true, &[1, 2, 3]).expect("fits");
        // Short last segment: length 10, 4 unused bytes, toggle 1, last.
        assert_eq!((n, taken), (16, 3));
        assert_eq!(out[0], 10);
        assert_eq!(out[8], 0x10 | (4 << 1) | 0x01);
        let mut small = [0u8; 12];
        assert!(download_segment(&mut small, 1, false, &data).is_none());
        assert!(upload(&mut small, 1, 0x1000, 0).is_none());
    }

    #[test]
    fn responses_decode() {
        // Expedited upload of 0x1018:01 = 0x0000001D (0x43: 4 bytes).
        let m = [
            10, 0, 0, 0, 0, 0x13, 0x00, 0x30, 0x43, 0x18, 0x10, 0x01, 0x1D, 0, 0, 0,
        ];
        assert_eq!(
            parse_response(&m),
            Ok(Response::UploadExpedited {
                index: 0x1018,
                sub: 1,
                data: &[0x1D, 0, 0, 0]
            })
        );
        // Abort as the twin sends it: service 2 (spec §6.5), 0602 0000h.
        let m = [
            10, 0, 0, 0, 0, 0x13, 0x00, 0x20, 0x80, 0xFF, 0x5F, 0x00, 0, 0, 0x02, 0x06,
        ];
        assert_eq!(
            parse_response(&m),
            Ok(Response::Abort {
                index: 0x5FFF,
                sub: 0,
                code: AbortCode(0x0602_0000)
            })
        );
        // Mailbox error 0x0002 (protocol not supported).
        let m = [4, 0, 0, 0, 0, 0x10, 0x01, 0x00, 0x02, 0x00];
        assert_eq!(parse_response(&m), Ok(Response::MailboxError(2)));
        // Emergency.
        let m = [10, 0, 0, 0, 0, 0x13, 0x00, 0x10, 0, 0, 0, 0, 0, 0, 0, 0];
        assert_eq!(parse_response(&m), Ok(Response::Emergency));
        // Short upload segment: 3 bytes, 4 unused, last.
        let m = [
            10, 0, 0, 0, 0, 0x13, 0x00, 0x30, 0x09, b'a', b'b', b'c', 0, 0, 0, 0,
        ];
        assert_eq!(
            parse_response(&m),
            Ok(Response::UploadSegment {
                toggle: false,
                last: true,
                data: b"abc"
            })
        );
        assert_eq!(parse_response(&m[..5]), Err(ResponseError::Truncated));
        let m = [10, 0, 0, 0, 0, 0x14, 0, 0x30, 0x43, 0, 0, 0, 0, 0, 0, 0];
        assert_eq!(parse_response(&m), Err(ResponseError::NotCoe(4)));
        // A service-2 message that is not an abort.
        let m = [10, 0, 0, 0, 0, 0x13, 0x00, 0x20, 0x40, 0, 0, 0, 0, 0, 0, 0];
        assert_eq!(parse_response(&m), Err(ResponseError::Service(2)));
        // A length field longer than the message.
        let m = [40, 0, 0, 0, 0, 0x13, 0x00, 0x30, 0x43, 0, 0, 0, 0, 0, 0, 0];
        assert_eq!(parse_response(&m), Err(ResponseError::Truncated));
    }

    /// The client messages against the crate's own SDO server: a 200-byte string written
    /// with a normal initiate and one segment, read back with a normal upload initiate and
    /// segments, toggles alternating.
    #[test]
    fn segmented_round_trip_against_the_server() {
        let desc = &devices::TESTBENCH;
        let mut od =
            od::ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).expect("storage");
        let mut server: CoeServer<8192> = CoeServer::new(desc, CoeConfig::FULL);
        let text: Vec<u8> = (0..200u32).map(|i| b'a' + (i % 26) as u8).collect();
        let mut counter = 0u8;
        let mut next = || {
            counter = crate::mailbox::next_counter(counter);
            counter
        };
        let mut exchange = |req: &[u8]| {
            let mut reply = [0u8; 128];
            let n = server.process(req, &mut od, &mut reply).expect("a reply");
            reply[..n].to_vec()
        };
        let mut out = [0u8; 128];
        let (n, mut pos) = download(&mut out, next(), 0x2001, 0, &text).expect("fits");
        let r = exchange(&out[..n]);
        assert_eq!(
            parse_response(&r),
            Ok(Response::DownloadInitiate {
                index: 0x2001,
                sub: 0
            })
        );
        let mut toggle = false;
        while pos < text.len() {
            let mut out = [0u8; 128];
            let (n, t) = download_segment(&mut out, next(), toggle, &text[pos..]).expect("fits");
            pos += t;
            let r = exchange(&out[..n]);
            assert_eq!(parse_response(&r), Ok(Response::DownloadSegment { toggle }));
            toggle = !toggle;
        }
        let mut out = [0u8; 128];
        let n = upload(&mut out, next(), 0x2001, 0).expect("fits");
        let r = exchange(&out[..n]);
        let mut got = Vec::new();
        let Ok(Response::UploadNormal { size, data, .. }) = parse_response(&r) else {
            panic!("normal upload expected: {r:02X?}");
        };
        assert_eq!(size, Some(200));
        got.extend_from_slice(data);
        let mut toggle = false;
        while got.len() < 200 {
            let mut out = [0u8; 128];
            let n = upload_segment(&mut out, next(), toggle).expect("fits");
            let r = exchange(&out[..n]);
            let Ok(Response::UploadSegment {
                toggle: t,
                last,
                data,
            }) = parse_response(&r)
            else {
                panic!("segment expected: {r:02X?}");
            };
            assert_eq!(t, toggle);
            got.extend_from_slice(data);
            if last {
                break;
            }
            toggle = !toggle;
        }
        assert_eq!(got, text);
    }
}
