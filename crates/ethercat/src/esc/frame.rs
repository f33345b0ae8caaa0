//! Frame processing (spec §1–§2): the datagrams of a frame walked in place,
//! each command addressed to this slave executed, working counters and auto-increment
//! addresses updated, the side effects of a datagram applied right after it.

use super::*;

impl<'a> Esc<'a> {
    /// Process an Ethernet frame in place (no hook: every transition the ESC's own checks
    /// accept is taken).
    pub fn process(&mut self, now: Instant, frame: &mut [u8]) -> FrameOutcome {
        self.process_with(now, frame, &mut NoHook)
    }

    /// Process an Ethernet frame in place, asking `hook` about AL transitions.
    pub fn process_with<H: AlHook>(
        &mut self,
        now: Instant,
        frame: &mut [u8],
        hook: &mut H,
    ) -> FrameOutcome {
        let Ok(mut eth) = EthernetFrame::new_checked(frame) else {
            self.errors.not_ethercat = self.errors.not_ethercat.wrapping_add(1);
            return FrameOutcome::NotEtherCat;
        };
        if eth.ethertype() != ETHERTYPE_ETHERCAT {
            self.errors.not_ethercat = self.errors.not_ethercat.wrapping_add(1);
            return FrameOutcome::NotEtherCat;
        }
        eth.mark_returned();
        self.process_ecat_with(now, eth.payload_mut(), hook)
    }

    /// Process a buffer that starts with the EtherCAT header (no Ethernet header, e.g.
    /// EtherCAT in UDP).
    pub fn process_ecat(&mut self, now: Instant, ecat: &mut [u8]) -> FrameOutcome {
        self.process_ecat_with(now, ecat, &mut NoHook)
    }

    /// [`Esc::process_ecat`] with a hook.
    pub fn process_ecat_with<H: AlHook>(
        &mut self,
        now: Instant,
        ecat: &mut [u8],
        hook: &mut H,
    ) -> FrameOutcome {
        self.advance(now, hook);
        let header = match ecat.get(0..2) {
            Some(&[lo, hi]) => u16::from_le_bytes([lo, hi]),
            _ => {
                self.count_truncated_frame();
                return FrameOutcome::Malformed {
                    datagrams: 0,
                    error: WireError::Truncated,
                };
            }
        };
        if header >> 12 != u16::from(crate::frame::TYPE_COMMANDS) {
            self.errors.unsupported_type = self.errors.unsupported_type.wrapping_add(1);
            return FrameOutcome::Ignored;
        }
        let length = usize::from(header & 0x07FF);
        let available = ecat.len() - 2;
        let frame_truncated = length > available;
        let Some(payload) = ecat.get_mut(2..2 + length.min(available)) else {
            return FrameOutcome::Ignored;
        };
        let mut off = 0usize;
        let mut count: u16 = 0;
        let mut error = None;
        while let Some(rest) = payload.get_mut(off..) {
            let total = match datagram::total_len(rest) {
                Some(t) if t <= rest.len() => t,
                _ => {
                    error = Some(WireError::Truncated);
                    break;
                }
            };
            let Some(dg) = rest.get_mut(..total) else {
                break;
            };
            let more = Datagram::new_unchecked(&*dg).more_follows();
            self.execute(dg, hook);
            count = count.wrapping_add(1);
            off += total;
            if !more {
                break;
            }
        }
        if error.is_some() {
            self.errors.truncated_datagrams = self.errors.truncated_datagrams.wrapping_add(1);
        }
        if frame_truncated {
            self.errors.truncated_frames = self.errors.truncated_frames.wrapping_add(1);
            error = Some(WireError::Truncated);
        }
        if error.is_some() {
            self.bump_invalid_frame_counter();
        }
        match error {
            Some(error) => FrameOutcome::Malformed {
                datagrams: count,
                error,
            },
            None => FrameOutcome::Processed { datagrams: count },
        }
    }

    pub(super) fn count_truncated_frame(&mut self) {
        self.errors.truncated_frames = self.errors.truncated_frames.wrapping_add(1);
        self.bump_invalid_frame_counter();
    }

    /// Invalid-frame counter of port 0 (0x0300), saturating at 0xFF as on the chip.
    pub(super) fn bump_invalid_frame_counter(&mut self) {
        let a = R::RxErrorCounter.addr();
        let v = self.rd8(a);
        self.wr8(a, v.saturating_add(1));
    }

    /// Let time pass without a frame: runs the process-data watchdog. Returns the next
    /// instant at which the ESC has something to do (the watchdog expiry), if any.
    pub fn poll(&mut self, now: Instant) -> Option<Instant> {
        self.poll_with(now, &mut NoHook)
    }

    /// [`Esc::poll`] with a hook (told about a watchdog fall-back).
    pub fn poll_with<H: AlHook>(&mut self, now: Instant, hook: &mut H) -> Option<Instant> {
        self.advance(now, hook);
        let timeout = self.watchdog_timeout_ns()?;
        let last = self.wd_last?;
        self.watchdog_armed()
            .then(|| Instant::from_nanos(last.as_nanos().saturating_add(timeout)))
    }

