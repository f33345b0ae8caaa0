//! `[drive.load]`: a co-simulation FMU as the drive's load, and the table naming which of its
//! variables is which quantity of the shaft (docs/cosimulation.md).
//!
//! ```toml
//! [drive.load]
//! fmu = "conveyor.fmu"           # relative to the cell file
//! torque = "motor_torque"        # Float64 input  ← the motor's torque, N·m
//! speed = "shaft_speed"          # Float64 input  ← the shaft speed, rad/s
//! angle = "shaft_angle"          # Float64 input  ← the shaft angle, rad
//! load_torque = "load_torque"    # Float64 output → the torque on the shaft, N·m
//! position = "belt_position"     # Float64 output → the load's position, reported
//! [drive.load.switches]          # Boolean outputs → the drive's switches, by name
//! home = "light_barrier"
//! [drive.load.parameters]        # Float64 parameters, set before the FMU initialises
//! mass = 0.8
//! ```

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::Deserialize;

use crate::cosim::mapping::LoadMapping;

/// `[drive.load]` as written.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LoadSection {
    pub fmu: PathBuf,
    pub torque: Option<String>,
    pub speed: Option<String>,
    pub angle: Option<String>,
    pub load_torque: String,
    pub position: Option<String>,
    #[serde(default)]
    pub switches: BTreeMap<String, String>,
    /// `[drive.load.parameters]`: the FMU's Float64 parameters, set before it initialises.
    #[serde(default)]
    pub parameters: BTreeMap<String, f64>,
}

impl LoadSection {
    /// The mapping it names (its FMU is opened, and its variables checked, when the cell is
    /// built).
    pub fn mapping(&self) -> LoadMapping {
        LoadMapping {
            fmu: self.fmu.clone(),
            torque: self.torque.clone(),
            speed: self.speed.clone(),
            angle: self.angle.clone(),
            load_torque: self.load_torque.clone(),
            position: self.position.clone(),
            switches: self.switches.clone(),
            parameters: self.parameters.clone(),
        }
    }
}
