// ---- coordinates
//!
//! # Decisions
//!
//! - **Coordinates** (fhpp §5.3): AZ = REF + PNU 1010, PZ = AZ + PNU 500. Every position of the
//!   I/O, PNU 404 and PNU 300 / 1041 is PZ-based: `pz = raw − REF − PNU 1010 − PNU 500`.
//! - **Actual velocity reported** (PNU 310:1 and the status bytes' actual values): the
//!   encoder's speed through PNU 1024:6 "time constant for filtering the motor speed"
//!   (Tab. B.136), read in ms (the manual prints no unit; default 20 ms, CHOSEN: steady
//!   within 4 % at 1 rev/s on the 2000-increment encoder, in open loop too, where the
//!   rotor's own speed swings by half). The monitoring (MOV, MC of a velocity task, the
//!   velocity following error, block detection, the comparators) stays on the controller's
//!   observer, which follows a ramp without the filter's lag; the reported speed follows it
//!   within the filter's time.

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

    /// Actual velocity, SINC/s, as the controller's encoder observer sees it (the monitoring:
    /// MC of a velocity task, the following error, block detection, the comparators).
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

    /// Actual velocity as the device reports it, SINC/s: the measured motor speed (see the
    /// module's decision).
    pub(super) fn reported_velocity(&self) -> f64 {
        let k = self.params.einc_per_sinc;
        if k <= 0.0 {
            return 0.0;
        }
        // Less than one SINC/s of filtered quantisation at rest is not motion.
        crate::rounding::round(self.velocity_readout.value() / k) * self.params.polarity
    }

    /// One sample of the encoder for the measured motor speed, `dt` s after the last.
    pub(super) fn measure_velocity(&mut self, dt: f64) {
        let einc = self.stepper.encoder_increments() + self.plant_watch.encoder.error();
        self.velocity_readout
            .sample(einc, dt, self.params.velocity_filter_s);
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
