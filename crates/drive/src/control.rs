//! The servo control cascade: position controller (P, optional integrator, speed
//! feed-forward, output clamp, dead band) → velocity controller (PI, actual-speed filter,
//! output = current set-point limited by 6073h, a current limitation and I²t) → current
//! controller (PI, output voltage limited by the DC-link voltage) → motor. Plus the motor I²t
//! monitor. The shape and units follow CMMP-AS §5.5–5.8 (the manual's extract, part 2 §6),
//! the manual that describes a cascade in full; which objects hold the parameters is the
//! vendor's ([`crate::personality::Vendor`]'s `control_params` and `control_parameter_sets`:
//! CiA 402 leaves the sub-indices of 60F6h, 60F9h and 60FBh to the manufacturer).
//!
//! [`ControlParams`] holds the parameters in the manual's object units (gains × 256, times in
//! µs, currents in mA, speeds in min⁻¹, positions in increments); [`Gains`] is the same set
//! converted to SI once, when the parameters are set, so the cycle itself is plain `f64`
//! arithmetic.
//!
//! # Gain normalisation (a decision of this implementation)
//!
//! The manual states only "256 = gain 1" and gives no physical unit for gain 1. The drive
//! works internally in per-unit of its power stage, so this implementation normalises on the
//! device data the firmware knows, never on the (unknown) load:
//!
//! | Controller | gain 1 ≙ | default |
//! |---|---|---|
//! | current (CMMP-AS 60F6h:01) | U_DC,nom / I_peak (the CMMP-AS's 6510h:33 / 6510h:41, V/A): a current error of the device peak current asks for the full nominal DC-link voltage | 3.0 × 325 V / 5 A = 195 V/A |
//! | velocity (CMMP-AS 60F9h:01) | I_peak per 1000 min⁻¹ (A·s/rad) | 1.0 × 5 A / 104.7 rad/s = 0.0477 A·s/rad |
//! | position (CMMP-AS 60FBh:01) | 100 s⁻¹ (6000 min⁻¹ of correction speed per revolution of following error) | 102/256 × 100 s⁻¹ = 39.8 s⁻¹ |
//!
//! The defaults are the engine's standard gains ([`ControlParams::default`]), tuned for the
//! default motor ([`crate::motor::MotorData::default`]): a current loop of ≈ 1 kHz, a
//! velocity loop crossing over at ≈ 850 rad/s and a position loop of ≈ 40 s⁻¹ (they are the
//! CMMP-AS's factory settings, §5.5–5.7). The integral actions are the usual `Kp/Tn` with
//! the controllers' time constants (0 = no integrator).

use crate::current_filters::{CurrentFilterParams, CurrentFilters};
use crate::motor::{MotorData, RPM_TO_RAD_S};

/// Stored value of a controller gain: gain × 256, rounded (manual's extract, part 2 §6: 1.5 → 384).
pub fn gain_to_raw(gain: f64) -> u16 {
    libm::round(gain * 256.0) as u16
}

/// Controller gain from its stored value (256 = gain 1).
pub fn gain_from_raw(raw: u16) -> f64 {
    raw as f64 / 256.0
}

/// Stored value of a controller time constant: the parameterisation software shows ms, the
/// objects hold µs (manual's extract, part 2 §6: 0.6 ms → 600).
pub fn time_ms_to_us(ms: f64) -> u16 {
    libm::round(ms * 1000.0) as u16
}

/// 6410h:11 encoder_offset_angle from degrees: `angle × 32767 / 180`, rounded to nearest
/// (CMMP-AS §5.5, L3110: −45° gives −8191.75, and the printed factory setting is E000h =
/// −8192), clamped to the printed range −32767 … 32767.
pub fn encoder_offset_angle_from_degrees(degrees: f64) -> i16 {
    libm::round(degrees * 32767.0 / 180.0).clamp(-32767.0, 32767.0) as i16
}

