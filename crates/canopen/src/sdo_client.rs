//! SDO client (CiA 301 §7.2.4): expedited and segmented upload and download, one transfer at
//! a time, with the toggle bit and aborts. Sans-IO: a transfer starts with the request to
//! send, each response of the server gives the next request (or the end), and the caller
//! moves the frames and keeps the time, so one client serves an async master, a recorder
//! that logs each request as a step, and a microcontroller.
//!
//! The client holds no buffer: a download takes the value at each call, an upload hands out
//! the bytes each response carries, to be appended by the caller.

use core::fmt;

use od::AbortCode;

/// The data bytes of an SDO request or response frame (always 8 on the wire, §7.2.4.3).
pub type Sdo = [u8; 8];

/// Client command specifiers (ccs, bits 5–7 of byte 0) and the server's answers (scs).
mod cs {
    /// ccs 0: download segment request.
    pub const DOWNLOAD_SEGMENT: u8 = 0x00;
    /// ccs 1: initiate download request.
    pub const INITIATE_DOWNLOAD: u8 = 0x20;
    /// ccs 2: initiate upload request.
    pub const INITIATE_UPLOAD: u8 = 0x40;
    /// ccs 3: upload segment request.
    pub const UPLOAD_SEGMENT: u8 = 0x60;
    /// cs 4: abort transfer (client and server).
    pub const ABORT: u8 = 0x80;
    /// The specifier bits.
    pub const MASK: u8 = 0xE0;

    /// scs 0: upload segment response.
    pub const UPLOAD_SEGMENT_RESPONSE: u8 = 0x00;
    /// scs 1: download segment response.
    pub const DOWNLOAD_SEGMENT_RESPONSE: u8 = 0x20;
    /// scs 2: initiate upload response.
    pub const INITIATE_UPLOAD_RESPONSE: u8 = 0x40;
    /// scs 3: initiate download response (no other bit set).
    pub const INITIATE_DOWNLOAD_RESPONSE: u8 = 0x60;

    /// Initiate: e, expedited transfer.
    pub const EXPEDITED: u8 = 0x02;
    /// Initiate: s, size indicated.
    pub const SIZE_INDICATED: u8 = 0x01;
    /// Segment: t, the toggle bit.
    pub const TOGGLE: u8 = 0x10;
    /// Segment: c, no more segments.
    pub const LAST: u8 = 0x01;
}

/// Bytes of the value in one segment.
const SEGMENT_DATA: usize = 7;
/// Bytes of the value in an expedited frame.
const EXPEDITED_DATA: usize = 4;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Idle,
    /// The initiate request went out.
    Initiate,
    /// A segment request went out.
    Segment,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Direction {
    Upload,
    Download,
}

/// What a response asks of the caller.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Progress<'r> {
    /// Send `request` and wait for its response. `data`: the bytes of the value the response
    /// carried (an upload's segment; empty in a download).
    Next { data: &'r [u8], request: Sdo },
    /// The transfer is complete. `data`: the last bytes of an uploaded value (all of it when
    /// expedited; empty in a download).
    Done { data: &'r [u8] },
}

/// Why a transfer ended without completing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SdoClientError {
    /// The server aborted the transfer (§7.2.4.3.17).
    Abort(AbortCode),
    /// A response that does not answer the request. `abort` is the abort request to send
    /// where the client ends the transfer with one.
    Unexpected { response: Sdo, abort: Option<Sdo> },
    /// A segmented upload ended with another size than its initiate response announced.
    Size {
        announced: u32,
        received: u32,
        response: Sdo,
    },
    /// A response came while no transfer runs.
    Idle,
}

impl fmt::Display for SdoClientError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SdoClientError::Abort(code) => write!(f, "SDO abort {code}"),
            SdoClientError::Unexpected { response, .. } => {
                write!(f, "unexpected SDO response {response:02X?}")
            }
            SdoClientError::Size {
                announced,
                received,
                ..
            } => write!(
                f,
                "the server announced {announced} bytes and sent {received}"
            ),
            SdoClientError::Idle => write!(f, "an SDO response without a transfer"),
        }
    }
}

/// One SDO client channel: at most one transfer at a time.
#[derive(Debug, Clone)]
pub struct SdoClient {
    phase: Phase,
    direction: Direction,
    index: u16,
    sub: u8,
    /// The toggle bit of the segment request in flight.
    toggle: bool,
    /// Download: the value's length. Upload: the size the server announced, if it did.
    size: Option<u32>,
    /// Bytes moved in segments so far.
    moved: u32,
}

