//! The AL state machine (spec §4.2): AL control processed, the ESC's own
//! checks of the mailbox and process-data SMs, the device's hook asked, AL status and its
//! event.

use super::*;

impl<'a> Esc<'a> {
    pub(super) fn set_al_status(&mut self, state: AlState, error: bool, code: AlStatusCode) {
        let v = AlStatus { state, error }.to_u16();
        if v != self.rd16(R::AlStatus.addr()) {
            let ev = self.rd16(R::EcatEventRequest.addr()) | EVENT_AL_STATUS;
            self.wr16(R::EcatEventRequest.addr(), ev);
            self.refresh_irq();
        }
        self.wr16(R::AlStatus.addr(), v);
        self.wr16(R::AlStatusCode.addr(), code.0);
    }

    pub(super) fn al_control_written<H: AlHook>(&mut self, hook: &mut H) {
        let control = AlControl::from_u16(self.rd16(R::AlControl.addr()));
        let status = self.al_status();
        // §4.2 step 2: with the error bit set, only an acknowledging request is served.
        if status.error && !control.error_ack {
            return;
        }
        let from = status.state;
        if control.error_ack {
            self.set_al_status(from, false, AlStatusCode::NO_ERROR);
        }
        let to = match check_transition(from, control.requested, self.config.bootstrap_supported) {
            Ok(to) => to,
            Err(code) => {
                self.set_al_status(from, true, code);
                return;
            }
        };
        if to == from {
            return;
        }
        if is_upward(from, to) {
            let checked = self
                .builtin_check(from, to)
                .and_then(|()| hook.check_transition(self, from, to));
            if let Err(code) = checked {
                self.set_al_status(from, true, code);
                return;
            }
        }
        self.enter_state(from, to, false, AlStatusCode::NO_ERROR);
        hook.state_changed(self, from, to);
    }

    pub(super) fn builtin_check(&self, from: AlState, to: AlState) -> Result<(), AlStatusCode> {
        match (from, to) {
            (AlState::Init, AlState::PreOp) => self.check_mailbox_sms(),
            (AlState::PreOp, AlState::SafeOp) => self.check_process_data_structure(),
            (AlState::SafeOp, AlState::Op)
                if self.config.require_outputs_for_op && !self.outputs_seen =>
            {
                Err(AlStatusCode::NO_VALID_OUTPUTS)
            }
            _ => Ok(()),
        }
    }

    pub(super) fn enter_state(
        &mut self,
        from: AlState,
        to: AlState,
        error: bool,
        code: AlStatusCode,
    ) {
        self.set_al_status(to, error, code);
        match to {
            AlState::Init | AlState::Bootstrap => {
                self.mailbox_running = false;
                self.clear_mailboxes();
                self.pd_out_new = false;
                self.wd_last = None;
            }
            AlState::PreOp => {
                if matches!(from, AlState::Init | AlState::Bootstrap) {
                    // Start the mailbox handler: both mailboxes empty, repeat-ack = request.
                    self.clear_mailboxes();
                    let s = self.sm(SM_MAILBOX_IN);
                    let pdi =
                        (s.pdi_control & !sm::PDI_REPEAT_ACK) | (s.activate & sm::ACTIVATE_REPEAT);
                    self.set_sm_pdi_control(SM_MAILBOX_IN, pdi);
                    self.mbx_backup_len = 0;
                    self.mailbox_running = true;
                }
                self.pd_out_new = false;
                self.wd_last = None;
            }
            AlState::SafeOp => {
                if from == AlState::PreOp {
                    self.outputs_seen = false;
                }
                self.wd_last = None;
            }
            AlState::Op => {
                self.wd_last = Some(self.now);
            }
        }
    }

    pub(super) fn clear_mailboxes(&mut self) {
        for n in [SM_MAILBOX_OUT, SM_MAILBOX_IN] {
            let s = self.sm(n);
            if s.mode() == SmMode::Mailbox {
                self.set_sm_status(
                    n,
                    s.status & !(STATUS_MAILBOX_FULL | STATUS_IRQ_WRITE | STATUS_IRQ_READ),
                );
            }
        }
    }

    pub(super) fn fall_back_with<H: AlHook>(
        &mut self,
        to: AlState,
        code: AlStatusCode,
        hook: &mut H,
    ) {
        let from = self.al_state();
        let target = if is_upward(from, to) { from } else { to };
        self.enter_state(from, target, true, code);
        if target != from {
            hook.state_changed(self, from, target);
        }
    }

