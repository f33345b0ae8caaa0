// ---- a load outside the device ([`crate::drive::external_load`])
//!
//! A machine model coupled to the CMMO-ST's shaft steps with the FHPP cycle: before each
//! cycle of `dt` at `now` it sees the shaft as it is at `now` (the stepper's torque, angle and
//! speed), advances to `now + dt`, and its load torque holds on the stepper over the cycle's
//! sub-steps, as the constant load torque of [`Stepper::set_load_torque`] does.
//!
//! # Decisions
//!
//! - **The load's switches.** The CMMO-ST has one switch input the twin models, the
//!   reference switch of homing methods 23 / 27 (§6.2, a digital input of the controller): a
//!   load's `home` switch drives it (and so does [`FhppDevice::force_reference_switch`]), in
//!   place of the cam of [`AxisMechanics::reference_switch`]. Its ends of travel are fixed
//!   stops ([`AxisMechanics::end_stops`]), not switch inputs: a load's limit switches have no
//!   input to go to and are not applied (the binary refuses to map them).

use super::*;
use crate::drive::external_load::{ExternalLoad, LoadReaction, Shaft, SWITCHES};
use crate::drive::named_switches::NamedSwitch;

impl<S: AsRef<[u8]> + AsMut<[u8]>> FhppDevice<S> {
    /// [`FhppDevice::step`] with `load` stepped before each FHPP cycle. An error of the load
    /// ends the step at the cycle it happened in (that cycle does not run) and is returned.
    pub fn step_with_load<L: ExternalLoad>(
        &mut self,
        now: Instant,
        load: &mut L,
    ) -> Result<Option<Instant>, L::Error> {
        let cycle = if self.settings.cycle.is_zero() {
            Duration::from_millis(1)
        } else {
            self.settings.cycle
        };
        let dt = cycle.as_secs_f64();
        let mut next = self.next.unwrap_or(now);
        let mut n = 0;
        while next <= now {
            if n == 1000 {
                // As `step`: more than a second behind, skip, do not spiral.
                next = now + cycle;
                break;
            }
            let reaction = match load.plant_step(next, dt, self.shaft()) {
                Ok(r) => r,
                Err(e) => {
                    self.next = Some(next);
                    return Err(e);
                }
            };
            self.apply_load(&reaction);
            self.cycle(dt);
            next = next + cycle;
            n += 1;
        }
        self.next = Some(next);
        Ok(self.next)
    }

    /// The shaft as an external load sees it.
    pub fn shaft(&self) -> Shaft {
        Shaft {
            motor_torque_nm: self.stepper.torque(),
            angle_rad: self.stepper.angle(),
            velocity_rad_s: self.stepper.velocity(),
        }
    }

    /// Holds the reference switch input at `level` (`None`: the cam of the mechanics again).
    pub fn force_reference_switch(&mut self, level: Option<bool>) {
        self.reference_forced = level;
    }

    /// The reference switch input at shaft angle `angle` rad: forced, or the cam's.
    pub(super) fn reference_switch(&self, angle: f64) -> bool {
        self.reference_forced
            .unwrap_or_else(|| self.settings.mechanics.switch_active(angle))
    }

    fn apply_load(&mut self, reaction: &LoadReaction) {
        self.stepper.set_load_torque(reaction.torque_nm);
        for (switch, level) in SWITCHES.iter().zip(reaction.switches) {
            if let (NamedSwitch::Home, Some(on)) = (switch, level) {
                self.reference_forced = Some(on);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    extern crate std;

    use super::*;
    use std::vec::Vec;

    fn device() -> FhppDevice<Vec<u8>> {
        let desc = &devices::CMMO_ST;
        let od = ObjectDictionary::new(desc, 1, std::vec![0u8; desc.storage_size]).unwrap();
        FhppDevice::new(od, FhppSettings::default())
    }

    /// A load that pushes with a constant torque and sees the shaft, once per cycle.
    struct Constant {
        torque: f64,
        seen: Vec<(Instant, f64, Shaft)>,
        home_from_step: Option<usize>,
    }

    impl ExternalLoad for Constant {
        type Error = ();
        fn plant_step(&mut self, now: Instant, dt: f64, shaft: Shaft) -> Result<LoadReaction, ()> {
            self.seen.push((now, dt, shaft));
            let mut switches = [None; 3];
            if self.home_from_step == Some(self.seen.len()) {
                switches[2] = Some(true);
            }
            Ok(LoadReaction {
                torque_nm: self.torque,
                switches,
            })
        }
    }

    #[test]
    fn the_load_steps_once_per_fhpp_cycle_and_its_torque_holds_on_the_stepper() {
        let mut d = device();
        let mut load = Constant {
            torque: 0.05,
            seen: Vec::new(),
            home_from_step: Some(3),
        };
        d.step_with_load(Instant::ZERO, &mut load).unwrap();
        d.step_with_load(Instant::from_millis(4), &mut load)
            .unwrap();
        let times: Vec<u64> = load.seen.iter().map(|(t, _, _)| t.as_nanos()).collect();
        assert_eq!(times, [0, 1_000_000, 2_000_000, 3_000_000, 4_000_000]);
        assert!(load.seen.iter().all(|(_, dt, _)| *dt == 1e-3));
        assert_eq!(d.stepper().load_torque(), 0.05);
        // The load's home switch is the reference switch from its third cycle on.
        assert!(d.reference_switch(100.0));
    }
}