impl Default for SdoClient {
    fn default() -> Self {
        Self::new()
    }
}

fn multiplexed(cs: u8, index: u16, sub: u8, data: [u8; 4]) -> Sdo {
    let [i0, i1] = index.to_le_bytes();
    let [d0, d1, d2, d3] = data;
    [cs, i0, i1, sub, d0, d1, d2, d3]
}

/// The abort request or response for `index`:`sub` (§7.2.4.3.17).
pub fn abort_request(index: u16, sub: u8, code: AbortCode) -> Sdo {
    multiplexed(cs::ABORT, index, sub, code.0.to_le_bytes())
}

impl SdoClient {
    pub const fn new() -> Self {
        SdoClient {
            phase: Phase::Idle,
            direction: Direction::Upload,
            index: 0,
            sub: 0,
            toggle: false,
            size: None,
            moved: 0,
        }
    }

    /// Whether no transfer runs.
    pub fn is_idle(&self) -> bool {
        self.phase == Phase::Idle
    }

    /// Starts reading `index`:`sub`: the initiate upload request (§7.2.4.3.6). A transfer
    /// that was running is dropped.
    pub fn upload(&mut self, index: u16, sub: u8) -> Sdo {
        self.start(Direction::Upload, index, sub, None);
        multiplexed(cs::INITIATE_UPLOAD, index, sub, [0; 4])
    }

    /// Starts writing `data` to `index`:`sub`: the initiate download request (§7.2.4.3.3),
    /// expedited for 1 to 4 bytes, segmented with the size indicated otherwise (an empty
    /// value too: one empty last segment follows). Every later call of
    /// [`on_response`](Self::on_response) takes the same `data`.
    pub fn download(&mut self, index: u16, sub: u8, data: &[u8]) -> Sdo {
        let len = u32::try_from(data.len()).unwrap_or(u32::MAX);
        self.start(Direction::Download, index, sub, Some(len));
        if (1..=EXPEDITED_DATA).contains(&data.len()) {
            // n: bytes of the 4 that hold no data.
            let n = (EXPEDITED_DATA - data.len()) as u8;
            let mut d = [0u8; 4];
            for (dst, src) in d.iter_mut().zip(data) {
                *dst = *src;
            }
            let cs = cs::INITIATE_DOWNLOAD | (n << 2) | cs::EXPEDITED | cs::SIZE_INDICATED;
            multiplexed(cs, index, sub, d)
        } else {
            let cs = cs::INITIATE_DOWNLOAD | cs::SIZE_INDICATED;
            multiplexed(cs, index, sub, len.to_le_bytes())
        }
    }

    /// Ends the running transfer from this side (a timeout, a value too large for the
    /// caller): the abort request to send, `None` when no transfer runs.
    pub fn abort(&mut self, code: AbortCode) -> Option<Sdo> {
        if self.is_idle() {
            return None;
        }
        self.phase = Phase::Idle;
        Some(abort_request(self.index, self.sub, code))
    }

    fn start(&mut self, direction: Direction, index: u16, sub: u8, size: Option<u32>) {
        *self = SdoClient {
            phase: Phase::Initiate,
            direction,
            index,
            sub,
            toggle: false,
            size,
            moved: 0,
        };
    }

