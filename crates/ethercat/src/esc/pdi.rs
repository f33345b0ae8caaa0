//! The PDI side: what the device behind the ESC does (spec §5, §7): mailbox
//! read and write, process outputs taken, inputs set.

use super::*;

impl<'a> Esc<'a> {
    /// Take the message the master wrote into the receive mailbox (SM0), if there is one:
    /// the whole SM window (header and padding; parse it with [`crate::mailbox::Mailbox`]).
    /// Taking it empties the mailbox, so the master may write the next one.
    pub fn mailbox_read(&mut self) -> Option<&[u8]> {
        if !self.mailbox_running {
            return None;
        }
        let s = self.sm(SM_MAILBOX_OUT);
        if !s.is_active()
            || s.mode() != SmMode::Mailbox
            || s.direction() != SmDirection::Write
            || !s.is_mailbox_full()
        {
            return None;
        }
        self.set_sm_status(
            SM_MAILBOX_OUT,
            s.status & !(STATUS_MAILBOX_FULL | STATUS_IRQ_WRITE),
        );
        self.window(s.start, s.length)
    }

    /// A message waits in the receive mailbox (SM0) for [`Esc::mailbox_read`], which would
    /// take it; this leaves it there.
    pub fn mailbox_waiting(&self) -> bool {
        let s = self.sm(SM_MAILBOX_OUT);
        self.mailbox_running
            && s.is_active()
            && s.mode() == SmMode::Mailbox
            && s.direction() == SmDirection::Write
            && s.is_mailbox_full()
    }

    /// The send mailbox (SM1) can take a message.
    pub fn mailbox_write_ready(&self) -> bool {
        let s = self.sm(SM_MAILBOX_IN);
        self.mailbox_running
            && s.is_active()
            && s.mode() == SmMode::Mailbox
            && s.direction() == SmDirection::Read
            && !s.is_mailbox_full()
    }

    /// Post a message (mailbox header included) into the send mailbox (SM1); the rest of
    /// the window is zeroed and "mailbox full" set. A copy is kept for the repeat request.
    pub fn mailbox_write(&mut self, msg: &[u8]) -> Result<(), PdiError> {
        if !self.mailbox_running {
            return Err(PdiError::NotRunning);
        }
        let s = self.sm(SM_MAILBOX_IN);
        if !s.is_active() || s.mode() != SmMode::Mailbox || s.direction() != SmDirection::Read {
            return Err(PdiError::NotConfigured);
        }
        if s.is_mailbox_full() {
            return Err(PdiError::Busy);
        }
        if msg.len() > usize::from(s.length) || msg.len() > MAILBOX_MAX {
            return Err(PdiError::TooLong);
        }
        let Some(w) = self.window_mut(s.start, s.length) else {
            return Err(PdiError::NotConfigured);
        };
        w.fill(0);
        if let Some(d) = w.get_mut(..msg.len()) {
            d.copy_from_slice(msg);
        }
        if let Some(b) = self.mbx_backup.get_mut(..msg.len()) {
            b.copy_from_slice(msg);
            self.mbx_backup_len = msg.len();
        }
        self.set_sm_status(
            SM_MAILBOX_IN,
            (s.status | STATUS_MAILBOX_FULL) & !STATUS_IRQ_READ,
        );
        Ok(())
    }

    /// The newest complete output buffer (SM2) if the master completed one since the last
    /// call. The ESC hands it over in every state; the device applies set-points only in Op
    /// (ETG.1000.6 ESM: Safe-Op ignores set-points).
    pub fn process_outputs(&mut self) -> Option<&[u8]> {
        if !self.pd_out_new {
            return None;
        }
        self.pd_out_new = false;
        let s = self.sm(SM_OUTPUTS);
        self.set_sm_status(SM_OUTPUTS, s.status & !STATUS_IRQ_WRITE);
        self.pd_out.get(..self.pd_out_len)
    }

    /// The newest complete output buffer, whether or not it was taken already (empty
    /// before the first complete write).
    pub fn outputs(&self) -> &[u8] {
        self.pd_out.get(..self.pd_out_len).unwrap_or(&[])
    }

    /// Write a complete input buffer (SM3); the master's next read returns it. `data` may be
    /// shorter than the SM (the rest keeps its content).
    pub fn set_inputs(&mut self, data: &[u8]) -> Result<(), PdiError> {
        let s = self.sm(SM_INPUTS);
        if !s.is_active() || s.mode() != SmMode::Buffered || s.direction() != SmDirection::Read {
            return Err(PdiError::NotConfigured);
        }
        if data.len() > usize::from(s.length) {
            return Err(PdiError::TooLong);
        }
        let Some(w) = self.window_mut(s.start, s.length) else {
            return Err(PdiError::NotConfigured);
        };
        if let Some(d) = w.get_mut(..data.len()) {
            copy_bytes(d, data);
        }
        let last = (s.status & STATUS_BUFFER_MASK) >> 4;
        let next = if last >= 2 { 0 } else { last + 1 };
        self.set_sm_status(
            SM_INPUTS,
            (s.status & !(STATUS_BUFFER_MASK | STATUS_IRQ_READ)) | (next << 4),
        );
        Ok(())
    }
}
