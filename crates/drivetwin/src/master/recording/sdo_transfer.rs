//! An SDO read or write of a script as the request frames a client sends (CiA 301 §7.2.4.3):
//! the initiate request, then, when the server chose a segmented transfer, one segment
//! request per answer, as `canopen`'s SDO client decides them. The next request depends only
//! on the previous answer, so a recording holds each frame as a step of its own and a replay
//! sends the same frames.
//!
//! **Decision:** an abort the client would end a transfer with is not sent: a recording holds
//! the script's requests and the node's answers, and a transfer that went wrong ends there.

use super::Step;
use crate::master::recording::AnswerRule;
use canopen::sdo_client::{Progress, SdoClient};
use canopen::CanFrame;

/// No transfer of a script runs longer than this many segments (7 bytes each).
pub const MAX_SEGMENTS: u32 = 4096;

/// One transfer, one request at a time.
#[derive(Debug, Clone)]
pub struct SdoTransfer {
    node: u8,
    index: u16,
    sub: u8,
    /// `None` reads; the bytes to write otherwise.
    data: Option<Vec<u8>>,
    client: SdoClient,
    segments: u32,
    rule: AnswerRule,
    line: usize,
    /// The script's name for the transfer (default: `sdo read IIII:SS`).
    name: Option<String>,
}

impl SdoTransfer {
    pub fn read(node: u8, index: u16, sub: u8, rule: AnswerRule, line: usize) -> Self {
        Self::new(node, index, sub, None, rule, line)
    }

    pub fn write(
        node: u8,
        index: u16,
        sub: u8,
        data: Vec<u8>,
        rule: AnswerRule,
        line: usize,
    ) -> Self {
        Self::new(node, index, sub, Some(data), rule, line)
    }

    fn new(
        node: u8,
        index: u16,
        sub: u8,
        data: Option<Vec<u8>>,
        rule: AnswerRule,
        line: usize,
    ) -> Self {
        SdoTransfer {
            node,
            index,
            sub,
            data,
            client: SdoClient::new(),
            segments: 0,
            rule,
            line,
            name: None,
        }
    }

    /// The same transfer under the script's name for it.
    pub fn named(mut self, name: Option<String>) -> Self {
        self.name = name;
        self
    }

    /// The same transfer at another line of the script.
    pub fn at_line(mut self, line: usize) -> Self {
        self.line = line;
        self
    }

    fn object(&self) -> String {
        if let Some(n) = &self.name {
            return n.clone();
        }
        let verb = if self.data.is_some() { "write" } else { "read" };
        format!("sdo {verb} {:04X}:{:02X}", self.index, self.sub)
    }

    fn step(&self, data: [u8; 8], label: String) -> Step {
        Step {
            label,
            line: self.line,
            request: CanFrame::full(0x600 + u16::from(self.node), data),
            rule: self.rule,
        }
    }

    /// The first request.
    pub fn first(&mut self) -> Step {
        let req = match &self.data {
            None => self.client.upload(self.index, self.sub),
            Some(d) => self.client.download(self.index, self.sub, d),
        };
        let label = match &self.data {
            Some(_) if self.name.is_some() => self.object(),
            Some(d) => format!("{} = {}", self.object(), canopen::decode::Hex(d)),
            None => self.object(),
        };
        self.step(req, label)
    }

    /// The request after `answer` (`None`: nothing came), or `None` when the transfer is over.
    pub fn next(&mut self, answer: Option<&[u8]>) -> Option<Step> {
        let answer = answer.filter(|a| !a.is_empty())?;
        let mut response = [0u8; 8];
        for (dst, src) in response.iter_mut().zip(answer) {
            *dst = *src;
        }
        let value = self.data.as_deref().unwrap_or(&[]);
        let Ok(Progress::Next { request, .. }) = self.client.on_response(&response, value) else {
            return None;
        };
        if self.segments >= MAX_SEGMENTS {
            return None;
        }
        self.segments += 1;
        let label = format!("{}, segment {}", self.object(), self.segments);
        Some(self.step(request, label))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::master::recording::Awaited;
    use std::time::Duration;

    fn rule() -> AnswerRule {
        AnswerRule {
            window: Duration::ZERO,
            until: Some(Awaited {
                cob_id: 0x581,
                timeout: Duration::from_secs(1),
            }),
        }
    }

    #[test]
    fn an_expedited_read_is_one_request() {
        let mut t = SdoTransfer::read(1, 0x1018, 1, rule(), 3);
        let s = t.first();
        assert_eq!(s.request.id, 0x601);
        assert_eq!(s.request.payload(), &[0x40, 0x18, 0x10, 1, 0, 0, 0, 0]);
        assert_eq!(s.label, "sdo read 1018:01");
        assert_eq!(s.line, 3);
        assert!(t
            .next(Some(&[0x43, 0x18, 0x10, 1, 0x1D, 0, 0, 0]))
            .is_none());
    }

    #[test]
    fn a_segmented_read_asks_for_segments_with_the_toggle_until_the_last() {
        let mut t = SdoTransfer::read(1, 0x1008, 0, rule(), 1);
        let _ = t.first();
        let s1 = t
            .next(Some(&[0x41, 0x08, 0x10, 0, 10, 0, 0, 0]))
            .expect("segment 1");
        assert_eq!(s1.request.payload()[0], 0x60);
        assert_eq!(s1.label, "sdo read 1008:00, segment 1");
        let s2 = t.next(Some(&[0x00, b'C', b'M', b'M', b'P', b'-', b'A', b'S']));
        assert_eq!(s2.expect("segment 2").request.payload()[0], 0x70);
        assert!(t
            .next(Some(&[0x15, b'x', b'y', b'z', 0, 0, 0, 0]))
            .is_none());
    }

    #[test]
    fn writes_are_expedited_up_to_four_bytes_and_segmented_above() {
        let mut t = SdoTransfer::write(2, 0x6040, 0, vec![0x06, 0x00], rule(), 1);
        let s = t.first();
        assert_eq!(s.request.id, 0x602);
        assert_eq!(s.request.payload(), &[0x2B, 0x40, 0x60, 0, 6, 0, 0, 0]);
        assert_eq!(s.label, "sdo write 6040:00 = 06 00");

        let mut t = SdoTransfer::write(1, 0x2000, 1, (1..=9).collect(), rule(), 1);
        assert_eq!(t.first().request.payload(), &[0x21, 0, 0x20, 1, 9, 0, 0, 0]);
        let s1 = t
            .next(Some(&[0x60, 0, 0x20, 1, 0, 0, 0, 0]))
            .expect("seg 1");
        assert_eq!(s1.request.payload(), &[0x00, 1, 2, 3, 4, 5, 6, 7]);
        let s2 = t.next(Some(&[0x20, 0, 0, 0, 0, 0, 0, 0])).expect("seg 2");
        assert_eq!(s2.request.payload(), &[0x1B, 8, 9, 0, 0, 0, 0, 0]);
        assert!(t.next(Some(&[0x30, 0, 0, 0, 0, 0, 0, 0])).is_none());
    }

    #[test]
    fn an_abort_or_no_answer_ends_the_transfer() {
        let mut t = SdoTransfer::read(1, 0x1008, 0, rule(), 1);
        assert!(t.next(None).is_none());
        let mut t = SdoTransfer::read(1, 0x1008, 0, rule(), 1);
        assert!(t.next(Some(&[0x80, 8, 0x10, 0, 0, 0, 2, 6])).is_none());
    }
}
