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

use crate::cosim::mapping::LoadMapping;

/// `[drive.load]` as written: the mapping itself (its FMU is opened, and its variables
/// checked, when the cell is built).
pub type LoadSection = LoadMapping;

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::super::CellFile;

    #[test]
    fn the_table_is_read_with_its_switches_and_parameters() {
        let f: CellFile = toml::from_str(
            "[[drive]]\n[drive.load]\nfmu = \"c.fmu\"\nspeed = \"w\"\nload_torque = \"t\"\n\
             [drive.load.switches]\nhome = \"barrier\"\n[drive.load.parameters]\nmass = 2.0\n",
        )
        .unwrap();
        let m = f.drive[0].load.clone().unwrap();
        assert_eq!(m.speed.as_deref(), Some("w"));
        assert_eq!(m.load_torque, "t");
        assert_eq!(m.switches["home"], "barrier");
        assert_eq!(m.parameters["mass"], 2.0);
        assert_eq!(m.inputs().collect::<Vec<_>>(), [("speed", "w")]);
    }

    #[test]
    fn a_load_on_a_cmmo_st_is_taken_for_its_stepper() {
        let f: CellFile = toml::from_str(
            "[[drive]]\ndevice = \"cmmo-st\"\n[drive.load]\nfmu = \"c.fmu\"\nload_torque = \"t\"\n",
        )
        .unwrap();
        let specs = f.drives(crate::cell::Vendors::NONE).unwrap();
        assert_eq!(specs[0].load.as_ref().unwrap().load_torque, "t");
    }
}
