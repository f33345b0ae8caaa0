// ---- motion commands
//!
//! # Decisions
//!
//! - Direct-mode velocity ramp byte = 0 % uses the base value PNU 560 (a ramp of 0 would
//!   never reach the speed); a position move with 0 % velocity does not move (Tab. 5.17
//!   "0 = no velocity"). Final velocities (PNU 423, 548) are not used: every move ends at rest.
//! - Velocities are limited to PNU 502 (SDIR/RSB.VLIM while limited).
//! - **Comparators** (§6.7.4): every cycle those of the task — the last record started in
//!   record selection (PNU 430…440), PNU 585…595 in direct mode — are evaluated: position on
//!   the PZ actual position, velocity, signed force, time since the task start; window times
//!   PNU 432/435/438 (587/590/593). Result in PNU 312.
//! - **Record chaining** (§6.5.3): after each cycle the running record's RCB2 condition is
//!   checked (MC, or the PNU 312 bit of its comparator). When met, PNU 416 names the next
//!   record; [`Fhpp::record_chained`] updates byte 3, RSB.RC1 and the PNU 425 MC pulse; the
//!   next record starts after its own start delay PNU 426 (also for a START edge).
//! - **Software limits** PNU 501 (relative to AZ, both 0 = off, only while referenced): a
//!   position start with a target behind a limit raises 29h / 2Ah and does not move; a
//!   velocity task whose set-point reaches a limit raises 11h / 12h and locks that direction
//!   (13h / 14h on a start into it) until the set-point is back inside; jog stops at the limit
//!   by itself with its ramp (§6.3 step 4), without an error.
//! - **Force mode** (§6.6, CDIR.COM = 01 / RCB1 COM = 01; closed loop only, open loop
//!   refuses it with 24h): an outer loop on the position set-point — towards the force's sign
//!   at the velocity limit until the force nears the set-point, then a deviation that makes
//!   the position controller produce that current (see `Motion::Force`). MC once the force
//!   stays within ±PNU 552 for PNU 1023; stroke limit PNU 510 (record PNU 427) from the start
//!   position, then the Quick-Stop ramp and SDIR/RSB.XLIM. Actual force = current / PNU 555.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>> FhppDevice<S> {
    pub(super) fn start_task(&mut self, task: Task) {
        self.task = task;
        self.task_started = self.cycles;
        self.mc = false;
        self.window_since = None;
        self.standstill_target = None;
        self.still_since = None;
        self.standstill_error = false;
        self.stroke_reached = false;
        // Warnings of one event (28h, 3Fh, 37h, … as W) clear at the next start (App. D).
        self.warnings &= !self.once_warnings;
        self.warnings_logged &= !self.once_warnings;
        self.once_warnings = 0;
    }

    /// Software limits PNU 501 in raw SINC (lower, upper): relative to AZ, both 0 = off, and
    /// only with a valid reference (§6.2: homing disables them until it has finished).
    pub(super) fn soft_limits(&self) -> Option<(f64, f64)> {
        let p = &self.params;
        let reference = self.reference?;
        if p.soft_lower == 0 && p.soft_upper == 0 {
            return None;
        }
        let az = reference + p.az_offset as f64;
        Some((az + p.soft_lower as f64, az + p.soft_upper as f64))
    }

    /// Why a move from the set-point towards `target` may not start: 13h / 14h into a
    /// direction locked by a passed limit, 29h / 2Ah for a target behind a limit (App. D).
    pub(super) fn limit_refusal(&self, target: f64) -> Option<u8> {
        let here = self.traj.position;
        if target > here && self.locked_positive {
            return Some(diag::POSITIVE_DIRECTION_LOCKED);
        }
        if target < here && self.locked_negative {
            return Some(diag::NEGATIVE_DIRECTION_LOCKED);
        }
        let (lo, hi) = self.soft_limits()?;
        if target < lo {
            Some(diag::TARGET_BEHIND_NEGATIVE_LIMIT)
        } else if target > hi {
            Some(diag::TARGET_BEHIND_POSITIVE_LIMIT)
        } else {
            None
        }
    }

    /// A start the limits refuse: no motion, the task ends, the diagnostic is raised.
    pub(super) fn refuse_start(&mut self, code: u8) {
        self.start_task(Task::None);
        self.pending = None;
        self.chain = None;
        self.raise_once(code);
    }

    /// Software limits while moving (velocity tasks, jog): the set-point reaching a limit
    /// raises 11h / 12h once and locks that direction until the set-point is back inside.
    pub(super) fn watch_limits(&mut self) {
        let Some((lo, hi)) = self.soft_limits() else {
            self.locked_positive = false;
            self.locked_negative = false;
            return;
        };
        let x = self.traj.position;
        let v = self.traj.velocity;
        if x < hi {
            self.locked_positive = false;
        }
        if x > lo {
            self.locked_negative = false;
        }
        // Position targets were checked at the start and jog stops by itself: the error is
        // for a velocity task (or its braking) that runs into a limit.
        let raise = matches!(
            self.motion,
            Motion::Velocity { .. } | Motion::Braking { .. }
        );
        if x >= hi && v > 0.0 && !self.locked_positive {
            self.locked_positive = true;
            if raise {
                self.raise_once(diag::SOFTWARE_LIMIT_POSITIVE);
            }
        }
        if x <= lo && v < 0.0 && !self.locked_negative {
            self.locked_negative = true;
            if raise {
                self.raise_once(diag::SOFTWARE_LIMIT_NEGATIVE);
            }
        }
    }

    pub(super) fn start_position(
        &mut self,
        target: f64,
        velocity: f64,
        accel: f64,
        decel: f64,
        fe: f64,
    ) {
        if let Some(code) = self.limit_refusal(target) {
            self.refuse_start(code);
            return;
        }
        let velocity = self.clamp_velocity(velocity);
        let lim = Limits {
            velocity,
            acceleration: accel.max(1.0),
            deceleration: decel.max(1.0),
        };
        self.start_task(Task::Position { target });
        self.motion = Motion::Position { target, lim };
        self.pending = Some(Pending { target, lim });
        self.task_decel = lim.deceleration;
        self.fe_window = fe;
        self.fe_time_ms = self.params.fe_timeout_ms;
        self.fe_velocity = false;
        self.last_target = target;
    }

    pub(super) fn start_velocity(
        &mut self,
        target: f64,
        accel: f64,
        decel: f64,
        stroke: Option<f64>,
    ) {
        if target > 0.0 && self.locked_positive {
            self.refuse_start(diag::POSITIVE_DIRECTION_LOCKED);
            return;
        }
        if target < 0.0 && self.locked_negative {
            self.refuse_start(diag::NEGATIVE_DIRECTION_LOCKED);
            return;
        }
        let mag = self.clamp_velocity(libm::fabs(target));
        let target = if target < 0.0 { -mag } else { mag };
        self.start_task(Task::Velocity { target });
        self.motion = Motion::Velocity {
            target,
            accel: accel.max(1.0),
            decel: decel.max(1.0),
            start: self.traj.position,
            stroke,
        };
        self.pending = None;
        self.task_decel = decel.max(1.0);
        self.fe_window = self.params.velocity_fe_window;
        self.fe_time_ms = self.params.fe_timeout_ms;
        self.fe_velocity = true;
    }

    pub(super) fn brake(&mut self, decel: f64, resync: bool) {
        self.motion = Motion::Braking {
            decel: decel.max(1.0),
            resync,
        };
    }

    pub(super) fn resync(&mut self) {
        self.traj = Trajectory::at(self.raw_actual());
        self.fe_since = None;
        self.following_error = false;
    }

    pub(super) fn execute(&mut self, cmd: MotionCommand) {
        let p = self.params;
        if !matches!(
            cmd,
            MotionCommand::Record { .. }
                | MotionCommand::Continue
                | MotionCommand::Halt
                | MotionCommand::ManualBrake { .. }
        ) {
            self.chain = None;
        }
        match cmd {
            MotionCommand::Enable => {
                self.stage_on = true;
                self.resync();
                self.motion = Motion::Hold;
                self.task = Task::None;
                self.pending = None;
            }
            MotionCommand::Disable => {
                self.stage_on = false;
                self.motion = Motion::Hold;
                self.task = Task::None;
                self.pending = None;
                self.standstill_target = None;
            }
            MotionCommand::ManualBrake { .. } => {} // no holding brake fitted
            MotionCommand::Home => self.start_homing(),
            MotionCommand::MoveAbsolute {
                target, velocity, ..
            } => {
                let t = self.pz_to_raw(f64::from(target));
                self.start_position(
                    t,
                    f64::from(velocity),
                    p.direct_accel,
                    p.direct_decel,
                    p.direct_fe_window,
                );
            }
            MotionCommand::MoveRelative {
                distance,
                velocity,
                reference,
                ..
            } => {
                let base = match reference {
                    RelativeTo::ActualPosition => self.raw_actual(),
                    RelativeTo::LastSetpoint => self.last_target,
                };
                self.start_position(
                    base + f64::from(distance),
                    f64::from(velocity),
                    p.direct_accel,
                    p.direct_decel,
                    p.direct_fe_window,
                );
            }
            MotionCommand::Velocity {
                velocity,
                ramp,
                stroke_monitoring,
                ..
            } => {
                let ramp = if ramp == 0 {
                    p.base_acceleration
                } else {
                    f64::from(ramp)
                };
                let stroke = stroke_monitoring.then_some(p.stroke_velocity);
                self.start_velocity(f64::from(velocity), ramp, ramp, stroke);
            }
            MotionCommand::Force {
                setpoint,
                velocity_limit,
                stroke_monitoring,
                ..
            } => {
                let stroke = stroke_monitoring.then_some(p.force_stroke);
                self.start_force(
                    f64::from(setpoint),
                    f64::from(velocity_limit),
                    p.direct_accel,
                    stroke,
                );
            }
            MotionCommand::Record { number, mode } => self.start_record(number, mode),
            MotionCommand::Jog { positive } => {
                self.start_task(Task::None);
                self.pending = None;
                self.motion = Motion::Jog {
                    positive,
                    since: self.cycles,
                };
                self.task_decel = p.jog_accel;
                self.fe_window = p.jog_fe_window;
                self.fe_time_ms = p.jog_fe_time_ms;
                self.fe_velocity = false;
            }
            MotionCommand::Halt => {
                let position_task = matches!(self.task, Task::Position { .. });
                if !position_task {
                    self.task = Task::None;
                    self.pending = None;
                }
                self.brake(self.task_decel, false);
            }
            MotionCommand::Continue => {
                if let Some(pd) = self.pending {
                    self.start_task(Task::Position { target: pd.target });
                    self.motion = Motion::Position {
                        target: pd.target,
                        lim: pd.lim,
                    };
                }
            }
            MotionCommand::Clear => {
                self.pending = None;
                self.task = Task::None;
                if !matches!(self.motion, Motion::Braking { .. }) {
                    self.brake(self.task_decel, false);
                }
            }
            MotionCommand::Stop => {
                self.task = Task::None;
                self.pending = None;
                self.brake(self.task_decel, true);
            }
            MotionCommand::QuickStop => {
                self.task = Task::None;
                self.pending = None;
                self.brake(p.quick_stop, true);
            }
        }
    }

    /// A record start (START edge or a chain switch): after its start delay PNU 426 ("the
    /// time counts from the start command", Tab. B.61), at once without one. Decision: the
    /// delay of an MC chain (Tab. 6.9 "PNU 426 as the wait time after MC") is the following
    /// record's own PNU 426, so every record has one delay, however it is started.
    pub(super) fn start_record(&mut self, number: u8, mode: ControlMode) {
        let Some(r) = self.records.get(number).copied() else {
            self.raise_once(diag::RECORD_INVALID);
            return;
        };
        if r.start_delay_ms > 0 {
            // The axis goes on with what it does (an MC chain stands, a comparator chain
            // keeps the previous profile) until the delay has run out.
            self.start_task(Task::Delayed {
                number,
                mode,
                until: self.cycles + u64::from(r.start_delay_ms),
            });
            self.pending = None;
            self.chain = None;
            return;
        }
        self.begin_record(number, mode);
    }

    pub(super) fn begin_record(&mut self, number: u8, mode: ControlMode) {
        let Some(r) = self.records.get(number).copied() else {
            self.raise_once(diag::RECORD_INVALID);
            return;
        };
        let p = self.params;
        let accel = f64::from(r.acceleration.max(0));
        let decel = f64::from(r.deceleration.max(0));
        let accel = if accel > 0.0 { accel } else { p.direct_accel };
        let decel = if decel > 0.0 { decel } else { p.direct_decel };
        match mode {
            ControlMode::Position => {
                let target = if r.rcb1.contains(Rcb1::ABS) {
                    let base = if r.rcb1.contains(Rcb1::REL) {
                        self.raw_actual()
                    } else {
                        self.last_target
                    };
                    base + f64::from(r.target)
                } else {
                    self.pz_to_raw(f64::from(r.target))
                };
                self.start_position(
                    target,
                    f64::from(r.velocity.unsigned_abs()),
                    accel,
                    decel,
                    f64::from(r.max_deviation.max(0)),
                );
            }
            ControlMode::Velocity => {
                let stroke =
                    (!r.rcb1.contains(Rcb1::XLIM)).then_some(f64::from(r.stroke_limit.max(0)));
                self.start_velocity(f64::from(r.setpoint_velocity), accel, decel, stroke);
                self.fe_window = f64::from(r.max_deviation.max(0));
            }
            ControlMode::Force => {
                let stroke =
                    (!r.rcb1.contains(Rcb1::XLIM)).then_some(f64::from(r.stroke_limit.max(0)));
                self.start_force(
                    f64::from(r.setpoint_force),
                    f64::from(r.velocity.unsigned_abs()),
                    accel,
                    stroke,
                );
            }
        }
        self.chain = Some(Chain { record: number });
        self.comparator_record = Some(number);
    }

    /// Force task `target` ‰ of PNU 555 (the sign is the direction) with the velocity limit
    /// `vmax` SINC/s (§6.6 force mode). App. D 24h: force control needs the encoder, so open
    /// loop refuses it.
    pub(super) fn start_force(&mut self, target: f64, vmax: f64, accel: f64, stroke: Option<f64>) {
        if self.settings.mode == StepperMode::OpenLoop {
            self.task = Task::None;
            self.raise_once(diag::NOT_IN_OPEN_LOOP);
            return;
        }
        let vmax = self.clamp_velocity(vmax);
        self.start_task(Task::Force { target });
        self.motion = Motion::Force {
            target,
            vmax,
            accel: accel.max(1.0),
            start: self.traj.position,
            stroke,
        };
        self.pending = None;
        self.task_decel = accel.max(1.0);
        // Tab. B.59: the record's maximum deviation has "no function" for force records.
        self.fe_window = 0.0;
        self.fe_velocity = false;
    }

    /// The actual force in ‰ of PNU 555, positive when it pushes towards `dir` (the current
    /// amplitude with the sign of the torque set-point).
    pub(super) fn force_along(&self, dir: f64) -> f64 {
        let torque = self.stepper.torque_set() * self.params.polarity;
        let f = f64::from(self.actual_force());
        if torque * dir >= 0.0 {
            f
        } else {
            -f
        }
    }

    /// The comparators of the task (§6.7.4): in record selection those of the last record
    /// started, in direct mode PNU 585…595. A comparator is on while its value is inside
    /// [min, max] for its window time (min > max: never); the time comparator counts from the
    /// task start. Result: PNU 312 and the chaining conditions 20…23.
    pub(super) fn compare(&mut self) {
        let direct = self.fhpp.operating_mode()
            == crate::vendors::festo_cmmo_st::fhpp::OperatingMode::Direct;
        let set = if direct {
            Some(self.params.direct_comparators)
        } else {
            self.comparator_record
                .and_then(|n| self.records.get(n))
                .map(|r| r.comparators)
        };
        let Some(c) = set else {
            self.comparator_outputs = 0;
            self.comparator_since = [None; 3];
            return;
        };
        let now = self.cycles;
        // §6.7.4: the position comparator is absolute (PZ) even for relative records.
        let pz = sat_i32(self.to_pz(self.raw_actual()));
        let v = sat_i32(self.actual_velocity());
        let f = sat_i32(self.force_along(1.0)).clamp(i16::MIN.into(), i16::MAX.into()) as i16;
        let inside = [
            (c.position.contains(pz), c.position.window_time_ms),
            (c.velocity.contains(v), c.velocity.window_time_ms),
            (c.force.contains(f), c.force.window_time_ms),
        ];
        let mut out = 0;
        for ((bit, (inn, ms)), since) in [CMP_POSITION, CMP_VELOCITY, CMP_FORCE]
            .into_iter()
            .zip(inside)
            .zip(self.comparator_since.iter_mut())
        {
            if !inn {
                *since = None;
                continue;
            }
            let t0 = *since.get_or_insert(now);
            if now.saturating_sub(t0) >= u64::from(ms) {
                out |= bit;
            }
        }
        let t = now.saturating_sub(self.task_started);
        if (u64::from(c.time.min_ms)..=u64::from(c.time.max_ms)).contains(&t) {
            out |= CMP_TIME;
        }
        self.comparator_outputs = out;
    }

    /// RCB2 of the running record (§6.5.3 Tab. 6.9): when its switching condition is met,
    /// the record of PNU 416 follows (its own start delay first); PNU 425 pulses MC.
    pub(super) fn check_chain(&mut self) {
        let Some(chain) = self.chain else {
            return;
        };
        if !self.stage_on || matches!(self.task, Task::Delayed { .. }) {
            return;
        }
        let Some(r) = self.records.get(chain.record).copied() else {
            self.chain = None;
            return;
        };
        let out = self.comparator_outputs;
        let met = match r.chain_condition() {
            None | Some(ChainCondition::None) => false,
            Some(ChainCondition::MotionComplete) => self.mc,
            Some(ChainCondition::PositionComparator) => out & CMP_POSITION != 0,
            Some(ChainCondition::VelocityComparator) => out & CMP_VELOCITY != 0,
            Some(ChainCondition::ForceComparator) => out & CMP_FORCE != 0,
            Some(ChainCondition::TimeComparator) => out & CMP_TIME != 0,
        };
        if !met {
            return;
        }
        let next = r.following_record;
        let Some(mode) = self
            .records
            .get(next)
            .filter(|n| n.is_valid())
            .and_then(|n| n.control_mode())
        else {
            // PNU 416 names no valid record (0 = homing is not a chain target): 3Fh.
            self.chain = None;
            self.raise_once(diag::RECORD_INVALID);
            return;
        };
        if self
            .fhpp
            .record_chained(next, mode, r.mc_on_continuation == 1)
        {
            self.start_record(next, mode);
        } else {
            // The state machine has left the task (halt, stop, fault): the chain ends.
            self.chain = None;
        }
    }

    /// TEACH falling edge: the actual position into the target of PNU 520 (§6.4).
    pub(super) fn teach(&mut self, record: u8, position: i32) {
        let target = get_i64(&self.od, 520, 1);
        let raw = self.pz_to_raw(f64::from(position));
        let (pnu, sub, value) = match target {
            1 => {
                // App. D 40h: the record must be an absolute position record.
                let absolute_position = self.records.get(record).is_some_and(|r| {
                    r.control_mode() == Some(ControlMode::Position) && !r.rcb1.contains(Rcb1::ABS)
                });
                if !absolute_position {
                    self.raise_once(diag::TEACH_FAILED);
                    return;
                }
                (404, record, i64::from(position))
            }
            // AZ := here: AZ = REF + PNU 1010.
            2 => (1010, 1, (raw - self.reference.unwrap_or(0.0)) as i64),
            // PZ := here: PZ = AZ + PNU 500.
            3 => {
                let az = self.reference.unwrap_or(0.0) + self.params.az_offset as f64;
                (500, 1, (raw - az) as i64)
            }
            4 | 5 => {
                let az = self.reference.unwrap_or(0.0) + self.params.az_offset as f64;
                (501, (target - 3) as u8, (raw - az) as i64)
            }
            6 => (430, record, i64::from(position)),
            7 => (431, record, i64::from(position)),
            _ => return,
        };
        let _ = self.od.set_value(pnu_index(pnu), sub, Value::Signed(value));
        self.params_dirty = true;
        if is_record_pnu(pnu_index(pnu)) {
            self.records_dirty |= record_bit(sub);
        }
        // A successful teach ends a 40h warning.
        self.clear_warning(diag::TEACH_FAILED);
    }
}
