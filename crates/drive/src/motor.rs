//! The simulated plant: a permanent-magnet servo motor as an equivalent DC motor, with its
//! load (inertia, viscous and Coulomb friction, a constant load torque such as gravity), a
//! holding brake, a "jammed load" switch and a quantising encoder.
//!
//! Model (SI units):
//!
//! ```text
//!   L di/dt = V − R·i − Ke·ω                 (Ke = Kt in SI units: V·s/rad = N·m/A)
//!   J dω/dt = Kt·i − B·ω − Tc·sign(ω) − T_load
//! ```
//!
//! The electrical pole is integrated exactly for a voltage and speed held over the step
//! (`i ← a·i + (1 − a)/R·(V − Ke·ω)`, `a = e^(−R·dt/L)`), so any step width is stable. The
//! mechanics are semi-implicit (viscous friction implicit) with a stick/slip (Karnopp)
//! treatment of Coulomb friction: at standstill the shaft stays at exactly zero speed while
//! the driving torque is below the breakaway torque, and a step that would reverse the speed
//! stops the shaft instead, so there is no chatter around ω = 0. The angle is `f64` radians,
//! which keeps sub-increment resolution over very long runs.
//!
//! "DC-equivalent" means: current = the RMS phase current (the quantity 6075h/6078h are
//! given in), torque = Kt·i, and R, L and the voltage are the equivalent values that give
//! the same copper losses and the same electrical power as the three phases: R = 3·R_phase
//! (= 1.5·R_line-line), L likewise, V = 3·V_phase,RMS. The simulation does not commutate;
//! phase order, pole number and the encoder offset angle (6410h:10/11, 604Dh) do not affect it.

use core::f64::consts::PI;

/// Encoder increments per motor revolution of the CMMP-AS internal position unit and of the X2A
/// resolver input (CMMP-AS §5.9, 2024h:01; the manual's extract, part 2 §6: "65536 increments =
/// 1 revolution").
pub const INCREMENTS_PER_REV: u32 = 65536;

/// rad/s → min⁻¹.
pub const RAD_S_TO_RPM: f64 = 60.0 / (2.0 * PI);
/// min⁻¹ → rad/s.
pub const RPM_TO_RAD_S: f64 = 2.0 * PI / 60.0;

/// Nameplate and load data of the simulated motor, in SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorData {
    /// Torque constant Kt, N·m/A (RMS); also the back-EMF constant Ke in V·s/rad.
    pub torque_constant: f64,
    /// Equivalent winding resistance, Ω.
    pub resistance: f64,
    /// Equivalent winding inductance, H.
    pub inductance: f64,
    /// Rotor plus reflected load inertia, kg·m².
    pub inertia: f64,
    /// Viscous friction, N·m·s/rad.
    pub viscous_friction: f64,
    /// Coulomb (and breakaway) friction, N·m.
    pub coulomb_friction: f64,
    /// Constant load torque, N·m, acting towards negative rotation (e.g. gravity on a
    /// vertical axis); 0 for none.
    pub load_torque: f64,
    /// Holding-brake torque, N·m: while the brake is engaged, the shaft stays put below this
    /// torque and slips against it above.
    pub brake_holding_torque: f64,
    /// Rated (continuous) current, A RMS (what 6075h should be set to).
    pub rated_current: f64,
    /// Peak current, A RMS (upper bound for 6075h × 6073h / 1000).
    pub peak_current: f64,
    /// Time the peak current may flow, s (what 6410h:03 should be set to).
    pub i2t_time: f64,
    /// Encoder increments per revolution (CMMP-AS internal unit: 65536).
    pub increments_per_rev: u32,
    /// Maximum mechanical speed, min⁻¹ (what 6080h should be set to).
    pub max_speed_rpm: f64,
}

