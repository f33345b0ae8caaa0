//! The sync managers' access rules (spec §1.4 rule 2, §5.2, §7.3): which ECAT
//! accesses an SM window allows, and the mailbox and buffered-mode bookkeeping of an access
//! that covers its first or last byte.

use super::*;

impl<'a> Esc<'a> {
    /// May an ECAT access of `len` bytes at `addr` in direction `dir` go ahead? (§1.4 rule
    /// 2, §5.2, §7.3.)
    pub(super) fn sm_allows(&self, addr: u32, len: usize, dir: Dir) -> bool {
        self.sm_access(addr, len, dir).is_some()
    }

    /// The SM rules and events of one ECAT access in one pass over the windows: `None` when
    /// a window refuses the access (§1.4 rule 2, §5.2, §7.3), else the SMs of its direction
    /// whose last byte it covers (bit n: SM n), whose buffer or mailbox event follows it.
    /// An access changes no SM's configuration or status before it completes, so what the
    /// windows say before it holds after it.
    pub(super) fn sm_access(&self, addr: u32, len: usize, dir: Dir) -> Option<u8> {
        if !self.sm_span.meets(addr, len) {
            return Some(0);
        }
        let mut events = 0u8;
        for i in set_bits(self.active_sms) {
            let Some(s) = self.sms.get(i) else {
                continue;
            };
            if !s.overlaps(addr, len) {
                continue;
            }
            let mailbox = s.mode() == SmMode::Mailbox;
            let same_direction = match (s.direction(), dir) {
                (SmDirection::Write, Dir::Read) | (SmDirection::Read, Dir::Write) => {
                    return None;
                }
                (SmDirection::Write, Dir::Write) if mailbox && s.is_mailbox_full() => {
                    return None;
                }
                (SmDirection::Read, Dir::Read) if mailbox && !s.is_mailbox_full() => {
                    return None;
                }
                (SmDirection::Write, Dir::Write) | (SmDirection::Read, Dir::Read) => true,
                (SmDirection::Reserved(_), _) => false,
            };
            if same_direction && s.covers_last_byte(addr, len) {
                events |= 1 << i;
            }
        }
        Some(events)
    }

    /// [`Esc::sm_access`] for an access through FMMU `fmmu` inside its physical window: the
    /// SM it is routed to ([`Esc::refresh_fmmu_routes`]) alone when it has one.
    pub(super) fn fmmu_sm_access(
        &self,
        fmmu: usize,
        addr: u32,
        len: usize,
        dir: Dir,
    ) -> Option<u8> {
        let Some(n) = self.fmmu_sm.get(fmmu).copied().flatten() else {
            return self.sm_access(addr, len, dir);
        };
        let events = if self.sm(usize::from(n)).covers_last_byte(addr, len) {
            1 << n
        } else {
            0
        };
        debug_assert_eq!(Some(events), self.sm_access(addr, len, dir));
        Some(events)
    }

    /// The SMs of direction `dir` whose last byte `[addr, addr + len)` covers.
    pub(super) fn sm_events(&self, addr: u32, len: usize, dir: Dir) -> u8 {
        // Covering an SM's last byte means meeting its window.
        if !self.sm_span.meets(addr, len) {
            return 0;
        }
        let want = match dir {
            Dir::Read => SmDirection::Read,
            Dir::Write => SmDirection::Write,
        };
        let mut events = 0u8;
        for n in set_bits(self.active_sms) {
            let s = self.sm(n);
            if s.direction() == want && s.covers_last_byte(addr, len) {
                events |= 1 << n;
            }
        }
        events
    }

    pub(super) fn set_sm_status(&mut self, n: usize, status: u8) {
        if let Some(s) = self.sms.get_mut(n) {
            s.status = status;
        }
        self.wr8(R::sync_manager(n as u8) + 5, status);
    }

    pub(super) fn set_sm_pdi_control(&mut self, n: usize, v: u8) {
        if let Some(s) = self.sms.get_mut(n) {
            s.pdi_control = v;
        }
        self.wr8(R::sync_manager(n as u8) + 7, v);
    }

    pub(super) fn sm(&self, n: usize) -> SyncManager {
        self.sms.get(n).copied().unwrap_or_default()
    }

    /// SM events of a completed ECAT read.
    pub(super) fn after_read(&mut self, addr: u32, len: usize) {
        let events = self.sm_events(addr, len, Dir::Read);
        self.after_read_events(addr, len, events);
    }

    /// [`Esc::after_read`] with the SMs whose last byte the read covered known
    /// ([`Esc::sm_access`]).
    pub(super) fn after_read_events(&mut self, addr: u32, len: usize, events: u8) {
        let (a0, a1) = (addr as usize, addr as usize + len);
        if overlaps(a0, a1, 0x0130, 0x0132) {
            let ev = self.rd16(R::EcatEventRequest.addr()) & !EVENT_AL_STATUS;
            self.wr16(R::EcatEventRequest.addr(), ev);
            self.refresh_irq();
        }
        for n in set_bits(events) {
            let s = self.sm(n);
            let status = match s.mode() {
                SmMode::Mailbox => (s.status & !STATUS_MAILBOX_FULL) | STATUS_IRQ_READ,
                _ => s.status | STATUS_IRQ_READ,
            };
            self.set_sm_status(n, status);
        }
    }

    /// SM events of a completed ECAT write: `events` are the SMs whose last byte it covered
    /// ([`Esc::sm_access`]).
    pub(super) fn after_write_events(&mut self, events: u8) {
        for n in set_bits(events) {
            let s = self.sm(n);
            match s.mode() {
                SmMode::Mailbox => {
                    self.set_sm_status(n, s.status | STATUS_MAILBOX_FULL | STATUS_IRQ_WRITE);
                }
                SmMode::Buffered => {
                    let last = (s.status & STATUS_BUFFER_MASK) >> 4;
                    let next = if last >= 2 { 0 } else { last + 1 };
                    let status = (s.status & !STATUS_BUFFER_MASK) | (next << 4) | STATUS_IRQ_WRITE;
                    self.set_sm_status(n, status);
                    if n == SM_OUTPUTS {
                        self.outputs_completed(s);
                    }
                    if s.control & sm::CONTROL_WATCHDOG != 0 {
                        self.watchdog_restarted();
                    }
                }
                SmMode::Reserved(_) => {}
            }
        }
    }

    pub(super) fn outputs_completed(&mut self, s: SyncManager) {
        let len = usize::from(s.length);
        let start = usize::from(s.start);
        let Some(src) = self.mem.get(start..start + len) else {
            return;
        };
        if let Some(dst) = self.pd_out.get_mut(..len) {
            copy_bytes(dst, src);
            self.pd_out_len = len;
            self.pd_out_new = true;
            self.outputs_seen = true;
        }
    }
}
