//! The filters between the velocity controller and the current controller: a first-order output
//! filter and a notch on the current set-point, and the velocity integrator's own limit. The Kinco
//! servo has all three (Kinco manual ch. 7, Tab. 7-3 and 7-5): Output_Filter_N 60F9h:15, Notch_N /
//! Notch_On 60F9h:03 / :04, Kvi_Sum_Limit 60F9h:08. The CMMP-AS has none of them: its parameters
//! leave them off, and the cascade is then the same, bit for bit, as without this module.

use core::f64::consts::PI;

/// The sample time the Kinco's Output_Filter_N is defined on: `f = −ln(1 − 1/N) /
/// (2π · 62.5 µs)`, i.e. `y += (x − y) / N` every 62.5 µs.
const OUTPUT_FILTER_SAMPLE_S: f64 = 62.5e-6;

/// The notch's quality factor. CHOSEN: the manual gives the centre frequency only; Q = 2 is
/// a notch about a quarter of its frequency wide at −3 dB, as servo notches usually are.
const NOTCH_Q: f64 = 2.0;

/// What the drive's parameters ask for (part of [`crate::control::ControlParams`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CurrentFilterParams {
    /// Output_Filter_N: 1 = no filter.
    pub output_filter_n: u16,
    /// The notch's centre frequency (Hz) while it is on; `None` = off.
    pub notch_hz: Option<u32>,
    /// The velocity integrator's limit in 1/32768 of the current limit (Kvi_Sum_Limit; 32768 =
    /// the current limit itself, the engine's default).
    pub velocity_integral_limit: u16,
}

impl Default for CurrentFilterParams {
    fn default() -> Self {
        CurrentFilterParams {
            output_filter_n: 1,
            notch_hz: None,
            velocity_integral_limit: 32768,
        }
    }
}

/// The notch as a biquad: `y = b0·x + b1·x₁ + b2·x₂ − a1·y₁ − a2·y₂` (RBJ cookbook notch,
/// normalised by a0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Notch {
    b0: f64,
    b1: f64,
    b2: f64,
    a1: f64,
    a2: f64,
}

impl Notch {
    /// A notch at `hz` for a sample time of `dt` s; `None` at or above half the sample rate,
    /// where it could not act.
    pub fn new(hz: f64, dt: f64) -> Option<Notch> {
        let w0 = 2.0 * PI * hz * dt;
        if !(w0 > 0.0 && w0 < PI) {
            return None;
        }
        let (sin, cos) = (libm::sin(w0), libm::cos(w0));
        let alpha = sin / (2.0 * NOTCH_Q);
        let a0 = 1.0 + alpha;
        Some(Notch {
            b0: 1.0 / a0,
            b1: -2.0 * cos / a0,
            b2: 1.0 / a0,
            a1: -2.0 * cos / a0,
            a2: (1.0 - alpha) / a0,
        })
    }
}

/// The coefficients per current-controller cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurrentFilters {
    /// PT1 coefficient of the output filter per cycle; 1 = none.
    pub output_alpha: f64,
    pub notch: Option<Notch>,
    /// The velocity integrator's limit as a share of the current limit (1 = the limit).
    pub integral_share: f64,
}

impl CurrentFilters {
    pub fn new(p: &CurrentFilterParams, dt: f64) -> Self {
        let n = f64::from(p.output_filter_n.max(1));
        let output_alpha = if n <= 1.0 {
            1.0
        } else {
            1.0 - libm::pow(1.0 - 1.0 / n, dt / OUTPUT_FILTER_SAMPLE_S)
        };
        CurrentFilters {
            output_alpha,
            notch: p.notch_hz.and_then(|hz| Notch::new(f64::from(hz), dt)),
            integral_share: (f64::from(p.velocity_integral_limit) / 32768.0).min(1.0),
        }
    }

    /// Whether the set-point passes unchanged.
    pub fn is_pass_through(&self) -> bool {
        self.output_alpha >= 1.0 && self.notch.is_none()
    }
}

/// The filters' memory.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FilterState {
    output: f64,
    x1: f64,
    x2: f64,
    y1: f64,
    y2: f64,
}

