//! The plant's temperatures: the motor winding and the drive's power stage, each a
//! first-order thermal node heated by the copper losses of the motor current (I²R) and
//! cooled towards the ambient temperature.
//!
//! ```text
//!   τ dT/dt = T_amb + ΔT_rated · (I / I_rated)² − T
//! ```
//!
//! `ΔT_rated` is the steady rise at the rated current (the losses I²R times the thermal
//! resistance, folded into one figure: the manuals give neither R_th nor a thermal time
//! constant), `τ` the thermal time constant. At the logic rate (≥ 250 µs) and time constants
//! of seconds the explicit step `T += (T_ss − T) · dt/τ` is exact to far below a degree; `dt/τ`
//! is clamped to 1 so a short time constant (a test) cannot oscillate.
//!
//! Decisions (CHOSEN figures, no manual prints them): motor ΔT_rated = 60 K with τ = 600 s
//! (a small servo or stepper motor at its rated current settles at 85 °C in a 25 °C cabinet,
//! below the CMMP-AS's 100 °C of 6510h:2F); power stage ΔT = 40 K at the motor's rated
//! current with τ = 60 s (a heat sink heats faster than a motor); ambient 25 °C. A cell file,
//! the control handle or a scenario changes the ambient; [`ThermalData`] the rest.
//!
//! Stepping costs a handful of float operations and never allocates.

/// How the plant heats (see the module doc for the defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermalData {
    /// Motor winding: steady temperature rise at the rated current, K.
    pub motor_rise_k: f64,
    /// Motor winding: thermal time constant, s.
    pub motor_time_constant_s: f64,
    /// Power stage: steady rise at the motor's rated current, K.
    pub stage_rise_k: f64,
    /// Power stage: thermal time constant, s.
    pub stage_time_constant_s: f64,
}

impl Default for ThermalData {
    fn default() -> Self {
        ThermalData {
            motor_rise_k: 60.0,
            motor_time_constant_s: 600.0,
            stage_rise_k: 40.0,
            stage_time_constant_s: 60.0,
        }
    }
}

/// The ambient temperature a drive starts in, °C (CHOSEN: a 25 °C cabinet).
pub const DEFAULT_AMBIENT_C: f64 = 25.0;

/// The motor's and the power stage's temperature.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Thermal {
    data: ThermalData,
    ambient_c: f64,
    motor_c: f64,
    stage_c: f64,
}

impl Default for Thermal {
    fn default() -> Self {
        Thermal::new(ThermalData::default(), DEFAULT_AMBIENT_C)
    }
}

impl Thermal {
    /// A cold plant: motor and power stage at the ambient temperature.
    pub fn new(data: ThermalData, ambient_c: f64) -> Self {
        Thermal {
            data,
            ambient_c,
            motor_c: ambient_c,
            stage_c: ambient_c,
        }
    }

    pub fn data(&self) -> &ThermalData {
        &self.data
    }

    /// New figures; the temperatures go on from where they are.
    pub fn set_data(&mut self, data: ThermalData) {
        self.data = data;
    }

    pub fn ambient_c(&self) -> f64 {
        self.ambient_c
    }

    /// The ambient temperature, °C: the motor and the stage cool (or heat) towards it.
    pub fn set_ambient_c(&mut self, celsius: f64) {
        if celsius.is_finite() {
            self.ambient_c = celsius;
        }
    }

    /// Motor winding temperature, °C.
    pub fn motor_c(&self) -> f64 {
        self.motor_c
    }

    /// Power stage temperature, °C.
    pub fn stage_c(&self) -> f64 {
        self.stage_c
    }

    /// Both temperatures at `celsius` at once (a plant that has been standing).
    pub fn settle_at(&mut self, celsius: f64) {
        if celsius.is_finite() {
            self.motor_c = celsius;
            self.stage_c = celsius;
        }
    }

    /// `dt` seconds with the motor current at `load` = (I / I_rated)².
    #[inline]
    pub fn step(&mut self, dt: f64, load: f64) {
        let d = &self.data;
        let k = |tau: f64| if tau > dt { dt / tau } else { 1.0 };
        let motor = self.ambient_c + d.motor_rise_k * load;
        let stage = self.ambient_c + d.stage_rise_k * load;
        self.motor_c += (motor - self.motor_c) * k(d.motor_time_constant_s);
        self.stage_c += (stage - self.stage_c) * k(d.stage_time_constant_s);
    }
}

/// `(I / I_rated)²`, 0 for a rated current of 0.
#[inline]
pub fn load(current_a: f64, rated_a: f64) -> f64 {
    if rated_a > 0.0 {
        let r = current_a / rated_a;
        r * r
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settles_at_the_rise_of_the_rated_current() {
        let mut t = Thermal::new(
            ThermalData {
                motor_time_constant_s: 1.0,
                stage_time_constant_s: 0.5,
                ..ThermalData::default()
            },
            25.0,
        );
        for _ in 0..20_000 {
            t.step(0.001, load(1.3, 1.3));
        }
        assert!((t.motor_c() - 85.0).abs() < 0.01, "{}", t.motor_c());
        assert!((t.stage_c() - 65.0).abs() < 0.01, "{}", t.stage_c());
        // One time constant at twice the rated current from cold: 63 % of 4 × 60 K.
        let mut t = Thermal::new(
            ThermalData {
                motor_time_constant_s: 1.0,
                ..ThermalData::default()
            },
            25.0,
        );
        for _ in 0..1000 {
            t.step(0.001, load(2.6, 1.3));
        }
        let expected = 25.0 + 240.0 * (1.0 - (-1.0f64).exp());
        assert!((t.motor_c() - expected).abs() < 0.2, "{}", t.motor_c());
    }

    #[test]
    fn cools_towards_a_new_ambient() {
        let mut t = Thermal::default();
        t.settle_at(90.0);
        t.set_ambient_c(40.0);
        for _ in 0..100_000 {
            t.step(0.1, 0.0);
        }
        assert!((t.motor_c() - 40.0).abs() < 0.01);
        assert!((t.stage_c() - 40.0).abs() < 0.01);
        t.set_ambient_c(f64::NAN);
        assert_eq!(t.ambient_c(), 40.0);
    }

    #[test]
    fn a_time_constant_shorter_than_the_step_does_not_oscillate() {
        let mut t = Thermal::new(
            ThermalData {
                motor_time_constant_s: 0.0001,
                stage_time_constant_s: 0.0,
                ..ThermalData::default()
            },
            25.0,
        );
        t.step(0.01, 1.0);
        assert_eq!(t.motor_c(), 85.0);
        assert_eq!(t.stage_c(), 65.0);
    }
}
