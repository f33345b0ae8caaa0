//! Profile velocity (pv, 6060h = 3): the target velocity 60FFh along the profile ramps,
//! the velocity set-point as the cycle's demand.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// Moves the velocity set-point towards `target` (increments/s), along the ramp
    /// `(acceleration, deceleration)` where one is given, and makes it the cycle's demand. The
    /// position set-point follows the actual position at the set-point's speed, so a quick
    /// stop brakes from there.
    pub(crate) fn command_velocity(&mut self, target: f64, ramp: Option<(f64, f64)>, dt: f64) {
        self.velocity_set = match ramp {
            Some((acc, dec)) => {
                let mut t = Trajectory {
                    position: 0.0,
                    velocity: self.velocity_set,
                };
                t.step_velocity(target, acc, dec, dt);
                t.velocity
            }
            None => target,
        };
        self.traj = Trajectory {
            position: self.actual_internal() as f64,
            velocity: self.velocity_set,
        };
        self.demand_position = self.traj.position;
        self.demand = Demand::Velocity {
            rpm: (self.velocity_set * RPM_PER_INC_S) as f32,
        };
    }

    pub(super) fn profile_velocity(&mut self, dt: f64) {
        let user = self
            .read(self.hot.target_velocity)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        // 6080h max_motor_speed caps the target where the drive has it (CiA 402 §6.5: an
        // optional object; without it no such cap).
        let user = self.fg.velocity_to_internal(user) as f64 * INC_S_PER_VEL;
        let mut target = match self.param(0x6080, 0) {
            Some(_) => {
                let max = self.value(0x6080, 0).max(0) as f64 * 4096.0 * INC_S_PER_VEL;
                user.clamp(-max, max)
            }
            None => user,
        };
        if self.halted {
            target = 0.0; // Halt: to zero with the profile deceleration, resumed when cleared.
        }
        let ramp = if self.halted {
            Some((self.accel(0x6084), self.accel(0x6084)))
        } else {
            let positive = self.velocity_set >= 0.0 && target >= 0.0;
            V::profile_velocity_ramp(self, positive)
        };
        self.command_velocity(target, ramp, dt);
        // Target reached: |v − target| < 606Dh velocity_window for 606Eh velocity_window_time
        // (CiA 402 profile velocity mode).
        let v_act = f64::from(self.plant_velocity_internal());
        let target_internal = target / INC_S_PER_VEL;
        let window = self
            .fg
            .velocity_magnitude_to_internal(self.value(0x606D, 0).max(0) as u32)
            as f64;
        let time = Duration::from_millis(self.value(0x606E, 0).max(0) as u64);
        if (v_act - target_internal).abs() < window {
            let since = *self.window_since.get_or_insert(self.now);
            self.target_reached = self.now.saturating_since(since) >= time;
        } else {
            self.window_since = None;
            self.target_reached = false;
        }
    }
}
