// ---- motion and plant
//!
//! # Decisions
//!
//! - **Decelerations**: Halt and Stop use the running task's deceleration (record PNU 408,
//!   direct PNU 542, jog PNU 532, homing PNU 1013), QuickStop PNU 1029. When a Stop or
//!   QuickStop has brought the set-point to rest the position controller takes the actual
//!   position as its set-point (a stopped drive holds where it stands), which also ends a
//!   following error left by lost steps, so the fault can be acknowledged.
//! - **MC** (fhpp §5.6): position tasks: the set-point has arrived and the actual position
//!   stays within ±PNU 1022 for PNU 1023 ms; velocity tasks: the ramp is done and the actual
//!   velocity stays within ±PNU 561 for PNU 1023 ms; homing: done; no task: not moving.
//! - **MOV** (SPOS.MOV, "speed ≥ limit value", no PNU names the limit): the set-point is
//!   moving or |actual velocity| > PNU 561 (velocity target window).
//! - **Following error**: |set-point − actual| > window for longer than the timeout: windows
//!   PNU 424 (record), 549 (direct position), 538 (jog, timeout 539), 568 (velocity tasks, on
//!   the velocity difference), timeout PNU 1045. Diagnostic 2Fh with the class and reaction of
//!   PNU 246 / 242 (default F, reaction E); as W it clears back inside the window, as I it is
//!   a memory entry per occurrence.
//! - **Standstill** after MC of a position task: outside ±PNU 1042 around the target for
//!   PNU 1043 ms → SPOS.STILL and warning 37h (PNU 1042 = 0: off).

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>> FhppDevice<S> {
    pub(super) fn advance(&mut self, dt: f64) {
        let p = self.params;
        if !self.stage_on {
            self.stepper.step(dt, StepperDemand::Off);
            self.traj = Trajectory::at(self.raw_actual());
            self.following_error = false;
            self.fe_since = None;
            return;
        }
        match self.motion {
            Motion::Hold => {}
            Motion::Position { target, lim } => {
                if self.traj.step_to(target, 0.0, lim, dt) {
                    self.motion = Motion::Hold;
                }
            }
            Motion::Velocity {
                target,
                accel,
                decel,
                start,
                stroke,
            } => {
                self.traj.step_velocity(target, accel, decel, dt);
                if let Some(limit) = stroke {
                    if libm::fabs(self.traj.position - start) >= limit {
                        // Stroke limit: Quick-Stop ramp, then hold position-controlled.
                        self.stroke_reached = true;
                        self.task = Task::None;
                        self.brake(p.quick_stop, false);
                    }
                }
            }
            Motion::Force {
                target,
                vmax,
                start,
                stroke,
                ..
            } => {
                let dir = if target < 0.0 { -1.0 } else { 1.0 };
                let err = libm::fabs(target) - self.force_along(dir);
                // The position controller integrates a standing deviation into current: a
                // deviation proportional to the force error lets it settle at the target
                // (0.02 rev per 1000 ‰ of error), the set-point moving at most at `vmax`.
                let inc_rev = f64::from(self.stepper.data().encoder_increments_per_rev.max(1));
                let sinc_per_rev = inc_rev / p.einc_per_sinc.max(1e-9);
                let desired = self.raw_actual() + dir * err / 1000.0 * 0.02 * sinc_per_rev;
                // Far from the force (below target − 4 windows: no contact yet) the set-point
                // travels at `vmax`; near it, first order towards `desired` (50 cycles, slow
                // enough for the stiffness of the position controller).
                let w = p.force_window.max(5.0);
                let approach = dir * vmax * ((err - 2.0 * w) / (2.0 * w)).clamp(0.0, 1.0);
                let settle = (desired - self.traj.position) * 0.02;
                let step = (approach * dt + settle).clamp(-vmax * dt, vmax * dt);
                self.traj.position += step;
                self.traj.velocity = if dt > 0.0 { step / dt } else { 0.0 };
                if let Some(limit) = stroke {
                    if libm::fabs(self.traj.position - start) >= limit {
                        // PNU 510 / 427: Quick-Stop ramp, then hold position-controlled.
                        self.stroke_reached = true;
                        self.task = Task::None;
                        self.brake(p.quick_stop, false);
                    }
                }
            }
            Motion::Jog { positive, since } => {
                let slow = self.cycles.saturating_sub(since) < p.jog_time_ms;
                let v = if slow { p.jog_slow } else { p.jog_fast };
                let v = self.clamp_velocity(v);
                let v = if positive { v } else { -v };
                // §6.3 step 4: referenced, jog stops at the software limit by itself (its
                // ramp planned to end there); it does not leave the limit.
                let stop_at = self
                    .soft_limits()
                    .map(|(lo, hi)| if positive { hi } else { lo });
                let room = stop_at.map(|end| (end - self.traj.position) * v.signum());
                match (stop_at, room) {
                    (_, Some(r)) if r < 0.0 => {
                        // Already beyond the limit: no further in this direction.
                        self.traj.step_stop(p.jog_accel, dt);
                    }
                    (Some(end), Some(r)) if r <= stop_room(self.traj.velocity, p.jog_accel, dt) => {
                        let lim = Limits {
                            velocity: libm::fabs(v).max(libm::fabs(self.traj.velocity)),
                            acceleration: p.jog_accel,
                            deceleration: p.jog_accel,
                        };
                        self.traj.step_to(end, 0.0, lim, dt);
                    }
                    _ => self.traj.step_velocity(v, p.jog_accel, p.jog_accel, dt),
                }
            }
            Motion::Braking { decel, resync } => {
                if self.traj.step_stop(decel, dt) {
                    self.motion = Motion::Hold;
                    if resync {
                        self.resync();
                    }
                }
            }
            Motion::Homing(h) => self.homing_cycle(h, dt),
        }
        // PNU 1015: homing limits the current to its share of PNU 555 (closed loop).
        let homing_limit =
            matches!(self.motion, Motion::Homing(_)).then(|| self.homing_current_limit());
        self.stepper.set_current_limit(homing_limit);
        self.watch_limits();
        let k = p.einc_per_sinc * p.polarity;
        let increments = crate::rounding::round(self.traj.position * k) as i64;
        let inc_rev = f64::from(self.stepper.data().encoder_increments_per_rev.max(1));
        // No speed feed-forward under force control: the force comes from the deviation.
        let ff = if matches!(self.motion, Motion::Force { .. }) {
            0.0
        } else {
            self.traj.velocity
        };
        let rpm = ff * k / inc_rev * 60.0;
        self.stepper.step(
            dt,
            StepperDemand::PositionIncrements {
                increments,
                velocity_ff_rpm: rpm as f32,
            },
        );
        self.monitor();
    }

    /// MC window, following error, standstill (§6.7).
    pub(super) fn monitor(&mut self) {
        let p = self.params;
        let now = self.cycles;
        let actual = self.raw_actual();
        let velocity = self.actual_velocity();
        let held = |since: &mut Option<u64>, inside: bool, ms: u64| -> bool {
            if !inside {
                *since = None;
                return false;
            }
            let t0 = *since.get_or_insert(now);
            now.saturating_sub(t0) >= ms
        };
        match self.task {
            Task::Position { target } if !self.mc => {
                let arrived = self.motion == Motion::Hold && self.traj.position == target;
                let inside = arrived && libm::fabs(actual - target) <= p.target_window;
                if held(&mut self.window_since, inside, p.target_window_ms) {
                    self.mc = true;
                    self.standstill_target = Some(target);
                }
            }
            Task::Force { target } if !self.mc => {
                let dir = if target < 0.0 { -1.0 } else { 1.0 };
                let inside =
                    libm::fabs(self.force_along(dir) - libm::fabs(target)) <= p.force_window;
                if held(&mut self.window_since, inside, p.target_window_ms) {
                    self.mc = true;
                }
            }
            Task::Velocity { target } if !self.mc => {
                let ramped = self.traj.velocity == target;
                let inside = ramped && libm::fabs(velocity - target) <= p.velocity_target_window;
                if held(&mut self.window_since, inside, p.target_window_ms) {
                    self.mc = true;
                }
            }
            _ => {}
        }
        // Following error against the theoretical trajectory.
        let deviation = if self.fe_velocity {
            libm::fabs(self.traj.velocity - velocity)
        } else {
            libm::fabs(self.traj.position - actual)
        };
        let over = self.fe_window > 0.0 && deviation > self.fe_window;
        let fe_time = self.fe_time_ms;
        let fe_was = self.following_error;
        self.following_error = held(&mut self.fe_since, over, fe_time);
        // §6.7.2: as a warning it clears once the error is back inside the window; as an
        // information it only goes to the memory (once per occurrence).
        let fe_class = self.diagnostic_class(diag::FOLLOWING_ERROR);
        match fe_class {
            Some(Class::Warning) if self.following_error => {
                self.warnings |= 1u128 << diag::FOLLOWING_ERROR;
            }
            Some(Class::Information) if self.following_error && !fe_was => {
                self.raise_once(diag::FOLLOWING_ERROR);
            }
            _ => self.clear_warning(diag::FOLLOWING_ERROR),
        }
        // Standstill monitoring after MC of a position task.
        if let Some(target) = self.standstill_target {
            let outside =
                p.standstill_window > 0.0 && libm::fabs(actual - target) > p.standstill_window;
            let mut since = self.still_since;
            if held(&mut since, outside, p.standstill_ms) {
                if !self.standstill_error {
                    // 37h is W or I (App. D): a warning until back in the window.
                    self.raise_once(diag::STANDSTILL);
                }
                self.standstill_error = true;
            } else if !outside {
                self.standstill_error = false;
                self.clear_warning(diag::STANDSTILL);
            }
            self.still_since = since;
        }
    }

    /// Actual values into their PNUs (300, 301, 310, 320, 321, 1040, 1041, 1059, 205, 230,
    /// 220, 221, 400:2).
    pub(super) fn publish(&mut self) {
        let s = self.status;
        let setpoint = sat_i32(self.to_pz(self.traj.position));
        let fe = sat_i32(self.traj.position - self.raw_actual());
        let setpoint_v = sat_i32(self.traj.velocity);
        let inp = self.inputs;
        let out = self.outputs.to_bytes();
        let fault = self.fhpp.fault();
        let ack = match fault {
            None => 0xFF,
            Some(f) => match f.ack {
                Ack::NotAckable => 0,
                Ack::AfterCause => 1,
                Ack::Immediately => 2,
            },
        };
        let record = inp[2];
        let last_target = sat_i32(self.to_pz(self.last_target));
        let current = self.stepper.current_ma();
        // PNU 301 force values (‰ of PNU 555): the set-point of a force task, else 0.
        let force_set = match self.task {
            Task::Force { target } => target,
            _ => 0.0,
        };
        let dir = if force_set < 0.0 { -1.0 } else { 1.0 };
        let force_act = dir * self.force_along(dir);
        let clamp16 = |v: f64| i64::from(sat_i32(v).clamp(i16::MIN.into(), i16::MAX.into()));
        let force = [
            clamp16(force_act),
            clamp16(force_set),
            clamp16(force_set - force_act),
        ];
        let od = &mut self.od;
        let cache = &mut self.published;
        cache.values.begin(od.stores());
        let mut n = 0;
        let mut set = |pnu: u16, sub: u8, v: Value| {
            cache.set(od, n, pnu_index(pnu), sub, v);
            n += 1;
        };
        set(300, 1, Value::Signed(s.actual_position.into()));
        set(300, 2, Value::Signed(setpoint.into()));
        set(300, 3, Value::Signed(fe.into()));
        set(310, 1, Value::Signed(s.actual_velocity.into()));
        set(310, 2, Value::Signed(setpoint_v.into()));
        set(
            310,
            3,
            Value::Signed(i64::from(setpoint_v) - i64::from(s.actual_velocity)),
        );
        for (sub, v) in (1u8..).zip(force) {
            set(301, sub, Value::Signed(v));
        }
        set(1040, 1, Value::Signed(last_target.into()));
        set(1041, 1, Value::Signed(s.actual_position.into()));
        set(1059, 1, Value::Signed(current.into()));
        set(
            320,
            1,
            Value::Unsigned(u32::from_be_bytes([inp[0], inp[1], inp[2], inp[3]]).into()),
        );
        set(
            320,
            2,
            Value::Signed(i32::from_be_bytes([inp[4], inp[5], inp[6], inp[7]]).into()),
        );
        set(
            321,
            1,
            Value::Unsigned(u32::from_be_bytes([out[0], out[1], out[2], out[3]]).into()),
        );
        set(
            321,
            2,
            Value::Signed(i32::from_be_bytes([out[4], out[5], out[6], out[7]]).into()),
        );
        set(
            205,
            1,
            Value::Unsigned(fault.map_or(0xFFFF, |f| u64::from(f.code))),
        );
        set(230, 1, Value::Unsigned(ack));
        set(400, 2, Value::Unsigned(record.into()));
        set(312, 1, Value::Unsigned(self.comparator_outputs.into()));
        let faults = self.faults_present;
        for (i, sub) in (1u8..=4).enumerate() {
            let shift = 32 * i as u32;
            set(220, sub, Value::Unsigned(((faults >> shift) as u32).into()));
            set(
                221,
                sub,
                Value::Unsigned(((self.warnings >> shift) as u32).into()),
            );
        }
        self.published.values.end(self.od.stores());
    }
}
