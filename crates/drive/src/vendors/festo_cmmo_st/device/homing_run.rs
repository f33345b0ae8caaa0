// ---- homing (§6.2)
//!
//! # Decisions
//!
//! - **Homing** (§6.2, PNU 1010…1017; the methods as data in [`crate::vendors::festo_cmmo_st::homing`], the end
//!   stops, reference switch and index pulse in [`crate::vendors::festo_cmmo_st::axis_mechanics`], set through
//!   [`FhppSettings::mechanics`]): HOM voids the old reference (SPOS.REF = 0, software
//!   limits off) and the method of PNU 1011 runs under the current limit PNU 1015 (‰ of
//!   PNU 555) with the ramps of PNU 1013 and no following-error monitoring:
//!   −35 REF := actual position, no motion; 33 / 34 at the search velocity PNU 1012:1 to the
//!   next index pulse (REF = its latched encoder count; none within 1.05 revolutions or a
//!   stop first: 23h); −17 / −18 at PNU 1012:1 into the stop until the block detection
//!   (current at the PNU 1015 limit and actual velocity < PNU 1016, both for PNU 1017 ms)
//!   takes the actual position as REF; 23 / 27 (CiA 402 numbering, see
//!   [`crate::vendors::festo_cmmo_st::homing::METHODS`]) at PNU 1012:1 onto the switch, back off it at the crawl
//!   velocity PNU 1012:3 to its edge (23: the negative edge, 27: the positive one), REF = the
//!   edge in open loop, the next index pulse behind it in closed loop (closer than 5 % of a
//!   revolution to the edge: 2Eh); a stop before the switch is 22h (closed loop), an
//!   open-loop search longer than [`FhppSettings::homing_timeout`] 3Ah. Tab. 6.2 refusals:
//!   3Bh (unknown number, fixed stop in open loop, switch method without a switch), 24h
//!   (index methods in open loop). Every homing error goes through the one fault path
//!   (`raise_once`, acknowledgeable at once; decision for 23h, whose App. D type is
//!   "software reset": the twin has no software reset and the cause was this run).
//!   Decision on step 3 of §6.2.1 ("optionally travel the AZ offset"): every searching method
//!   travels to AZ = REF + PNU 1010 at the drive velocity PNU 1012:2 (PNU 1015: "the stop is
//!   taken as REF and the drive travels to the axis zero point"), and the run completes (MC,
//!   SPOS.REF) once the axis is inside ±PNU 1022 of AZ for PNU 1023 ms; −35 does not move
//!   (CiA 402 35/37 do not), so the actual position becomes −(PNU 1010 + PNU 500) (§6.2.1
//!   step 2 "current position = 0 − offset"). With PNU 1010 = 0 a fixed-stop run ends at the
//!   stop: §6.2.1 asks for at least 1 mm of back-off through PNU 1010 (or an index method).

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>> FhppDevice<S> {
    /// CPOS.HOM (or record 0): the method of PNU 1011 (Tab. 6.2, [`homing::select`]). The
    /// old reference is void from the start (SPOS.REF = 0, software limits off, §6.2.2) until
    /// the run completes.
    pub(super) fn start_homing(&mut self) {
        let p = self.params;
        self.start_task(Task::Homing { done: false });
        self.pending = None;
        self.task_decel = p.homing_accel;
        let method = match homing::select(
            p.homing_method,
            self.settings.mode,
            self.settings.mechanics.has_switch() || self.reference_forced.is_some(),
        ) {
            Ok(m) => m,
            Err(code) => {
                self.task = Task::None;
                self.raise_once(code);
                return;
            }
        };
        self.reference = None;
        if method.target == Target::CurrentPosition {
            // −35 current position: REF = here, the task completes at the next cycle.
            // Decision: no travel to AZ (CiA 402 35/37 do not move); the actual position
            // becomes −(PNU 1010 + PNU 500) (§6.2.1 step 2 "current position = 0 − offset").
            self.reference = Some(self.raw_actual());
            self.traj.velocity = 0.0;
            self.motion = Motion::Hold;
            self.task = Task::Homing { done: true };
            return;
        }
        // Decision: no following-error monitoring while homing (the search runs into a stop
        // on purpose, under the PNU 1015 current limit).
        self.fe_window = 0.0;
        self.fe_since = None;
        self.following_error = false;
        let angle = self.stepper.angle();
        self.motion = Motion::Homing(Homing {
            method,
            phase: HomingPhase::Search,
            dir: f64::from(method.direction),
            angle,
            phase_start: angle,
            started: self.cycles,
            stall_since: None,
        });
    }

    /// Shaft angle (rad) of an index pulse → raw SINC, through the encoder count latched
    /// there (the index sits on a count boundary: rounded, not floored, against the binary
    /// fraction of the angle).
    pub(super) fn angle_to_raw(&self, angle: f64) -> f64 {
        let k = self.params.einc_per_sinc;
        if k <= 0.0 {
            return 0.0;
        }
        let inc_rev = f64::from(self.stepper.data().encoder_increments_per_rev.max(1));
        libm::round(angle / core::f64::consts::TAU * inc_rev) / k * self.params.polarity
    }

    /// The PNU 1015 current limit of a homing run, A (‰ of PNU 555, at most the motor's).
    pub(super) fn homing_current_limit(&self) -> f64 {
        let p = &self.params;
        (p.homing_torque * p.base_force_ma / 1e6).min(self.stepper.data().max_current)
    }

    /// Block detection (PNU 1015…1017, Tab. B.131: "if this torque is reached for the time
    /// of PNU 1017 the stop is taken as REF"): the current at the PNU 1015 limit, pushing in
    /// the search direction, while the actual velocity stays below PNU 1016, for PNU 1017 ms.
    /// Closed loop only (it needs the encoder and the current control).
    pub(super) fn stalled(&self, h: &mut Homing) -> bool {
        let p = &self.params;
        let limit = self.homing_current_limit();
        let pushing = self.stepper.torque_set() * p.polarity * h.dir > 0.0;
        let pressing = limit > 0.0 && pushing && self.stepper.current_a() >= 0.95 * limit;
        let standing = libm::fabs(self.actual_velocity()) < p.block_velocity.max(1.0);
        if self.settings.mode != StepperMode::ClosedLoop || !(standing && pressing) {
            h.stall_since = None;
            return false;
        }
        let t0 = *h.stall_since.get_or_insert(self.cycles);
        self.cycles.saturating_sub(t0) >= p.block_ms
    }

    /// The run ends without a reference: brake at PNU 1013, hold where the axis stands,
    /// raise `code` (its reaction comes from PNU 242 as for every error).
    pub(super) fn homing_failed(&mut self, code: u8) {
        self.task = Task::None;
        self.fe_window = self.params.direct_fe_window;
        self.brake(self.params.homing_accel, true);
        self.raise_once(code);
    }

    /// REF found at `reference` raw SINC: on to AZ = REF + PNU 1010 (§6.2.1 step 3; PNU 1015
    /// "the stop is taken as REF and the drive travels to the axis zero point").
    pub(super) fn homing_found(&mut self, h: &mut Homing, reference: f64, at_stop: bool) {
        if at_stop {
            // The set-point ran ahead into the stop: it restarts at the actual position.
            self.resync();
        }
        h.phase = HomingPhase::ToZero {
            target: reference + self.params.az_offset as f64,
            reference,
        };
    }

    /// One cycle of a homing run: the inputs of the last plant step (switch, index pulse,
    /// block detection), then the set-point of the phase.
    pub(super) fn homing_cycle(&mut self, mut h: Homing, dt: f64) {
        let p = self.params;
        let mech = self.settings.mechanics;
        let angle = self.stepper.angle();
        let shaft_dir = h.dir * p.polarity;
        let moved_on = (angle - h.angle) * shaft_dir > 0.0;
        let index = mech.index_crossed(h.angle, angle).filter(|_| moved_on);
        let travelled = libm::fabs(angle - h.phase_start) / core::f64::consts::TAU;
        let closed = self.settings.mode == StepperMode::ClosedLoop;
        let timed_out = !closed
            && self.cycles.saturating_sub(h.started)
                > self.settings.homing_timeout.as_millis() as u64;
        let stalled = self.stalled(&mut h);
        h.angle = angle;
        let mut failed = None;
        match (h.method.target, h.phase) {
            (_, HomingPhase::ToZero { target, reference }) => {
                let lim = Limits {
                    velocity: self.clamp_velocity(p.homing_drive.max(1.0)),
                    acceleration: p.homing_accel,
                    deceleration: p.homing_accel,
                };
                let arrived = self.traj.step_to(target, 0.0, lim, dt);
                // Done as a position task is (§6.7 MC): inside ±PNU 1022 for PNU 1023 ms.
                let inside = arrived && libm::fabs(self.raw_actual() - target) <= p.target_window;
                let now = self.cycles;
                let since = if inside {
                    *self.window_since.get_or_insert(now)
                } else {
                    self.window_since = None;
                    now
                };
                if inside && now.saturating_sub(since) >= p.target_window_ms {
                    self.reference = Some(reference);
                    self.motion = Motion::Hold;
                    self.task = Task::Homing { done: true };
                    self.fe_window = p.direct_fe_window;
                    return;
                }
            }
            (Target::IndexPulse, _) => {
                if let Some(ix) = index {
                    let r = self.angle_to_raw(ix);
                    self.homing_found(&mut h, r, false);
                } else if travelled > 1.0 + MIN_INDEX_DISTANCE || stalled {
                    // More than a revolution (or a stop) without a pulse.
                    failed = Some(homing::NO_INDEX_PULSE);
                }
            }
            (Target::FixedStop, _) => {
                if stalled {
                    let r = self.raw_actual();
                    self.homing_found(&mut h, r, true);
                }
            }
            (Target::ReferenceSwitch, HomingPhase::Search) => {
                if self.reference_switch(angle) {
                    // CiA 402 23 / 27: on the switch, back off it the other way.
                    h.phase = HomingPhase::LeaveSwitch;
                    h.dir = -h.dir;
                    h.phase_start = angle;
                } else if stalled {
                    failed = Some(homing::SWITCH_NOT_FOUND);
                } else if timed_out {
                    failed = Some(homing::HOMING_TIMEOUT);
                }
            }
            (Target::ReferenceSwitch, HomingPhase::LeaveSwitch) => {
                if !self.reference_switch(angle) {
                    if closed {
                        h.phase = HomingPhase::IndexAfterSwitch { edge: angle };
                        h.phase_start = angle;
                    } else {
                        let r = self.raw_actual();
                        self.homing_found(&mut h, r, false);
                    }
                } else if stalled {
                    failed = Some(homing::SWITCH_NOT_FOUND);
                } else if timed_out {
                    failed = Some(homing::HOMING_TIMEOUT);
                }
            }
            (Target::ReferenceSwitch, HomingPhase::IndexAfterSwitch { edge }) => {
                if let Some(ix) = index {
                    let d = libm::fabs(ix - edge) / core::f64::consts::TAU;
                    if !(MIN_INDEX_DISTANCE..=1.0 - MIN_INDEX_DISTANCE).contains(&d) {
                        failed = Some(homing::INDEX_TOO_CLOSE);
                    } else {
                        let r = self.angle_to_raw(ix);
                        self.homing_found(&mut h, r, false);
                    }
                } else if travelled > 1.0 + MIN_INDEX_DISTANCE || stalled {
                    failed = Some(homing::NO_INDEX_PULSE);
                }
            }
            (Target::CurrentPosition, _) => {}
        }
        if let Some(code) = failed {
            self.homing_failed(code);
            return;
        }
        let v = match h.phase {
            HomingPhase::Search => p.homing_search,
            HomingPhase::LeaveSwitch | HomingPhase::IndexAfterSwitch { .. } => p.homing_crawl,
            HomingPhase::ToZero { .. } => {
                self.motion = Motion::Homing(h);
                return;
            }
        };
        let v = self.clamp_velocity(v.max(1.0));
        self.traj
            .step_velocity(h.dir * v, p.homing_accel, p.homing_accel, dt);
        self.motion = Motion::Homing(h);
    }
}
