//! The Kinco velocity and position loop objects as the controller's gains (ch. 7 §7.3, Tab. 7-3 /
//! 7-4, Tab. 7-2 = 4-5; lines L1846-1905, L670-691 of the manual's text kept beside the project):
//! what a write of Kvp, Kvi, Kpp, the velocity feed-forward, Velocity_BW, Stiffness or
//! Inertia_Ratio does to the loop.
//!
//! The manual's rules:
//! - `Kpp[x]` (60FBh:01, 2340h:06 / :09 / :0C) is the position-loop gain in 0.01 Hz
//!   ("Kpp = 100 × Pc_Loop_BW", the print's "103" read as 10²);
//! - `Kvp[x]` (60F9h:01, 2340h:04 / :07 / :0A) "can be shown in Hz if the inertia ratio is
//!   right"; "writing Velocity_BW 2FF0h:0A changes `Kvp[0]` by the inertia ratio"; Tab. 7-2
//!   gives Kvp in 0.1 Hz per stiffness; "tn01 / tn02 take effect at once" (§4.3.2);
//! - Kvi_Mix 2FF0h:19 = 32 × Kvi 60F9h:02 + Kvi/32 60F9h:07; a write of Kvi_Mix sets Kvi = 0
//!   and Kvi/32 = the value (Tab. 7-3);
//! - K_Velocity_FF‰ 2FF0h:1A: "0 no feed-forward, 1000 = 100 %" (unit 0.1 %).
//!
//! Decisions (the printed Kvp formula, L1876, is garbled: with the device file's values it
//! gives kHz bandwidths; its J / kt dependence is kept, its constant is not):
//! - Kvp is the velocity-loop bandwidth in 0.1 Hz the loop would have with the rotor alone
//!   (Jr_Motor 6410h:10): gain [A·s/rad] = 2π · Kvp / 10 · Jr / Kt. With a load the bandwidth
//!   is Kvp / Inertia_Ratio Hz when the inertia ratio is right; Velocity_BW (Hz) writes
//!   `Kvp[0]` = Velocity_BW × Inertia_Ratio, and Tab. 7-2's "Kvp" column is Kvp at ratio 1.0;
//! - Kvi is the PI corner frequency in Hz, Kvi + Kvi/32 / 32 for set 0 (sets 1-3 have no
//!   Kvi/32): integral time 1 / (2π · Kvi); 0 = no integral (Kvi Off forces that);
//! - Kpp: gain [1/s] = 2π · Kpp / 100;
//! - the engine's controller holds gains in steps of 1/256 of its unit (control.rs): Kvp
//!   and Kpp are quantised to about 1 % at their defaults;
//! - the position loop's output is not clamped below the top speed 6080h (the manual names
//!   no clamp);
//! - writing Stiffness 3040h:08 or Inertia_Ratio 3040h:0B sets `Kpp[0]`, Velocity_BW and
//!   `Kvp[0]` from the stiffness table's row at the ratio; the row's filter column sets
//!   nothing (the manual names no object for it, and its 18 Hz needs an Output_Filter_N
//!   beyond 60F9h:15's 1…127);
//! - Speed_Fb_N 60F9h:05 sets the actual-speed filter (bandwidth 100 + 20·N Hz);
//!   Output_Filter_N 60F9h:15, the notch (Notch_N 60F9h:03 at 10·N + 100 Hz while Notch_On
//!   60F9h:04 = 1) and Kvi_Sum_Limit 60F9h:08 (the velocity integrator's limit, of 2¹⁵ = the
//!   current limit) act on the current set-point (`current_filters.rs`);
//! - K_Acc_FF 2FF0h:1B / 60FBh:03 and Speed_Mode are stored only: the engine's cascade has no
//!   current feed-forward input; Kcp / Kci stay the engine's current loop (`kinco_drive.rs`).

use od::{AbortCode, ObjectAccess as _};

use super::hooks::Kinco;
use super::STIFFNESS;
use crate::control::ControlParams;
use crate::current_filters::CurrentFilterParams;
use crate::drive::Drive;
use crate::motor::RPM_TO_RAD_S;

/// The gains of one set in the manual's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopGains {
    /// Kvp: velocity bandwidth with the rotor alone, 0.1 Hz.
    pub kvp: f64,
    /// Kvi: the PI corner, Hz (0 = no integral).
    pub kvi_hz: f64,
    /// Kpp: 0.01 Hz.
    pub kpp: f64,
}

/// The velocity gain in A·s/rad of `kvp` (0.1 Hz) for rotor inertia `jr` (kg·m²) and torque
/// constant `kt` (N·m/A).
pub fn velocity_gain(kvp: f64, jr: f64, kt: f64) -> f64 {
    if kt <= 0.0 {
        return 0.0;
    }
    2.0 * core::f64::consts::PI * kvp / 10.0 * jr / kt
}

