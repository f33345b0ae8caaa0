//! Velocity mode VL (CiA 402 §10, 6060h = 2; Nanotec ch. 6): the target 6042h clamped by
//! the min / max amounts 6046h, ramps 6048h / 6049h / 604Ah given as fractions Δv / Δt, and
//! the dimension factor 604Ch between the user unit and min⁻¹.
//!
//! Rules (Nanotec ch. 6; the extract's §9 item 8): target 0 stops; a magnitude below min runs at
//! min; a magnitude above max runs at max with statusword bit 11; halt (bit 8) brakes with 6049h
//! and a falling edge accelerates again; a quick stop brakes with 604Ah.
//!
//! Decisions:
//! * 604Ch: `min⁻¹ = user × numerator / denominator`, the worked example of §6.10 (2000 ×
//!   60/2000 = 60 min⁻¹), not the inverse formula of §9.27 (the manual contradicts itself); Δv of
//!   the ramps is in the same user unit, Δt in seconds.
//! * The halt bit is read as a level: its rising edge brakes, its falling edge resumes, and a
//!   bit held at 1 keeps the motor stopped, which is what the two edges of §6.1 describe.
//! * 607Eh bit 6 turns the direction over (§9.4).

use super::*;

/// 607Eh bit 6: velocity polarity.
const VELOCITY_POLARITY: u8 = 0x40;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// 604Ch as (numerator, denominator); 1/1 where a part is 0 or missing.
    fn vl_dimension_factor(&self) -> (f64, f64) {
        let num = self.value(0x604C, 1);
        let den = self.value(0x604C, 2);
        if num == 0 || den == 0 {
            (1.0, 1.0)
        } else {
            (num as f64, den as f64)
        }
    }

    /// A VL user velocity in increments/s.
    fn vl_to_internal(&self, user: f64) -> f64 {
        let (num, den) = self.vl_dimension_factor();
        user * num / den / RPM_PER_INC_S
    }

    /// Increments/s as a VL user velocity.
    pub(crate) fn vl_from_internal(&self, increments_per_s: f64) -> f64 {
        let (num, den) = self.vl_dimension_factor();
        increments_per_s * RPM_PER_INC_S * den / num
    }

    /// A speed in increments/s as 6044h shows it: VL user units, the polarity 607Eh bit 6
    /// applied, rounded and held within INTEGER16.
    pub(crate) fn vl_actual_user(&self, increments_per_s: f64) -> i64 {
        let polarity = self.value(0x607E, 0) as u8 & VELOCITY_POLARITY != 0;
        let sign = if polarity { -1.0 } else { 1.0 };
        let user = libm::round(sign * self.vl_from_internal(increments_per_s)) as i64;
        user.clamp(i64::from(i16::MIN), i64::from(i16::MAX))
    }

    /// A ramp record (6048h, 6049h, 604Ah): Δv / Δt in increments/s²; `None` if a part is 0.
    pub(crate) fn vl_ramp(&self, index: u16) -> Option<f64> {
        let dv = self.value(index, 1);
        let dt = self.value(index, 2);
        (dv > 0 && dt > 0).then(|| self.vl_to_internal(dv as f64) / dt as f64)
    }

    /// The target after the 6046h rules, user units, and whether it was clamped to the
    /// maximum (bit 11).
    pub(crate) fn vl_clamped_target(&self) -> (i64, bool) {
        let target = self.value(0x6042, 0);
        if target == 0 {
            return (0, false);
        }
        let min = self.value(0x6046, 1).max(0);
        let max = self.value(0x6046, 2).max(0);
        let magnitude = target.abs();
        let (magnitude, limited) = if max > 0 && magnitude > max {
            (max, true)
        } else {
            (magnitude.max(min), false)
        };
        (target.signum() * magnitude, limited)
    }

    /// One cycle of velocity mode.
    pub(crate) fn velocity_mode(&mut self, dt: f64) {
        let (user, limited) = self.vl_clamped_target();
        self.internal_limit = limited;
        let polarity = self.value(0x607E, 0) as u8 & VELOCITY_POLARITY != 0;
        let sign = if polarity { -1.0 } else { 1.0 };
        let mut target = (sign * self.vl_to_internal(user as f64))
            .clamp(-self.max_motor_speed(), self.max_motor_speed());
        if self.halted {
            target = 0.0;
        }
        let acc = self.vl_ramp(0x6048).unwrap_or(f64::INFINITY);
        let dec = self.vl_ramp(0x6049).unwrap_or(f64::INFINITY);
        self.command_velocity(target, Some((acc, dec)), dt);
        self.target_reached = self.velocity_set == target;
        self.publish_vl();
    }

    /// 6043h demand velocity in user units (§5.3); 6044h is a readout of every mode
    /// (`publish.rs`).
    pub(crate) fn publish_vl(&mut self) {
        let sign = if self.value(0x607E, 0) as u8 & VELOCITY_POLARITY != 0 {
            -1.0
        } else {
            1.0
        };
        let demand = libm::round(sign * self.vl_from_internal(self.velocity_set)) as i64;
        let clamp = |v: i64| v.clamp(i64::from(i16::MIN), i64::from(i16::MAX));
        if let Some(e) = self.od.description().entry(0x6043, 0) {
            self.store(Some(e), clamp(demand));
        }
    }
}
