//! The actual velocity a drive reports: the encoder's position difference per sample through a
//! first-order low pass (PT1), as drive firmware measures speed. It is not the plant's true
//! speed: a micro-stepped rotor's instantaneous speed swings many times its mean at low speed,
//! while its position, and any reading a drive takes from its encoder, advances steadily.
//!
//! Cheap enough for the hot path (a subtraction, a division and a multiply-add per sample, no
//! allocation); the mean of the readout over a steady motion is the mean speed exactly.

/// The filter's state: the last position sample and the filtered speed.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MeasuredVelocity {
    last: Option<i64>,
    value: f64,
}

impl MeasuredVelocity {
    /// A position sample `dt` seconds after the previous one, filtered with time constant
    /// `tau` seconds (0: no filter); returns the speed in position units per second.
    pub fn sample(&mut self, position: i64, dt: f64, tau: f64) -> f64 {
        let last = self.last.replace(position);
        let Some(last) = last.filter(|_| dt > 0.0) else {
            return self.value;
        };
        let raw = position.wrapping_sub(last) as f64 / dt;
        // Euler-discretised PT1: exact for dt ≪ tau and stable for every dt ≥ 0.
        let alpha = dt / (tau.max(0.0) + dt);
        self.value += alpha * (raw - self.value);
        self.value
    }

    /// The last filtered speed, position units per second.
    pub fn value(&self) -> f64 {
        self.value
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_steady_motion_reads_its_speed_and_a_step_settles_with_tau() {
        let mut v = MeasuredVelocity::default();
        let dt = 0.001;
        // 100 units/s in integer positions: one step every 10 samples, 1000 units/s for
        // one millisecond in ten.
        let mut readings = [0.0; 2000];
        for (k, r) in readings.iter_mut().enumerate() {
            *r = v.sample((k as i64) / 10, dt, 0.020);
        }
        let settled = &readings[1000..];
        let min = settled.iter().copied().fold(f64::MAX, f64::min);
        let max = settled.iter().copied().fold(f64::MIN, f64::max);
        let mean = settled.iter().sum::<f64>() / settled.len() as f64;
        assert!(min > 75.0 && max < 125.0, "{min} .. {max}");
        assert!((mean - 100.0).abs() < 1.0, "{mean}");
        // A step from rest: 63 % after one time constant (within the Euler error).
        let mut v = MeasuredVelocity::default();
        let mut p = 0;
        v.sample(p, dt, 0.020);
        for _ in 0..20 {
            p += 1;
            v.sample(p, dt, 0.020);
        }
        assert!((v.value() / 1000.0 - 0.63).abs() < 0.03, "{}", v.value());
    }

    #[test]
    fn no_filter_and_no_time_are_safe() {
        let mut v = MeasuredVelocity::default();
        assert_eq!(
            v.sample(5, 0.001, 0.0),
            0.0,
            "the first sample has no speed"
        );
        assert_eq!(v.sample(7, 0.001, 0.0), 2000.0);
        assert_eq!(v.sample(9, 0.0, 0.0), 2000.0, "dt = 0 keeps the reading");
        assert!(v.sample(i64::MIN, 0.001, 0.0).is_finite());
    }
}
