//! The Kinco telegram protocol on a line (`spec/kinco-fd-cd.md` §2.1–2.2, the codec
//! `canopen::kinco_rs232`): bytes become 10-byte telegrams, each answered by the drive it
//! addresses through its object access.
//!
//! Topologies:
//! - point to point (RS232, one drive): the host's telegrams to the drive, its answers back;
//! - ring (RS232_Loop_Enable 6510h:0B = 1, several drives on one RS232 path, §2.1 multi-point):
//!   the host's bytes reach the first drive, each drive's output the next one, the last one's
//!   the host, so the host reads its own telegram, then the answer (KINCO-232-09);
//! - bus (RS485 with RS485_Protocol 6510h:0C = 1): every drive hears the host; the one
//!   addressed answers.
//!
//! Decisions:
//! - A partial telegram is dropped after [`canopen::kinco_rs232::DEFAULT_GAP`] of silence on
//!   the wire (the codec's rule), counted here.
//! - In a ring a drive passes a telegram on when it is whole, not byte by byte: the host
//!   reads the same 20 bytes, 10 character times later than through a real repeater chain.
//! - U2BRG (2FE1h) applies at once (§9.1 item 7): after each answer the line takes the rate
//!   its code gives, for the bytes after the answer.

use canopen::kinco_rs232::{KincoRs232, TelegramCutter, DEFAULT_GAP, TELEGRAM_LEN};
use od::Instant;

use super::wire::Wire;
use super::{baud_of_code, LineDrives};
use crate::cell::poll_loop::OnBus;

/// How the drives of a telegram line are wired.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Topology {
    /// One drive, or drives in a ring in this order.
    Ring,
    /// Every drive hears the host (RS485).
    Bus,
}

/// What a telegram line counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TelegramCounters {
    pub answered: u32,
    pub bad_checksum: u32,
    pub other_station: u32,
    /// Partial telegrams dropped after a silence.
    pub partial: u32,
}

pub struct TelegramLine {
    ports: Vec<(OnBus, KincoRs232)>,
    topology: Topology,
    cutter: TelegramCutter,
    /// Follow U2BRG (2FE1h) of the first drive: the RS232 port's own rate.
    follow_u2brg: Option<u64>,
    partial: u32,
    /// Scratch: what one drive of a ring passes to the next.
    hop: Vec<u8>,
    next: Vec<u8>,
}

impl TelegramLine {
    /// `ports`: each drive with its codec (station, ring flag at power-up).
    pub fn new(ports: Vec<(OnBus, KincoRs232)>, topology: Topology, u2brg: Option<u64>) -> Self {
        TelegramLine {
            ports,
            topology,
            cutter: TelegramCutter::new(DEFAULT_GAP),
            follow_u2brg: u2brg,
            partial: 0,
            hop: Vec::with_capacity(64),
            next: Vec::with_capacity(64),
        }
    }

    pub fn counters(&self) -> TelegramCounters {
        let mut c = TelegramCounters {
            partial: self.partial,
            ..TelegramCounters::default()
        };
        for (_, p) in &self.ports {
            let k = p.counters();
            c.answered += k.answered;
            c.bad_checksum += k.bad_checksum;
            c.other_station += k.other_station;
        }
        // In a ring every drive sees every telegram: a bad one counts once.
        if self.topology == Topology::Ring {
            if let Some((_, p)) = self.ports.first() {
                c.bad_checksum = p.counters().bad_checksum;
            }
        }
        c
    }

    /// One byte complete on the wire at `at`.
    pub fn on_byte(&mut self, at: Instant, byte: u8, drives: &mut dyn LineDrives, wire: &mut Wire) {
        let mut dropped = false;
        let t = self.cutter.push(at, byte, &mut dropped);
        if dropped {
            self.partial = self.partial.saturating_add(1);
        }
        if let Some(t) = t {
            self.on_telegram(at, &t, drives, wire);
        }
    }

    fn on_telegram(
        &mut self,
        at: Instant,
        t: &[u8; TELEGRAM_LEN],
        drives: &mut dyn LineDrives,
        wire: &mut Wire,
    ) {
        match self.topology {
            Topology::Bus => {
                for (on_bus, port) in &mut self.ports {
                    let mut answer = [0u8; 2 * TELEGRAM_LEN];
                    let mut n = 0;
                    drives.access(*on_bus, at, &mut |od| {
                        port.on_telegram(t, od, &mut |b| {
                            for &x in b {
                                if let Some(slot) = answer.get_mut(n) {
                                    *slot = x;
                                    n += 1;
                                }
                            }
                        })
                    });
                    wire.send(at, answer.get(..n).unwrap_or(&[]));
                }
            }
            Topology::Ring => {
                self.hop.clear();
                self.hop.extend_from_slice(t);
                for (on_bus, port) in &mut self.ports {
                    self.next.clear();
                    let next = &mut self.next;
                    for block in self.hop.chunks_exact(TELEGRAM_LEN) {
                        let Ok(block) = <&[u8; TELEGRAM_LEN]>::try_from(block) else {
                            continue;
                        };
                        drives.access(*on_bus, at, &mut |od| {
                            port.on_telegram(block, od, &mut |b| next.extend_from_slice(b))
                        });
                    }
                    std::mem::swap(&mut self.hop, &mut self.next);
                }
                wire.send(at, &self.hop);
            }
        }
        if let (Some(last), Some((on_bus, _))) = (self.follow_u2brg, self.ports.first()) {
            let mut code = last;
            drives.access(*on_bus, at, &mut |od| {
                let mut b = [0u8; 2];
                if od.read(0x2FE1, 0, &mut b).is_ok() {
                    code = u64::from(u16::from_le_bytes(b));
                }
            });
            if code != last {
                self.follow_u2brg = Some(code);
                match baud_of_code(code) {
                    Some(baud) => {
                        tracing::info!(code, baud, "RS232: U2BRG applied");
                        wire.set_baud(baud);
                    }
                    None => tracing::warn!(code, "RS232: U2BRG code of no bit rate, ignored"),
                }
            }
        }
    }
}