impl FilterState {
    /// One current-controller cycle of set-point `x` (A) through the output filter, then the
    /// notch.
    #[inline]
    pub fn step(&mut self, f: &CurrentFilters, x: f64) -> f64 {
        self.output += (x - self.output) * f.output_alpha;
        let x = self.output;
        let Some(n) = f.notch else {
            return x;
        };
        let y = n.b0 * x + n.b1 * self.x1 + n.b2 * self.x2 - n.a1 * self.y1 - n.a2 * self.y2;
        self.x2 = self.x1;
        self.x1 = x;
        self.y2 = self.y1;
        self.y1 = y;
        y
    }

    pub fn reset(&mut self) {
        *self = FilterState::default();
    }

    /// Settled at set-point `x`: filters switched on while a current flows start from it
    /// instead of from zero (the notch passes a steady value unchanged).
    pub fn settle_at(&mut self, x: f64) {
        *self = FilterState {
            output: x,
            x1: x,
            x2: x,
            y1: x,
            y2: x,
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The gain of `f` for a sine of `hz` after it settled (peak of the output over the last
    /// periods, against 1).
    fn gain(f: &CurrentFilters, hz: f64, dt: f64) -> f64 {
        let mut s = FilterState::default();
        let n = (0.2 / dt) as usize;
        let mut peak: f64 = 0.0;
        for k in 0..n {
            let y = s.step(f, libm::sin(2.0 * PI * hz * k as f64 * dt));
            if k > n / 2 {
                peak = peak.max(y.abs());
            }
        }
        peak
    }

    #[test]
    fn the_notch_takes_out_its_frequency_and_passes_the_others() {
        let dt = 125e-6;
        let p = CurrentFilterParams {
            notch_hz: Some(550),
            ..CurrentFilterParams::default()
        };
        let f = CurrentFilters::new(&p, dt);
        assert!(gain(&f, 550.0, dt) < 0.05, "{}", gain(&f, 550.0, dt));
        assert!(gain(&f, 50.0, dt) > 0.98);
        assert!(gain(&f, 2000.0, dt) > 0.9);
    }

    #[test]
    fn output_filter_n_is_the_manuals_first_order_filter() {
        // N = 1: no filter.
        let none = CurrentFilters::new(&CurrentFilterParams::default(), 125e-6);
        assert!(none.is_pass_through());
        let mut s = FilterState::default();
        assert_eq!(s.step(&none, 1.25), 1.25);
        // N = 2 on 62.5 µs samples: a step reaches 1 − ½ⁿ after n samples; at 125 µs per
        // cycle, two samples a cycle: 0.75 after one cycle, 0.9375 after two.
        let p = CurrentFilterParams {
            output_filter_n: 2,
            ..CurrentFilterParams::default()
        };
        let f = CurrentFilters::new(&p, 125e-6);
        let mut s = FilterState::default();
        assert!((s.step(&f, 1.0) - 0.75).abs() < 1e-12);
        assert!((s.step(&f, 1.0) - 0.9375).abs() < 1e-12);
        // Its −3 dB frequency is the manual's −ln(1 − 1/N) / (2π · 62.5 µs) = 1765 Hz.
        let p = CurrentFilterParams {
            output_filter_n: 2,
            ..CurrentFilterParams::default()
        };
        let f = CurrentFilters::new(&p, 62.5e-6);
        let fc = -libm::log(0.5) / (2.0 * PI * 62.5e-6);
        let g = gain(&f, fc, 62.5e-6);
        assert!((g - core::f64::consts::FRAC_1_SQRT_2).abs() < 0.08, "{g}");
    }

    /// Switched on while a current flows, the filters hold it instead of dropping to zero.
    #[test]
    fn filters_settled_at_a_current_keep_it() {
        let p = CurrentFilterParams {
            output_filter_n: 64,
            notch_hz: Some(550),
            ..CurrentFilterParams::default()
        };
        let f = CurrentFilters::new(&p, 125e-6);
        let mut s = FilterState::default();
        s.settle_at(1.5);
        for _ in 0..100 {
            assert!((s.step(&f, 1.5) - 1.5).abs() < 1e-9);
        }
    }

    #[test]
    fn a_notch_beyond_half_the_sample_rate_is_off() {
        assert!(Notch::new(5000.0, 125e-6).is_none());
        assert!(Notch::new(0.0, 125e-6).is_none());
    }
}