/// The position gain in 1/s of Kpp (0.01 Hz).
pub fn position_gain(kpp: f64) -> f64 {
    2.0 * core::f64::consts::PI * kpp / 100.0
}

/// The integral time in µs of a PI corner at `hz` (0: no integral; at most 65 535 µs).
pub fn integral_time_us(hz: f64) -> u16 {
    if hz <= 0.0 {
        return 0;
    }
    libm::round(1e6 / (2.0 * core::f64::consts::PI * hz)).clamp(1.0, 65535.0) as u16
}

/// `Kvp[0]` for a velocity bandwidth `bw_hz` at Inertia_Ratio `ratio` (0.1).
pub fn kvp_of_bandwidth(bw_hz: i64, ratio: i64) -> i64 {
    (bw_hz * ratio).clamp(1, 32767)
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Kinco> {
    /// The gains of set `set` (PI_Pointer, 0-3): set 0 in 60F9h / 60FBh, sets 1-3 in 2340h.
    pub(crate) fn kinco_loop_gains(&self, set: u8) -> LoopGains {
        if set == 0 {
            return LoopGains {
                kvp: self.value(0x60F9, 0x01) as f64,
                kvi_hz: self.value(0x60F9, 0x02) as f64 + self.value(0x60F9, 0x07) as f64 / 32.0,
                kpp: self.value(0x60FB, 0x01) as f64,
            };
        }
        let first = 0x04 + 3 * (set.min(3) - 1);
        LoopGains {
            kvp: self.value(0x2340, first) as f64,
            kvi_hz: self.value(0x2340, first + 1) as f64,
            kpp: self.value(0x2340, first + 2) as f64,
        }
    }

    /// `base` (the engine's controller for the Kinco motor) with the velocity and position
    /// gains of the active set (module doc) and the Kvi Off input.
    pub(crate) fn kinco_loop_params(&self, base: ControlParams) -> ControlParams {
        let set = self.value(0x60F9, 0x28).clamp(0, 3) as u8;
        let g = self.kinco_loop_gains(set);
        let m = self.settings.motor;
        let jr = match self.value(0x6410, 0x10) {
            j if j > 0 => j as f64 * 1e-6,
            _ => m.inertia,
        };
        // control.rs: velocity gain 1 (256) = peak current per 1000 rpm; position gain 1 =
        // 100 s⁻¹.
        let i_peak = f64::from(base.peak_current_ma.max(1)) / 1000.0;
        let vel_unit = i_peak / (1000.0 * RPM_TO_RAD_S);
        let raw =
            |gain: f64, unit: f64| libm::round(gain / unit * 256.0).clamp(1.0, 65535.0) as u16;
        let kvi_hz = if self.vendor.din.kvi_off {
            0.0
        } else {
            g.kvi_hz
        };
        ControlParams {
            velocity_control_gain: raw(velocity_gain(g.kvp, jr, m.torque_constant), vel_unit),
            velocity_control_time_us: integral_time_us(kvi_hz),
            position_control_gain: raw(position_gain(g.kpp), 100.0),
            position_control_v_max_rpm: base.max_motor_speed_rpm,
            // Kinco ch. 7: Speed_Fb_N sets the actual-speed filter's bandwidth; the output
            // filter, the notch and Kvi_Sum_Limit shape the current set-point.
            velocity_control_filter_time_us: kinco_speed_feedback_time_us(
                self.value(0x60F9, 0x05).clamp(0, 45) as u32,
            ),
            filters: CurrentFilterParams {
                output_filter_n: self.value(0x60F9, 0x15).clamp(1, 127) as u16,
                notch_hz: (self.value(0x60F9, 0x04) == 1)
                    .then(|| kinco_notch_hz(self.value(0x60F9, 0x03).clamp(0, 127) as u32)),
                velocity_integral_limit: self.value(0x60F9, 0x08).clamp(0, 32768) as u16,
            },
            ..base
        }
    }

    /// K_Velocity_FF‰ 2FF0h:1A applied to the position set-point's speed feed-forward.
    pub(crate) fn kinco_velocity_feed_forward(&mut self) {
        let k = self.cycle_value(0x2FF0, 0x1A).clamp(0, 4000) as f32 / 1000.0;
        if let crate::axis::Demand::Position {
            velocity_ff_rpm, ..
        } = &mut self.demand
        {
            *velocity_ff_rpm *= k;
        }
    }

    /// A loop object: stored, Kvi_Mix kept as 32 × Kvi + Kvi/32, the controller retuned.
    pub(crate) fn kinco_write_gain(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        if (index, sub) == (0x2FF0, 0x19) {
            // Kvi_Mix: Kvi := 0, Kvi/32 := the value (Tab. 7-3).
            let v = self.value(0x2FF0, 0x19).clamp(0, 32767);
            self.kinco_store(0x60F9, 0x02, 0);
            self.kinco_store(0x60F9, 0x07, v);
        }
        let mix = 32 * self.value(0x60F9, 0x02) + self.value(0x60F9, 0x07);
        self.kinco_store(0x2FF0, 0x19, mix.clamp(0, 65535));
        self.params_dirty = true;
        Ok(())
    }

    /// Velocity_BW 2FF0h:0A: `Kvp[0]` = Velocity_BW × Inertia_Ratio.
    pub(crate) fn kinco_write_velocity_bw(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        let kvp = kvp_of_bandwidth(self.value(0x2FF0, 0x0A), self.value(0x3040, 0x0B));
        self.kinco_store(0x60F9, 0x01, kvp);
        self.params_dirty = true;
        Ok(())
    }

    /// Stiffness 3040h:08 / Inertia_Ratio 3040h:0B: the stiffness table's row at once.
    pub(crate) fn kinco_write_stiffness(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        self.kinco_apply_stiffness();
        Ok(())
    }

    /// `Kpp[0]`, Velocity_BW and `Kvp[0]` from the row of Stiffness 3040h:08 at Inertia_Ratio.
    pub(crate) fn kinco_apply_stiffness(&mut self) {
        let s = self.value(0x3040, 0x08);
        let Some(row) = usize::try_from(s).ok().and_then(|s| STIFFNESS.get(s)) else {
            return;
        };
        let ratio = self.value(0x3040, 0x0B);
        self.kinco_store(0x60FB, 0x01, i64::from(row.kpp));
        self.kinco_store(0x2FF0, 0x0A, i64::from(row.kvp_bandwidth / 10));
        let kvp = (i64::from(row.kvp_bandwidth) * ratio / 10).clamp(1, 32767);
        self.kinco_store(0x60F9, 0x01, kvp);
        self.params_dirty = true;
    }

    /// Stores a value past the write rules (a derived object).
    pub(crate) fn kinco_store(&mut self, index: u16, sub: u8, v: i64) {
        let e = self.kinco_entry(index, sub);
        self.store(e, v);
    }

    /// The entry of `index:sub`: its parameter slot where it has one (the objects a logic
    /// cycle writes, resolved at power-on), else looked up in the dictionary.
    #[inline]
    pub(crate) fn kinco_entry(&self, index: u16, sub: u8) -> Option<&'static od::Entry> {
        self.param(index, sub)
            .or_else(|| self.od.description().entry(index, sub))
    }
}

