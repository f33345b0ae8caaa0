//! What follows a datagram (spec §2.4 "after the whole datagram"): SM and
//! FMMU reconfiguration, the EEPROM (SII) command, AL control, the DC latch and system time.

use super::*;

impl<'a> Esc<'a> {
    pub(super) fn after_datagram<H: AlHook>(&mut self, hook: &mut H) {
        let d = core::mem::take(&mut self.dirty);
        if d.sm != 0 {
            self.sm_config_written(d.sm, hook);
        }
        if d.fmmu {
            self.refresh_fmmus();
        }
        if d.sii_control {
            self.sii_command();
        }
        if d.dc_latch {
            self.dc_latch();
        }
        if d.system_time {
            self.dc_system_time_written();
        }
        if d.speed_counter_start {
            self.dc_filters_reset();
        }
        if d.sync_start {
            self.sync0_start = self.rd64(R::DcSyncStartTime.addr());
        }
        if d.al_control {
            self.al_control_written(hook);
        }
    }

    pub(super) fn read_sm_block(&self, n: usize) -> SyncManager {
        let mut b = [0u8; SM_LEN];
        let a = usize::from(R::sync_manager(n as u8));
        if let Some(src) = self.mem.get(a..a + SM_LEN) {
            b.copy_from_slice(src);
        }
        SyncManager::from_bytes(&b)
    }

    pub(super) fn refresh_all_sms(&mut self) {
        for n in 0..SM_COUNT {
            let s = self.read_sm_block(n);
            if let Some(c) = self.sms.get_mut(n) {
                *c = s;
            }
        }
        self.recompute_active_sms();
    }

    pub(super) fn recompute_active_sms(&mut self) {
        self.active_sms = 0;
        self.sm_span = Span::EMPTY;
        for (n, s) in self.sms.iter().enumerate() {
            if s.is_active() {
                self.active_sms |= 1 << n;
                self.sm_span = self.sm_span.with(u64::from(s.start), u64::from(s.end()));
            }
        }
        self.refresh_fmmu_routes();
    }

    /// Resolves, for each active byte-aligned FMMU of one direction, the buffered SM of
    /// that direction whose window holds all its physical bytes while no other active SM
    /// meets them: every access through the FMMU then meets that SM's rules alone, which
    /// its configuration decides (a buffered SM of the access's direction allows it; its
    /// status does not matter), and completes a buffer when it covers the window's last
    /// byte. The process data of every cycle go through these, so [`Esc::sm_access`]'s look
    /// at every window is taken once per configuration, not per datagram.
    pub(super) fn refresh_fmmu_routes(&mut self) {
        for i in 0..FMMU_COUNT {
            let route = self.fmmus.get(i).and_then(|f| self.fmmu_route(f));
            if let Some(r) = self.fmmu_sm.get_mut(i) {
                *r = route;
            }
        }
    }

    fn fmmu_route(&self, f: &Fmmu) -> Option<u8> {
        if !f.is_active() || !f.is_byte_aligned() || f.read_enable == f.write_enable {
            return None;
        }
        let want = if f.write_enable {
            SmDirection::Write
        } else {
            SmDirection::Read
        };
        let p0 = u32::from(f.physical_start);
        let len = usize::from(f.length);
        let p1 = p0 + u32::from(f.length);
        let mut met = set_bits(self.active_sms).filter(|&n| self.sm(n).overlaps(p0, len));
        let n = met.next()?;
        if met.next().is_some() {
            return None;
        }
        let s = self.sm(n);
        let holds = u32::from(s.start) <= p0 && p1 <= s.end();
        (holds && s.mode() == SmMode::Buffered && s.direction() == want)
            .then(|| u8::try_from(n).ok())
            .flatten()
    }

    pub(super) fn refresh_fmmus(&mut self) {
        self.active_fmmus = 0;
        self.fmmu_span = Span::EMPTY;
        for n in 0..FMMU_COUNT {
            let a = usize::from(R::fmmu(n as u8));
            let mut b = [0u8; FMMU_LEN];
            if let Some(src) = self.mem.get(a..a + FMMU_LEN) {
                b.copy_from_slice(src);
            }
            let f = Fmmu::from_bytes(&b);
            if f.is_active() && f.bit_count() > 0 {
                self.active_fmmus |= 1 << n;
                // A mapping's logical bits all lie in its `length` bytes (fmmu.rs).
                let start = u64::from(f.logical_start);
                self.fmmu_span = self.fmmu_span.with(start, start + u64::from(f.length));
            }
            if let Some(c) = self.fmmus.get_mut(n) {
                *c = f;
            }
        }
        self.refresh_fmmu_routes();
    }