impl Default for MotorData {
    /// A Festo EMMS-AS-55-S (55 mm flange, short, 325 V DC-link winding) with a small load.
    ///
    /// Assumptions (catalogue-like figures from memory, not a datasheet copy; change them for
    /// another motor): Kt ≈ 0.55 N·m/A, rated current 1.3 A (≈ 0.7 N·m), peak current
    /// 4.5 A, equivalent R = 30 Ω and L = 30 mH (1.5 × line-to-line values of 20 Ω / 20 mH;
    /// electrical time constant 1 ms), rotor
    /// inertia ≈ 0.1 kg·cm² plus 0.2 kg·cm² of load (J = 3·10⁻⁵ kg·m²), 6000 min⁻¹ max.
    /// Friction: 10 mN·m Coulomb, 2·10⁻⁵ N·m·s/rad viscous (≈ 6 mN·m at 3000 min⁻¹).
    /// Holding brake 2.5 N·m (above the peak torque, so an engaged brake holds the shaft).
    /// I²t: 2 s, the CMMP-AS default of 6410h:03.
    fn default() -> Self {
        MotorData {
            torque_constant: 0.55,
            resistance: 30.0,
            inductance: 0.030,
            inertia: 3.0e-5,
            viscous_friction: 2.0e-5,
            coulomb_friction: 0.01,
            load_torque: 0.0,
            brake_holding_torque: 2.5,
            rated_current: 1.3,
            peak_current: 4.5,
            i2t_time: 2.0,
            increments_per_rev: INCREMENTS_PER_REV,
            max_speed_rpm: 6000.0,
        }
    }
}

/// State of the simulated motor and load.
#[derive(Debug, Clone, PartialEq)]
pub struct Motor {
    data: MotorData,
    /// Winding current, A.
    current: f64,
    /// Angular velocity, rad/s.
    velocity: f64,
    /// Shaft angle, rad (f64 so long runs keep resolution).
    angle: f64,
    /// The encoder reading of `angle` (read several times per cycle; set with the angle).
    increments: i64,
    /// `increments` as `f64` (exact below 2⁵³): the axis's speed measurement takes the
    /// difference of two readings without a conversion on the plant's dependent chain.
    increments_f: f64,
    /// Holding brake engaged.
    brake: bool,
    /// External stop: the load is jammed (infinite friction).
    blocked: bool,
    /// Mechanical hard stops of the travel, rad (lower, upper): the shaft cannot pass them.
    stops: (f64, f64),
    /// Step width the electrical coefficients were computed for (0 = none yet).
    coeff_dt: f64,
    /// e^(−R·dt/L).
    coeff_a: f64,
    /// (1 − a)/R (or dt/L when R = 0).
    coeff_b: f64,
    /// dt/(J + B·dt) and J/(J + B·dt) for the mechanics.
    mech_k: f64,
    mech_j: f64,
    /// 2π / increments per revolution.
    rad_per_inc: f64,
    /// 1 / `rad_per_inc`.
    inc_per_rad: f64,
    /// The share of Kt·i that turns the shaft: 1 for the servo's field-oriented control; the
    /// block commutation of a BLDC sets it per sector (`crate::bldc`).
    torque_factor: f64,
}

fn sign(x: f64) -> f64 {
    if x < 0.0 {
        -1.0
    } else {
        1.0
    }
}

impl Motor {
    pub fn new(data: MotorData) -> Self {
        let inc = if data.increments_per_rev == 0 {
            INCREMENTS_PER_REV
        } else {
            data.increments_per_rev
        };
        Motor {
            data,
            current: 0.0,
            velocity: 0.0,
            angle: 0.0,
            increments: 0,
            increments_f: 0.0,
            brake: false,
            blocked: false,
            stops: (f64::NEG_INFINITY, f64::INFINITY),
            coeff_dt: 0.0,
            coeff_a: 0.0,
            coeff_b: 0.0,
            mech_k: 0.0,
            mech_j: 0.0,
            rad_per_inc: 2.0 * PI / inc as f64,
            inc_per_rad: inc as f64 / (2.0 * PI),
            torque_factor: 1.0,
        }
    }

