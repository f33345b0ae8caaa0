//! What a write to one of the drive's objects does beyond storing it, as a table of hooks
//! (object and sub-index to a handler): the personality's own hooks first
//! (`personality/*.rs`), then the CiA 402 ones here. An object without a hook is stored as it
//! is (`Drive::write_plain`).

use super::*;

/// A write handler: the drive, the object's index and sub-index, the value.
pub type Hook<S, V> = fn(&mut Drive<S, V>, u16, u8, &[u8]) -> Result<(), AbortCode>;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// The objects whose writes do more than store a value, and their handlers.
    fn write_hook(&self, index: u16, sub: u8) -> Hook<S, V> {
        V::write_hook(index, sub).unwrap_or(match (index, sub) {
            (0x6040, 0x00) => Self::write_controlword,
            (0x6060, 0x00) => Self::write_mode,
            (0x6093 | 0x6094 | 0x6097, 0x01 | 0x02) => Self::write_factor,
            (0x607E, 0x00) => Self::write_polarity,
            (0x60FF | 0x6071, 0x00) => Self::write_target_value,
            (0x60C1, 0x01) => Self::write_ip_data,
            (0x60C2, 0x01 | 0x02) => Self::write_ip_period,
            (0x60C4, 0x06) => Self::write_ip_buffer_clear,
            _ => Self::write_plain,
        })
    }

    /// A write from outside (SDO, PDO, console): the object's hook, else stored as it is.
    pub(super) fn write_object(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.write_hook(index, sub)(self, index, sub, data)
    }

    /// 6040h: rising edges for the state machine and the modes; a new homing start clears
    /// the old result at once.
    pub(crate) fn write_controlword(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        let cw = Controlword(self.read(self.hot.controlword) as u16);
        let rising = self.take_controlword(cw);
        if rising.contains(Controlword::HOMING_START) && self.mode == mode::HOMING {
            // A new homing start: the old result goes at once, so a master reading
            // the statusword right after never sees it (python-canopen's homing()).
            self.homing_attained = false;
            self.homing_error = false;
            self.target_reached = false;
            let clear =
                Statusword::HOMING_ATTAINED | Statusword::HOMING_ERROR | Statusword::TARGET_REACHED;
            let sw = self.read(self.hot.statusword) & !i64::from(clear.bits());
            self.store(self.hot.statusword, sw);
        }
        Ok(())
    }

    /// A controlword that has been set (a confirmed write, an input function, the panel): its
    /// rising edges latched for the modes, the word queued for the state machine in order
    /// ([`ControlwordQueue`]). Returns the rising edges.
    pub(crate) fn take_controlword(&mut self, cw: Controlword) -> Controlword {
        let rising = cw.difference(self.last_cw);
        self.cw_rising |= rising;
        self.cw_written.push(cw.bits(), self.last_cw.bits());
        self.last_cw = cw;
        rising
    }

    /// 6060h: the modes the personality has, taking effect after the mode change time.
    pub(crate) fn write_mode(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let m = match data {
            [b] => *b as i8,
            _ => return self.od.write(index, sub, data),
        };
        if !self.personality.accepts_mode(m, self.settings.ethercat) {
            return Err(AbortCode::INVALID_VALUE);
        }
        self.od.write(index, sub, data)?;
        if m != self.mode || self.mode_pending.is_some() {
            self.mode_pending = Some((m, self.now + self.settings.mode_change_time));
        }
        Ok(())
    }

    /// 6060h through a personality's rule: the entry exists and the mode is one the
    /// personality has (else 0609 0030h) before `refusal` says whether the drive takes it now
    /// (an input owns the mode, a brake wait runs, …); then [`Drive::write_mode`].
    pub(crate) fn write_mode_unless(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
        refusal: impl FnOnce(&Self, i8) -> Option<AbortCode>,
    ) -> Result<(), AbortCode> {
        self.od.entry(index, sub)?;
        if let [b] = data {
            let m = *b as i8;
            if !self.personality.accepts_mode(m, self.settings.ethercat) {
                return Err(AbortCode::INVALID_VALUE);
            }
            if let Some(abort) = refusal(self, m) {
                return Err(abort);
            }
        }
        self.write_mode(index, sub, data)
    }

    /// 6093h / 6094h / 6097h: a factor group numerator or divisor, checked before it is stored.
    fn write_factor(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let obj = match index {
            0x6093 => FactorObject::Position,
            0x6094 => FactorObject::Velocity,
            _ => FactorObject::Acceleration,
        };
        let v = match data {
            [a, b, c, d] => u32::from_le_bytes([*a, *b, *c, *d]),
            _ => return self.od.write(index, sub, data),
        };
        let mut r = self.fg.factor(obj);
        if sub == 1 {
            r.numerator = v;
        } else {
            r.divisor = v;
        }
        // Numerator and divisor not 0; the quotient within the vendor's limit, if it has one.
        let mut fg = self.fg;
        fg.set_factor_within(obj, r, V::factor_limit(obj))
            .map_err(|e| match e {
                crate::factor_group::FactorError::ExceedsLimit(..) => AbortCode::VALUE_TOO_HIGH,
                _ => AbortCode::INVALID_VALUE,
            })?;
        self.od.write(index, sub, data)?;
        self.fg = fg;
        Ok(())
    }

    /// 607Eh: the polarity, stored set-points turned over.
    fn write_polarity(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let v = data.first().copied().unwrap_or(0);
        let mut fg = self.fg;
        fg.set_polarity(v).map_err(|_| AbortCode::INVALID_VALUE)?;
        self.od.write(index, sub, data)?;
        // CMMP-AS 607Eh (L2683–2704): the drive keeps set-points internally, so a
        // value stored before the change is not converted and reads with the other
        // sign afterwards. The twin keeps them in user units: it turns them over.
        let flipped = fg.polarity ^ self.fg.polarity;
        self.fg = fg;
        if flipped & crate::factor_group::POSITION_POLARITY_FLAG != 0 {
            self.negate_stored(0x607A);
        }
        if flipped & crate::factor_group::VELOCITY_POLARITY_FLAG != 0 {
            self.negate_stored(0x60FF);
        }
        Ok(())
    }

    /// 60FFh / 6071h: a new velocity or torque target.
    fn write_target_value(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        // A new velocity or torque target: target reached drops at once, not a cycle
        // later, so a master that writes and then reads never sees the old bit.
        let before = self.value(index, sub);
        self.od.write(index, sub, data)?;
        if before != self.value(index, sub) {
            self.clear_target_reached();
        }
        Ok(())
    }

    /// 60C1h:01 interpolation data record (CiA 402 IP, linear interpolation): the position
    /// set-point the interpolator takes at the next SYNC. Refused with 0800 0022h while
    /// 60C4h:06 buffer_clear keeps the buffer locked (access disabled).
    fn write_ip_data(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.entry(index, sub)?;
        if !self.ip.is_unlocked() {
            return Err(AbortCode::DEVICE_STATE);
        }
        self.od.write(index, sub, data)?;
        let user = self
            .value(0x60C1, 1)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        let increments = self.fg.position_to_internal(user) as f64;
        self.ip.set_point(increments);
        Ok(())
    }

    /// 60C2h interpolation time period: in force at once (CiA 402 gives it no delay); the
    /// SYNC grid is checked against it from the next SYNC on.
    fn write_ip_period(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        self.ip.set_period(interpolation_period::<S, V>(&self.od));
        Ok(())
    }

    /// 60C4h:06 buffer_clear: 1 enables access to the input buffer, 0 clears it and disables
    /// access.
    fn write_ip_buffer_clear(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        self.ip.set_unlocked(data.first() == Some(&1));
        Ok(())
    }

    /// Any other object: stored; the controllers see a changed control parameter.
    pub(crate) fn write_plain(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        if is_control_parameter::<V>(index) {
            self.params_dirty = true;
        }
        Ok(())
    }
}
