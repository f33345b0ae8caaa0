//! One simulated servo axis of the CMMP-AS twin: the motor and load of [`crate::motor`] under
//! the control cascade of [`crate::control`]. The CiA 402 device logic calls
//! [`Axis::step`] once per current-controller cycle (6510h:B0, 125 µs) with what the active
//! operating mode demands; the velocity and position controllers run every n-th call
//! (6510h:B1 = 250 µs, 6510h:B2 = 500 µs), at a fixed phase: call 0, n, 2n, …
//!
//! Order inside one call: read the encoder; position controller (when due); velocity
//! controller (when due); current controller; motor for one cycle; I²t.

use crate::control::{clamp, ControlParams, Gains, I2t, Pi};
use crate::current_filters::FilterState;
use crate::motor::{Motor, MotorData, RAD_S_TO_RPM, RPM_TO_RAD_S};

/// A demand that is not a number counts as 0 (a NaN must not poison the plant state).
#[inline]
fn finite(x: f64) -> f64 {
    if x.is_nan() {
        0.0
    } else {
        x
    }
}

/// Up to this magnitude (2⁵²) encoder readings are exact in `f64`, and so is the difference
/// of two.
const EXACT_INCREMENTS: f64 = 4_503_599_627_370_496.0;

/// What the operating mode asks of the axis for one current-controller cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Demand {
    /// Output stage off: no current, the shaft coasts (a holding brake is the caller's
    /// business, see [`Axis::hold_brake`]). Resets all controllers.
    Off,
    /// Current (torque) set-point in A; limited by 6073h max_current and I²t (the 2415h
    /// limitation does not apply in torque mode). Torque in ‰ of 6076h converts with
    /// [`ControlParams::current_for_torque_permille`].
    Torque { current_a: f32 },
    /// Speed set-point in min⁻¹ (rpm), limited by 6080h.
    Velocity { rpm: f32 },
    /// Position set-point in increments (position_demand_value in internal units) and the
    /// speed feed-forward in min⁻¹ (the trajectory generator's set-point speed; 0 for none).
    Position {
        increments: i64,
        velocity_ff_rpm: f32,
    },
}

/// Motor, load and the drive's control loops.
#[derive(Debug, Clone)]
pub struct Axis {
    motor: Motor,
    params: ControlParams,
    g: Gains,
    /// Countdown to the next velocity / position controller run (0 = runs this call).
    vel_due: u32,
    pos_due: u32,
    cur_pi: Pi,
    vel_pi: Pi,
    pos_int: f64,
    i2t: I2t,
    /// Encoder reading at the last velocity-controller run, and as `f64`.
    last_inc: i64,
    last_inc_f: f64,
    /// Actual speed, filtered by 60F9h:04 (rad/s), and by 2073h (rad/s).
    speed: f64,
    speed_display: f64,
    /// Speed set-point to the velocity controller (60FAh control_effort), rad/s.
    speed_set: f64,
    /// Velocity-controller output before the current limit (A), held between its runs.
    vel_out: f64,
    /// Current set-point after the limits (A), the voltage applied (V).
    current_set: f64,
    voltage: f64,
    /// The current set-point was clamped by a limit in the last cycle.
    limited: bool,
    following_error: i64,
    steps: u64,
    /// What the controllers see of the shaft (see [`Axis::set_hall_only`]).
    feedback: Feedback,
    /// Hall only: the shaft stands on the edge of a standing set-point (no current).
    edge_hold: bool,
    /// The current set-point's filters ([`crate::current_filters`]).
    filter: FilterState,
}

/// What the position and velocity controllers see of the shaft. On a BLDC's Hall sensors
/// alone the drive cannot see inside an edge, and three rules of the cascade change: each a
/// decision of ours, as the Nanotec manual names motor type 1 (2004h:07, "BLDC with Hall, no
/// encoder") but not how its controllers run on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Feedback {
    Encoder,
    /// Nanotec 2004h:07 = 1: one increment is one Hall edge.
    HallEdges,
}

impl Feedback {
    /// The error the position controller acts on: none within the window 60FBh:05. On Hall
    /// edges an error below one edge is already 0, and the window (encoder increments, a
    /// fraction of an edge) widens nothing: a band of ±1 edge would leave the shaft beside
    /// its target, outside 6067h.
    fn position_error(self, e: i64, window: i64) -> i64 {
        match self {
            Feedback::Encoder if e.unsigned_abs() < window as u64 => 0,
            _ => e,
        }
    }