    pub(super) fn sm_config_written<H: AlHook>(&mut self, mask: u16, hook: &mut H) {
        let mut changed = 0u16;
        for n in 0..SM_COUNT {
            if mask & (1 << n) == 0 {
                continue;
            }
            let new = self.read_sm_block(n);
            let old = self.sm(n);
            if let Some(c) = self.sms.get_mut(n) {
                *c = new;
            }
            if !old.layout_eq(&new) {
                changed |= 1 << n;
                // A reconfigured SM starts empty (mailbox) / with no buffer written.
                let status = if new.mode() == SmMode::Buffered {
                    STATUS_BUFFER_MASK
                } else {
                    0
                };
                self.set_sm_status(n, status);
                if n == SM_OUTPUTS {
                    self.pd_out_new = false;
                }
            }
            if n == SM_MAILBOX_IN && self.mailbox_running {
                let s = self.sm(n);
                let request = s.activate & sm::ACTIVATE_REPEAT != 0;
                let ack = s.pdi_control & sm::PDI_REPEAT_ACK != 0;
                if request != ack {
                    self.mailbox_repeat();
                }
            }
        }
        self.recompute_active_sms();
        // Autonomous fall-backs (spec §4.2): SMs reconfigured invalidly while in use.
        let state = self.al_state();
        if changed & 0b0011 != 0 && self.mailbox_running && self.check_mailbox_sms().is_err() {
            self.fall_back_with(
                AlState::Init,
                AlStatusCode::INVALID_MAILBOX_CONFIGURATION,
                hook,
            );
        } else if changed & 0b1100 != 0 && matches!(state, AlState::SafeOp | AlState::Op) {
            if let Err(code) = self.check_process_data_structure() {
                self.fall_back_with(AlState::PreOp, code, hook);
            }
        }
    }

    /// Repeat request (§5.4): post the last reply again and acknowledge.
    pub(super) fn mailbox_repeat(&mut self) {
        let s = self.sm(SM_MAILBOX_IN);
        let len = self.mbx_backup_len;
        if len > 0 && s.is_active() && len <= usize::from(s.length) {
            let mut backup = [0u8; MAILBOX_MAX];
            if let (Some(b), Some(src)) = (backup.get_mut(..len), self.mbx_backup.get(..len)) {
                b.copy_from_slice(src);
            }
            if let Some(w) = self.window_mut(s.start, s.length) {
                w.fill(0);
                if let (Some(d), Some(src)) = (w.get_mut(..len), backup.get(..len)) {
                    d.copy_from_slice(src);
                }
            }
            self.set_sm_status(
                SM_MAILBOX_IN,
                (s.status | STATUS_MAILBOX_FULL) & !STATUS_IRQ_READ,
            );
        }
        let pdi = (s.pdi_control & !sm::PDI_REPEAT_ACK) | (s.activate & sm::ACTIVATE_REPEAT);
        self.set_sm_pdi_control(SM_MAILBOX_IN, pdi);
    }

    pub(super) fn sii_command(&mut self) {
        let a = R::SiiControl.addr();
        let control = self.rd16(a);
        let mut status = eeprom::READ_SIZE_8;
        let addr = self.rd32(R::SiiAddress.addr());
        match SiiCommand::from_control(control) {
            SiiCommand::Nop => {}
            SiiCommand::Read => {
                for i in 0..4u32 {
                    let w = self.eeprom.word(addr.wrapping_add(i));
                    self.wr16(R::SiiData.addr() + 2 * i as u16, w);
                }
            }
            SiiCommand::Write => {
                if control & eeprom::WRITE_ENABLE == 0 {
                    status |= eeprom::WRITE_ENABLE_ERROR;
                } else {
                    let v = self.rd16(R::SiiData.addr());
                    if !self.eeprom.write_word(addr, v) {
                        status |= eeprom::ACK_ERROR;
                    }
                }
            }
            SiiCommand::Reload => {}
            SiiCommand::Invalid(_) => status |= eeprom::ACK_ERROR,
        }
        self.wr16(a, status);
    }

    pub(super) fn dc_latch(&mut self) {
        let t = self.local_time_at(self.now);
        for p in 0..4u16 {
            self.wr32(R::DcReceiveTimePort0.addr() + 4 * p, t as u32);
        }
        self.wr64(R::DcReceiveTimeProcessingUnit.addr(), t);
    }

    pub(super) fn dc_system_time_written(&mut self) {
        let written = u64::from_le_bytes(self.systime_write);
        let delay = u64::from(self.rd32(R::DcSystemTimeDelay.addr()));
        let received = written.wrapping_add(delay);
        let local_copy = self.system_time_at(self.now);
        let diff = received.wrapping_sub(local_copy) as i64;
        let magnitude = diff.unsigned_abs().min(0x7FFF_FFFF) as u32;
        let sign = if diff <= 0 { 0x8000_0000 } else { 0 };
        self.wr32(R::DcSystemTimeDifference.addr(), sign | magnitude);
        let offset = self.rd64(R::DcSystemTimeOffset.addr());
        self.wr64(
            R::DcSystemTimeOffset.addr(),
            offset.wrapping_add(diff as u64),
        );
    }

    /// A write to the speed counter start 0x0930 resets the time-control loop's filters: the
    /// system time difference 0x092C and the speed counter difference 0x0932 start again from
    /// 0 (ESC datasheet section II, 0x0930; masters write it right after zeroing 0x0910 in
    /// their DC reset, spec §8.1). Without it the reference clock, which never receives a
    /// system time again (FRMW reads it), would show the difference of that reset write for
    /// ever, and ethercrab's alignment check on 0x092C (examples/dc.rs) would never settle.
    pub(super) fn dc_filters_reset(&mut self) {
        self.wr32(R::DcSystemTimeDifference.addr(), 0);
        self.wr16(R::DcSpeedCounterDifference.addr(), 0);
    }
}
