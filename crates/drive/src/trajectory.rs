//! The profile (trajectory) generator: position and velocity set-points that follow the
//! trapezoid of profile velocity, acceleration and deceleration (CiA 402 §12, CMMP-AS §7.3
//! Fig. 7.3), computed online every cycle so a new target can replace the running one.
//!
//! Units are internal (increments, increments/s, increments/s²) in `f64`: positions of long
//! runs keep their resolution, and the arithmetic is the same on every run.

use libm::sqrt;

/// Motion limits of one move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    pub velocity: f64,
    pub acceleration: f64,
    pub deceleration: f64,
}

/// Position and velocity of the set-point.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Trajectory {
    pub position: f64,
    pub velocity: f64,
}

fn sign(x: f64) -> f64 {
    if x < 0.0 {
        -1.0
    } else {
        1.0
    }
}

impl Trajectory {
    pub fn at(position: f64) -> Self {
        Trajectory {
            position,
            velocity: 0.0,
        }
    }

    /// One cycle of `dt` s towards `target`, arriving with `end_velocity` (≥ 0, in the
    /// direction of travel). Returns true once the target is reached.
    pub fn step_to(&mut self, target: f64, end_velocity: f64, lim: Limits, dt: f64) -> bool {
        let d = target - self.position;
        let accel = lim.acceleration.max(1e-9);
        let decel = lim.deceleration.max(1e-9);
        if d == 0.0 && self.velocity.abs() <= end_velocity {
            self.velocity = 0.0;
            return true;
        }
        let dir = sign(d);
        let v = self.velocity * dir; // speed towards the target (negative: moving away)
        if v < 0.0 {
            // Moving away: brake first (a relative move reversed, or a new target behind).
            let nv = (v + decel * dt).min(0.0);
            self.position += (v + nv) * 0.5 * dt * dir;
            self.velocity = nv * dir;
            return false;
        }
        let v_end = end_velocity.max(0.0).min(lim.velocity);
        // Highest speed at the end of this cycle from which the distance left after it still
        // allows braking to v_end: nv² − v_end² ≤ 2·decel·(|d| − (v + nv)·dt/2), solved for nv.
        let rest = d.abs() - v * dt * 0.5;
        let b = decel * dt;
        let v_allow =
            (-b + sqrt(b * b + 4.0 * (v_end * v_end + 2.0 * decel * rest).max(0.0))) * 0.5;
        let mut nv = (v + accel * dt).min(lim.velocity).min(v_allow);
        // Braking is limited too: if the profile asks for more, overshoot is unavoidable and
        // the next cycles come back.
        nv = nv.max(v - decel * dt).max(0.0);
        let step = (v + nv) * 0.5 * dt;
        if step >= d.abs() {
            self.position = target;
            self.velocity = v_end * dir;
            return true;
        }
        self.position += step * dir;
        self.velocity = nv * dir;
        false
    }

    /// One cycle of a velocity ramp towards `target` (profile velocity mode): `accel` when the
    /// speed grows, `decel` when it shrinks.
    pub fn step_velocity(&mut self, target: f64, accel: f64, decel: f64, dt: f64) {
        let v = self.velocity;
        let growing = (target.abs() > v.abs() && target * v >= 0.0) || v == 0.0;
        let rate = if growing { accel } else { decel };
        let dv = rate.max(0.0) * dt;
        let nv = if (target - v).abs() <= dv {
            target
        } else {
            v + dv * sign(target - v)
        };
        self.position += (v + nv) * 0.5 * dt;
        self.velocity = nv;
    }

    /// One cycle of braking to standstill with `decel`. Returns true once stopped.
    pub fn step_stop(&mut self, decel: f64, dt: f64) -> bool {
        self.step_velocity(0.0, decel, decel, dt);
        self.velocity == 0.0
    }

    /// The time a rest-to-rest move of `distance` takes with these limits (the trapezoid, or
    /// the triangle when the profile velocity is not reached).
    pub fn move_time(distance: f64, lim: Limits) -> f64 {
        let d = distance.abs();
        let (a, b, v) = (lim.acceleration, lim.deceleration, lim.velocity);
        let d_ramps = v * v / (2.0 * a) + v * v / (2.0 * b);
        if d >= d_ramps {
            v / a + v / b + (d - d_ramps) / v
        } else {
            let vp = sqrt(2.0 * d * a * b / (a + b));
            vp / a + vp / b
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 0.0005;

    fn run(distance: f64, lim: Limits) -> (f64, Trajectory, f64) {
        let mut t = Trajectory::at(0.0);
        let mut time = 0.0;
        let mut peak: f64 = 0.0;
        while !t.step_to(distance, 0.0, lim, DT) {
            time += DT;
            peak = peak.max(t.velocity.abs());
            assert!(time < 100.0, "never arrived");
        }
        (time, t, peak)
    }

    #[test]
    fn trapezoid_takes_the_time_the_formula_says() {
        // 10 revolutions at 1000 rpm, 10000 rpm/s, in increments.
        let rev = 65536.0;
        let lim = Limits {
            velocity: 1000.0 / 60.0 * rev,
            acceleration: 10000.0 / 60.0 * rev,
            deceleration: 10000.0 / 60.0 * rev,
        };
        let (time, t, peak) = run(10.0 * rev, lim);
        let expect = Trajectory::move_time(10.0 * rev, lim);
        assert!((time - expect).abs() < 0.003, "{time} vs {expect}");
        assert_eq!(t.position, 10.0 * rev);
        assert_eq!(t.velocity, 0.0);
        assert!(peak <= lim.velocity * 1.000001);
    }

    #[test]
    fn triangle_when_the_profile_velocity_is_not_reached() {
        let lim = Limits {
            velocity: 1e9,
            acceleration: 1e6,
            deceleration: 4e6,
        };
        let (time, t, _) = run(-5e4, lim);
        assert!((time - Trajectory::move_time(5e4, lim)).abs() < 0.002);
        assert_eq!(t.position, -5e4);
    }

    #[test]
    fn a_target_behind_the_motion_brakes_then_returns() {
        let lim = Limits {
            velocity: 1e5,
            acceleration: 1e6,
            deceleration: 1e6,
        };
        let mut t = Trajectory {
            position: 0.0,
            velocity: 1e5,
        };
        let mut min_v: f64 = 1e9;
        for _ in 0..20000 {
            if t.step_to(-1000.0, 0.0, lim, DT) {
                break;
            }
            min_v = min_v.min(t.velocity);
        }
        assert_eq!(t.position, -1000.0);
        assert!(min_v < 0.0, "it reversed");
    }

    #[test]
    fn velocity_ramp_uses_accel_up_and_decel_down() {
        let mut t = Trajectory::default();
        for _ in 0..1000 {
            t.step_velocity(1000.0, 2000.0, 4000.0, DT);
        }
        assert_eq!(t.velocity, 1000.0);
        let mut steps = 0;
        while !t.step_stop(4000.0, DT) {
            steps += 1;
        }
        assert!((steps as f64 * DT - 0.25).abs() < 0.002);
    }
}
