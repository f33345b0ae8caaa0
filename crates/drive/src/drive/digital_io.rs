//! The digital inputs and outputs: input levels, forced inputs, limit and reference switches
//! and the axis's hard stops.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// Mechanical hard stops of the travel into the motor model.
    pub(super) fn place_hard_stops(&mut self) {
        let t = self.settings.travel;
        let rad = self.axis.motor().rad_per_increment();
        self.axis.motor_mut().set_stops(
            t.negative_stop.map(|p| p as f64 * rad),
            t.positive_stop.map(|p| p as f64 * rad),
        );
        // The stepper plant has the same stops (a shaft angle, 65536 increments a turn).
        if let Some(s) = self.stepper.as_mut() {
            let rad = core::f64::consts::TAU / 65536.0;
            let stops = match (t.negative_stop, t.positive_stop) {
                (None, None) => None,
                (lo, hi) => Some((
                    lo.map_or(f64::MIN, |p| p as f64 * rad),
                    hi.map_or(f64::MAX, |p| p as f64 * rad),
                )),
            };
            s.motor.set_end_stops(stops);
        }
    }

    /// Outside homing a limit switch blocks motion towards it where the personality has an
    /// error for it: the error's fault reaction brakes with the vendor's emergency ramp (the
    /// hook `emergency_deceleration`); motion away stays possible after the fault reset.
    pub(super) fn supervise_limit_switches(&mut self) {
        let inputs = self.switch_inputs(self.plant_position());
        let v = self.traj.velocity;
        let fault = if inputs.negative_limit && v < 0.0 {
            Fault::LimitSwitchNegative
        } else if inputs.positive_limit && v > 0.0 {
            Fault::LimitSwitchPositive
        } else {
            return;
        };
        if self.personality.error(fault).is_some() {
            self.limit_stop = true;
            self.raise_fault(fault);
        }
    }

    /// The input levels at `position`: the simulated wiring (the vendor's `INPUT_WIRING`:
    /// the travel's switches and the hardware enables) with the forced inputs over it.
    pub(crate) fn input_levels(&self, position: i64) -> Levels {
        Levels::wired(
            &V::INPUT_WIRING,
            self.settings.travel.inputs(position),
            self.settings.enables_present,
        )
        .forced(self.forced_mask, self.forced_levels)
    }

    /// The switches as the drive reads them (the vendor hook `switches`): a polarity set
    /// against the normally open switches of the simulation reads them inverted, and swapped
    /// limit-switch inputs are a wiring set-up the homing then trips over, as on a real
    /// drive.
    pub(super) fn switch_inputs(&self, position: i64) -> Inputs {
        V::switches(self, position)
    }

    /// Drives digital inputs from outside (a test, a fault injection): the inputs in `mask`
    /// (bit n = the vendor's input n) take the level in `levels`; the others follow the
    /// simulated wiring. Forcing an input of the wiring's hardware enables LOW removes the
    /// enable (60FDh bit 3 interlock).
    pub fn force_inputs(&mut self, mask: u16, levels: u16) {
        self.forced_mask = mask;
        self.forced_levels = levels;
    }

    /// The output levels the host commands through 60FEh (CMMP-AS §5.13): bit 0 the holding
    /// brake (1 = applied), the other bits of 60FEh:01 where 60FEh:02 puts them under bus
    /// control. Outputs left to their 2420h function are not simulated and read 0.
    pub fn digital_outputs(&self) -> u32 {
        let data = self.value(0x60FE, 1) as u32;
        let mask = self.value(0x60FE, 2) as u32;
        (data & mask & !1) | u32::from(self.axis.motor().brake())
    }
}