    pub(super) fn advance<H: AlHook>(&mut self, now: Instant, hook: &mut H) {
        self.now = now;
        self.check_watchdog(hook);
    }

    pub(super) fn matches_station(&self, adp: u16) -> bool {
        adp == self.station_address()
            || (self.rd8(R::DlControlAliasEnable.addr()) & 0x01 != 0
                && adp == self.rd16(R::ConfiguredStationAlias.addr()))
    }

    pub(super) fn execute<H: AlHook>(&mut self, buf: &mut [u8], hook: &mut H) {
        let mut dg = Datagram::new_unchecked(buf);
        let cmd = dg.command();
        let adp = dg.adp();
        let ado = u32::from(dg.ado());
        let inc: u16 = match cmd {
            Command::Nop => 0,
            Command::Unknown(_) => {
                self.errors.unknown_commands = self.errors.unknown_commands.wrapping_add(1);
                return;
            }
            Command::Aprd | Command::Apwr | Command::Aprw | Command::Armw => {
                dg.set_adp(adp.wrapping_add(1));
                self.physical(cmd, adp == 0, ado, dg.data_mut())
            }
            Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw => {
                let hit = self.matches_station(adp);
                self.physical(cmd, hit, ado, dg.data_mut())
            }
            Command::Brd | Command::Bwr | Command::Brw => {
                dg.set_adp(adp.wrapping_add(1));
                self.physical(cmd, true, ado, dg.data_mut())
            }
            Command::Lrd | Command::Lwr | Command::Lrw => {
                let addr = dg.logical_address();
                self.logical(cmd, addr, dg.data_mut())
            }
        };
        if inc != 0 {
            let w = dg.wkc();
            dg.set_wkc(w.wrapping_add(inc));
        }
        let irq = self.irq;
        if irq != 0 {
            let v = dg.irq();
            dg.set_irq(v | irq);
        }
        self.after_datagram(hook);
    }

    /// Position, configured and broadcast commands; returns the WKC increment.
    pub(super) fn physical(
        &mut self,
        cmd: Command,
        addressed: bool,
        ado: u32,
        data: &mut [u8],
    ) -> u16 {
        match cmd {
            Command::Aprd | Command::Fprd if addressed => {
                u16::from(self.ecat_read(ado, data, false))
            }
            Command::Brd => u16::from(self.ecat_read(ado, data, true)),
            Command::Apwr | Command::Fpwr if addressed => u16::from(self.ecat_write(ado, data)),
            Command::Bwr => u16::from(self.ecat_write(ado, data)),
            Command::Aprw | Command::Fprw if addressed => {
                let offset = u32::from(self.rd16(R::PhysicalRwOffset.addr()));
                self.ecat_exchange(ado, ado + offset, data, false)
            }
            Command::Brw => self.ecat_exchange(ado, ado, data, true),
            // ARMW/FRMW: the addressed slave reads, every other one writes (DC time
            // distribution, spec §1.4).
            Command::Armw | Command::Frmw if addressed => {
                u16::from(self.ecat_read(ado, data, false))
            }
            Command::Armw | Command::Frmw => u16::from(self.ecat_write(ado, data)),
            _ => 0,
        }
    }

    pub(super) fn ecat_read(&mut self, addr: u32, out: &mut [u8], or: bool) -> bool {
        let Some(events) = self.sm_access(addr, out.len(), Dir::Read) else {
            return false;
        };
        self.phys_read_events(addr, out, or, events);
        true
    }

    pub(super) fn ecat_write(&mut self, addr: u32, data: &[u8]) -> bool {
        let Some(events) = self.sm_access(addr, data.len(), Dir::Write) else {
            return false;
        };
        self.phys_write_events(addr, data, events);
        true
    }

    /// APRW/FPRW/BRW: old memory into the frame (ORed for BRW), the frame's data as it
    /// arrived into memory. +1 for the read, +2 for the write.
    pub(super) fn ecat_exchange(
        &mut self,
        raddr: u32,
        waddr: u32,
        data: &mut [u8],
        or: bool,
    ) -> u16 {
        const CHUNK: usize = 64;
        let n = data.len();
        let read_ok = self.sm_allows(raddr, n, Dir::Read);
        let write_ok = self.sm_allows(waddr, n, Dir::Write);
        let mut off = 0usize;
        for chunk in data.chunks_mut(CHUNK) {
            let mut orig = [0u8; CHUNK];
            let len = chunk.len();
            if let Some(o) = orig.get_mut(..len) {
                o.copy_from_slice(chunk);
            }
            if read_ok {
                self.phys_read(raddr + off as u32, chunk, or);
            }
            if write_ok {
                if let Some(o) = orig.get(..len) {
                    self.phys_write(waddr + off as u32, o);
                }
            }
            off += len;
        }
        u16::from(read_ok) + 2 * u16::from(write_ok)
    }

