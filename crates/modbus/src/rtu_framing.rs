//! Modbus RTU framing on a serial line: a frame ends with a silence of 3.5 character times
//! (Modbus over Serial Line V1.02 §2.5.1.1). Sans-IO: the caller passes each read's bytes
//! with the time they arrived, and calls [`RtuFramer::poll`] at [`RtuFramer::deadline`].
//!
//! The standard's rules, and the decisions:
//! - t3.5 is 3.5 character times; above 19200 bit/s the standard recommends a fixed 1.75 ms
//!   ([`t3_5`], [`RtuFramer::new`]). A device whose manual asks 3.5 characters at every rate
//!   frames with [`three_and_a_half_characters`] ([`RtuFramer::with_gap`]).
//! - Decision: a character is 10 bits, an 8N1 line's (8 data bits, 1 stop bit, no parity, as
//!   the drives' serial lines run); the standard's 11 bits are for lines with parity or two
//!   stop bits.
//! - A frame longer than 256 bytes is dropped whole (and counted), as a frame the server
//!   cannot have been sent.
//! - Bytes of one read share its time, so two frames are told apart only by the silence the
//!   caller saw between its reads, as a UART driver's inter-byte timeout does it.

use core::time::Duration;

use od::Instant;

use crate::rtu::MAX_FRAME;

/// Bits of one character on an 8N1 line.
pub const BITS_PER_CHAR: u64 = 10;

/// The silence that ends a frame at `baud` bit/s: 3.5 characters, fixed at 1.75 ms above
/// 19200 bit/s (the standard's recommended value); a baud rate of 0 is taken as 1.
pub fn t3_5(baud: u32) -> Duration {
    if baud > 19_200 {
        return Duration::from_micros(1750);
    }
    three_and_a_half_characters(baud)
}

/// 3.5 characters at `baud` bit/s at every rate, without the standard's 1.75 ms above
/// 19200 bit/s; a baud rate of 0 is taken as 1.
pub fn three_and_a_half_characters(baud: u32) -> Duration {
    let ns = 35 * BITS_PER_CHAR * 100_000_000 / u64::from(baud.max(1));
    Duration::from_nanos(ns)
}

/// What the framer dropped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Dropped {
    /// Frames longer than [`MAX_FRAME`].
    pub too_long: u32,
}

/// Cuts a byte stream into RTU frames by the silence between them.
#[derive(Debug, Clone)]
pub struct RtuFramer {
    buf: [u8; MAX_FRAME],
    len: usize,
    overflow: bool,
    last: Option<Instant>,
    gap: Duration,
    dropped: Dropped,
}

impl RtuFramer {
    /// A framer for a line at `baud` bit/s, frames ended by the standard's [`t3_5`].
    pub fn new(baud: u32) -> Self {
        Self::with_gap(t3_5(baud))
    }

    /// A framer whose frames end after `gap` of silence.
    pub fn with_gap(gap: Duration) -> Self {
        RtuFramer {
            buf: [0; MAX_FRAME],
            len: 0,
            overflow: false,
            last: None,
            gap,
            dropped: Dropped::default(),
        }
    }

