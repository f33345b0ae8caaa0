//! ECAT reads and writes of the ESC's memory (spec §1.4): registers computed
//! when read (system time, next SYNC0), and the registers whose write has an effect after
//! the datagram, marked dirty.

use super::*;

impl<'a> Esc<'a> {
    /// Registers whose content is computed when read.
    pub(super) fn refresh_dynamic(&mut self, a0: usize, a1: usize) {
        if overlaps(a0, a1, 0x0910, 0x0918) {
            let t = self.system_time_at(self.now);
            self.wr64(R::DcSystemTime.addr(), t);
        }
        if overlaps(a0, a1, 0x0990, 0x0998) {
            if let Some(t) = self.next_sync0_at(self.now) {
                self.wr64(R::DcSyncStartTime.addr(), t);
            }
        }
    }

    pub(super) fn phys_read(&mut self, addr: u32, out: &mut [u8], or: bool) {
        let events = self.sm_events(addr, out.len(), Dir::Read);
        self.phys_read_events(addr, out, or, events);
    }

    /// [`Esc::phys_read`] with the SMs whose last byte it covers known ([`Esc::sm_access`]).
    pub(super) fn phys_read_events(&mut self, addr: u32, out: &mut [u8], or: bool, events: u8) {
        let start = addr as usize;
        let end = start + out.len();
        if start < 0x1000 {
            self.refresh_dynamic(start, end);
        }
        let backed_end = end.min(MEMORY_SIZE);
        let n = backed_end.saturating_sub(start);
        if let (Some(src), Some(dst)) = (self.mem.get(start..backed_end), out.get_mut(..n)) {
            if or {
                for (d, s) in dst.iter_mut().zip(src) {
                    *d |= *s;
                }
            } else {
                copy_bytes(dst, src);
            }
        }
        if !or && n < out.len() {
            if let Some(rest) = out.get_mut(n..) {
                rest.fill(0);
            }
        }
        self.after_read_events(addr, out.len(), events);
    }

    pub(super) fn phys_write(&mut self, addr: u32, data: &[u8]) {
        let events = self.sm_events(addr, data.len(), Dir::Write);
        self.phys_write_events(addr, data, events);
    }

    /// [`Esc::phys_write`] with the SMs whose last byte it covers known ([`Esc::sm_access`]).
    pub(super) fn phys_write_events(&mut self, addr: u32, data: &[u8], events: u8) {
        let start = addr as usize;
        let end = start + data.len();
        if start < 0x1000 {
            let rend = end.min(0x1000);
            self.note_register_write(start, rend);
            let systime = usize::from(R::DcSystemTime.addr());
            match self
                .systime_write
                .get_mut(start.wrapping_sub(systime)..rend.wrapping_sub(systime))
            {
                // Within the system time (the ARMW / FRMW of every cycle): all of it an
                // input to the time-control loop, as byte by byte below.
                Some(dst) if start >= systime => {
                    if let Some(src) = data.get(..dst.len()) {
                        copy_bytes(dst, src);
                    }
                }
                _ => {
                    for (i, &d) in data.iter().enumerate().take(rend - start) {
                        self.write_register_byte(start + i, d);
                    }
                }
            }
            self.registers_written(start, rend);
        }
        let lo = start.max(0x1000);
        let hi = end.min(MEMORY_SIZE);
        if lo < hi {
            if let (Some(dst), Some(src)) =
                (self.mem.get_mut(lo..hi), data.get(lo - start..hi - start))
            {
                copy_bytes(dst, src);
            }
        }
        self.after_write_events(events);
    }

    /// Keeps what the ESC holds beside its registers in step with a write to `[a0, a1)`:
    /// the datagrams' IRQ (0x0200, 0x0210) and the watchdog's timeout (0x0400, 0x0420).
    pub(super) fn registers_written(&mut self, a0: usize, a1: usize) {
        if overlaps(a0, a1, 0x0200, 0x0212) {
            self.refresh_irq();
        }
        if overlaps(a0, a1, 0x0400, 0x0402) || overlaps(a0, a1, 0x0420, 0x0422) {
            self.refresh_watchdog_timeout();
        }
    }

    pub(super) fn write_register_byte(&mut self, a: usize, d: u8) {
        match a {
            // Error counters: any write clears (spec §2.1).
            0x0300..=0x0313 | 0x0442..=0x0443 => {
                if let Some(m) = self.mem.get_mut(a) {
                    *m = 0;
                }
            }
            // System time: an input to the time-control loop, handled after the datagram.
            0x0910..=0x0917 => {
                if let Some(b) = self.systime_write.get_mut(a - 0x0910) {
                    *b = d;
                }
            }
            _ => {
                let mask = register::ECAT_WRITE_MASK.get(a).copied().unwrap_or(0);
                if mask != 0 {
                    if let Some(m) = self.mem.get_mut(a) {
                        *m = (*m & !mask) | (d & mask);
                    }
                }
            }
        }
    }

    pub(super) fn note_register_write(&mut self, a0: usize, a1: usize) {
        if overlaps(a0, a1, 0x0120, 0x0122) {
            self.dirty.al_control = true;
        }
        if overlaps(a0, a1, 0x0502, 0x0504) {
            self.dirty.sii_control = true;
        }
        if overlaps(a0, a1, 0x0600, 0x0600 + FMMU_LEN * FMMU_COUNT) {
            self.dirty.fmmu = true;
        }
        if overlaps(a0, a1, 0x0800, 0x0800 + SM_LEN * SM_COUNT) {
            for n in 0..SM_COUNT {
                let s = 0x0800 + SM_LEN * n;
                if overlaps(a0, a1, s, s + SM_LEN) {
                    self.dirty.sm |= 1 << n;
                }
            }
        }
        if overlaps(a0, a1, 0x0900, 0x0910) {
            self.dirty.dc_latch = true;
        }
        if overlaps(a0, a1, 0x0910, 0x0918) && !self.dirty.system_time {
            self.dirty.system_time = true;
            // Bytes the datagram does not cover keep the current system time.
            if a0 > 0x0910 || a1 < 0x0918 {
                self.systime_write = self.system_time_at(self.now).to_le_bytes();
            }
        }
        if overlaps(a0, a1, 0x0930, 0x0932) {
            self.dirty.speed_counter_start = true;
        }
        if overlaps(a0, a1, 0x0990, 0x0998) {
            self.dirty.sync_start = true;
        }
    }
}