/// Maximum current in mA from 6075h (mA) and 6073h (‰ of 6075h):
/// `I_max = 6075h × 6073h / 1000` (manual's extract, part 2 §6).
pub fn max_current_ma(rated_current_ma: u32, max_current_permille: u16) -> f64 {
    rated_current_ma as f64 * max_current_permille as f64 / 1000.0
}

/// 6073h value for an overload factor (CMMP-AS §5.5: factor 4 → 4000).
pub fn overload_factor_to_permille(factor: f64) -> u16 {
    libm::round(factor * 1000.0) as u16
}

/// Drive parameters in the units of their objects.
///
/// Position and speed values are in the drive's internal base units (increments, min⁻¹);
/// with the default factor group (65536 inc/rev, min⁻¹) they equal the user units of the
/// objects. Converting other user units is the factor group's job.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlParams {
    /// 6075h motor_rated_current, mA RMS (default 296).
    pub motor_rated_current_ma: u32,
    /// 6073h max_current, ‰ of 6075h (default 2023).
    pub max_current_permille: u16,
    /// 6410h:03 iit_time_motor, ms: how long max_current may flow (default 2000).
    pub iit_time_motor_ms: u16,
    /// Current controller gain, 256 = 1 (CMMP-AS 60F6h:01 torque_control_gain; default 768
    /// = 3.0).
    pub torque_control_gain: u16,
    /// Current controller integral time, µs (CMMP-AS 60F6h:02; default 1020).
    pub torque_control_time_us: u16,
    /// Velocity controller gain, 256 = 1 (CMMP-AS 60F9h:01; default 256 = 1.0).
    pub velocity_control_gain: u16,
    /// Velocity controller integral time, µs (CMMP-AS 60F9h:02; default 2000).
    pub velocity_control_time_us: u16,
    /// PT1 on the actual speed, µs (CMMP-AS 60F9h:04 velocity_control_filter_time; default
    /// 400).
    pub velocity_control_filter_time_us: u16,
    /// 2073h velocity_display_filter_time, µs: PT1 of the displayed speed (default 20000).
    pub velocity_display_filter_time_us: u32,
    /// Position controller gain, 256 = 1 (CMMP-AS 60FBh:01; default 102 ≈ 0.398).
    pub position_control_gain: u16,
    /// Position controller integral time, µs; 0 = no integrator (CMMP-AS 60FBh:02; default
    /// 0).
    pub position_control_time_us: u16,
    /// Clamp of the correction speed, min⁻¹ (CMMP-AS 60FBh:04 position_control_v_max;
    /// default 500).
    pub position_control_v_max_rpm: u32,
    /// Dead band, increments (CMMP-AS 60FBh:05 position_error_tolerance_window; default 2).
    pub position_error_tolerance_window: u32,
    /// 6080h max_motor_speed, min⁻¹: limit of every speed set-point (default 32768).
    pub max_motor_speed_rpm: u32,
    /// 2415h current_limitation as a fixed value, mA; `None` = no limitation (2415h:01 = 0).
    /// Active in the velocity and position loops (PP, IP, HM, PV), not in torque mode.
    pub limit_current_ma: Option<u32>,
    /// 6510h:33 nominal_dc_link_circuit_voltage, mV (device file: 325000).
    pub nominal_dc_link_voltage_mv: u32,
    /// 6510h:34 actual_dc_link_circuit_voltage, mV: sets the current controller's voltage
    /// limit (see [`Gains::u_max`]).
    pub dc_link_voltage_mv: u32,
    /// 6510h:41 peak_current of the device, mA (device file: 5000, CMMP-AS-C2-3A).
    pub peak_current_ma: u32,
    /// 6510h:B0 cycletime_current_controller, µs (125).
    pub cycletime_current_us: u32,
    /// 6510h:B1 cycletime_velocity_controller, µs (250).
    pub cycletime_velocity_us: u32,
    /// 6510h:B2 cycletime_position_controller, µs (500).
    pub cycletime_position_us: u32,
    /// The current set-point's filters and the velocity integrator's limit (the Kinco's;
    /// off for the others).
    pub filters: CurrentFilterParams,
}