    /// On Hall edges, a shaft on the edge of a standing set-point gets no current (friction
    /// holds it there): any current would push it off an edge the drive cannot see inside,
    /// and it would hunt by an edge or two.
    fn holds_without_current(self, error: f64, speed_set: f64) -> bool {
        self == Feedback::HallEdges && error == 0.0 && speed_set == 0.0
    }

    /// The velocity controller's integral gain. On Hall edges the speed (one edge difference
    /// per cycle) is 0 between edges; an integral would wind up over the edge period and
    /// throw the shaft through its target edge: the controller is P only.
    fn velocity_ki(self, ki: f64) -> f64 {
        match self {
            Feedback::Encoder => ki,
            Feedback::HallEdges => 0.0,
        }
    }
}

impl Axis {
    pub fn new(motor: MotorData, params: ControlParams) -> Self {
        let motor = Motor::new(motor);
        let g = params.gains(motor.data().increments_per_rev);
        let inc = motor.position_increments();
        let motor_inc_f = motor.position_increments_f();
        Axis {
            motor,
            params,
            g,
            vel_due: 0,
            pos_due: 0,
            cur_pi: Pi::default(),
            vel_pi: Pi::default(),
            pos_int: 0.0,
            i2t: I2t::default(),
            last_inc: inc,
            last_inc_f: motor_inc_f,
            speed: 0.0,
            speed_display: 0.0,
            speed_set: 0.0,
            vel_out: 0.0,
            current_set: 0.0,
            voltage: 0.0,
            limited: false,
            following_error: 0,
            steps: 0,
            feedback: Feedback::Encoder,
            edge_hold: false,
            filter: FilterState::default(),
        }
    }

    /// The encoder is a BLDC's Hall sensors alone (Nanotec 2004h:07 = 1): one increment is
    /// one Hall edge, and the position and velocity controllers hold a shaft they cannot see
    /// inside an edge (see [`Axis::step`]).
    pub fn set_hall_only(&mut self, hall_only: bool) {
        self.feedback = if hall_only {
            Feedback::HallEdges
        } else {
            Feedback::Encoder
        };
        self.edge_hold = false;
    }

    /// Replaces the drive parameters (after an SDO write, say). Controller states are kept;
    /// the loop phases restart at the next call.
    pub fn set_params(&mut self, params: ControlParams) {
        if params.filters != self.params.filters {
            self.filter.settle_at(self.current_set);
        }
        self.params = params;
        self.g = params.gains(self.motor.data().increments_per_rev);
        self.vel_due = self.vel_due.min(self.g.vel_every - 1);
        self.pos_due = self.pos_due.min(self.g.pos_every - 1);
    }

    pub fn params(&self) -> &ControlParams {
        &self.params
    }

    /// The parameters converted to SI units.
    pub fn gains(&self) -> &Gains {
        &self.g
    }

    pub fn motor(&self) -> &Motor {
        &self.motor
    }

    /// The plant, for test set-ups (load torque, initial angle).
    pub fn motor_mut(&mut self) -> &mut Motor {
        &mut self.motor
    }

    /// Engages (true) or releases the holding brake.
    pub fn hold_brake(&mut self, engaged: bool) {
        self.motor.set_brake(engaged);
    }

    /// Jams the load (true): the shaft cannot turn.
    pub fn set_blocked(&mut self, blocked: bool) {
        self.motor.set_blocked(blocked);
    }

    /// Current-controller cycle, s.
    pub fn cycle_s(&self) -> f64 {
        self.g.dt
    }

    /// Calls of [`Axis::step`] so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The current limit in force for set-points of the velocity/position loops (`limitation`
    /// = true) or of torque mode: 6073h, 2415h, and the rated current while I²t limits.
    #[inline]
    fn current_limit(&self, limitation: bool) -> f64 {
        let mut lim = self.g.i_max;
        if limitation && self.g.i_limitation < lim {
            lim = self.g.i_limitation;
        }
        if self.i2t.active && self.g.i_rated < lim {
            lim = self.g.i_rated;
        }
        lim
    }

