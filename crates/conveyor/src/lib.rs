//! A belt conveyor, the model of the example load FMU (FMI 3.0 §4 "Co-Simulation"): the machine
//! a drivetwin drive takes as its load (`[drive.load]`, docs/cosimulation.md).
//!
//! Inputs: the motor shaft's angle and speed (and, for an importer that gives it, the motor's
//! torque, which this model reports back as `motor_torque_seen` and does not integrate: the belt
//! is coupled through its elasticity, [`belt`]). Outputs: the torque the belt puts on the shaft,
//! the belt's position and speed, and a light barrier that is `true` while the belt position is
//! within `barrier_from` … `barrier_to`.
//!
//! This crate is the model alone, safe Rust: the belt, its FMI variables (`FmuModel` derive)
//! and the FMI 3.0 and 2.0 model descriptions written from them ([`description`]). The FMU's
//! C library (the FMI 3.0 functions of `fmi_export::export_fmu!`, the FMI 2.0 ones written by
//! hand) and its packer are the `conveyor-fmu` crate.

pub mod belt;
pub mod description;

use belt::{Belt, BeltData};
use fmi::fmi3::{Fmi3Error, Fmi3Res};
use fmi_export::{
    fmi3::{CSDoStepResult, Context, DefaultLoggingCategory, UserModel},
    FmuModel,
};

/// A belt conveyor driven by a servo motor through a toothed belt, with a light barrier.
#[derive(FmuModel, Default, Debug)]
#[model(model_exchange = false, co_simulation = true, user_model = false)]
pub struct Conveyor {
    /// Motor shaft angle, rad.
    #[variable(causality = Input, variability = Continuous, start = 0.0)]
    pub shaft_angle: f64,
    /// Motor shaft speed, rad/s.
    #[variable(causality = Input, variability = Continuous, start = 0.0)]
    pub shaft_speed: f64,
    /// The motor's electromagnetic torque, N·m (reported back, not integrated).
    #[variable(causality = Input, variability = Continuous, start = 0.0)]
    pub motor_torque: f64,

    /// Torque of the belt on the motor shaft, N·m, towards negative rotation.
    #[variable(causality = Output, variability = Continuous)]
    pub load_torque: f64,
    /// Position of the belt (and its goods), m.
    #[variable(causality = Output, variability = Continuous)]
    pub belt_position: f64,
    /// Speed of the belt, m/s.
    #[variable(causality = Output, variability = Continuous)]
    pub belt_speed: f64,
    /// The motor torque of the last step's inputs, N·m.
    #[variable(causality = Output, variability = Continuous)]
    pub motor_torque_seen: f64,
    /// Light barrier: true while the belt position is within `barrier_from` … `barrier_to`.
    #[variable(causality = Output, variability = Discrete)]
    pub light_barrier: bool,

    /// Moving mass, kg.
    #[variable(causality = Parameter, variability = Fixed, start = 0.5)]
    pub mass: f64,
    /// Pulley radius, m (belt travel per shaft radian).
    #[variable(causality = Parameter, variability = Fixed, start = 0.01)]
    pub pulley_radius: f64,
    /// Belt stiffness, N/m.
    #[variable(causality = Parameter, variability = Fixed, start = 1.0e5)]
    pub stiffness: f64,
    /// Belt damping, N·s/m.
    #[variable(causality = Parameter, variability = Fixed, start = 100.0)]
    pub damping: f64,
    /// Viscous friction of the mass, N·s/m.
    #[variable(causality = Parameter, variability = Fixed, start = 5.0)]
    pub viscous_friction: f64,
    /// Coulomb friction of the mass, N.
    #[variable(causality = Parameter, variability = Fixed, start = 2.0)]
    pub coulomb_friction: f64,
    /// Start of the light barrier's window, m.
    #[variable(causality = Parameter, variability = Fixed, start = 0.10)]
    pub barrier_from: f64,
    /// End of the light barrier's window, m.
    #[variable(causality = Parameter, variability = Fixed, start = 0.12)]
    pub barrier_to: f64,

    /// The mass's state.
    #[variable(skip = true)]
    belt: Belt,
}

impl Conveyor {
    fn data(&self) -> BeltData {
        BeltData {
            mass: self.mass,
            pulley_radius: self.pulley_radius,
            stiffness: self.stiffness,
            damping: self.damping,
            viscous_friction: self.viscous_friction,
            coulomb_friction: self.coulomb_friction,
        }
    }

    /// One communication step of `h` s, the same for the FMI 3.0 and the FMI 2.0 interface:
    /// the belt is stepped while the shaft turns on at its speed, and the outputs are those of
    /// the step's end until the importer sets the next inputs. The error is the message the
    /// FMU logs with its `Error` status.
    pub fn advance(&mut self, h: f64) -> Result<(), String> {
        if !h.is_finite() || h < 0.0 {
            return Err(format!("communication step size {h} s is not a time"));
        }
        if self.mass.is_nan() || self.mass <= 0.0 {
            return Err(format!("mass {} kg must be positive", self.mass));
        }
        let d = self.data();
        self.belt.step(&d, self.shaft_angle, self.shaft_speed, h);
        self.shaft_angle += self.shaft_speed * h;
        self.outputs();
        Ok(())
    }

    /// The outputs from the state and the inputs.
    pub fn outputs(&mut self) {
        let d = self.data();
        self.load_torque = self
            .belt
            .load_torque(&d, self.shaft_angle, self.shaft_speed);
        self.belt_position = self.belt.position;
        self.belt_speed = self.belt.speed;
        self.motor_torque_seen = self.motor_torque;
        self.light_barrier =
            self.belt.position >= self.barrier_from && self.belt.position <= self.barrier_to;
    }
}

impl UserModel for Conveyor {
    type LoggingCategory = DefaultLoggingCategory;

    fn calculate_values(&mut self, _context: &dyn Context<Self>) -> Result<Fmi3Res, Fmi3Error> {
        self.outputs();
        Ok(Fmi3Res::OK)
    }

    fn do_step(
        &mut self,
        context: &mut dyn Context<Self>,
        current_communication_point: f64,
        communication_step_size: f64,
        _no_set_fmu_state_prior_to_current_point: bool,
    ) -> Result<CSDoStepResult, Fmi3Error> {
        if let Err(message) = self.advance(communication_step_size) {
            context.log(
                Fmi3Error::Error.into(),
                DefaultLoggingCategory::LogAll,
                format_args!("{message}"),
            );
            return Err(Fmi3Error::Error);
        }
        let end = current_communication_point + communication_step_size;
        context.set_time(end);
        Ok(CSDoStepResult::completed(end))
    }
}