impl Default for ControlParams {
    /// The engine's standard parameters: the gains tuned for the default motor (the module
    /// doc; the CMMP-AS's factory settings, §5.5–5.7) and its power stage (§5.17; device file
    /// cmmp-as.toml for the device-dependent 6510h values).
    fn default() -> Self {
        ControlParams {
            motor_rated_current_ma: 296,
            max_current_permille: 2023,
            iit_time_motor_ms: 2000,
            torque_control_gain: 768,
            torque_control_time_us: 1020,
            velocity_control_gain: 256,
            velocity_control_time_us: 2000,
            velocity_control_filter_time_us: 400,
            velocity_display_filter_time_us: 20000,
            position_control_gain: 102,
            position_control_time_us: 0,
            position_control_v_max_rpm: 500,
            position_error_tolerance_window: 2,
            max_motor_speed_rpm: 32768,
            limit_current_ma: None,
            nominal_dc_link_voltage_mv: 325_000,
            dc_link_voltage_mv: 325_000,
            peak_current_ma: 5000,
            cycletime_current_us: 125,
            cycletime_velocity_us: 250,
            cycletime_position_us: 500,
            filters: CurrentFilterParams::default(),
        }
    }
}

impl ControlParams {
    /// Defaults commissioned for `motor`: 6075h = its rated current (at most the device's
    /// nominal 2.5 A is the OD's job, not checked here), 6073h = peak/rated (bounded by the
    /// device peak current 6510h:41), 6410h:03 = its I²t time, 6080h = its max speed.
    pub fn for_motor(motor: &MotorData) -> Self {
        let mut p = ControlParams::default();
        let rated_ma = libm::round(motor.rated_current * 1000.0).max(1.0);
        p.motor_rated_current_ma = rated_ma as u32;
        let peak_ma = (motor.peak_current * 1000.0).min(p.peak_current_ma as f64);
        p.max_current_permille = libm::floor(peak_ma * 1000.0 / rated_ma) as u16;
        p.iit_time_motor_ms = libm::round(motor.i2t_time * 1000.0) as u16;
        p.max_motor_speed_rpm = libm::round(motor.max_speed_rpm) as u32;
        p
    }

    /// Maximum current (A) = 6075h × 6073h / 1000, never above the device peak 6510h:41.
    pub fn max_current_a(&self) -> f64 {
        let i = max_current_ma(self.motor_rated_current_ma, self.max_current_permille);
        i.min(self.peak_current_ma as f64) / 1000.0
    }

    /// Rated current (A) of 6075h.
    pub fn rated_current_a(&self) -> f64 {
        self.motor_rated_current_ma as f64 / 1000.0
    }

    /// Current (A) for a torque in ‰ of 6076h motor_rated_torque. 6076h is the torque at
    /// 6075h (both nameplate values; CMMP-AS §7.7 ties 6072h to 6073h), so ‰ of rated
    /// torque = ‰ of rated current.
    pub fn current_for_torque_permille(&self, permille: f64) -> f64 {
        self.rated_current_a() * permille / 1000.0
    }

    /// Converts the parameters to SI gains for a motor whose encoder has
    /// `increments_per_rev` increments per revolution.
    pub fn gains(&self, increments_per_rev: u32) -> Gains {
        Gains::new(self, increments_per_rev)
    }
}

/// First-order (PT1) filter coefficient `1 − e^(−T/Tf)` for a sample time `t` and filter
/// time `tf` (both s); 1 = no filtering.
fn pt1_alpha(t: f64, tf: f64) -> f64 {
    if tf <= 0.0 {
        1.0
    } else {
        1.0 - libm::exp(-t / tf)
    }
}

/// Integral increment per sample `Kp·T/Tn`; `Tn = 0` means no integrator.
fn integral_gain(kp: f64, t: f64, tn_us: u16) -> f64 {
    if tn_us == 0 {
        0.0
    } else {
        kp * t / (tn_us as f64 * 1e-6)
    }
}