    /// Advances the axis by one current-controller cycle.
    pub fn step(&mut self, demand: Demand) {
        let g = &self.g;
        let inc = self.motor.position_increments();

        let vel_run = self.vel_due == 0;
        self.vel_due = if vel_run {
            g.vel_every - 1
        } else {
            self.vel_due - 1
        };
        let pos_run = self.pos_due == 0;
        self.pos_due = if pos_run {
            g.pos_every - 1
        } else {
            self.pos_due - 1
        };

        // Actual speed from the encoder difference over one velocity cycle, PT1-filtered.
        if vel_run {
            // The difference in floating point where both readings are exact there (then so
            // is the difference, and equal to the integers'): no conversions on the plant's
            // dependent chain.
            let inc_f = self.motor.position_increments_f();
            let diff =
                if inc_f.abs() <= EXACT_INCREMENTS && self.last_inc_f.abs() <= EXACT_INCREMENTS {
                    inc_f - self.last_inc_f
                } else {
                    inc.wrapping_sub(self.last_inc) as f64
                };
            let raw = diff * g.vel_per_inc;
            self.last_inc = inc;
            self.last_inc_f = inc_f;
            self.speed += (raw - self.speed) * g.vel_filter;
            self.speed_display += (raw - self.speed_display) * g.display_filter;
        }

        let limitation = matches!(demand, Demand::Velocity { .. } | Demand::Position { .. });
        let lim = self.current_limit(limitation);
        let g = &self.g;

        let i_demand = match demand {
            Demand::Off => {
                self.cur_pi.reset();
                self.vel_pi.reset();
                self.filter.reset();
                self.pos_int = 0.0;
                self.speed_set = 0.0;
                self.vel_out = 0.0;
                self.current_set = 0.0;
                self.voltage = 0.0;
                self.limited = false;
                self.motor.step_open(g.dt);
                self.i2t.step(0.0, g);
                self.steps = self.steps.wrapping_add(1);
                return;
            }
            Demand::Torque { current_a } => {
                self.pos_int = 0.0;
                self.speed_set = self.speed;
                // Bumpless change to velocity control: the integrator carries the current.
                self.vel_pi.integral = self.current_set;
                self.vel_out = self.current_set;
                finite(current_a as f64)
            }
            Demand::Velocity { rpm } => {
                self.pos_int = 0.0;
                if vel_run {
                    let w = finite(rpm as f64) * RPM_TO_RAD_S;
                    self.speed_set = w.max(-g.max_speed).min(g.max_speed);
                    self.vel_out =
                        self.vel_pi
                            .step(self.speed_set - self.speed, g.vel_kp, g.vel_ki, lim);
                    self.limit_integral(lim);
                }
                self.vel_out
            }
            Demand::Position {
                increments,
                velocity_ff_rpm,
            } => {
                if pos_run {
                    let e = increments.wrapping_sub(inc);
                    self.following_error = e;
                    let e = self.feedback.position_error(e, g.pos_window) as f64;
                    let mut v = g.pos_kv * e + self.pos_int + g.pos_ki * e;
                    if v > g.pos_vmax {
                        v = g.pos_vmax;
                    } else if v < -g.pos_vmax {
                        v = -g.pos_vmax;
                    } else {
                        self.pos_int += g.pos_ki * e;
                    }
                    let w = v + finite(velocity_ff_rpm as f64) * RPM_TO_RAD_S;
                    self.speed_set = w.max(-g.max_speed).min(g.max_speed);
                    self.edge_hold = self.feedback.holds_without_current(e, w);
                }
                if self.edge_hold {
                    self.vel_pi.reset();
                    self.vel_out = 0.0;
                } else if vel_run {
                    let ki = self.feedback.velocity_ki(g.vel_ki);
                    self.vel_out = self
                        .vel_pi
                        .step(self.speed_set - self.speed, g.vel_kp, ki, lim);
                    self.limit_integral(lim);
                }
                self.vel_out
            }
        };
        let g = &self.g;
        let i_demand = if g.filters.is_pass_through() {
            i_demand
        } else {
            self.filter.step(&g.filters, i_demand)
        };

        // Current set-point limit.
        self.limited = i_demand > lim || i_demand < -lim;
        let i_set = clamp(i_demand, lim);
        self.current_set = i_set;

        // Current controller and plant.
        let i = self.motor.current();
        let u = clamp(
            self.cur_pi.step(i_set - i, g.cur_kp, g.cur_ki, g.u_max),
            g.u_max,
        );
        self.voltage = u;
        self.motor.step(g.dt, u);
        self.i2t.step(self.motor.current(), g);
        self.steps = self.steps.wrapping_add(1);
    }

