//! The sync managers' access rules (spec §1.4 rule 2, §5.2, §7.3): which ECAT
//! accesses an SM window allows, and the mailbox and buffered-mode bookkeeping of an access
//! that covers its first or last byte.

use super::*;

impl<'a> Esc<'a> {
    /// May an ECAT access of `len` bytes at `addr` in direction `dir` go ahead? (§1.4 rule
    /// 2, §5.2, §7.3.)
    pub(super) fn sm_allows(&self, addr: u32, len: usize, dir: Dir) -> bool {
        if !self.sm_span.meets(addr, len) {
            return true;
        }
        for i in set_bits(self.active_sms) {
            let s = self.sm(i);
            if !s.overlaps(addr, len) {
                continue;
            }
            let mailbox = s.mode() == SmMode::Mailbox;
            let refused = match (s.direction(), dir) {
                (SmDirection::Write, Dir::Read) | (SmDirection::Read, Dir::Write) => true,
                (SmDirection::Write, Dir::Write) => mailbox && s.is_mailbox_full(),
                (SmDirection::Read, Dir::Read) => mailbox && !s.is_mailbox_full(),
                (SmDirection::Reserved(_), _) => false,
            };
            if refused {
                return false;
            }
        }
        true
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
        let (a0, a1) = (addr as usize, addr as usize + len);
        if overlaps(a0, a1, 0x0130, 0x0132) {
            let ev = self.rd16(R::EcatEventRequest.addr()) & !EVENT_AL_STATUS;
            self.wr16(R::EcatEventRequest.addr(), ev);
        }
        // Covering an SM's last byte means meeting its window.
        if !self.sm_span.meets(addr, len) {
            return;
        }
        for n in set_bits(self.active_sms) {
            let s = self.sm(n);
            if s.direction() != SmDirection::Read || !s.covers_last_byte(addr, len) {
                continue;
            }
            let status = match s.mode() {
                SmMode::Mailbox => (s.status & !STATUS_MAILBOX_FULL) | STATUS_IRQ_READ,
                _ => s.status | STATUS_IRQ_READ,
            };
            self.set_sm_status(n, status);
        }
    }

    /// SM events of a completed ECAT write.
    pub(super) fn after_write(&mut self, addr: u32, len: usize) {
        if !self.sm_span.meets(addr, len) {
            return;
        }
        for n in set_bits(self.active_sms) {
            let s = self.sm(n);
            if s.direction() != SmDirection::Write || !s.covers_last_byte(addr, len) {
                continue;
            }
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
                        self.wd_last = Some(self.now);
                        let st = self.rd16(R::WatchdogStatusProcessData.addr()) | 1;
                        self.wr16(R::WatchdogStatusProcessData.addr(), st);
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
            dst.copy_from_slice(src);
            self.pd_out_len = len;
            self.pd_out_new = true;
            self.outputs_seen = true;
        }
    }
}
