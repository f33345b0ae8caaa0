//! Kinco mode −4, pulse / gear (§6.5): the position command is
//! the pulse input times the gear ratio `Gear_Factor[x]` / `Gear_Divider[x]` of the set the
//! Multifunction inputs select (§5.5.3, KINCO-SC-04), counted in Gear_Master 2508h:04 (before
//! the gear) and Gear_Slave 2508h:05 (after it); more than Frequency_Check 2508h:08 pulses
//! per millisecond is Overfrequency (Error_State bit 12, 8A80h).
//!
//! The twin has no pulse connector: the pulse source is simulated, a frequency a test or the
//! host sets ([`Drive::set_pulse_input`]). Decisions: PD_CW 2508h:03 (CW/CCW, pulse and
//! direction, A/B) only says how the wires are decoded, so the simulated source is already a
//! signed count and PD_CW does not change it; positive pulses count up (CCW with Invert_Dir
//! 607Eh = 0); the position reached (Target_Reach_Time_Window 2508h:09) is "no pulse for
//! that long".

use core::time::Duration;

use super::hooks::Kinco;
use super::{selected_index, DinFunction};
use crate::drive::Drive;
use od::Instant;

/// The simulated pulse source and what the gear has made of it.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PulseInput {
    /// Pulses per second, signed.
    pub(crate) frequency: f64,
    /// Pulses not yet counted (the fraction of a pulse).
    pub(crate) pending: f64,
    /// Output increments not yet commanded (the gear's remainder).
    pub(crate) remainder: f64,
    /// When the last pulse came.
    pub(crate) last_pulse: Option<Instant>,
    /// The output increments commanded since power-on (converted as a whole, so the
    /// increment ratio never accumulates rounding).
    pub(crate) commanded: i64,
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Kinco> {
    /// The simulated pulse input of mode −4: `pulses_per_s` pulses per second (negative:
    /// the other direction) from now on.
    pub fn set_pulse_input(&mut self, pulses_per_s: f64) {
        self.vendor.pulse.frequency = if pulses_per_s.is_finite() {
            pulses_per_s
        } else {
            0.0
        };
    }

    /// The gear ratio in force: set x = BCD(Multifunction2:1:0), set 0 in 2508h:01 / :02,
    /// sets 1 … 7 in 2509h:01 … :0E (factor, divider).
    pub(crate) fn kinco_gear(&self) -> (i64, i64) {
        let bits = [
            DinFunction::Multifunction0,
            DinFunction::Multifunction1,
            DinFunction::Multifunction2,
        ]
        .map(|f| {
            self.kinco_din_configured(f)
                .then(|| self.kinco_din_active(f))
        });
        let x = selected_index(&bits);
        let (factor, divider) = if x == 0 {
            (self.value(0x2508, 0x01), self.value(0x2508, 0x02))
        } else {
            (self.value(0x2509, 2 * x - 1), self.value(0x2509, 2 * x))
        };
        (factor, divider.max(1))
    }

    /// One logic cycle of mode −4.
    pub(crate) fn kinco_pulse_mode(&mut self, dt: f64) {
        let p = &mut self.vendor.pulse;
        p.pending += p.frequency * dt;
        let pulses = libm::trunc(p.pending);
        p.pending -= pulses;
        let per_ms = (p.frequency / 1000.0).abs();
        if per_ms > self.value(0x2508, 0x08).max(0) as f64 {
            // Overfrequency, Error_State bit 12 (8A80h).
            self.raise_fault(super::Fault::Overfrequency);
            return;
        }
        let (factor, divider) = self.kinco_gear();
        let exact = pulses * factor as f64 / divider as f64 + self.vendor.pulse.remainder;
        let out = libm::trunc(exact);
        self.vendor.pulse.remainder = exact - out;
        if pulses != 0.0 {
            self.vendor.pulse.last_pulse = Some(self.now);
            for (sub, add) in [(0x04, pulses as i64), (0x05, out as i64)] {
                let v = self.value(0x2508, sub).wrapping_add(add) as i32;
                let e = self.od.description().entry(0x2508, sub);
                self.store(e, i64::from(v));
            }
        }
        let mut before = self.vendor.pulse.commanded;
        let mut after = before.saturating_add(out as i64);
        if after.abs() > 1 << 30 {
            // Re-based by whole multiples of 625 increments (4096 internal ones, exact).
            let k = after / 625 * 625;
            before -= k;
            after -= k;
        }
        self.vendor.pulse.commanded = after;
        let to_internal = |v: i64| {
            self.fg
                .position_to_internal(v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32)
        };
        let internal = (to_internal(after) - to_internal(before)) as f64;
        self.traj.position += internal;
        self.traj.velocity = if dt > 0.0 { internal / dt } else { 0.0 };
        let v = self.traj.velocity;
        self.position_demand(v);
        let window = Duration::from_millis(self.value(0x2508, 0x09).max(0) as u64);
        self.target_reached = self
            .vendor
            .pulse
            .last_pulse
            .is_none_or(|t| self.now.saturating_since(t) >= window);
    }
}