    /// The velocity integrator within its own limit (Kinco Kvi_Sum_Limit), a share of the
    /// current limit `lim`; the whole limit (the engine's default) changes nothing.
    fn limit_integral(&mut self, lim: f64) {
        let share = self.g.filters.integral_share;
        if share < 1.0 {
            self.vel_pi.integral = clamp(self.vel_pi.integral, lim * share);
        }
    }

    // ---- actual values -------------------------------------------------------------------

    /// Encoder position, increments (6063h position_actual_value_s).
    #[inline]
    pub fn position_increments(&self) -> i64 {
        self.motor.position_increments()
    }

    /// Actual speed (60F9h:04-filtered, as the velocity controller sees it), min⁻¹.
    pub fn velocity_rpm(&self) -> f32 {
        (self.speed * RAD_S_TO_RPM) as f32
    }

    /// Actual speed in the internal unit 1/4096 min⁻¹ (606Ch before the factor group).
    pub fn velocity_internal(&self) -> i32 {
        crate::rounding::round(self.speed * RAD_S_TO_RPM * 4096.0) as i32
    }

    /// Actual speed through the 2073h display filter, min⁻¹.
    pub fn velocity_display_rpm(&self) -> f32 {
        (self.speed_display * RAD_S_TO_RPM) as f32
    }

    /// Motor current, mA.
    pub fn current_ma(&self) -> i32 {
        crate::rounding::round(self.motor.current() * 1000.0) as i32
    }

    /// Motor current in ‰ of 6075h (6078h current_actual_value).
    pub fn current_permille(&self) -> i16 {
        self.permille(self.motor.current())
    }

    /// Actual torque in ‰ of 6076h (6077h torque_actual_value); equal to the current in ‰
    /// of 6075h, see [`ControlParams::current_for_torque_permille`].
    pub fn torque_permille(&self) -> i16 {
        self.current_permille()
    }

    /// Current set-point after all limits, mA.
    pub fn current_demand_ma(&self) -> i32 {
        crate::rounding::round(self.current_set * 1000.0) as i32
    }

    /// Torque set-point after all limits in ‰ of 6076h (6074h torque_demand_value).
    pub fn torque_demand_permille(&self) -> i16 {
        self.permille(self.current_set)
    }

    fn permille(&self, current: f64) -> i16 {
        let r = self.g.i_rated;
        if r <= 0.0 {
            return 0;
        }
        crate::rounding::round(current / r * 1000.0) as i16
    }

    /// Speed set-point to the velocity controller (60FAh control_effort: position-controller
    /// output plus feed-forward in position control, the speed demand in velocity control),
    /// min⁻¹.
    pub fn control_effort_rpm(&self) -> f32 {
        (self.speed_set * RAD_S_TO_RPM) as f32
    }

    /// Position demand − actual at the last position-controller run, increments.
    pub fn following_error(&self) -> i64 {
        self.following_error
    }

    /// Voltage applied to the winding in the last cycle, V.
    pub fn voltage(&self) -> f32 {
        self.voltage as f32
    }

    /// I²t load in ‰ (6410h:04 iit_ratio_motor).
    pub fn i2t_permille(&self) -> u16 {
        crate::rounding::round(self.i2t.ratio(&self.g) * 1000.0) as u16
    }

    /// I²t load in % (0…100).
    pub fn i2t_percent(&self) -> f32 {
        (self.i2t.ratio(&self.g) * 100.0) as f32
    }

    /// I²t limiting active: the current is limited to 6075h (statusword bit 11
    /// internal_limit_active; error 31-0 when 6510h:38 = 1).
    pub fn i2t_limit_active(&self) -> bool {
        self.i2t.active
    }

    /// The current set-point was clamped (6073h, 2415h or I²t) in the last cycle.
    pub fn current_limited(&self) -> bool {
        self.limited
    }
}
