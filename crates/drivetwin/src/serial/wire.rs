//! The virtual serial wire between a host and the drives: a pty moves bytes at once, a real
//! line at its baud rate, so this module gives every byte the time it would take. Pure (the
//! time comes in as an argument); the [`super::line`] around it does the I/O.
//!
//! - Received bytes: the host writes a telegram at once; on the wire its bytes follow each
//!   other one character time apart (10 bits, 8N1: Kinco manual §10.1 / §12.2). Byte `i` of
//!   what waits is complete at `start + (i + 1) · t_char`, and is handed to the protocol then.
//! - Sent bytes: an answer starts when the drive has it and the wire is free, and is written
//!   to the host when its last byte would have crossed, in one write (10 bytes at 38400 bit/s
//!   take 2.6 ms). A half-duplex line (RS485) shares one transmitter.
//! - Bounded both ways: at most [`MAX_RX`] bytes wait for the wire and [`MAX_OUT`] for the
//!   host to read; beyond that bytes are dropped and counted, so a host that never reads, or
//!   one that floods the line, never stalls it nor the drives.
//! - A real device (a UART) does its own timing: a wire of baud rate 0 passes bytes at once.

use std::collections::VecDeque;
use std::time::Duration;

use od::Instant;

/// Bits of one character on the Kinco lines (8N1: start, 8 data, stop).
pub const BITS_PER_CHAR: u64 = 10;

/// Bytes the wire holds before the drive has taken them (beyond: dropped, counted).
pub const MAX_RX: usize = 4096;

/// Bytes waiting for the host to read them (beyond: dropped, counted).
pub const MAX_OUT: usize = 4096;

/// The time of one character at `baud` bit/s (zero: no timing, a real UART's own).
pub fn char_time(baud: u32) -> Duration {
    if baud == 0 {
        return Duration::ZERO;
    }
    Duration::from_nanos(BITS_PER_CHAR * 1_000_000_000 / u64::from(baud))
}

/// What the wire dropped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WireCounters {
    /// Received bytes beyond [`MAX_RX`].
    pub rx_dropped: u64,
    /// Answer bytes the host did not take in time (beyond [`MAX_OUT`]).
    pub tx_dropped: u64,
}

/// One serial wire with its timing.
#[derive(Debug)]
pub struct Wire {
    char_time: Duration,
    rx: VecDeque<u8>,
    /// When the first byte of `rx` is complete.
    rx_front: Instant,
    /// When the last received byte was complete.
    rx_last: Instant,
    /// Answer bytes on the wire, and where each answer ends and when.
    tx: VecDeque<u8>,
    tx_chunks: VecDeque<(Instant, usize)>,
    tx_free: Instant,
    /// Bytes crossed, for the host.
    out: VecDeque<u8>,
    counters: WireCounters,
}

impl Wire {
    /// A wire at `baud` bit/s (0: no timing).
    pub fn new(baud: u32) -> Self {
        Wire {
            char_time: char_time(baud),
            rx: VecDeque::with_capacity(256),
            rx_front: Instant::ZERO,
            rx_last: Instant::ZERO,
            tx: VecDeque::with_capacity(256),
            tx_chunks: VecDeque::with_capacity(16),
            tx_free: Instant::ZERO,
            out: VecDeque::with_capacity(1024),
            counters: WireCounters::default(),
        }
    }

    /// A new baud rate (U2BRG, applied at once): for the bytes that come from now on.
    pub fn set_baud(&mut self, baud: u32) {
        self.char_time = char_time(baud);
    }

    pub fn char_time(&self) -> Duration {
        self.char_time
    }

    pub fn counters(&self) -> WireCounters {
        self.counters
    }

    /// The host wrote `bytes` at `now`: they cross one after the other.
    pub fn receive(&mut self, now: Instant, bytes: &[u8]) {
        if self.rx.is_empty() {
            self.rx_front = now.max(self.rx_last) + self.char_time;
        }
        let room = MAX_RX.saturating_sub(self.rx.len());
        let (take, drop) = bytes.split_at(room.min(bytes.len()));
        self.rx.extend(take);
        self.counters.rx_dropped += drop.len() as u64;
    }

    /// Every received byte complete by `now`, with the time it was.
    pub fn arrived(&mut self, now: Instant, f: &mut dyn FnMut(Instant, u8)) {
        while self.rx_front <= now {
            let Some(b) = self.rx.pop_front() else {
                break;
            };
            let at = self.rx_front;
            self.rx_last = at;
            self.rx_front = at + self.char_time;
            f(at, b);
        }
    }

