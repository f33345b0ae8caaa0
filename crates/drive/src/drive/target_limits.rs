//! Profile Position targets checked before they are taken (CiA 402 607Bh position range
//! limit, 607Dh software position limit; Nanotec §4.1 "Positions-Fehlerbehandlung"), and the
//! change-on-set-point bit 9 of a queued job. A personality turns them on with
//! [`crate::personality::Capabilities::pp_target_limits`].

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// The PP target of 607Ah checked as Nanotec §4.1 lists it, user units: (1) outside the
    /// position range limit 607Bh it wraps round inside [min, max] (bit 11); (2) outside the
    /// software limits 607Dh, corrected by the home offset, it is refused with EMCY 0800h;
    /// (3) a relative target that overflows the position is refused with EMCY 1000h.
    /// Returns the absolute target, or the refusal.
    ///
    /// Decisions: a relative target counts from the position set-point (the last target once
    /// a move has ended; §4.1 "relative to the last target position" and §4.2 "relative to
    /// the current position" agree at standstill). 607Bh and 607Dh with min = max = 0 are off
    /// (§3.4 says so of 607Bh; CiA 402 of both). The wrap applies to the resolved target.
    pub(crate) fn check_target(&self, cw: Controlword) -> Result<i32, Fault> {
        let target = self.value(0x607A, 0);
        let absolute = if cw.contains(Controlword::RELATIVE) {
            let queued = self
                .setpoints
                .active
                .filter(|_| !cw.contains(Controlword::CHANGE_SET_IMMEDIATELY));
            let base_internal = queued.map_or(self.traj.position, |j| j.target);
            let base = i64::from(
                self.fg
                    .position_from_internal(libm::round(base_internal) as i64),
            );
            let sum = base + target;
            if i32::try_from(sum).is_err() {
                return Err(Fault::PositionOverflow);
            }
            sum
        } else {
            target
        };
        let (min, max) = (self.value(0x607B, 1), self.value(0x607B, 2));
        let absolute = if (min, max) != (0, 0) && min < max && !(min..=max).contains(&absolute) {
            min + (absolute - min).rem_euclid(max - min + 1)
        } else {
            absolute
        };
        let home = self.value(0x607C, 0);
        let (lo, hi) = (self.value(0x607D, 1), self.value(0x607D, 2));
        if (lo, hi) != (0, 0) && !(lo - home..=hi - home).contains(&absolute) {
            return Err(Fault::SoftwareLimit);
        }
        i32::try_from(absolute).map_err(|_| Fault::PositionOverflow)
    }

    /// A PP set-point was taken: a refused one raises its EMCY and bit 11; a valid one
    /// clears both (§4.1 item 4: "cleared only by the next valid position"), bit 11 staying
    /// for a wrapped one. With bit 9 (change on set-point) a queued job follows the running
    /// one without braking at its target.
    pub(crate) fn target_taken(&mut self, result: Result<i32, Fault>, cw: Controlword) {
        match result {
            Err(fault) => {
                self.internal_limit = true;
                self.raise_fault(fault);
            }
            Ok(target) => {
                for fault in [Fault::SoftwareLimit, Fault::PositionOverflow] {
                    if let Some(e) = self.personality.error(fault) {
                        self.clear_notice(e.code);
                    }
                }
                self.internal_limit = i64::from(target) != self.value(0x607A, 0)
                    && !cw.contains(Controlword::RELATIVE);
            }
        }
        if self.setpoints.buffered.is_some() {
            let on_the_fly = cw.contains(Controlword::CHANGE_ON_SET_POINT);
            if let Some(active) = self.setpoints.active.as_mut() {
                active.end_velocity = if on_the_fly { active.velocity } else { 0.0 };
            }
        }
    }
}
