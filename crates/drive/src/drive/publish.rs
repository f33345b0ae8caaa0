//! The statusword 6041h and the actual values, written once per logic cycle: the state
//! bits and manufacturer bits from the personality, target reached, internal limit,
//! following error and the mode's bits 12 / 13, then positions, speeds, currents.
//!
//! Readouts are what the device reports, not the plant's raw state:
//! - CMMP-AS 606Ch is the actual speed through the velocity controller's filter 60F9h:04
//!   ("actual-speed filter", §5.4), as the controller uses it; 2074h the display value
//!   through 2073h (20 ms by default, §7.5.2: "for display only"). 6077h / 6078h: the manual
//!   names no filter; they are the current controller's measured values.
//! - Kinco 606Ch (Speed_Real) is the speed feedback through Speed_Fb_N 60F9h:05 (bandwidth
//!   100 + 20·N Hz, ch. 7); d1.25 Real_Speed_RPM the display value (`kinco_drive.rs`).
//! - Nanotec 6044h: 0 in open loop (§6.5: "only with closed loop activated is a value
//!   output"); in closed loop the encoder's speed through [`VL_ACTUAL_FILTER_S`].

use super::*;

/// **Decision:** the time constant of the Nanotec's measured speed 6044h in closed loop. The
/// manual names no filter (§6.5); 20 ms, the CMMP-AS display filter's default (2073h), reads
/// steady at the speeds a stepper runs (within 1 % at 60 min⁻¹) and still follows a ramp a
/// master polls every 100 ms.
pub const VL_ACTUAL_FILTER_S: f64 = 0.020;