/// The parameters converted to SI units and per-sample coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gains {
    /// Current-loop cycle, s.
    pub dt: f64,
    /// Velocity / position loop run every `vel_every` / `pos_every` current cycles.
    pub vel_every: u32,
    pub pos_every: u32,
    /// Current controller: Kp (V/A), integral per cycle (V/A).
    pub cur_kp: f64,
    pub cur_ki: f64,
    /// Voltage limit of the DC-equivalent winding, V: a three-phase bridge with space-vector
    /// modulation reaches a phase RMS voltage of U_DC/√6, i.e. 3·U_DC/√6 = U_DC·√(3/2) in the
    /// equivalent model of [`crate::motor`] (398 V at 325 V DC link).
    pub u_max: f64,
    /// Velocity controller: Kp (A·s/rad), integral per velocity cycle (A·s/rad).
    pub vel_kp: f64,
    pub vel_ki: f64,
    /// Speed from an encoder difference over one velocity cycle: rad/s per increment.
    pub vel_per_inc: f64,
    /// PT1 coefficients of the actual-speed filter (60F9h:04) and display filter (2073h),
    /// per velocity cycle.
    pub vel_filter: f64,
    pub display_filter: f64,
    /// Position controller: Kv (1/s per increment of error → rad/s), integral per position
    /// cycle, output clamp (rad/s), dead band (increments).
    pub pos_kv: f64,
    pub pos_ki: f64,
    pub pos_vmax: f64,
    pub pos_window: i64,
    /// Limit of every speed set-point (6080h), rad/s.
    pub max_speed: f64,
    /// Current limits, A: 6073h (with 6510h:41), 2415h (∞ when off), 6075h.
    pub i_max: f64,
    pub i_limitation: f64,
    pub i_rated: f64,
    /// I²t: ∫(i² − I_rated²)dt that makes 100 % = (I_max² − I_rated²) × 6410h:03.
    pub i2t_full: f64,
    /// The current set-point's filters, per current cycle.
    pub filters: CurrentFilters,
}

/// √(3/2): DC-link voltage → largest equivalent winding voltage (see [`Gains::u_max`]).
pub const SQRT_3_2: f64 = 1.224_744_871_391_589;

/// Loop ratio `slow / fast`, at least 1 (cycle times that are not multiples are rounded).
fn ratio(slow_us: u32, fast_us: u32) -> u32 {
    if fast_us == 0 {
        return 1;
    }
    let r = slow_us.saturating_add(fast_us / 2) / fast_us;
    r.max(1)
}