    /// The device drops the slave to `to` (not above the current state) with the error bit
    /// and `code`, e.g. a synchronisation error (0x001A) in Op. The hook is not called: the
    /// device knows.
    pub fn fall_back(&mut self, to: AlState, code: AlStatusCode) {
        self.fall_back_with(to, code, &mut NoHook);
    }

    /// Init → Pre-Op check of SM0/SM1 against the configured mailbox (§4.2 table).
    pub fn check_mailbox_sms(&self) -> Result<(), AlStatusCode> {
        let Some(m) = self.config.mailbox else {
            return Ok(());
        };
        let rx = self.sm(SM_MAILBOX_OUT);
        let tx = self.sm(SM_MAILBOX_IN);
        let ok = rx.is_enabled()
            && rx.start == m.rx_offset
            && rx.length == m.rx_size
            && rx.mode() == SmMode::Mailbox
            && rx.direction() == SmDirection::Write
            && tx.is_enabled()
            && tx.start == m.tx_offset
            && tx.length == m.tx_size
            && tx.mode() == SmMode::Mailbox
            && tx.direction() == SmDirection::Read
            && !tx.overlaps(u32::from(rx.start), usize::from(rx.length))
            && usize::from(rx.length) <= MAILBOX_MAX
            && usize::from(tx.length) <= MAILBOX_MAX;
        if ok {
            Ok(())
        } else {
            Err(AlStatusCode::INVALID_MAILBOX_CONFIGURATION)
        }
    }

    /// The ESC's structural Pre-Op → Safe-Op check: an enabled SM2 is buffered with the
    /// master writing (else 0x001D), an enabled SM3 buffered with the master reading (else
    /// 0x001E), and no two of SM0–SM3 overlap (3 × length for buffered SMs; else 0x0017).
    pub fn check_process_data_structure(&self) -> Result<(), AlStatusCode> {
        let out = self.sm(SM_OUTPUTS);
        if out.is_active()
            && (out.mode() != SmMode::Buffered || out.direction() != SmDirection::Write)
        {
            return Err(AlStatusCode::INVALID_OUTPUT_CONFIGURATION);
        }
        let inp = self.sm(SM_INPUTS);
        if inp.is_active()
            && (inp.mode() != SmMode::Buffered || inp.direction() != SmDirection::Read)
        {
            return Err(AlStatusCode::INVALID_INPUT_CONFIGURATION);
        }
        if usize::from(out.length) > PROCESS_DATA_MAX && out.is_active() {
            return Err(AlStatusCode::INVALID_OUTPUT_CONFIGURATION);
        }
        for a in 0..4 {
            for b in (a + 1)..4 {
                let (sa, sb) = (self.sm(a), self.sm(b));
                if !sa.is_active() || !sb.is_active() {
                    continue;
                }
                if u32::from(sa.start) < sb.reserved_end()
                    && u32::from(sb.start) < sa.reserved_end()
                {
                    return Err(AlStatusCode::INVALID_SYNC_MANAGER_CONFIGURATION);
                }
            }
        }
        Ok(())
    }

    /// Pre-Op → Safe-Op check for a device that needs `outputs` bytes in SM2 and `inputs`
    /// bytes in SM3 (§4.2 table): with data, the SM must be enabled with exactly that length
    /// (buffered, right direction); without, it must be disabled or have length 0 (both are
    /// what masters write). Failures: 0x001D outputs, 0x001E inputs; then the structural
    /// check.
    pub fn check_process_data(&self, outputs: u16, inputs: u16) -> Result<(), AlStatusCode> {
        let fits = |s: SyncManager, len: u16, dir: SmDirection| {
            if len == 0 {
                !s.is_active()
            } else {
                s.is_enabled()
                    && s.length == len
                    && s.mode() == SmMode::Buffered
                    && s.direction() == dir
            }
        };
        if !fits(self.sm(SM_OUTPUTS), outputs, SmDirection::Write) {
            return Err(AlStatusCode::INVALID_OUTPUT_CONFIGURATION);
        }
        if !fits(self.sm(SM_INPUTS), inputs, SmDirection::Read) {
            return Err(AlStatusCode::INVALID_INPUT_CONFIGURATION);
        }
        self.check_process_data_structure()
    }
}