    pub fn data(&self) -> &MotorData {
        &self.data
    }

    /// Changes the constant load torque (N·m, towards negative rotation).
    pub fn set_load_torque(&mut self, torque: f64) {
        self.data.load_torque = torque;
    }

    /// Engages (true) or releases the holding brake.
    pub fn set_brake(&mut self, engaged: bool) {
        self.brake = engaged;
    }

    pub fn brake(&self) -> bool {
        self.brake
    }

    /// Jams the load (true): the shaft cannot turn, whatever the torque.
    pub fn set_blocked(&mut self, blocked: bool) {
        self.blocked = blocked;
        if blocked {
            self.velocity = 0.0;
        }
    }

    pub fn blocked(&self) -> bool {
        self.blocked
    }

    /// Places mechanical hard stops at `lower` and `upper` rad (`None`: no stop that side).
    /// Against a stop the shaft stands while the winding current rises to whatever the
    /// controller drives into it.
    pub fn set_stops(&mut self, lower: Option<f64>, upper: Option<f64>) {
        self.stops = (
            lower.unwrap_or(f64::NEG_INFINITY),
            upper.unwrap_or(f64::INFINITY),
        );
    }

    /// Winding current, A.
    pub fn current(&self) -> f64 {
        self.current
    }

    /// Angular velocity, rad/s.
    pub fn velocity(&self) -> f64 {
        self.velocity
    }

    /// Shaft angle, rad.
    pub fn angle(&self) -> f64 {
        self.angle
    }

    /// Places the shaft at `angle` rad at rest (initial conditions for tests and homing
    /// set-ups).
    pub fn set_angle(&mut self, angle: f64) {
        self.angle = angle;
        (self.increments, self.increments_f) = self.encoder(angle);
    }

    /// Electromagnetic torque Kt·i, N·m.
    pub fn torque(&self) -> f64 {
        self.data.torque_constant * self.current
    }

    /// The commutation's share of Kt·i that turns the shaft (1 unless a BLDC sets it).
    pub fn set_torque_factor(&mut self, factor: f64) {
        self.torque_factor = factor;
    }

    /// Radians per encoder increment.
    pub fn rad_per_increment(&self) -> f64 {
        self.rad_per_inc
    }

    /// Encoder reading: ⌊angle / 2π × increments per revolution⌋.
    #[inline]
    pub fn position_increments(&self) -> i64 {
        self.increments
    }

    /// [`Motor::position_increments`] as `f64`.
    #[inline]
    pub fn position_increments_f(&self) -> f64 {
        self.increments_f
    }

    fn encoder(&self, angle: f64) -> (i64, f64) {
        crate::rounding::floored_quotient(angle, self.inc_per_rad, self.rad_per_inc)
    }

    fn coefficients(&mut self, dt: f64) {
        if dt == self.coeff_dt {
            return;
        }
        let d = &self.data;
        if d.inductance > 0.0 && d.resistance > 0.0 {
            self.coeff_a = libm::exp(-d.resistance * dt / d.inductance);
            self.coeff_b = (1.0 - self.coeff_a) / d.resistance;
        } else if d.inductance > 0.0 {
            self.coeff_a = 1.0;
            self.coeff_b = dt / d.inductance;
        } else if d.resistance > 0.0 {
            // No inductance: the current follows the voltage at once.
            self.coeff_a = 0.0;
            self.coeff_b = 1.0 / d.resistance;
        } else {
            self.coeff_a = 1.0;
            self.coeff_b = 0.0;
        }
        let den = d.inertia + d.viscous_friction * dt;
        if den > 0.0 {
            self.mech_k = dt / den;
            self.mech_j = d.inertia / den;
        } else {
            self.mech_k = 0.0;
            self.mech_j = 0.0;
        }
        self.coeff_dt = dt;
    }

