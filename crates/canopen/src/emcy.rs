//! EMCY producer (CiA 301 §7.2.7): the device raises and clears errors through this API; the
//! producer keeps 1001h and the 1003h history, and sends the frames on the 1014h COB-ID with
//! the 1015h inhibit time, an error-free EMCY (0000h) when the last error goes.

use core::time::Duration;

use heapless::{Deque, Vec};
use od::{Instant, ObjectAccess};

/// Most errors active at once.
pub const MAX_ACTIVE: usize = 16;
/// Frames waiting for the inhibit time or for a state that may send.
const QUEUE: usize = 16;

/// Error register (1001h) bits, CiA 301 Tab. 48.
pub mod register {
    pub const GENERIC: u8 = 0x01;
    pub const CURRENT: u8 = 0x02;
    pub const VOLTAGE: u8 = 0x04;
    pub const TEMPERATURE: u8 = 0x08;
    pub const COMMUNICATION: u8 = 0x10;
    pub const PROFILE: u8 = 0x20;
    pub const MANUFACTURER: u8 = 0x80;
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Active {
    code: u16,
    register_bits: u8,
}

/// The EMCY producer of one node.
#[derive(Debug, Default)]
pub struct EmcyProducer {
    active: Vec<Active, MAX_ACTIVE>,
    queue: Deque<[u8; 8], QUEUE>,
    last_sent: Option<Instant>,
}

impl EmcyProducer {
    /// An error appears: EMCY with its code and the new error register, entry in 1003h.
    /// Raising an error that is already active does nothing (CiA 301: one EMCY per error
    /// occurrence).
    pub fn raise(
        &mut self,
        od: &mut dyn ObjectAccess,
        code: u16,
        register_bits: u8,
        vendor: [u8; 5],
    ) {
        if self.active.iter().any(|a| a.code == code) {
            return;
        }
        if self
            .active
            .push(Active {
                code,
                register_bits,
            })
            .is_err()
        {
            // Full: the oldest active error makes room; its EMCY was sent long ago.
            self.active.remove(0);
            let _ = self.active.push(Active {
                code,
                register_bits,
            });
        }
        let reg = self.register();
        write_register(od, reg);
        push_history(
            od,
            u32::from(code) | (u32::from(vendor[0]) << 16) | (u32::from(vendor[1]) << 24),
        );
        let [c0, c1] = code.to_le_bytes();
        self.enqueue([
            c0, c1, reg, vendor[0], vendor[1], vendor[2], vendor[3], vendor[4],
        ]);
    }

    /// Sends the EMCY of an active error again (its frame was lost, e.g. with the node off
    /// the bus); nothing for an error not active. 1003h keeps its one entry.
    pub fn repeat(&mut self, code: u16) {
        if !self.is_active(code) {
            return;
        }
        let reg = self.register();
        let [c0, c1] = code.to_le_bytes();
        self.enqueue([c0, c1, reg, 0, 0, 0, 0, 0]);
    }

    /// An error goes away; when none is left the error-free EMCY (0000h) is sent.
    pub fn clear(&mut self, od: &mut dyn ObjectAccess, code: u16) {
        let before = self.active.len();
        self.active.retain(|a| a.code != code);
        if self.active.len() == before {
            return;
        }
        let reg = self.register();
        write_register(od, reg);
        if self.active.is_empty() {
            self.enqueue([0, 0, reg, 0, 0, 0, 0, 0]);
        }
    }

    /// Clears every error (fault reset with all causes gone).
    pub fn clear_all(&mut self, od: &mut dyn ObjectAccess) {
        if self.active.is_empty() {
            return;
        }
        self.active.clear();
        write_register(od, 0);
        self.enqueue([0; 8]);
    }

    pub fn is_active(&self, code: u16) -> bool {
        self.active.iter().any(|a| a.code == code)
    }

    pub fn has_errors(&self) -> bool {
        !self.active.is_empty()
    }

    /// The error register the active errors give: bit 0 is set whenever any error is.
    pub fn register(&self) -> u8 {
        let bits = self.active.iter().fold(0u8, |r, a| r | a.register_bits);
        if self.active.is_empty() {
            0
        } else {
            bits | register::GENERIC
        }
    }

    fn enqueue(&mut self, frame: [u8; 8]) {
        if self.queue.is_full() {
            self.queue.pop_front();
        }
        let _ = self.queue.push_back(frame);
    }

    /// Sends what the inhibit time allows; `may_send` is false outside Pre-Operational and
    /// Operational (frames wait). Returns when to call again.
    pub fn poll(
        &mut self,
        now: Instant,
        od: &dyn ObjectAccess,
        may_send: bool,
        out: &mut dyn FnMut(u16, [u8; 8]),
    ) -> Option<Instant> {
        if !may_send || self.queue.is_empty() {
            return None;
        }
        let cob = match od.read_u32(0x1014, 0) {
            Some(c) if c & 0x8000_0000 == 0 => (c & 0x7FF) as u16,
            _ => {
                // EMCY not valid: nothing is sent (CiA 301 §7.5.2.28), the queue is dropped.
                self.queue.clear();
                return None;
            }
        };
        let inhibit = Duration::from_micros(u64::from(od.read_u16(0x1015, 0).unwrap_or(0)) * 100);
        while !self.queue.is_empty() {
            if let Some(last) = self.last_sent {
                let ready = last + inhibit;
                if now < ready {
                    return Some(ready);
                }
            }
            if let Some(frame) = self.queue.pop_front() {
                out(cob, frame);
                self.last_sent = Some(now);
            }
            if inhibit.is_zero() {
                continue;
            }
        }
        None
    }

    /// The deadline of a frame held back by the inhibit time.
    pub fn deadline(&self, od: &dyn ObjectAccess) -> Option<Instant> {
        if self.queue.is_empty() {
            return None;
        }
        let inhibit = Duration::from_micros(u64::from(od.read_u16(0x1015, 0).unwrap_or(0)) * 100);
        Some(self.last_sent.map(|l| l + inhibit).unwrap_or(Instant::ZERO))
    }

    /// Reset communication: the queue goes, the active errors stay (they are the device's).
    pub fn reset_communication(&mut self) {
        self.queue.clear();
        self.last_sent = None;
    }
}

/// 1001h is read-only for masters; the device sets it through its own path.
fn write_register(od: &mut dyn ObjectAccess, reg: u8) {
    let _ = od.write_internal(0x1001, 0, &[reg]);
}

/// Pushes an entry to 1003h: newest at sub 1, older ones shift up, count in sub 0.
fn push_history(od: &mut dyn ObjectAccess, value: u32) {
    let mut depth = 0u8;
    while od.entry(0x1003, depth + 1).is_ok() && depth < 254 {
        depth += 1;
    }
    if depth == 0 {
        return;
    }
    let count = od.read_u8(0x1003, 0).unwrap_or(0).min(depth);
    let mut sub = count.saturating_add(1).min(depth);
    while sub > 1 {
        if let Some(v) = od.read_u32(0x1003, sub - 1) {
            let _ = od.write_internal(0x1003, sub, &v.to_le_bytes());
        }
        sub -= 1;
    }
    let _ = od.write_internal(0x1003, 1, &value.to_le_bytes());
    let _ = od.write_internal(0x1003, 0, &[count.saturating_add(1).min(depth)]);
}