    /// Bytes that arrived at `now`; every frame a silence ended goes to `out`.
    pub fn on_bytes(&mut self, now: Instant, bytes: &[u8], out: &mut dyn FnMut(&[u8])) {
        self.poll(now, out);
        for &b in bytes {
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = b;
                    self.len += 1;
                }
                None => self.overflow = true,
            }
        }
        if !bytes.is_empty() {
            self.last = Some(now);
        }
    }

    /// Hands the waiting frame to `out` if the line has been silent for t3.5 at `now`.
    pub fn poll(&mut self, now: Instant, out: &mut dyn FnMut(&[u8])) {
        let silent = self
            .last
            .is_some_and(|t| now.saturating_since(t) >= self.gap);
        if !silent || (self.len == 0 && !self.overflow) {
            return;
        }
        if core::mem::take(&mut self.overflow) {
            self.dropped.too_long = self.dropped.too_long.saturating_add(1);
        } else {
            out(self.buf.get(..self.len).unwrap_or(&[]));
        }
        self.len = 0;
    }

    /// When the waiting frame is complete, if one waits.
    pub fn deadline(&self) -> Option<Instant> {
        (self.len > 0 || self.overflow)
            .then(|| self.last.map(|t| t + self.gap))
            .flatten()
    }

    /// What was dropped so far.
    pub fn dropped(&self) -> Dropped {
        self.dropped
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::{vec, vec::Vec};

    #[test]
    fn silence_of_three_and_a_half_characters() {
        assert_eq!(t3_5(9600), Duration::from_nanos(3_645_833));
        assert_eq!(t3_5(19200), Duration::from_nanos(1_822_916));
        assert_eq!(t3_5(38400), Duration::from_micros(1750));
        assert_eq!(t3_5(115_200), Duration::from_micros(1750));
        assert_eq!(three_and_a_half_characters(19200), t3_5(19200));
        assert_eq!(
            three_and_a_half_characters(38400),
            Duration::from_nanos(911_458)
        );
        assert_eq!(
            three_and_a_half_characters(115_200),
            Duration::from_nanos(303_819)
        );
    }

    /// A framer with 3.5 characters at 115200 bit/s ends a frame after 0.31 ms of silence,
    /// where the standard's framer still waits.
    #[test]
    fn a_framer_of_three_and_a_half_characters_at_115200() {
        let gap = three_and_a_half_characters(115_200);
        let mut f = RtuFramer::with_gap(gap);
        let mut standard = RtuFramer::new(115_200);
        let mut frames: Vec<Vec<u8>> = Vec::new();
        let us = |n: u64| Instant::from_nanos(n * 1000);
        let request = [0x01, 0x06, 0x31, 0x00, 0x00, 0x0F, 0xC7, 0x32];
        f.on_bytes(us(0), &request, &mut |_| {});
        standard.on_bytes(us(0), &request, &mut |_| {});
        f.on_bytes(us(400), &[0x01], &mut |b| frames.push(b.to_vec()));
        standard.on_bytes(us(400), &[0x01], &mut |b| frames.push(b.to_vec()));
        assert_eq!(
            frames,
            vec![request.to_vec()],
            "only the 3.5-character framer"
        );
    }

    /// A frame split over two reads is one frame; it is handed out after the silence, at the
    /// next read or at the deadline.
    #[test]
    fn frames_end_with_silence() {
        let mut f = RtuFramer::new(19200);
        let mut frames: Vec<Vec<u8>> = Vec::new();
        let us = |n: u64| Instant::from_nanos(n * 1000);
        let request = [0x01, 0x06, 0x31, 0x00, 0x00, 0x0F, 0xC7, 0x32];
        f.on_bytes(us(0), &request[..3], &mut |b| frames.push(b.to_vec()));
        f.on_bytes(us(500), &request[3..], &mut |b| frames.push(b.to_vec()));
        assert!(frames.is_empty());
        assert_eq!(f.deadline(), Some(us(500) + t3_5(19200)));
        f.poll(us(2000), &mut |b| frames.push(b.to_vec()));
        assert!(frames.is_empty(), "1.5 ms is not yet 3.5 characters");
        f.poll(us(2400), &mut |b| frames.push(b.to_vec()));
        assert_eq!(frames, vec![request.to_vec()]);
        // The next frame after a silence, handed out when a third one begins.
        f.on_bytes(us(10_000), &[0x02, 0x03], &mut |b| frames.push(b.to_vec()));
        f.on_bytes(us(20_000), &[0x01], &mut |b| frames.push(b.to_vec()));
        assert_eq!(frames.len(), 2);
        assert_eq!(frames.get(1), Some(&vec![0x02, 0x03]));
    }

    #[test]
    fn too_long_frames_are_dropped_and_counted() {
        let mut f = RtuFramer::new(115_200);
        let mut n = 0;
        f.on_bytes(Instant::ZERO, &[0x55; 300], &mut |_| n += 1);
        f.poll(Instant::from_millis(5), &mut |_| n += 1);
        assert_eq!(n, 0);
        assert_eq!(f.dropped().too_long, 1);
        assert_eq!(f.deadline(), None);
    }
}