    /// Advances the motor by `dt` s with `voltage` V across the (equivalent) winding.
    pub fn step(&mut self, dt: f64, voltage: f64) {
        if dt <= 0.0 {
            return;
        }
        self.coefficients(dt);
        let emf = self.data.torque_constant * self.velocity;
        self.current = self.coeff_a * self.current + self.coeff_b * (voltage - emf);
        self.mechanics(dt);
    }

    /// Advances the motor by `dt` s with the output stage off: the winding carries no current
    /// and the shaft coasts (the brake, if engaged, still acts).
    pub fn step_open(&mut self, dt: f64) {
        if dt <= 0.0 {
            return;
        }
        self.coefficients(dt);
        self.current = 0.0;
        self.mechanics(dt);
    }

    fn mechanics(&mut self, dt: f64) {
        if self.blocked {
            self.velocity = 0.0;
            return;
        }
        let d = &self.data;
        let drive = d.torque_constant * self.current * self.torque_factor - d.load_torque;
        let hold = d.coulomb_friction
            + if self.brake {
                d.brake_holding_torque
            } else {
                0.0
            };
        let w0 = self.velocity;
        let w1 = if w0 == 0.0 {
            // Sticking: break away only when the driving torque exceeds the friction.
            if libm::fabs(drive) <= hold {
                0.0
            } else {
                self.mech_k * (drive - sign(drive) * hold)
            }
        } else {
            let s = sign(w0);
            let w = self.mech_j * w0 + self.mech_k * (drive - s * hold);
            // Friction cannot reverse the motion: a sign change means the shaft stopped.
            if w * s < 0.0 {
                0.0
            } else {
                w
            }
        };
        let mut w1 = w1;
        let mut angle = self.angle + 0.5 * (w0 + w1) * dt;
        // A hard stop takes the motion towards it (a fully plastic impact: no bounce).
        let (lower, upper) = self.stops;
        if angle < lower {
            angle = lower;
            w1 = w1.max(0.0);
        } else if angle > upper {
            angle = upper;
            w1 = w1.min(0.0);
        }
        self.angle = angle;
        (self.increments, self.increments_f) = self.encoder(angle);
        self.velocity = w1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The encoder reading by a multiplication is the floored quotient bit for bit: on and
    /// next to every increment edge, far out, and for the values that are not numbers.
    #[test]
    fn encoder_is_the_floored_quotient() {
        for per_rev in [INCREMENTS_PER_REV, 2000, 4096, 10_000, 3, 1] {
            let motor = Motor::new(MotorData {
                increments_per_rev: per_rev,
                ..MotorData::default()
            });
            let rpi = motor.rad_per_inc;
            let reference = |angle: f64| crate::rounding::floor(angle / rpi) as i64;
            for k in (-3000i64..3000).chain([1 << 20, -(1 << 33), 1 << 45]) {
                let edge = k as f64 * rpi;
                let mut below = edge;
                let mut above = edge;
                for _ in 0..8 {
                    for a in [edge, below, above, edge + 0.5 * rpi] {
                        let (inc, inc_f) = motor.encoder(a);
                        assert_eq!(inc, reference(a), "{per_rev} {a}");
                        assert_eq!(inc_f.to_bits(), (inc as f64).to_bits(), "{per_rev} {a}");
                    }
                    below = f64::from_bits(below.to_bits().wrapping_sub(1));
                    above = f64::from_bits(above.to_bits().wrapping_add(1));
                }
            }
            for a in [
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
                1e300,
                -1e300,
                0.0,
                -0.0,
            ] {
                let (inc, inc_f) = motor.encoder(a);
                assert_eq!(inc, reference(a), "{per_rev} {a}");
                assert_eq!(inc_f.to_bits(), (inc as f64).to_bits(), "{per_rev} {a}");
            }
        }
    }
}
