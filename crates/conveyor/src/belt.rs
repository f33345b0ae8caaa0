//! The belt's mechanics: a mass on an elastic toothed belt driven by the motor's pulley.
//!
//! ```text
//!   F      = k·(r·θ − x) + d·(r·ω − v)          belt force, N (θ, ω: the motor shaft)
//!   m dv/dt = F − c·v − Fc·sign(v)               mass with viscous and Coulomb friction
//!   T_load = r·F                                 torque on the shaft, towards negative rotation
//! ```
//!
//! The shaft's angle and speed are the inputs (displacement coupling: the belt's spring is
//! what an explicit co-simulation step can hold stable, where a rigid coupling would need the
//! motor's acceleration of the same instant). Within a communication step the shaft turns at
//! the speed it had at the step's start; the mass is integrated in sub-steps of at most
//! [`MAX_SUBSTEP_S`] (symplectic Euler, viscous terms implicit) with the same stick/slip
//! treatment of Coulomb friction as the drive's motor model: at rest the mass stays at rest
//! while the belt force is below the breakaway force, and friction never reverses the motion.

/// The longest internal integration step, s: a tenth of the belt's oscillation period with
/// the default parameters and the drive's inertia (about 90 Hz).
pub const MAX_SUBSTEP_S: f64 = 50e-6;

/// The belt's parameters, SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeltData {
    /// Moving mass (belt and goods), kg.
    pub mass: f64,
    /// Pulley radius (with any gear folded in), m: belt travel per shaft radian.
    pub pulley_radius: f64,
    /// Belt stiffness between pulley and mass, N/m.
    pub stiffness: f64,
    /// Belt damping, N·s/m.
    pub damping: f64,
    /// Viscous friction of the mass, N·s/m.
    pub viscous_friction: f64,
    /// Coulomb (and breakaway) friction of the mass, N.
    pub coulomb_friction: f64,
}

/// The state of the mass.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Belt {
    /// Position of the mass, m.
    pub position: f64,
    /// Speed of the mass, m/s.
    pub speed: f64,
}

impl Belt {
    /// The belt force, N, for the shaft at `angle` rad turning at `speed` rad/s.
    pub fn force(&self, d: &BeltData, angle: f64, speed: f64) -> f64 {
        d.stiffness * (d.pulley_radius * angle - self.position)
            + d.damping * (d.pulley_radius * speed - self.speed)
    }

    /// The torque the belt puts on the shaft, N·m, towards negative rotation.
    pub fn load_torque(&self, d: &BeltData, angle: f64, speed: f64) -> f64 {
        d.pulley_radius * self.force(d, angle, speed)
    }

    /// Advances the mass by `h` s while the shaft turns from `angle` at `speed` rad/s.
    pub fn step(&mut self, d: &BeltData, angle: f64, speed: f64, h: f64) {
        if h.is_nan() || h <= 0.0 || d.mass.is_nan() || d.mass <= 0.0 {
            return;
        }
        let n = (h / MAX_SUBSTEP_S).ceil().max(1.0);
        let dt = h / n;
        let mut theta = angle;
        // `n` is at most h / 50 µs; a communication step of hours would still count exactly.
        let mut left = n as u64;
        while left > 0 {
            left -= 1;
            self.substep(d, theta, speed, dt);
            theta += speed * dt;
        }
    }

    fn substep(&mut self, d: &BeltData, angle: f64, speed: f64, dt: f64) {
        // The belt's damping and the viscous friction act on v: implicit in them.
        let drive = d.stiffness * (d.pulley_radius * angle - self.position)
            + d.damping * d.pulley_radius * speed;
        let den = d.mass + (d.damping + d.viscous_friction) * dt;
        let v0 = self.speed;
        let v1 = if v0 == 0.0 {
            if drive.abs() <= d.coulomb_friction {
                0.0
            } else {
                (dt * (drive - drive.signum() * d.coulomb_friction)) / den
            }
        } else {
            let s = v0.signum();
            let v = (d.mass * v0 + dt * (drive - s * d.coulomb_friction)) / den;
            if v * s < 0.0 {
                0.0
            } else {
                v
            }
        };
        // Symplectic: the new speed moves the mass, so that belt and shaft moving together
        // keep the stretch the friction needs.
        self.position += v1 * dt;
        self.speed = v1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data() -> BeltData {
        BeltData {
            mass: 0.5,
            pulley_radius: 0.01,
            stiffness: 1.0e5,
            damping: 100.0,
            viscous_friction: 5.0,
            coulomb_friction: 2.0,
        }
    }

    #[test]
    fn a_turning_shaft_pulls_the_mass_along_and_is_loaded_by_the_friction() {
        let d = data();
        let mut b = Belt::default();
        let w = 10.0; // rad/s: 0.1 m/s of belt
        let mut angle = 0.0;
        for _ in 0..2000 {
            b.step(&d, angle, w, 1e-3);
            angle += w * 1e-3;
        }
        assert!((b.speed - 0.1).abs() < 1e-6, "{}", b.speed);
        // Steady state: the belt carries the friction, c·v + Fc = 0.5 + 2 N, at r = 0.01 m.
        let t = b.load_torque(&d, angle, w);
        assert!((t - 0.025).abs() < 1e-6, "{t}");
        assert!((b.position - d.pulley_radius * angle).abs() < 1e-3);
    }

    #[test]
    fn below_the_breakaway_force_the_mass_sticks() {
        let d = data();
        let mut b = Belt::default();
        // 1 N of belt stretch: below the 2 N of Coulomb friction.
        let angle = 1.0 / (d.stiffness * d.pulley_radius);
        b.step(&d, angle, 0.0, 0.1);
        assert_eq!(b.speed, 0.0);
        assert_eq!(b.position, 0.0);
    }

    #[test]
    fn the_same_inputs_give_the_same_bits() {
        let d = data();
        let run = || {
            let mut b = Belt::default();
            for i in 0..1000 {
                b.step(&d, f64::from(i) * 1e-3, 7.0, 250e-6);
            }
            (b.position.to_bits(), b.speed.to_bits())
        };
        assert_eq!(run(), run());
    }
}