    /// The server's response to the request in flight. `data` is the value being
    /// downloaded (ignored in an upload). Any error ends the transfer.
    pub fn on_response<'r>(
        &mut self,
        response: &'r Sdo,
        data: &[u8],
    ) -> Result<Progress<'r>, SdoClientError> {
        let phase = self.phase;
        if phase == Phase::Idle {
            return Err(SdoClientError::Idle);
        }
        // Ended unless a segment request follows.
        self.phase = Phase::Idle;
        if response[0] == cs::ABORT {
            let [_, _, _, _, c0, c1, c2, c3] = *response;
            return Err(SdoClientError::Abort(AbortCode(u32::from_le_bytes([
                c0, c1, c2, c3,
            ]))));
        }
        let progress = match (self.direction, phase) {
            (Direction::Upload, Phase::Initiate) => self.upload_initiated(response),
            (Direction::Upload, _) => self.upload_segment(response),
            (Direction::Download, Phase::Initiate) => self.download_initiated(response, data),
            (Direction::Download, _) => self.download_segment(response, data),
        }?;
        if matches!(progress, Progress::Next { .. }) {
            self.phase = Phase::Segment;
        }
        Ok(progress)
    }

    fn unexpected(&self, response: &Sdo, abort: Option<AbortCode>) -> SdoClientError {
        SdoClientError::Unexpected {
            response: *response,
            abort: abort.map(|code| abort_request(self.index, self.sub, code)),
        }
    }

    /// The initiate upload response (§7.2.4.3.7): the value itself (e = 1), or the size of a
    /// segmented one. Its multiplexer must be the request's, as python-canopen checks too.
    fn upload_initiated<'r>(&mut self, r: &'r Sdo) -> Result<Progress<'r>, SdoClientError> {
        let [c, i0, i1, sub, d0, d1, d2, d3] = *r;
        if c & cs::MASK != cs::INITIATE_UPLOAD_RESPONSE
            || u16::from_le_bytes([i0, i1]) != self.index
            || sub != self.sub
        {
            return Err(self.unexpected(r, None));
        }
        let size_indicated = c & cs::SIZE_INDICATED != 0;
        if c & cs::EXPEDITED != 0 {
            // n: bytes of the 4 that hold no data, valid with s = 1.
            let n = if size_indicated {
                usize::from((c >> 2) & 3)
            } else {
                0
            };
            let data = r.get(4..8 - n).unwrap_or(&[]);
            return Ok(Progress::Done { data });
        }
        self.size = size_indicated.then(|| u32::from_le_bytes([d0, d1, d2, d3]));
        Ok(Progress::Next {
            data: &[],
            request: self.segment_request(cs::UPLOAD_SEGMENT),
        })
    }

    /// An upload segment response (§7.2.4.3.9).
    ///
    /// **Decision:** any response but the segment with the awaited toggle bit (another
    /// command too) is answered with abort 0503 0000h "toggle bit not alternated": the client
    /// awaited that segment and no other.
    fn upload_segment<'r>(&mut self, r: &'r Sdo) -> Result<Progress<'r>, SdoClientError> {
        let c = r[0];
        if c & cs::MASK != cs::UPLOAD_SEGMENT_RESPONSE || (c & cs::TOGGLE != 0) != self.toggle {
            return Err(self.unexpected(r, Some(AbortCode::TOGGLE_BIT)));
        }
        // n: bytes of the 7 that hold no data.
        let n = usize::from((c >> 1) & 7);
        let data = r.get(1..8 - n).unwrap_or(&[]);
        self.moved = self.moved.saturating_add(data.len() as u32);
        if c & cs::LAST == 0 {
            self.toggle = !self.toggle;
            return Ok(Progress::Next {
                data,
                request: self.segment_request(cs::UPLOAD_SEGMENT),
            });
        }
        match self.size {
            Some(announced) if announced != self.moved => Err(SdoClientError::Size {
                announced,
                received: self.moved,
                response: *r,
            }),
            _ => Ok(Progress::Done { data }),
        }
    }

    /// The initiate download response (§7.2.4.3.4): done if expedited, else the first
    /// segment.
    fn download_initiated<'r>(
        &mut self,
        r: &'r Sdo,
        data: &[u8],
    ) -> Result<Progress<'r>, SdoClientError> {
        if r[0] != cs::INITIATE_DOWNLOAD_RESPONSE {
            return Err(self.unexpected(r, None));
        }
        if (1..=EXPEDITED_DATA).contains(&data.len()) {
            return Ok(Progress::Done { data: &[] });
        }
        Ok(Progress::Next {
            data: &[],
            request: self.download_segment_request(data),
        })
    }

    /// A download segment response (§7.2.4.3.5), with the toggle bit of the segment it
    /// confirms.
    fn download_segment<'r>(
        &mut self,
        r: &'r Sdo,
        data: &[u8],
    ) -> Result<Progress<'r>, SdoClientError> {
        let c = r[0];
        if c & cs::MASK != cs::DOWNLOAD_SEGMENT_RESPONSE {
            return Err(self.unexpected(r, None));
        }
        if (c & cs::TOGGLE != 0) != self.toggle {
            return Err(self.unexpected(r, Some(AbortCode::TOGGLE_BIT)));
        }
        if self.moved as usize >= data.len() {
            return Ok(Progress::Done { data: &[] });
        }
        self.toggle = !self.toggle;
        Ok(Progress::Next {
            data: &[],
            request: self.download_segment_request(data),
        })
    }

    /// An upload segment request with the current toggle bit.
    fn segment_request(&self, ccs: u8) -> Sdo {
        let t = if self.toggle { cs::TOGGLE } else { 0 };
        [ccs | t, 0, 0, 0, 0, 0, 0, 0]
    }

    /// The next download segment of `data` (§7.2.4.3.5): up to 7 bytes, c set on the last.
    fn download_segment_request(&mut self, data: &[u8]) -> Sdo {
        let rest = data.get(self.moved as usize..).unwrap_or(&[]);
        let chunk = rest.get(..SEGMENT_DATA).unwrap_or(rest);
        self.moved = self.moved.saturating_add(chunk.len() as u32);
        let last = chunk.len() == rest.len();
        // n: bytes of the 7 that hold no data.
        let n = (SEGMENT_DATA - chunk.len()) as u8;
        let mut req = self.segment_request(cs::DOWNLOAD_SEGMENT);
        req[0] |= (n << 1) | if last { cs::LAST } else { 0 };
        for (dst, src) in req.iter_mut().skip(1).zip(chunk) {
            *dst = *src;
        }
        req
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_expedited_upload_is_one_request() {
        let mut c = SdoClient::new();
        assert_eq!(c.upload(0x1018, 1), [0x40, 0x18, 0x10, 1, 0, 0, 0, 0]);
        let r = [0x43, 0x18, 0x10, 1, 0x1D, 0, 0, 0];
        assert_eq!(
            c.on_response(&r, &[]),
            Ok(Progress::Done {
                data: &[0x1D, 0, 0, 0]
            })
        );
        assert!(c.is_idle());
        // One byte (n = 3), and e = 1 without s: four bytes.
        c.upload(0x2005, 0);
        let r = [0x4F, 0x05, 0x20, 0, 42, 0, 0, 0];
        assert_eq!(c.on_response(&r, &[]), Ok(Progress::Done { data: &[42] }));
        c.upload(0x2005, 0);
        let r = [0x42, 0x05, 0x20, 0, 1, 2, 3, 4];
        assert_eq!(
            c.on_response(&r, &[]),
            Ok(Progress::Done {
                data: &[1, 2, 3, 4]
            })
        );
    }

    #[test]
    fn a_segmented_upload_asks_with_the_toggle_until_the_last() {
        let mut c = SdoClient::new();
        c.upload(0x1008, 0);
        let r = [0x41, 0x08, 0x10, 0, 10, 0, 0, 0];
        assert_eq!(
            c.on_response(&r, &[]),
            Ok(Progress::Next {
                data: &[],
                request: [0x60, 0, 0, 0, 0, 0, 0, 0]
            })
        );
        let r = [0x00, b'd', b'r', b'i', b'v', b'e', b' ', b'1'];
        assert_eq!(
            c.on_response(&r, &[]),
            Ok(Progress::Next {
                data: b"drive 1",
                request: [0x70, 0, 0, 0, 0, 0, 0, 0]
            })
        );
        let r = [0x19, b'x', b'y', b'z', 0, 0, 0, 0];
        assert_eq!(c.on_response(&r, &[]), Ok(Progress::Done { data: b"xyz" }));
    }

    #[test]
    fn a_wrong_toggle_or_size_ends_the_upload() {
        let mut c = SdoClient::new();
        c.upload(0x1008, 0);
        let _ = c.on_response(&[0x41, 0x08, 0x10, 0, 10, 0, 0, 0], &[]);
        let r = [0x10, 1, 2, 3, 4, 5, 6, 7];
        assert_eq!(
            c.on_response(&r, &[]),
            Err(SdoClientError::Unexpected {
                response: r,
                abort: Some([0x80, 0x08, 0x10, 0, 0, 0, 0x03, 0x05])
            })
        );
        assert!(c.is_idle());
        assert_eq!(c.on_response(&r, &[]), Err(SdoClientError::Idle));

        c.upload(0x1008, 0);
        let _ = c.on_response(&[0x41, 0x08, 0x10, 0, 10, 0, 0, 0], &[]);
        let r = [0x07, 1, 2, 3, 4, 0, 0, 0];
        assert_eq!(
            c.on_response(&r, &[]),
            Err(SdoClientError::Size {
                announced: 10,
                received: 4,
                response: r
            })
        );
    }

    #[test]
    fn an_upload_answered_for_another_object_is_refused() {
        let mut c = SdoClient::new();
        c.upload(0x1018, 1);
        let r = [0x43, 0x18, 0x10, 2, 0x1D, 0, 0, 0];
        assert_eq!(
            c.on_response(&r, &[]),
            Err(SdoClientError::Unexpected {
                response: r,
                abort: None
            })
        );
    }

    #[test]
    fn downloads_are_expedited_up_to_four_bytes_and_segmented_above() {
        let mut c = SdoClient::new();
        let v = [0x06, 0x00];
        assert_eq!(c.download(0x6040, 0, &v), [0x2B, 0x40, 0x60, 0, 6, 0, 0, 0]);
        let r = [0x60, 0x40, 0x60, 0, 0, 0, 0, 0];
        assert_eq!(c.on_response(&r, &v), Ok(Progress::Done { data: &[] }));
        assert_eq!(
            c.download(0x6060, 0, &[1]),
            [0x2F, 0x60, 0x60, 0, 1, 0, 0, 0]
        );
        assert_eq!(
            c.download(0x607A, 0, &[1, 2, 3, 4]),
            [0x23, 0x7A, 0x60, 0, 1, 2, 3, 4]
        );

        let v: [u8; 9] = [1, 2, 3, 4, 5, 6, 7, 8, 9];
        assert_eq!(c.download(0x2000, 1, &v), [0x21, 0, 0x20, 1, 9, 0, 0, 0]);
        let r = [0x60, 0, 0x20, 1, 0, 0, 0, 0];
        assert_eq!(
            c.on_response(&r, &v),
            Ok(Progress::Next {
                data: &[],
                request: [0x00, 1, 2, 3, 4, 5, 6, 7]
            })
        );
        let r = [0x20, 0, 0, 0, 0, 0, 0, 0];
        assert_eq!(
            c.on_response(&r, &v),
            Ok(Progress::Next {
                data: &[],
                request: [0x1B, 8, 9, 0, 0, 0, 0, 0]
            })
        );
        let r = [0x30, 0, 0, 0, 0, 0, 0, 0];
        assert_eq!(c.on_response(&r, &v), Ok(Progress::Done { data: &[] }));
    }

    #[test]
    fn an_empty_download_sends_one_empty_last_segment() {
        let mut c = SdoClient::new();
        assert_eq!(c.download(0x2000, 1, &[]), [0x21, 0, 0x20, 1, 0, 0, 0, 0]);
        let r = [0x60, 0, 0x20, 1, 0, 0, 0, 0];
        assert_eq!(
            c.on_response(&r, &[]),
            Ok(Progress::Next {
                data: &[],
                request: [0x0F, 0, 0, 0, 0, 0, 0, 0]
            })
        );
        let r = [0x20, 0, 0, 0, 0, 0, 0, 0];
        assert_eq!(c.on_response(&r, &[]), Ok(Progress::Done { data: &[] }));
    }

    #[test]
    fn a_download_segment_confirmed_with_the_wrong_toggle_is_aborted() {
        let mut c = SdoClient::new();
        let v = [0u8; 10];
        c.download(0x2000, 1, &v);
        let _ = c.on_response(&[0x60, 0, 0x20, 1, 0, 0, 0, 0], &v);
        let r = [0x30, 0, 0, 0, 0, 0, 0, 0];
        assert_eq!(
            c.on_response(&r, &v),
            Err(SdoClientError::Unexpected {
                response: r,
                abort: Some([0x80, 0, 0x20, 1, 0, 0, 0x03, 0x05])
            })
        );
    }

    #[test]
    fn a_server_abort_ends_the_transfer_with_its_code() {
        let mut c = SdoClient::new();
        c.download(0x6041, 0, &[0, 0]);
        let r = [0x80, 0x41, 0x60, 0, 0x02, 0, 0x01, 0x06];
        assert_eq!(
            c.on_response(&r, &[0, 0]),
            Err(SdoClientError::Abort(AbortCode::READ_ONLY))
        );
        assert!(c.is_idle());
        assert_eq!(c.abort(AbortCode::TIMEOUT), None);
        c.upload(0x1008, 0);
        assert_eq!(
            c.abort(AbortCode::TIMEOUT),
            Some([0x80, 0x08, 0x10, 0, 0, 0, 0x04, 0x05])
        );
    }
}
