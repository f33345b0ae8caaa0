//! The plant behind the CiA 402 engine: the servo [`Axis`] (CMMP-AS), or the hybrid stepper
//! of [`crate::stepper`] that the CMMO-ST uses, for a stepper personality (Nanotec). The
//! engine reads positions in its internal unit (65536 increments per revolution) and speeds
//! in min⁻¹ from here, whichever plant it is.
//!
//! The stepper runs open loop (micro-stepping; above the pull-out torque it loses steps) or
//! closed loop (the encoder closes the loops; no step is lost below the peak torque).
//!
//! Which loop the stepper runs, which motor the output stage drives and a BLDC's settings
//! are the vendor's objects: the engine asks the vendor ([`Vendor`]'s `stepper_closed_loop`,
//! [`Vendor`]'s `plant_motor`, [`Vendor`]'s `bldc_settings`) and shows the loop where the vendor
//! names an object for it ([`Vendor`]'s `CLOSED_LOOP_OBJECT`).
//!
//! Decisions:
//! * The servo [`Axis`] stays in the drive for its brake and its parameters; with a stepper
//!   plant it is not stepped.
//! * A velocity demand (VL) drives the stepper as a position set-point moving at that speed.
//!   A torque demand is the closed loop's torque set-point (`k × current`); in open loop the
//!   stepper holds.

use super::*;
use crate::stepper::{Stepper, StepperDemand, StepperMode};

/// Internal increments per revolution.
const INC_PER_REV: f64 = 65536.0;

/// The stepper plant and the engine's view of it.
#[derive(Debug, Clone)]
pub struct StepperPlant {
    pub(crate) motor: Stepper,
    /// A velocity demand integrated into a position set-point, internal increments.
    set_point: f64,
    following_velocity: bool,
    /// The last encoder reading, the encoder's increments per revolution and the position
    /// in internal increments (the logic asks several times per cycle).
    position_memo: core::cell::Cell<(i64, u32, i64)>,
}

impl StepperPlant {
    pub fn new(motor: Stepper) -> Self {
        StepperPlant {
            motor,
            set_point: 0.0,
            following_velocity: false,
            position_memo: core::cell::Cell::new((0, 0, 0)),
        }
    }

    fn encoder_per_rev(&self) -> f64 {
        f64::from(self.motor.data().encoder_increments_per_rev.max(1))
    }

    /// The encoder position in internal increments.
    fn position(&self) -> i64 {
        let encoder = self.motor.encoder_increments();
        let per_rev = self.motor.data().encoder_increments_per_rev;
        let (last, last_per_rev, position) = self.position_memo.get();
        if encoder == last && per_rev == last_per_rev {
            return position;
        }
        let position =
            crate::rounding::round(encoder as f64 * INC_PER_REV / self.encoder_per_rev()) as i64;
        self.position_memo.set((encoder, per_rev, position));
        position
    }