    /// Logical commands through the FMMUs; +1 if any read FMMU hit, +1 (LWR) or +2 (LRW)
    /// if any write FMMU hit, whatever the number of FMMUs (spec §1.4 rule 4, §7.5).
    pub(super) fn logical(&mut self, cmd: Command, addr: u32, data: &mut [u8]) -> u16 {
        // No active mapping meets the datagram: nothing to do (most slaves of a long line
        // for most logical datagrams).
        if !self.fmmu_span.meets(addr, data.len()) {
            return 0;
        }
        let mut inc = 0;
        // Writes take the data as it arrived, so they go first (LRW, §7.5).
        if matches!(cmd, Command::Lwr | Command::Lrw) {
            let mut hit = false;
            for i in set_bits(self.active_fmmus) {
                let Some(f) = self.fmmus.get(i).copied() else {
                    continue;
                };
                if f.write_enable {
                    hit |= self.fmmu_write(i, &f, addr, data);
                }
            }
            if hit {
                inc += if cmd == Command::Lrw { 2 } else { 1 };
            }
        }
        if matches!(cmd, Command::Lrd | Command::Lrw) {
            let mut hit = false;
            for i in set_bits(self.active_fmmus) {
                let Some(f) = self.fmmus.get(i).copied() else {
                    continue;
                };
                if f.read_enable {
                    hit |= self.fmmu_read(i, &f, addr, data);
                }
            }
            if hit {
                inc += 1;
            }
        }
        inc
    }

    /// Writes through FMMU `i` (`f`).
    pub(super) fn fmmu_write(&mut self, i: usize, f: &Fmmu, addr: u32, data: &[u8]) -> bool {
        if f.is_byte_aligned() {
            let Some(w) = f.byte_window(addr, data.len()) else {
                return false;
            };
            let Some(src) = data.get(w.datagram_offset..w.datagram_offset + w.len) else {
                return false;
            };
            let Some(events) = self.fmmu_sm_access(i, w.physical, w.len, Dir::Write) else {
                return false;
            };
            self.phys_write_events(w.physical, src, events);
            return true;
        }
        let Some(bw) = f.bit_window(addr, data.len()) else {
            return false;
        };
        let (p0, _) = f.physical_bit(bw.first);
        let (p1, _) = f.physical_bit(bw.end - 1);
        let plen = (p1 - p0 + 1) as usize;
        if !self.sm_allows(p0, plen, Dir::Write) {
            return false;
        }
        for i in bw.first..bw.end {
            let (lbyte, lbit) = f.logical_bit(addr, i);
            let Some(&src) = usize::try_from(lbyte).ok().and_then(|b| data.get(b)) else {
                continue;
            };
            let bit = (src >> lbit) & 1;
            let (pa, pb) = f.physical_bit(i);
            let mut cur = [0u8];
            self.peek(pa, &mut cur);
            let new = (cur[0] & !(1 << pb)) | (bit << pb);
            self.phys_write(pa, &[new]);
        }
        true
    }

    /// Reads through FMMU `i` (`f`).
    pub(super) fn fmmu_read(&mut self, i: usize, f: &Fmmu, addr: u32, data: &mut [u8]) -> bool {
        if f.is_byte_aligned() {
            let Some(w) = f.byte_window(addr, data.len()) else {
                return false;
            };
            let Some(dst) = data.get_mut(w.datagram_offset..w.datagram_offset + w.len) else {
                return false;
            };
            let Some(events) = self.fmmu_sm_access(i, w.physical, w.len, Dir::Read) else {
                return false;
            };
            self.phys_read_events(w.physical, dst, false, events);
            return true;
        }
        let Some(bw) = f.bit_window(addr, data.len()) else {
            return false;
        };
        let (p0, _) = f.physical_bit(bw.first);
        let (p1, _) = f.physical_bit(bw.end - 1);
        let plen = (p1 - p0 + 1) as usize;
        if !self.sm_allows(p0, plen, Dir::Read) {
            return false;
        }
        self.refresh_dynamic(p0 as usize, p0 as usize + plen);
        for i in bw.first..bw.end {
            let (pa, pb) = f.physical_bit(i);
            let mut cur = [0u8];
            self.peek(pa, &mut cur);
            let bit = (cur[0] >> pb) & 1;
            let (lbyte, lbit) = f.logical_bit(addr, i);
            if let Some(d) = usize::try_from(lbyte).ok().and_then(|b| data.get_mut(b)) {
                *d = (*d & !(1 << lbit)) | (bit << lbit);
            }
        }
        self.after_read(p0, plen);
        true
    }

    /// Memory content without side effects (0 beyond the backed memory).
    pub(super) fn peek(&self, addr: u32, out: &mut [u8]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.mem.get(addr as usize + i).copied().unwrap_or(0);
        }
    }
}
