//! What a write to one of the drive's objects does beyond storing it: the CMMP-AS object
//! rules, as a table of hooks (object and sub-index to a handler). An object without a
//! hook is stored as it is ([`Drive::write_plain`]).

use super::*;

/// A write handler: the drive, the object's index and sub-index, the value.
type Hook<S> = fn(&mut Drive<S>, u16, u8, &[u8]) -> Result<(), AbortCode>;

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S> {
    /// The objects whose writes do more than store a value, and their handlers.
    fn write_hook(index: u16, sub: u8) -> Hook<S> {
        match (index, sub) {
            (0x1011, _) => Self::write_restore_defaults,
            (0x6040, 0x00) => Self::write_controlword,
            (0x6060, 0x00) => Self::write_mode,
            (0x6093 | 0x6094 | 0x6097, 0x01 | 0x02) => Self::write_factor,
            (0x607E, 0x00) => Self::write_polarity,
            (0x6510, 0xF0) => Self::write_compatibility,
            (0x2100, 0x01) => Self::write_reaction_group,
            (0x2100, 0x02) => Self::write_reaction,
            (0x6510, 0x22) => Self::write_following_error_reaction,
            (0x6083 | 0x6084, 0x00) => Self::write_profile_ramp,
            (0x60FF | 0x6071, 0x00) => Self::write_target_value,
            (0x60C4, 0x06) => Self::write_buffer_clear,
            (0x60C1, 0x01) => Self::write_ip_set_point,
            (0x2030, 0x00) => Self::write_set_position_absolute,
            (0x6098, 0x00) => Self::write_homing_method,
            _ => Self::write_plain,
        }
    }

    /// A write from outside (SDO, PDO, console): the object's hook, else stored as it is.
    pub(super) fn write_object(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        Self::write_hook(index, sub)(self, index, sub, data)
    }

    /// 6040h: rising edges for the state machine and the modes; a new homing start clears
    /// the old result at once.
    fn write_controlword(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        let cw = self.read(self.hot.controlword) as u16;
        let rising = cw & !self.last_cw;
        self.cw_rising |= rising;
        self.last_cw = cw;
        if rising & 0x0010 != 0 && self.mode == mode::HOMING {
            // A new homing start: the old result goes at once, so a master reading
            // the statusword right after never sees it (python-canopen's homing()).
            self.homing_attained = false;
            self.homing_error = false;
            self.target_reached = false;
            let sw = self.read(self.hot.statusword) & !0x3400;
            self.store(self.hot.statusword, sw);
        }
        Ok(())
    }

    /// 6060h: the modes the CMMP-AS has, taking effect after the mode change time.
    fn write_mode(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let m = match data {
            [b] => *b as i8,
            _ => return self.od.write(index, sub, data),
        };
        // CMMP-AS 6060h: 1, 3, 4, 6, 7 over CANopen (8 only over EtherCAT).
        let csp = m == mode::CYCLIC_SYNCHRONOUS_POSITION && self.settings.ethercat;
        if !matches!(m, 1 | 3 | 4 | 6 | 7) && !csp {
            return Err(AbortCode::INVALID_VALUE);
        }
        self.od.write(index, sub, data)?;
        if m != self.mode || self.mode_pending.is_some() {
            self.mode_pending = Some((m, self.now + self.settings.mode_change_time));
        }
        Ok(())
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
        // CMMP-AS §5.3: the factor may not exceed 2^24, numerator and divisor not 0.
        let mut fg = self.fg;
        fg.set_factor(obj, r).map_err(|e| match e {
            crate::factor_group::FactorError::ExceedsLimit(_) => AbortCode::VALUE_TOO_HIGH,
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

    /// 6510h:F0h: the compatibility settings.
    fn write_compatibility(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        // CMMP-AS §5.2 (CMMP-SDO-15): bits 0 and 2 (homing method scheme) mirror each other.
        let v = match data {
            [a, b] => u16::from_le_bytes([*a, *b]),
            _ => return self.od.write(index, sub, data),
        };
        let v = if v & 0x0005 != 0 { v | 0x0005 } else { v };
        self.od.write(index, sub, &v.to_le_bytes())
    }

    /// 2100h:01h: the error group whose reaction 2100h:02h shows.
    fn write_reaction_group(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        self.show_reaction();
        Ok(())
    }

    /// 2100h:02h: the reaction of the selected error group.
    fn write_reaction(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        // CMMP-AS §5.18: a reaction below the manufacturer's minimum is clamped to it.
        self.od.entry(index, sub)?;
        let code = match data {
            [b] => *b,
            _ => return self.od.write(index, sub, data),
        };
        let main = self.od.get_unsigned(0x2100, 1).unwrap_or(1) as u8;
        self.reactions
            .set(main, code)
            .map_err(|_| AbortCode::INVALID_VALUE)?;
        self.show_reaction();
        Ok(())
    }

    /// 6510h:22h: the following-error reaction.
    fn write_following_error_reaction(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        self.following_error_reaction();
        self.params_dirty = true;
        Ok(())
    }

    /// 1011h: restore defaults, not with the output stage on.
    fn write_restore_defaults(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        if self.dc.state().power_enabled() {
            // CMMP-AS §5.1 (CMMP-SDO-10): defaults only with the output stage off.
            self.od.entry(index, sub)?;
            return Err(AbortCode::DEVICE_STATE);
        }
        self.write_plain(index, sub, data)
    }

    /// 6083h / 6084h: the profile ramps, also the 2090h ramps.
    fn write_profile_ramp(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        // CMMP-AS §7.6: 6083h/6084h and the 2090h ramps are the same values.
        let (a, b) = if index == 0x6083 { (2, 4) } else { (3, 5) };
        let _ = self.od.write_internal(0x2090, a, data);
        let _ = self.od.write_internal(0x2090, b, data);
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

    /// 60C4h:06h: buffer_clear of interpolated position.
    fn write_buffer_clear(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        // buffer_clear: 1 unlocks 60C1h, 0 clears the buffer and locks it (§7.4.2).
        self.od.write(index, sub, data)?;
        self.ip.set_unlocked(data.first() == Some(&1));
        Ok(())
    }

    /// 60C1h:01h: an interpolated-position set-point.
    fn write_ip_set_point(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        // Decision: 60C1h written while locked (60C4h:06 = 0) is refused with the
        // device-state abort; the manual says only "access is not allowed".
        self.od.entry(index, sub)?;
        if !self.ip.is_unlocked() {
            return Err(AbortCode::DEVICE_STATE);
        }
        self.od.write(index, sub, data)?;
        let user = self
            .value(0x60C1, 1)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        let increments = self.fg.position_to_internal(user) as f64;
        // 60C1h:02 = 1: a relative distance from the last set-point.
        let target = if self.value(0x60C1, 2) == 1 {
            self.ip.last_set_point() + increments
        } else {
            increments
        };
        self.ip.set_point(target);
        Ok(())
    }

    /// 2030h: set_position_absolute.
    fn write_set_position_absolute(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        // set_position_absolute: the actual position becomes this value, no motion.
        self.od.write(index, sub, data)?;
        let user = self
            .value(0x2030, 0)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        self.position_offset = self.fg.position_to_internal(user) - self.axis.position_increments();
        self.resync_trajectory();
        Ok(())
    }

    /// 6098h: the homing method.
    fn write_homing_method(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        if self.mode == mode::HOMING
            && self.dc.state() == State::OperationEnabled
            && self.last_cw & 0x10 != 0
        {
            // CMMP-AS 7.2: the method is writable only while homing is not active.
            return Err(AbortCode::DEVICE_STATE);
        }
        let m = match data {
            [b] => *b as i8,
            _ => return self.od.write(index, sub, data),
        };
        // The printed 6098h range plus −23/−27 of Tab. 7.1 (cmmp-as-3 §9); 32 is in
        // the printed range only and fails at the start (see `start_homing`).
        // Beyond −27 … 35 the dictionary's range check answers.
        let listed = m == 32 || crate::homing::METHODS.iter().any(|(n, _)| *n == m);
        if !listed && (-27..=35).contains(&m) {
            self.od.entry(index, sub)?;
            return Err(AbortCode::INVALID_VALUE);
        }
        self.od.write(index, sub, data)
    }

    /// Any other object: stored; the controllers see a changed control parameter.
    fn write_plain(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        if is_control_parameter(index) {
            self.params_dirty = true;
        }
        Ok(())
    }
}