    /// One cycle of `dt` s with the engine's demand.
    fn step(&mut self, dt: f64, demand: Demand) {
        let position = |p: &Self, increments: f64, ff: f32| {
            let d = p.motor.data();
            match p.motor.mode() {
                StepperMode::OpenLoop => {
                    let per_rev = f64::from(d.full_steps_per_rev) * f64::from(d.microsteps);
                    StepperDemand::Position {
                        microsteps: crate::rounding::round(increments * per_rev / INC_PER_REV)
                            as i64,
                    }
                }
                StepperMode::ClosedLoop => StepperDemand::PositionIncrements {
                    increments: crate::rounding::round(
                        increments * p.encoder_per_rev() / INC_PER_REV,
                    ) as i64,
                    velocity_ff_rpm: ff,
                },
            }
        };
        let velocity = matches!(demand, Demand::Velocity { .. });
        if velocity && !self.following_velocity {
            self.set_point = self.position() as f64;
        }
        self.following_velocity = velocity;
        let d = match demand {
            Demand::Off => StepperDemand::Off,
            Demand::Torque { current_a } => StepperDemand::Torque {
                newton_metres: self.motor.data().torque_constant() * f64::from(current_a),
            },
            Demand::Velocity { rpm } => {
                self.set_point += f64::from(rpm) / 60.0 * INC_PER_REV * dt;
                position(self, self.set_point, rpm)
            }
            Demand::Position {
                increments,
                velocity_ff_rpm,
            } => position(self, increments as f64, velocity_ff_rpm),
        };
        self.motor.step(dt, d);
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// The actual position as the drive reads it, internal increments (without the homing
    /// offset): the shaft through a possibly faulted encoder (`crate::encoder_fault`).
    #[inline]
    pub fn plant_position(&self) -> i64 {
        self.shaft_position()
            .wrapping_add(self.plant_watch.encoder.error())
    }

    /// The shaft's true position, internal increments.
    pub(crate) fn shaft_position(&self) -> i64 {
        match &self.stepper {
            Some(s) => s.position(),
            None => match self.hall_edges() {
                // A BLDC on its Hall sensors alone: the position counts Hall edges.
                Some(n) => self.axis.position_increments() * 65536 / i64::from(n),
                None => self.axis.position_increments(),
            },
        }
    }

    /// Hall edges per revolution when a BLDC runs on its Hall sensors alone
    /// ([`PlantMotor::BldcHall`](crate::personality::PlantMotor::BldcHall)).
    fn hall_edges(&self) -> Option<u32> {
        self.bldc
            .filter(|_| self.motor_type == 1)
            .map(|b| b.hall_edges_per_rev())
    }

    /// The motor type the output stage runs ([`Vendor`]'s `plant_motor`). Decision: the
    /// Nanotec's manual names no moment at which a new type (2004h:07) applies; the twin
    /// takes it while the output stage is off (not while a motor is being driven), so a
    /// change made in Operation Enabled applies at the next disable. A BLDC's position
    /// resolution follows: type 1 counts Hall edges (6 × pole pairs a turn), type 2 the
    /// quadrature encoder (the servo motor data's increments).
    fn take_motor_type(&mut self) {
        let t = V::plant_motor(self).code();
        self.bldc_currents();
        if t == self.motor_type {
            return;
        }
        self.motor_type = t;
        let Some(b) = self.bldc else {
            return;
        };
        let increments = if t == 1 {
            b.hall_edges_per_rev()
        } else {
            crate::motor::INCREMENTS_PER_REV
        };
        if self.axis.motor().data().increments_per_rev != increments {
            let angle = self.axis.motor().angle();
            let data = crate::motor::MotorData {
                increments_per_rev: increments,
                ..*self.axis.motor().data()
            };
            let params = *self.axis.params();
            self.axis = crate::axis::Axis::new(data, params);
            self.axis.motor_mut().set_angle(angle);
            self.place_hard_stops();
        }
        // Hall only: the cascade holds on whole Hall edges (`Axis::set_hall_only`).
        self.axis.set_hall_only(t == 1);
    }

    /// The actual speed, min⁻¹.
    pub fn plant_velocity_rpm(&self) -> f32 {
        match &self.stepper {
            Some(s) => s.motor.velocity_rpm(),
            None => self.axis.velocity_rpm(),
        }
    }

    /// The actual speed in the internal unit 1/4096 min⁻¹.
    pub(crate) fn plant_velocity_internal(&self) -> i32 {
        match &self.stepper {
            Some(s) => crate::rounding::round(f64::from(s.motor.velocity_rpm()) * 4096.0) as i32,
            None => self.axis.velocity_internal(),
        }
    }

    /// The stepper plant, if the drive has one.
    pub fn stepper(&self) -> Option<&Stepper> {
        self.stepper.as_ref().map(|s| &s.motor)
    }

    pub fn stepper_mut(&mut self) -> Option<&mut Stepper> {
        self.stepper.as_mut().map(|s| &mut s.motor)
    }

    /// One current-controller cycle of the plant.
    pub(crate) fn plant_step(&mut self) {
        let dt = self.cycle.as_secs_f64();
        if self.demand == Demand::Off && self.personality.stepper_plant {
            self.take_motor_type();
        }
        if let Some(s) = &mut self.stepper {
            // Decision: BLDC selected with a stepper connected ("can destroy the stepper",
            // §6): the twin's stepper refuses to run — no current, the shaft stays put; the
            // manual names no error for it, so none is raised.
            let demand = if self.motor_type != 0 {
                Demand::Off
            } else {
                self.demand
            };
            s.step(dt, demand);
            return;
        }
        match self.bldc {
            // A BLDC with type 0: the stepper's micro-stepping does not turn it.
            Some(_) if self.motor_type == 0 => {
                self.axis.motor_mut().set_torque_factor(0.0);
                self.axis.step(Demand::Off);
            }
            Some(b) => {
                let mode = V::bldc_settings(self).commutation;
                let edges = self.hall_edges();
                let factor = b.torque_factor(mode, self.axis.motor().angle());
                self.axis.motor_mut().set_torque_factor(factor);
                let demand = match (self.demand, edges) {
                    (
                        Demand::Position {
                            increments,
                            velocity_ff_rpm,
                        },
                        Some(n),
                    ) => Demand::Position {
                        increments: crate::rounding::round(
                            increments as f64 * f64::from(n) / INC_PER_REV,
                        ) as i64,
                        velocity_ff_rpm,
                    },
                    (d, _) => d,
                };
                self.axis.step(demand);
            }
            None => self.axis.step(self.demand),
        }
    }

    /// The BLDC's current limits ([`Vendor`]'s `bldc_settings`), taken with the output stage
    /// off: a share of the motor's rated current continuously; the peak, when above it, for
    /// a while (the axis's I²t); with no peak above it the limit is the continuous share.
    fn bldc_currents(&mut self) {
        if self.bldc.is_none() {
            return;
        }
        let rated = self.axis.motor().data().rated_current * 1000.0;
        let settings = V::bldc_settings(self);
        let percent = settings.current_percent;
        let peak = settings.peak_percent;
        let time = settings.peak_time_ms;
        let mut params = *self.axis.params();
        params.motor_rated_current_ma = (rated * percent / 100.0).max(1.0) as u32;
        let (permille, time) = if peak > percent {
            ((peak / percent * 1000.0) as u16, time.max(1))
        } else {
            (1000, params.iit_time_motor_ms)
        };
        params.max_current_permille = permille;
        params.iit_time_motor_ms = time;
        if params != *self.axis.params() {
            self.axis.set_params(params);
        }
    }

    /// The BLDC connected to a stepper personality, if any.
    pub fn bldc(&self) -> Option<&crate::bldc::BldcData> {
        self.bldc.as_ref()
    }

    /// The object that shows the stepper's loop ([`Vendor`]'s `CLOSED_LOOP_OBJECT`).
    #[inline]
    fn closed_loop_entry(&self) -> Option<&'static Entry> {
        V::CLOSED_LOOP_OBJECT.and_then(|(index, sub)| self.param(index, sub))
    }

    /// The stepper's loop as the vendor sets it ([`Vendor`]'s `stepper_closed_loop`), shown in
    /// [`Vendor`]'s `CLOSED_LOOP_OBJECT`.
    pub(crate) fn stepper_mode(&mut self) {
        if self.bldc.is_some() {
            // Decision: a BLDC runs commutated from its Hall sensors, its current, speed and
            // position controlled: closed loop (Nanotec 200Ah = 1) whenever the motor type
            // selects it.
            self.store_changed(self.closed_loop_entry(), i64::from(self.motor_type != 0));
            return;
        }
        if self.stepper.is_none() {
            return;
        }
        let closed = V::stepper_closed_loop(self);
        let Some(s) = self.stepper.as_mut() else {
            return;
        };
        let mode = if closed {
            StepperMode::ClosedLoop
        } else {
            StepperMode::OpenLoop
        };
        if s.motor.mode() != mode {
            s.motor.set_mode(mode);
        }
        self.store_changed(self.closed_loop_entry(), i64::from(closed));
    }
}