/// The publishing sites of [`Drive::publish`] ([`Drive::publish_store`]): each stores one
/// entry, once per pass.
pub(crate) mod slot {
    pub(crate) const STATUSWORD: usize = 0;
    pub(crate) const DIGITAL_INPUTS: usize = 1;
    pub(crate) const MODE_DISPLAY: usize = 2;
    pub(crate) const POSITION_INTERNAL: usize = 3;
    pub(crate) const POSITION_ACTUAL: usize = 4;
    pub(crate) const POSITION_DEMAND: usize = 5;
    pub(crate) const FOLLOWING_ERROR: usize = 6;
    pub(crate) const VELOCITY_ACTUAL: usize = 7;
    pub(crate) const VELOCITY_DEMAND: usize = 8;
    pub(crate) const CONTROL_EFFORT: usize = 9;
    pub(crate) const CURRENT_ACTUAL: usize = 10;
    pub(crate) const TORQUE_ACTUAL: usize = 11;
    pub(crate) const TORQUE_DEMAND: usize = 12;
    pub(crate) const VL_VELOCITY_ACTUAL: usize = 13;
    pub(crate) const VELOCITY_FILTERED: usize = 14;
    /// The first of the vendor's sites (its hooks that `publish` calls store through them).
    pub(crate) const VENDOR: usize = 16;
    pub(crate) const COUNT: usize = 48;
}

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// Writes the statusword and every actual value.
    pub(super) fn publish(&mut self) {
        self.published.begin(self.od.stores());
        self.publish_values();
        self.published.end(self.od.stores());
    }

    fn publish_values(&mut self) {
        let state = self.dc.state();
        let power = !matches!(self.demand, Demand::Off);
        let v_act = i64::from(self.plant_velocity_internal());
        let threshold = self
            .fg
            .velocity_magnitude_to_internal(self.cycle_value(0x606F, 0).max(0) as u32);
        // |v| above velocity_threshold 606Fh; speed zero (PV bit 12) once it has been above
        // for 6070h.
        let moving = v_act.abs() > threshold;
        if moving {
            let since = *self.over_threshold_since.get_or_insert(self.now);
            let time = Duration::from_millis(self.cycle_value(0x6070, 0).max(0) as u64);
            if self.now.saturating_since(since) >= time {
                self.speed_zero = false;
            }
        } else {
            self.over_threshold_since = None;
            self.speed_zero = true;
        }
        let mut sw = V::state_bits(self, state, power, moving);
        let in_oe = state == State::OperationEnabled;
        sw |= Statusword::TARGET_REACHED.when(self.target_reached && in_oe);
        sw |= Statusword::INTERNAL_LIMIT_ACTIVE
            .when(self.axis.i2t_limit_active() || self.internal_limit);
        // Following error (PP): |actual − demand| > 6065h for 6066h.
        let demand_pos = crate::rounding::round(self.demand_position) as i64;
        let fe = self.actual_internal() - demand_pos;
        let fe_window = self.fg.position_magnitude_to_internal(
            self.cycle_value(0x6065, 0).clamp(0, u32::MAX as i64) as u32,
        );
        if power && fe.abs() > fe_window {
            let since = *self.fe_since.get_or_insert(self.now);
            let time = Duration::from_millis(self.cycle_value(0x6066, 0).max(0) as u64);
            self.following_error = self.now.saturating_since(since) >= time;
        } else {
            self.fe_since = None;
            self.following_error = false;
        }
        // 60F4h's value, for the vendor as well.
        let fe_user = self.fg.position_from_internal(fe);
        V::following_error(
            self,
            &crate::personality::FollowingError {
                increments: fe,
                window: fe_window,
                user: fe_user,
            },
        );
        // Nanotec §4.1: the following error is watched in closed loop only; an open-loop
        // stepper does not know it.
        let open_loop = self
            .stepper
            .as_ref()
            .is_some_and(|s| s.motor.mode() == crate::stepper::StepperMode::OpenLoop);
        let fe_bit = Statusword::FOLLOWING_ERROR.when(self.following_error && !open_loop);
        sw |= match self.mode {
            mode::PROFILE_POSITION => {
                Statusword::SET_POINT_ACKNOWLEDGE.when(self.setpoints.acknowledge) | fe_bit
            }
            mode::PROFILE_VELOCITY => Statusword::SPEED_ZERO.when(self.speed_zero),
            // Bit 12 ip_mode_active, bit 13 following error (CiA 402 interpolated position
            // mode).
            mode::INTERPOLATED_POSITION => {
                Statusword::IP_MODE_ACTIVE.when(self.ip.is_active()) | fe_bit
            }
            // CiA 402 CSP: bit 12 "drive follows the command value", bit 13 following error.
            mode::CYCLIC_SYNCHRONOUS_POSITION => {
                Statusword::OPERATION_MODE_SPECIFIC_12.when(in_oe) | fe_bit
            }
            mode::HOMING => {
                Statusword::HOMING_ATTAINED.when(self.homing_attained)
                    | Statusword::HOMING_ERROR.when(self.homing_error)
            }
            _ => Statusword::EMPTY,
        };
        sw |= V::manufacturer_bits(self);
        // Bit 7 warning (CiA 402 §6.3.2): the vendor's error management has a warning active.
        sw |= Statusword::WARNING.when(V::active_warning(self).is_some());
        let sw = sw.bits();
        self.publish_store(slot::STATUSWORD, self.hot.statusword, i64::from(sw));
        let position = self.plant_position();
        let inputs = V::digital_inputs(self, position);
        self.publish_store(
            slot::DIGITAL_INPUTS,
            self.hot.digital_inputs,
            i64::from(inputs),
        );
        // A personality with `ip_changing_until_synchronised`: in IP mode 6061h shows −1
        // until the drive is on the SYNC grid.
        let display = if self.mode_pending.is_some()
            || (self.mode == mode::INTERPOLATED_POSITION
                && !self.ip.is_synchronised()
                && self.personality.capabilities.ip_changing_until_synchronised)
        {
            mode::CHANGING
        } else {
            self.mode
        };
        self.publish_store(
            slot::MODE_DISPLAY,
            self.hot.mode_display,
            i64::from(display),
        );
        let actual = self.actual_internal();
        let fg = self.fg;
        let actual_user = fg.position_from_internal(actual);
        let caps = &self.personality.capabilities;
        let internal = if caps.feed_constant {
            self.encoder_position(actual)
        } else if caps.internal_position_in_user_units {
            i64::from(actual_user)
        } else {
            actual
        };
        self.publish_store(
            slot::POSITION_INTERNAL,
            self.hot.position_internal,
            internal,
        );
        self.publish_store(
            slot::POSITION_ACTUAL,
            self.hot.position_actual,
            i64::from(actual_user),
        );
        self.publish_store(
            slot::POSITION_DEMAND,
            self.hot.position_demand,
            i64::from(fg.position_from_internal(demand_pos)),
        );
        self.publish_store(
            slot::FOLLOWING_ERROR,
            self.hot.following_error_actual,
            i64::from(fe_user),
        );
        self.publish_store(
            slot::VELOCITY_ACTUAL,
            self.hot.velocity_actual,
            i64::from(fg.velocity_from_internal(v_act)),
        );
        let v_dem = match self.demand {
            Demand::Velocity { rpm } => f64::from(rpm) * 4096.0,
            _ => self.traj.velocity / INC_S_PER_VEL,
        };
        self.publish_store(
            slot::VELOCITY_DEMAND,
            self.hot.velocity_demand,
            i64::from(fg.velocity_from_internal(crate::rounding::round(v_dem) as i64)),
        );
        let effort =
            crate::rounding::round(f64::from(self.axis.control_effort_rpm()) * 4096.0) as i64;
        self.publish_store(
            slot::CONTROL_EFFORT,
            self.hot.control_effort,
            i64::from(fg.velocity_from_internal(effort)),
        );
        self.publish_store(
            slot::CURRENT_ACTUAL,
            self.hot.current_actual,
            i64::from(self.axis.current_permille()),
        );
        self.publish_store(
            slot::TORQUE_ACTUAL,
            self.hot.torque_actual,
            i64::from(self.axis.torque_permille()),
        );
        self.publish_store(
            slot::TORQUE_DEMAND,
            self.hot.torque_demand,
            i64::from(self.axis.torque_demand_permille()),
        );
        self.publish_velocity_readouts();
    }

    /// 6044h (the measured speed, or 0 where the personality shows it in closed loop only)
    /// and 2074h (the display-filtered speed). Each only where the dictionary has it.
    fn publish_velocity_readouts(&mut self) {
        if let Some(e) = self.hot.vl_velocity_actual {
            let dt = self.cycle.as_secs_f64() * f64::from(self.logic_every);
            let position = self.plant_position();
            let measured = self
                .velocity_readout
                .sample(position, dt, VL_ACTUAL_FILTER_S);
            let shown = !self.personality.capabilities.vl_actual_closed_loop_only
                || V::CLOSED_LOOP_OBJECT.is_some_and(|(index, sub)| self.value(index, sub) != 0);
            let v = if shown {
                self.vl_actual_user(measured)
            } else {
                0
            };
            self.publish_store(slot::VL_VELOCITY_ACTUAL, Some(e), v);
        }
        if let Some(e) = self.hot.velocity_actual_filtered {
            let internal = f64::from(self.axis.velocity_display_rpm()) * 4096.0;
            let v = self
                .fg
                .velocity_from_internal(crate::rounding::round(internal) as i64);
            self.publish_store(slot::VELOCITY_FILTERED, Some(e), i64::from(v));
        }
    }
}
