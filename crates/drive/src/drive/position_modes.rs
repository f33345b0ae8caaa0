//! The position modes: profile position (pp), cyclic synchronous position (csp) and
//! interpolated position (ip), and holding a position.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// No mode that moves: the set-point brakes with 6084h and stands.
    pub(crate) fn hold(&mut self, dt: f64) {
        let decel = self.accel(0x6084);
        self.traj.step_stop(decel, dt);
        self.position_demand(self.traj.velocity);
    }

    pub(crate) fn profile_position(&mut self, cw: Controlword, dt: f64) {
        let bit4 = cw.contains(Controlword::NEW_SET_POINT)
            || self.cw_rising.contains(Controlword::NEW_SET_POINT);
        let demand = self.traj.position;
        let fg = self.fg;
        let max_speed = self.max_motor_speed();
        let target_limits = self.personality.capabilities.pp_target_limits;
        let abrupt_zero = self.personality.capabilities.zero_ramp_is_abrupt;
        // Nanotec §4.1: range-limit wrap, software limits and relative overflow checked before
        // the set-point is taken; a refused one becomes a job that stays where it is. Only on
        // bit 4's rising edge: `update` takes a set-point (and `target_taken` its check) then
        // only, and the check reads nothing the cycle changes before.
        let checked = (target_limits && self.setpoints.rising(bit4)).then(|| self.check_target(cw));
        let get = |i: u16| self.cycle_value(i, 0);
        // Read and convert the set-point only on bit 4's rising edge, the only time
        // `update` takes it (not in every cycle bit 4 is held).
        let req = self.setpoints.rising(bit4).then(|| {
            let user = get(0x607A).clamp(i32::MIN as i64, i32::MAX as i64) as i32;
            let (user, relative) = match checked {
                Some(Ok(absolute)) => (absolute, false),
                Some(Err(_)) => (0, true),
                None => (user, cw.contains(Controlword::RELATIVE)),
            };
            let target = fg.position_to_internal(user) as f64;
            let vel = |i| {
                fg.velocity_magnitude_to_internal(get(i).clamp(0, u32::MAX as i64) as u32) as f64
                    * INC_S_PER_VEL
            };
            let acc = |i| match fg.acceleration_to_internal(get(i).clamp(0, u32::MAX as i64) as u32)
            {
                0 if abrupt_zero => ABRUPT_STOP,
                a => a as f64 * INC_S2_PER_ACC,
            };
            Request {
                target,
                relative,
                immediately: cw.contains(Controlword::CHANGE_SET_IMMEDIATELY),
                job: Job {
                    target,
                    velocity: vel(0x6081).min(max_speed),
                    // Nanotec §4.9, §4.2: 6082h is the start / stop speed of the ramp, not an
                    // end velocity; bit 9 decides whether a queued job follows at speed.
                    end_velocity: if target_limits { 0.0 } else { vel(0x6082) },
                    acceleration: acc(0x6083),
                    deceleration: acc(0x6084),
                },
            }
        });
        let request = move || {
            req.unwrap_or(Request {
                target: demand,
                relative: false,
                immediately: false,
                job: Job {
                    target: demand,
                    velocity: 0.0,
                    end_velocity: 0.0,
                    acceleration: 1.0,
                    deceleration: 1.0,
                },
            })
        };
        // While halted new set-points are still acknowledged but not run (CMMP-AS §6.1.3).
        let accepted = self.setpoints.update(bit4, demand, request);
        if let (true, Some(result)) = (accepted, checked) {
            self.target_taken(result, cw);
        }
        if accepted {
            self.target_reached = false;
            self.window_since = None;
            // 6086h = 2: jerk-free, the acceleration ramps over the window (a quarter of the
            // time to profile velocity, at most the buffer).
            let jerk_free = self.cycle_value(0x6086, 0) == 2;
            let window = match (jerk_free, self.setpoints.active) {
                (true, Some(job)) if self.traj.velocity == 0.0 => {
                    let t_acc = job.velocity / job.acceleration.max(1.0);
                    let dt = self.cycle.as_secs_f64() * f64::from(self.logic_every);
                    libm::round(t_acc * 0.5 / dt) as usize
                }
                _ => self.smoother.window(),
            };
            if window != self.smoother.window() && self.smoother.settled(self.traj.position) {
                self.smoother.reset(self.demand_position, window);
            }
        }
        if self.halted {
            // Halt: brake with the profile deceleration; the job is dropped, and target
            // reached is set once standing (CMMP-AS Tab. 6.5).
            let decel = self.accel(0x6084);
            let stopped = self.traj.step_stop(decel, dt);
            self.setpoints.abort();
            self.position_demand(self.traj.velocity);
            if stopped {
                self.target_reached = true;
            }
            return;
        }
        match self.setpoints.active {
            Some(job) => {
                let lim = Limits {
                    velocity: job.velocity.max(1.0),
                    acceleration: job.acceleration.max(1.0),
                    deceleration: job.deceleration.max(1.0),
                };
                let end = self.setpoints.end_velocity();
                if self.traj.step_to(job.target, end, lim, dt) {
                    self.setpoints.finished();
                }
                self.position_demand(self.traj.velocity);
            }
            None => {
                self.position_demand(0.0);
                // Target reached: generator done (smoothing included) and the actual position
                // inside the window for the window time (6067h, 6068h).
                let done = self.smoother.settled(self.traj.position);
                if let Some(target) = self.setpoints.last_target.filter(|_| done) {
                    let window = self.fg.position_magnitude_to_internal(
                        self.cycle_value(0x6067, 0).clamp(0, u32::MAX as i64) as u32,
                    );
                    let inside =
                        (self.actual_internal() - libm::round(target) as i64).abs() <= window;
                    let time = Duration::from_millis(self.cycle_value(0x6068, 0).max(0) as u64);
                    if inside {
                        let since = *self.window_since.get_or_insert(self.now);
                        if self.now.saturating_since(since) >= time {
                            self.target_reached = true;
                        }
                    } else {
                        self.window_since = None;
                        self.target_reached = false;
                    }
                }
            }
        }
    }

    /// CSP (CiA 402 §13): the master sends a position every cycle; it is the set-point as it
    /// stands, with the speed between two set-points as feed-forward. The CMMP-AS runs the
    /// interpolator on the frame cycle (CMMP-AS §4: "the EtherCAT cycle equals the
    /// interpolator cycle"), so no further interpolation happens here.
    pub(super) fn cyclic_synchronous_position(&mut self, dt: f64) {
        let user = self
            .value(0x607A, 0)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        let target = self.fg.position_to_internal(user) as f64;
        if target != self.traj.position {
            // The feed-forward is the speed between the last two set-points, over the time
            // they really came apart (the master's cycle, not ours).
            let elapsed = self
                .csp_changed_at
                .map(|t| self.now.saturating_since(t).as_secs_f64())
                .unwrap_or(dt)
                .max(dt);
            self.traj.velocity = (target - self.traj.position) / elapsed;
            self.traj.position = target;
            self.csp_changed_at = Some(self.now);
        } else if self
            .csp_changed_at
            .is_none_or(|t| self.now.saturating_since(t).as_secs_f64() > 4.0 * dt.max(0.001))
        {
            // Set-points stopped coming: standstill at the last one.
            self.traj.velocity = 0.0;
        }
        let v = self.traj.velocity;
        self.position_demand(v);
        self.target_reached = false;
    }

    /// Interpolated position (CMMP-AS §7.4): with enable_ip_mode (bit 4) on the SYNC grid
    /// the drive takes one set-point of 60C1h:01 per SYNC and moves linearly between them;
    /// without, it holds.
    pub(super) fn interpolated_position(&mut self, cw: Controlword, dt: f64) {
        let enable = cw.contains(Controlword::ENABLE_IP_MODE);
        if enable && !self.ip.is_active() {
            if self.ip.is_synchronised() {
                // Nanotec ch. 7: 60C1h:01 is the target 607Ah shares; what it holds is the
                // first set-point (the manual's warning: write the actual position first).
                let pending = self.personality.capabilities.ip_follows_sync.then(|| {
                    let user = self
                        .value(0x60C1, 1)
                        .clamp(i32::MIN as i64, i32::MAX as i64);
                    self.fg.position_to_internal(user as i32) as f64
                });
                self.ip.activate_with(self.traj.position, self.now, pending);
            } else if self.cw_rising.contains(Controlword::ENABLE_IP_MODE) {
                // CMMP-AS 34-0: activation without synchronisation.
                self.raise_fault(Fault::NoFieldbusSync);
                return;
            }
        } else if !enable && self.ip.is_active() {
            self.ip.deactivate();
        }
        if self.ip.is_engaged() {
            let (position, velocity) = self.ip.demand(self.now);
            self.traj.position = position;
            self.traj.velocity = velocity;
            self.position_demand(velocity);
        } else {
            let decel = self.accel(0x6084);
            self.traj.step_stop(decel, dt);
            self.position_demand(self.traj.velocity);
        }
        self.target_reached = false;
    }
}
