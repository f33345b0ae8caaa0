//! The process-data watchdog (spec §7.6): in Op, with SM2 watchdog-triggered
//! and an active write FMMU, no complete SM2 write within 0x0420 × (0x0400 + 2) × 40 ns drops
//! the slave to Safe-Op with 0x001B.

use super::*;

impl<'a> Esc<'a> {
    /// The process-data watchdog's timeout, `None` when it is off (0x0420 = 0).
    pub(super) fn watchdog_timeout_ns(&self) -> Option<u64> {
        self.pd_watchdog_timeout
    }

    /// [`Esc::watchdog_timeout_ns`] from 0x0400 and 0x0420, after either changed: every
    /// frame asks for it, and a register line of every slave of a long line read per frame
    /// is a cache miss.
    pub(super) fn refresh_watchdog_timeout(&mut self) {
        let t = u64::from(self.rd16(R::WatchdogTimeProcessData.addr()));
        let div = u64::from(self.rd16(R::WatchdogDivider.addr()));
        self.pd_watchdog_timeout = (t != 0).then(|| t * (div + 2) * 40);
    }

    /// A complete SM2 write restarts the watchdog (§7.6): 0x0440 bit 0 shows it running
    /// again once it had expired.
    pub(super) fn watchdog_restarted(&mut self) {
        self.wd_last = Some(self.now);
        if self.pd_watchdog_expired {
            self.pd_watchdog_expired = false;
            let st = self.rd16(R::WatchdogStatusProcessData.addr()) | 1;
            self.wr16(R::WatchdogStatusProcessData.addr(), st);
        }
    }

    pub(super) fn watchdog_armed(&self) -> bool {
        let out = self.sm(SM_OUTPUTS);
        self.al_state() == AlState::Op
            && out.is_active()
            && out.control & sm::CONTROL_WATCHDOG != 0
            && self
                .fmmus
                .iter()
                .enumerate()
                .any(|(i, f)| self.active_fmmus & (1 << i) != 0 && f.write_enable)
    }

    pub(super) fn check_watchdog<H: AlHook>(&mut self, hook: &mut H) {
        let (Some(timeout), Some(last)) = (self.watchdog_timeout_ns(), self.wd_last) else {
            return;
        };
        if self.now.saturating_since(last).as_nanos() <= u128::from(timeout)
            || !self.watchdog_armed()
        {
            return;
        }
        let st = self.rd16(R::WatchdogStatusProcessData.addr()) & !1;
        self.wr16(R::WatchdogStatusProcessData.addr(), st);
        self.pd_watchdog_expired = true;
        let a = R::WatchdogCounterProcessData.addr();
        let c = self.rd8(a);
        self.wr8(a, c.saturating_add(1));
        self.wd_last = None;
        self.fall_back_with(AlState::SafeOp, AlStatusCode::SYNC_MANAGER_WATCHDOG, hook);
    }
}
