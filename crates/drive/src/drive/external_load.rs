//! A load outside the drive: a machine model (a conveyor, a vertical axis, the cam that trips
//! the home switch) that sees the motor shaft every plant cycle and answers with the torque it
//! puts on the shaft and the levels of the switches it actuates.
//!
//! The engine knows no model format: the std binary couples an FMI co-simulation unit through
//! this trait (docs/cosimulation.md). Each plant cycle of `dt` at `now` first hands the load
//! the shaft as it is at `now` (the motor's torque, angle and speed), lets it advance to
//! `now + dt`, takes back its load torque (held over the cycle, as the constant load torque of
//! [`crate::motor::MotorData::load_torque`] is) and its switches (through the same forcing
//! as a console's [`Drive::set_switch`]), and then steps the plant. The cycles are the ones
//! [`Drive::step`] runs; the logic runs on the same cycles as there.

use od::Instant;

use super::named_switches::NamedSwitch;
use super::Drive;
use crate::personality::Vendor;

/// The motor shaft as the load sees it at the start of a plant cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Shaft {
    /// The motor's torque on the shaft, N·m (Kt·i; the stepper's torque).
    pub motor_torque_nm: f64,
    /// Shaft angle, rad.
    pub angle_rad: f64,
    /// Shaft speed, rad/s.
    pub velocity_rad_s: f64,
}

/// What the load gives back for one plant cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LoadReaction {
    /// The load's torque on the shaft, N·m, towards negative rotation.
    pub torque_nm: f64,
    /// The switches whose level changed, in [`SWITCHES`]' order: `Some(true)` actuated,
    /// `Some(false)` released, `None` left as they are.
    pub switches: [Option<bool>; 3],
}

/// The switches a load can actuate, in [`LoadReaction::switches`]' order.
pub const SWITCHES: [NamedSwitch; 3] = [
    NamedSwitch::LimitPositive,
    NamedSwitch::LimitNegative,
    NamedSwitch::Home,
];

/// A machine model coupled to the shaft, stepped once per plant cycle.
pub trait ExternalLoad {
    /// Why the load could not step (the cell stops with it).
    type Error;

    /// Advances the load from `now` by `dt_s` s with the shaft as it is at `now`.
    fn plant_step(
        &mut self,
        now: Instant,
        dt_s: f64,
        shaft: Shaft,
    ) -> Result<LoadReaction, Self::Error>;
}

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// [`Drive::step`] with `load` stepped before each plant cycle. An error of the load ends
    /// the step at the cycle it happened in (that cycle's plant is not stepped) and is returned.
    pub fn step_with_load<L: ExternalLoad>(
        &mut self,
        now: Instant,
        load: &mut L,
    ) -> Result<Option<Instant>, L::Error> {
        self.step_epoch = self.step_epoch.wrapping_add(1);
        let dt = self.cycle.as_secs_f64();
        let next = self.step_cycles(now, |drive, at| {
            let reaction = load.plant_step(at, dt, drive.shaft())?;
            drive.apply_load(&reaction);
            Ok(())
        });
        self.step_epoch = self.step_epoch.wrapping_add(1);
        next.map(Some)
    }

    /// The shaft as an external load sees it.
    pub fn shaft(&self) -> Shaft {
        match &self.stepper {
            Some(s) => Shaft {
                motor_torque_nm: s.motor.torque(),
                angle_rad: s.motor.angle(),
                velocity_rad_s: s.motor.velocity(),
            },
            None => {
                let m = self.axis.motor();
                Shaft {
                    motor_torque_nm: m.torque(),
                    angle_rad: m.angle(),
                    velocity_rad_s: m.velocity(),
                }
            }
        }
    }

    fn apply_load(&mut self, reaction: &LoadReaction) {
        match &mut self.stepper {
            Some(s) => s.motor.set_load_torque(reaction.torque_nm),
            None => self.axis.motor_mut().set_load_torque(reaction.torque_nm),
        }
        for (switch, level) in SWITCHES.iter().zip(reaction.switches) {
            if let Some(on) = level {
                self.set_switch(*switch, Some(on));
            }
        }
    }
}