    /// The drive has `bytes` to send at `at`: they go once the wire is free.
    pub fn send(&mut self, at: Instant, bytes: &[u8]) {
        if bytes.is_empty() {
            return;
        }
        let start = at.max(self.tx_free);
        let end = start + self.char_time * u32::try_from(bytes.len()).unwrap_or(u32::MAX);
        self.tx_free = end;
        let room = MAX_OUT.saturating_sub(self.tx.len());
        let (take, drop) = bytes.split_at(room.min(bytes.len()));
        self.tx.extend(take);
        self.counters.tx_dropped += drop.len() as u64;
        self.tx_chunks.push_back((end, take.len()));
    }

    /// Moves every answer that has crossed by `now` to the host's side; the number of bytes
    /// dropped because the host had left [`MAX_OUT`] unread.
    pub fn crossed(&mut self, now: Instant) -> u64 {
        let mut dropped = 0;
        while let Some(&(end, n)) = self.tx_chunks.front() {
            if end > now {
                break;
            }
            self.tx_chunks.pop_front();
            for _ in 0..n {
                let Some(b) = self.tx.pop_front() else {
                    break;
                };
                if self.out.len() < MAX_OUT {
                    self.out.push_back(b);
                } else {
                    dropped += 1;
                }
            }
        }
        self.counters.tx_dropped += dropped;
        dropped
    }

    /// Bytes for the host: `write` takes what it can and says how many.
    pub fn flush(&mut self, write: &mut dyn FnMut(&[u8]) -> usize) {
        while !self.out.is_empty() {
            let (a, _) = self.out.as_slices();
            let n = write(a);
            if n == 0 {
                return;
            }
            self.out.drain(..n.min(self.out.len()));
        }
    }

    /// Bytes waiting for the host.
    pub fn unread(&self) -> usize {
        self.out.len()
    }

    /// When a received byte completes or an answer has crossed.
    pub fn deadline(&self) -> Option<Instant> {
        let rx = (!self.rx.is_empty()).then_some(self.rx_front);
        od::time::earliest(rx, self.tx_chunks.front().map(|&(t, _)| t))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 10 bytes at 38400 bit/s take 2.6 ms; the answer is there 2.6 ms after it started.
    #[test]
    fn ten_bytes_at_38400_take_2_6_ms() {
        let mut w = Wire::new(38_400);
        assert_eq!(w.char_time(), Duration::from_nanos(260_416));
        let t = [1u8; 10];
        w.receive(Instant::ZERO, &t);
        let mut got = Vec::new();
        w.arrived(Instant::from_nanos(2_000_000), &mut |at, b| {
            got.push((at, b))
        });
        assert_eq!(got.len(), 7);
        w.arrived(Instant::from_nanos(2_604_160), &mut |at, b| {
            got.push((at, b))
        });
        assert_eq!(got.len(), 10);
        let done = got.last().map(|&(at, _)| at).unwrap_or(Instant::ZERO);
        assert_eq!(done, Instant::from_nanos(2_604_160));
        w.send(done, &t);
        assert_eq!(w.deadline(), Some(Instant::from_nanos(5_208_320)));
        w.crossed(Instant::from_nanos(5_208_319));
        assert_eq!(w.unread(), 0, "not before its last byte has crossed");
        w.crossed(Instant::from_nanos(5_208_320));
        assert_eq!(w.unread(), 10);
    }

    /// Two answers queue on one transmitter; a host that never reads loses bytes, counted,
    /// and the wire goes on.
    #[test]
    fn answers_queue_and_an_unread_host_loses_bytes() {
        let mut w = Wire::new(115_200);
        w.send(Instant::ZERO, &[0; 10]);
        w.send(Instant::ZERO, &[0; 10]);
        let end = w.deadline().unwrap_or(Instant::ZERO);
        w.crossed(end);
        assert_eq!(
            w.unread(),
            10,
            "the second starts when the first has crossed"
        );
        for _ in 0..(MAX_OUT / 10 + 5) {
            w.send(Instant::from_millis(100), &[0; 10]);
        }
        w.crossed(Instant::from_millis(1000));
        assert_eq!(w.unread(), MAX_OUT);
        assert!(w.counters().tx_dropped > 0);
        let mut taken = 0;
        w.flush(&mut |b| {
            taken += b.len();
            b.len()
        });
        assert_eq!(taken, MAX_OUT);
        assert_eq!(w.unread(), 0);
    }

    /// A real device: no timing.
    #[test]
    fn a_real_uart_times_itself() {
        let mut w = Wire::new(0);
        w.receive(Instant::from_millis(5), &[1, 2, 3]);
        let mut n = 0;
        w.arrived(Instant::from_millis(5), &mut |at, _| {
            assert_eq!(at, Instant::from_millis(5));
            n += 1
        });
        assert_eq!(n, 3);
    }
}