impl Gains {
    pub fn new(p: &ControlParams, increments_per_rev: u32) -> Self {
        let cur_us = if p.cycletime_current_us == 0 {
            125
        } else {
            p.cycletime_current_us
        };
        let dt = cur_us as f64 * 1e-6;
        let vel_every = ratio(p.cycletime_velocity_us, cur_us);
        let pos_every = ratio(p.cycletime_position_us, cur_us);
        let dt_vel = dt * vel_every as f64;
        let dt_pos = dt * pos_every as f64;
        let inc = if increments_per_rev == 0 {
            crate::motor::INCREMENTS_PER_REV
        } else {
            increments_per_rev
        };
        let rad_per_inc = 2.0 * core::f64::consts::PI / inc as f64;

        let i_peak_dev = (p.peak_current_ma.max(1)) as f64 / 1000.0;
        let u_nom = p.nominal_dc_link_voltage_mv as f64 / 1000.0;

        let cur_kp = gain_from_raw(p.torque_control_gain) * u_nom / i_peak_dev;
        let vel_kp = gain_from_raw(p.velocity_control_gain) * i_peak_dev / (1000.0 * RPM_TO_RAD_S);
        let pos_kv = gain_from_raw(p.position_control_gain) * 100.0;

        let i_max = p.max_current_a();
        let i_rated = p.rated_current_a();
        let i2t_full =
            ((i_max * i_max - i_rated * i_rated) * p.iit_time_motor_ms as f64 * 1e-3).max(1e-12);
        Gains {
            dt,
            vel_every,
            pos_every,
            cur_kp,
            cur_ki: integral_gain(cur_kp, dt, p.torque_control_time_us),
            u_max: p.dc_link_voltage_mv as f64 / 1000.0 * SQRT_3_2,
            vel_kp,
            vel_ki: integral_gain(vel_kp, dt_vel, p.velocity_control_time_us),
            vel_per_inc: rad_per_inc / dt_vel,
            vel_filter: pt1_alpha(dt_vel, p.velocity_control_filter_time_us as f64 * 1e-6),
            display_filter: pt1_alpha(dt_vel, p.velocity_display_filter_time_us as f64 * 1e-6),
            pos_kv: pos_kv * rad_per_inc,
            pos_ki: integral_gain(pos_kv * rad_per_inc, dt_pos, p.position_control_time_us),
            pos_vmax: p.position_control_v_max_rpm as f64 * RPM_TO_RAD_S,
            pos_window: p.position_error_tolerance_window as i64,
            max_speed: p.max_motor_speed_rpm as f64 * RPM_TO_RAD_S,
            i_max,
            i_limitation: match p.limit_current_ma {
                Some(ma) => ma as f64 / 1000.0,
                None => f64::INFINITY,
            },
            i_rated,
            i2t_full,
            filters: CurrentFilters::new(&p.filters, dt),
        }
    }
}

/// `x` limited to ±`lim`.
pub fn clamp(x: f64, lim: f64) -> f64 {
    if x > lim {
        lim
    } else if x < -lim {
        -lim
    } else {
        x
    }
}

/// A PI controller with output clamp and conditional integration (the integrator holds
/// while the output is saturated in the direction of the error), so it does not wind up.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pi {
    pub integral: f64,
}

impl Pi {
    /// One sample: error `e`, proportional gain `kp`, integral increment per unit error `ki`,
    /// output limit `lim` (≥ 0). Returns the output before the clamp to ±`lim` (the caller
    /// clamps it, and can tell whether it limited); the integrator stays within ±`lim`.
    #[inline]
    pub fn step(&mut self, e: f64, kp: f64, ki: f64, lim: f64) -> f64 {
        let i = self.integral + ki * e;
        let u = kp * e + i;
        if (u <= lim || e < 0.0) && (u >= -lim || e > 0.0) {
            self.integral = clamp(i, lim);
        }
        u
    }

    pub fn reset(&mut self) {
        self.integral = 0.0;
    }
}

/// Motor I²t monitor (6410h:03/04, statusword bit 11, error 31-0).
///
/// Integrates `i² − I_rated²` and reports the ratio to `(I_max² − I_rated²) × 6410h:03`, so
/// 100 % is reached after max_current has flowed for iit_time_motor from cold, as the manual
/// describes ("after the I²t time the current is limited to 6075h"). From 100 % on, the
/// current is limited to the rated current; the limit is released once the load has fallen
/// to 95 % (a hysteresis of this implementation, so the flag does not chatter while the
/// current sits at the rated value).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct I2t {
    /// ∫(i² − I_rated²)dt, A²·s, within [0, full].
    pub acc: f64,
    pub active: bool,
}

/// Ratio at which an active I²t limit is released.
pub const I2T_RELEASE: f64 = 0.95;

impl I2t {
    #[inline]
    pub fn step(&mut self, i: f64, g: &Gains) {
        let acc = self.acc + (i * i - g.i_rated * g.i_rated) * g.dt;
        self.acc = acc.max(0.0).min(g.i2t_full);
        let ratio = self.acc / g.i2t_full;
        if ratio >= 1.0 {
            self.active = true;
        } else if ratio < I2T_RELEASE {
            self.active = false;
        }
    }

    /// Load ratio 0…1.
    pub fn ratio(&self, g: &Gains) -> f64 {
        (self.acc / g.i2t_full).min(1.0)
    }
}