/// The Kinco's Notch_N → centre frequency: `F = Notch_N × 10 + 100` Hz (Tab. 7-5).
fn kinco_notch_hz(notch_n: u32) -> u32 {
    notch_n * 10 + 100
}

/// The Kinco's Speed_Fb_N → the actual-speed filter's time constant, µs: bandwidth
/// `100 + 20 × N` Hz (§9.2 d2.05), `τ = 1 / (2π f)`.
fn kinco_speed_feedback_time_us(speed_fb_n: u32) -> u16 {
    let hz = 100.0 + 20.0 * f64::from(speed_fb_n);
    libm::round(1e6 / (2.0 * core::f64::consts::PI * hz)).clamp(1.0, 65535.0) as u16
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The device file's defaults (stiffness 12 of Tab. 7-2): Kvp 380 is 38 Hz with the
    /// rotor alone; Kpp 1000 is 10 Hz, 62.8 s⁻¹.
    #[test]
    fn gains_in_the_manuals_units() {
        let kv = velocity_gain(380.0, 30e-6, 0.5);
        // Bandwidth back: Kv·Kt/J in rad/s over 2π.
        let hz = kv * 0.5 / 30e-6 / (2.0 * core::f64::consts::PI);
        assert!((hz - 38.0).abs() < 1e-9);
        assert!((position_gain(1000.0) - 62.831_853).abs() < 1e-5);
        assert_eq!(integral_time_us(0.0), 0);
        assert_eq!(integral_time_us(10.0), 15_915);
        assert_eq!(kvp_of_bandwidth(40, 30), 1200);
    }

    #[test]
    fn speed_feedback_bandwidth() {
        // N = 25 (default): 600 Hz → 265 µs.
        assert_eq!(kinco_speed_feedback_time_us(25), 265);
        assert_eq!(kinco_speed_feedback_time_us(0), 1592);
    }
}
