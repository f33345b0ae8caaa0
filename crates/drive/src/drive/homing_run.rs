//! Homing (CiA 402 mode 6) on the engine: controlword bit 4 starts the personality's method
//! (its table of 6098h methods, [`crate::personality::Personality::homing_methods`]),
//! [`crate::homing`] searches the reference point against the switches, the block or an
//! external switch, and the drive brakes, settles, travels to zero where the personality does
//! (the vendor hooks `homing_to_zero`, `homing_to_offset_point`), and sets the position.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// Homing (CiA 402 homing mode): controlword bit 4 0 → 1 starts the method of 6098h,
    /// 1 → 0 aborts it; halt aborts it, with homing_error where the vendor makes it one (the
    /// vendor hook `HALT_IS_HOMING_ERROR`); past the vendor's `homing_timeout` it fails. The
    /// search of [`crate::homing`] finds the reference point; then the drive brakes with
    /// 609Ah homing_acceleration and, where the vendor says (`homing_to_zero`), travels to
    /// the zero position.
    pub(crate) fn homing(&mut self, cw: Controlword, dt: f64) {
        let bit4 = cw.contains(Controlword::HOMING_START);
        let idle = matches!(self.homing, HomingRun::Idle);
        if !bit4 {
            self.homing_interrupted = false;
        }
        if self.cw_rising.contains(Controlword::HOMING_START)
            || (bit4
                && idle
                && !self.homing_attained
                && !self.homing_error
                && !self.homing_interrupted)
        {
            self.start_homing();
        } else if !idle && !bit4 {
            // Bit 4 1 → 0 aborts homing (neither attained nor error).
            self.homing = HomingRun::Brake {
                then: Then::Nothing,
            };
        } else if !idle && self.halted && !matches!(self.homing, HomingRun::Brake { .. }) {
            // Halt aborts homing (CiA 402: interrupted); homing_error where the vendor says.
            self.homing_error = V::HALT_IS_HOMING_ERROR;
            self.homing_interrupted = !V::HALT_IS_HOMING_ERROR;
            self.homing = HomingRun::Brake {
                then: Then::Nothing,
            };
        }
        if !matches!(self.homing, HomingRun::Idle) {
            if let Some(timeout) = V::homing_timeout(self) {
                if self.now.saturating_since(self.homing_started) > timeout {
                    self.homing_failed(HomingError::Timeout);
                }
            }
        }
        let acc = self.accel(0x609A);
        // `homing_immediate`: 609Ah only when starting; at the switch the speed changes at
        // once, at the end the motor stops at once.
        let immediate = self.personality.capabilities.homing_immediate;
        let (switch_acc, stop_dec) = if immediate {
            (ABRUPT_STOP, ABRUPT_STOP)
        } else {
            (acc, acc)
        };
        match self.homing {
            HomingRun::Idle => {
                self.traj.step_stop(acc, dt);
                self.position_demand(self.traj.velocity);
            }
            HomingRun::Search(mut search) => {
                let position = self.plant_position();
                let mut inputs = self.switch_inputs(position);
                if let Some(x) = self.homing_external {
                    // The reference switch an external I/O node sends (the personality's
                    // `external_home_switch`).
                    let bit = self.value(x.index, x.bit_sub).clamp(0, 7);
                    inputs.home = self.value(x.index, x.value_sub) >> bit & 1 != 0;
                }
                let sense = Sense {
                    position,
                    inputs,
                    stalled: self.stalled(),
                };
                let command = search.step(&sense, &self.settings.travel);
                self.homing = HomingRun::Search(search);
                match command {
                    Command::Run {
                        direction,
                        speed,
                        restart,
                    } => {
                        if restart {
                            self.hold_here();
                        }
                        let v = f64::from(direction) * self.homing_speed(speed);
                        let starting = self.traj.velocity == 0.0 && speed == Speed::Search;
                        let a = if starting { acc } else { switch_acc };
                        let accelerating = self.traj.velocity * v >= 0.0
                            && v.abs() > self.traj.velocity.abs()
                            && (starting || !immediate || self.homing_accelerating);
                        self.homing_accelerating = accelerating;
                        self.traj.step_velocity(
                            v,
                            if accelerating { acc } else { a },
                            switch_acc,
                            dt,
                        );
                        self.position_demand(self.traj.velocity);
                    }
                    Command::Reference { at, stalled } => {
                        if stalled {
                            self.hold_here();
                        }
                        self.set_reference(at);
                        if immediate {
                            self.traj.velocity = 0.0;
                            if stalled {
                                // On the block the position is set once the shaft has settled.
                                let settle = V::homing_block_settle(self);
                                self.homing_settle = Some(self.now + settle);
                            }
                        }
                        let to_zero = V::homing_to_offset_point(self) || V::homing_to_zero(self);
                        self.homing = HomingRun::Brake {
                            then: if to_zero {
                                Then::ToZero
                            } else {
                                Then::Attained
                            },
                        };
                        self.traj.step_stop(acc, dt);
                        self.position_demand(self.traj.velocity);
                    }
                    Command::Failed(e) => {
                        if sense.stalled {
                            self.hold_here();
                        }
                        self.homing_failed(e);
                        self.position_demand(self.traj.velocity);
                    }
                }
            }
            HomingRun::Brake { then } => {
                if self.traj.step_stop(stop_dec, dt) && self.homing_settled() {
                    self.homing = match then {
                        Then::ToZero => HomingRun::ToZero,
                        Then::Attained => {
                            self.homing_done();
                            HomingRun::Idle
                        }
                        Then::Nothing => HomingRun::Idle,
                    };
                }
                self.position_demand(self.traj.velocity);
            }
            HomingRun::ToZero => {
                // To the zero position at 6099h:01 search speed.
                let zero = self.fg.position_to_internal(0) as f64;
                let lim = Limits {
                    velocity: self.homing_speed(Speed::Search).max(1.0),
                    acceleration: acc.max(1.0),
                    deceleration: acc.max(1.0),
                };
                let window = self.fg.position_magnitude_to_internal(
                    self.value(0x6067, 0).clamp(0, u32::MAX as i64) as u32,
                );
                // Done when the set-point is there and the axis inside the window 6067h.
                if self.traj.step_to(zero, 0.0, lim, dt)
                    && (self.actual_internal() - crate::rounding::round(zero) as i64).abs()
                        <= window
                {
                    self.homing_done();
                    self.homing = HomingRun::Idle;
                }
                self.position_demand(self.traj.velocity);
            }
        }
        self.target_reached = matches!(self.homing, HomingRun::Idle) && self.traj.velocity == 0.0;
    }

    /// A homing on block has settled (or none waits): the reference is where the shaft now
    /// stands.
    fn homing_settled(&mut self) -> bool {
        match self.homing_settle {
            Some(t) if self.now < t => false,
            Some(_) => {
                self.homing_settle = None;
                self.hold_here();
                let at = self.plant_position();
                self.set_reference(at);
                true
            }
            None => true,
        }
    }

    fn start_homing(&mut self) {
        self.homing_interrupted = false;
        self.homing_settle = None;
        self.homing_attained = false;
        self.homing_error = false;
        self.referenced = false;
        self.homing_started = self.now;
        let method = self.value(0x6098, 0).clamp(i8::MIN as i64, i8::MAX as i64) as i8;
        self.homing_external = self
            .personality
            .external_home_switch
            .filter(|x| x.methods.contains(&method));
        match Search::start_in(
            self.personality.homing_methods,
            method,
            self.plant_position(),
            self.axis.motor().data().increments_per_rev,
            self.settings.homing_max_distance,
        ) {
            Ok(search) => self.homing = HomingRun::Search(search),
            Err(e) => self.homing_failed(e),
        }
    }

    /// Homing ends with an error: homing_error, the group-11 message, fault reaction.
    pub(super) fn homing_failed(&mut self, e: HomingError) {
        self.homing = HomingRun::Idle;
        self.homing_error = true;
        self.homing_attained = false;
        self.raise_fault(Fault::Homing(e));
    }

    fn homing_done(&mut self) {
        self.homing_attained = true;
        self.homing_error = false;
        self.referenced = true;
    }

    /// The reference point at encoder position `at` gets the value 607Ch home_offset.
    ///
    /// Decision: CiA 402 calls 607Ch home_offset the offset of the zero position from the
    /// reference point without a sign convention (so does the CMMP-AS's Fig. 7.2); as CiA 402
    /// masters expect, the position at the reference point reads home_offset afterwards (and
    /// "zero" lies home_offset before it).
    fn set_reference(&mut self, at: i64) {
        let home = self
            .value(0x607C, 0)
            .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        // Homing to the offset point: the offset point lies the home offset beyond the home
        // point, which then reads −607Ch; otherwise the home point reads 607Ch.
        let home = if V::homing_to_offset_point(self) {
            home.saturating_neg()
        } else {
            home
        };
        let offset = self.fg.position_to_internal(home) - at;
        let shift = (offset - self.position_offset) as f64;
        self.position_offset = offset;
        self.traj.position += shift;
        self.demand_position += shift;
        self.smoother.reset(self.traj.position, 1);
    }

    /// 6099h:01 (search) or :02 (crawl) in increments/s.
    fn homing_speed(&self, speed: Speed) -> f64 {
        let sub = match speed {
            Speed::Search => 1,
            Speed::Crawl => 2,
        };
        let user = self.value(0x6099, sub).clamp(0, u32::MAX as i64) as u32;
        self.fg.velocity_magnitude_to_internal(user) as f64 * INC_S_PER_VEL
    }

    /// The motor stands on a hard stop: the set-point moves on while the actual position
    /// lags by more than the following-error window 6065h (at most a revolution).
    fn stalled(&self) -> bool {
        let window = self
            .fg
            .position_magnitude_to_internal(self.value(0x6065, 0).clamp(0, u32::MAX as i64) as u32)
            .clamp(1, 65536);
        let lag = crate::rounding::round(self.demand_position) as i64 - self.actual_internal();
        self.traj.velocity != 0.0 && lag.abs() > window
    }

    /// The set-point jumps to the actual position and stands (after a stall on a stop).
    fn hold_here(&mut self) {
        self.traj = Trajectory::at(self.actual_internal() as f64);
        self.demand_position = self.traj.position;
        self.smoother.reset(self.traj.position, 1);
    }
}
