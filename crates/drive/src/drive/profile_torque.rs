//! Profile torque (tq, 6060h = 4): the target torque 6071h along the torque slope.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    pub(super) fn profile_torque(&mut self, dt: f64) {
        let max = self.value(0x6072, 0).max(0) as f64;
        let mut target = (self.read(self.hot.target_torque) as f64).clamp(-max, max);
        if self.halted {
            target = 0.0;
        }
        // 6087h torque_slope: ‰ of rated torque per second (CiA 402 profile torque mode).
        let slope = (self.value(0x6087, 0).max(0) as f64) * dt;
        let d = target - self.torque_set;
        self.torque_set += d.clamp(-slope, slope);
        self.target_reached = self.torque_set == target;
        self.traj = Trajectory {
            position: self.actual_internal() as f64,
            velocity: f64::from(self.plant_velocity_rpm()) / RPM_PER_INC_S,
        };
        self.demand_position = self.traj.position;
        let current = self
            .axis
            .params()
            .current_for_torque_permille(self.torque_set);
        self.demand = Demand::Torque {
            current_a: current as f32,
        };
    }
}
