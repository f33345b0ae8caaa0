// ---- coordinates
//!
//! # Decisions
//!
//! - **Coordinates** (fhpp §5.3): AZ = REF + PNU 1010, PZ = AZ + PNU 500. Every position of the
//!   I/O, PNU 404 and PNU 300 / 1041 is PZ-based: `pz = raw − REF − PNU 1010 − PNU 500`.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>> FhppDevice<S> {
    /// Actual position, raw SINC (encoder based).
    pub(super) fn raw_actual(&self) -> f64 {
        let k = self.params.einc_per_sinc;
        if k <= 0.0 {
            return 0.0;
        }
        (self.stepper.encoder_increments() + self.plant_watch.encoder.error()) as f64 / k
            * self.params.polarity
    }

    /// Actual velocity, SINC/s (as the controller's encoder observer sees it).
    pub(super) fn actual_velocity(&self) -> f64 {
        let k = self.params.einc_per_sinc;
        if k <= 0.0 {
            return 0.0;
        }
        let inc_rev = f64::from(self.stepper.data().encoder_increments_per_rev.max(1));
        let v = f64::from(self.stepper.estimated_velocity_rpm()) / 60.0 * inc_rev / k;
        // Quantisation noise of the observer at rest is not motion.
        crate::rounding::round(v) * self.params.polarity
    }

    /// Actual current in ‰ of PNU 555 (the force actual value).
    pub(super) fn actual_force(&self) -> i32 {
        if self.params.base_force_ma <= 0.0 {
            return 0;
        }
        let ma = self.stepper.current_ma() as f64;
        sat_i32(ma * 1000.0 / self.params.base_force_ma)
    }

    pub(super) fn zero(&self) -> f64 {
        self.reference.unwrap_or(0.0) + (self.params.az_offset + self.params.project_zero) as f64
    }

    pub(super) fn to_pz(&self, raw: f64) -> f64 {
        raw - self.zero()
    }

    pub(super) fn pz_to_raw(&self, pz: f64) -> f64 {
        pz + self.zero()
    }

    pub(super) fn clamp_velocity(&mut self, v: f64) -> f64 {
        let max = self.params.max_velocity;
        if max > 0.0 && v > max {
            self.velocity_limited = true;
            max
        } else {
            self.velocity_limited = false;
            v
        }
    }
}
