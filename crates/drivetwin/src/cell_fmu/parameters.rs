//! The cell FMU's parameters: keys of the cell file that act when the cell is built, as FMI
//! parameters (`causality="parameter"`, `variability="fixed"`) an importer sets before the
//! FMU initialises.
//!
//! Per drive with a servo motor (a stepper's motor is another model), by its node-ID `N` (an
//! EtherCAT slave's drive by its place, `driveK`), the `[drive.motor]` keys of the load the
//! shaft carries:
//!
//! | name | unit | key |
//! |---|---|---|
//! | `nodeN.motor.inertia` | kg·m² | `[drive.motor] inertia`: rotor plus reflected load |
//! | `nodeN.motor.viscous_friction` | N·m·s/rad | `[drive.motor] viscous_friction` |
//! | `nodeN.motor.coulomb_friction` | N·m | `[drive.motor] coulomb_friction` |
//!
//! Per stepper (`[drive.stepper]`: a CMMO-ST by its place `driveK` among the cell file's
//! drives, [`DriveName`]; a Nanotec stepper by its node-ID), the keys of its motor and load:
//!
//! | name | unit | key |
//! |---|---|---|
//! | `driveK.stepper.load_inertia` | kg·m² | `[drive.stepper] load_inertia`: load reflected to the shaft |
//! | `driveK.stepper.viscous_friction` | N·m·s/rad | `[drive.stepper] viscous_friction` |
//! | `driveK.stepper.coulomb_friction` | N·m | `[drive.stepper] coulomb_friction` |
//! | `driveK.stepper.holding_torque` | N·m | `[drive.stepper] holding_torque`: the motor's |
//!
//! Their start values are the built cell's (the cell file's value, else the device's motor
//! data). A value set is written into the cell file's drive section before the cell is built,
//! so it is checked as the cell file's own key is (a negative inertia is refused with the
//! key's name). Value references are a range of their own, from [`FIRST_VALUE_REFERENCE`].
//!
//! Decision: the node-ID and the bus's bit rate are not parameters. A variable's name is its
//! drive's node-ID, written into the description, so a node-ID set at start would rename it;
//! a bus's rate follows its drives' switches and objects, and a rate the drives are not set to
//! silences them (the cell file's `bitrate` key stays the way to name it).

use std::fmt::Write;

use crate::cell::config::CellFile;
use crate::cell::Vendors;
use crate::scenario::virtual_rig::VirtualRig;

use super::variables::DriveName;
use super::CellFmuError;

/// The first parameter's value reference ("PA").
pub const FIRST_VALUE_REFERENCE: u32 = 0x5041_0000;
/// Value references per drive.
const STRIDE: u32 = 8;

/// A key of a drive's section that is a parameter: `[drive.motor]`'s of a servo drive,
/// `[drive.stepper]`'s of a CMMO-ST.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Key {
    Inertia,
    ViscousFriction,
    CoulombFriction,
    /// The stepper's load inertia (its rotor's is the motor's own, not a key).
    LoadInertia,
    StepperViscousFriction,
    StepperCoulombFriction,
    HoldingTorque,
}

impl Key {
    const SERVO: [Key; 3] = [Key::Inertia, Key::ViscousFriction, Key::CoulombFriction];
    const STEPPER: [Key; 4] = [
        Key::LoadInertia,
        Key::StepperViscousFriction,
        Key::StepperCoulombFriction,
        Key::HoldingTorque,
    ];

    /// The drive's section the key is in: `motor` or `stepper`.
    pub fn section(self) -> &'static str {
        match self {
            Key::Inertia | Key::ViscousFriction | Key::CoulombFriction => "motor",
            _ => "stepper",
        }
    }

    /// The key's name in its section.
    pub fn name(self) -> &'static str {
        match self {
            Key::Inertia => "inertia",
            Key::ViscousFriction | Key::StepperViscousFriction => "viscous_friction",
            Key::CoulombFriction | Key::StepperCoulombFriction => "coulomb_friction",
            Key::LoadInertia => "load_inertia",
            Key::HoldingTorque => "holding_torque",
        }
    }

    /// The unit's name in the description's `UnitDefinitions`, with its SI base units.
    pub fn unit(self) -> (&'static str, &'static str) {
        match self {
            Key::Inertia | Key::LoadInertia => ("kg.m2", r#"kg="1" m="2""#),
            Key::ViscousFriction | Key::StepperViscousFriction => {
                ("N.m.s/rad", r#"kg="1" m="2" s="-1" rad="-1""#)
            }
            Key::CoulombFriction | Key::StepperCoulombFriction | Key::HoldingTorque => {
                ("N.m", r#"kg="1" m="2" s="-2""#)
            }
        }
    }

    fn description(self) -> &'static str {
        match self {
            Key::Inertia => "rotor plus reflected load inertia ([drive.motor] inertia)",
            Key::ViscousFriction => {
                "viscous friction of the shaft ([drive.motor] viscous_friction)"
            }
            Key::CoulombFriction => {
                "Coulomb friction of the shaft ([drive.motor] coulomb_friction)"
            }
            Key::LoadInertia => {
                "load inertia reflected to the stepper's shaft ([drive.stepper] load_inertia)"
            }
            Key::StepperViscousFriction => {
                "viscous friction and iron losses of the stepper's shaft ([drive.stepper] viscous_friction)"
            }
            Key::StepperCoulombFriction => {
                "Coulomb friction of the stepper's shaft ([drive.stepper] coulomb_friction)"
            }
            Key::HoldingTorque => {
                "the stepper's holding torque at its rated current ([drive.stepper] holding_torque)"
            }
        }
    }

    fn offset(self) -> u32 {
        match self {
            Key::Inertia | Key::LoadInertia => 0,
            Key::ViscousFriction | Key::StepperViscousFriction => 1,
            Key::CoulombFriction | Key::StepperCoulombFriction => 2,
            Key::HoldingTorque => 3,
        }
    }

    fn of_motor(data: &drive::motor::MotorData, key: Key) -> f64 {
        match key {
            Key::Inertia => data.inertia,
            Key::ViscousFriction => data.viscous_friction,
            _ => data.coulomb_friction,
        }
    }

    fn of_stepper(data: &drive::stepper::StepperData, key: Key) -> f64 {
        match key {
            Key::LoadInertia => data.load_inertia,
            Key::StepperViscousFriction => data.viscous_friction,
            Key::StepperCoulombFriction => data.coulomb_friction,
            _ => data.holding_torque,
        }
    }
}

/// What a drive's parameters start at: its servo motor's data, or its stepper's (a CMMO-ST's
/// `[drive.stepper]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Start {
    Servo(drive::motor::MotorData),
    Stepper(drive::stepper::StepperData),
}

impl Start {
    /// A CiA 402 drive's: its stepper's data (a Nanotec stepper's `[drive.stepper]`), else
    /// its servo motor's; none for a dictionary without a plant.
    pub fn of_drive(drive: Option<&drive::vendors::AnyDrive<Vec<u8>>>) -> Option<Start> {
        let d = drive?;
        Some(match d.stepper() {
            Some(s) => Start::Stepper(*s.data()),
            None => Start::Servo(*d.axis().motor().data()),
        })
    }
}

/// One parameter, with its start value.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// Its drive, as its variables are named.
    pub drive: DriveName,
    pub key: Key,
    pub value_reference: u32,
    pub start: f64,
}

impl Parameter {
    pub fn name(&self) -> String {
        format!("{}.{}.{}", self.drive, self.key.section(), self.key.name())
    }
}

/// Whether `vr` is in the parameters' range (the cell need not be built to know it).
pub fn is_parameter(vr: u32) -> bool {
    (FIRST_VALUE_REFERENCE..FIRST_VALUE_REFERENCE + 0x1_0000).contains(&vr)
}

/// The parameters of a cell.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Parameters {
    pub list: Vec<Parameter>,
}

impl Parameters {
    /// The parameters of the CANopen drives `nodes` (drive `i` of the table is `nodes[i]`)
    /// of `rig`, their starts as the rig has built them, then of the CMMO-STs `steppers`
    /// (the `[[drive]]` section's index and the stepper it is built with), drive
    /// `nodes.len() + j` of the table, then the drives `more` (the EtherCAT slaves').
    pub fn of(
        rig: &VirtualRig,
        nodes: &[u8],
        steppers: &[(usize, drive::stepper::StepperData)],
        more: impl IntoIterator<Item = (DriveName, Option<Start>)>,
    ) -> Parameters {
        Parameters::of_drives(
            nodes
                .iter()
                .map(|n| (DriveName::Node(*n), Start::of_drive(rig.drive_model(*n))))
                .chain(
                    steppers
                        .iter()
                        .map(|(k, data)| (DriveName::Section(*k), Some(Start::Stepper(*data)))),
                )
                .chain(more),
        )
    }

    /// The parameters of the table's drives, drive `i` the `i`-th: each one's name and what
    /// its keys start at (`None`: a drive without keys to offer).
    pub fn of_drives(drives: impl IntoIterator<Item = (DriveName, Option<Start>)>) -> Parameters {
        let mut list = Vec::new();
        let base_of = |i: usize| {
            u32::try_from(i)
                .ok()
                .and_then(|i| i.checked_mul(STRIDE))
                .and_then(|o| o.checked_add(FIRST_VALUE_REFERENCE))
                .filter(|b| is_parameter(b + STRIDE - 1))
        };
        for (i, (drive, start)) in drives.into_iter().enumerate() {
            let (Some(start), Some(base)) = (start, base_of(i)) else {
                continue;
            };
            let (keys, value): (&[Key], &dyn Fn(Key) -> f64) = match &start {
                Start::Servo(data) => (&Key::SERVO, &|k| Key::of_motor(data, k)),
                Start::Stepper(data) => (&Key::STEPPER, &|k| Key::of_stepper(data, k)),
            };
            for key in keys {
                list.push(Parameter {
                    drive,
                    key: *key,
                    value_reference: base + key.offset(),
                    start: value(*key),
                });
            }
        }
        Parameters { list }
    }

    pub fn find(&self, vr: u32) -> Option<&Parameter> {
        self.list.iter().find(|p| p.value_reference == vr)
    }

    /// `file` with the values `set` (value reference, value) written into its drives'
    /// sections; a value reference that is no parameter is refused.
    pub fn apply(
        &self,
        file: &mut CellFile,
        vendors: Vendors,
        set: &[(u32, f64)],
    ) -> Result<(), CellFmuError> {
        if set.is_empty() {
            return Ok(());
        }
        let specs = file
            .drives(vendors)
            .map_err(|e| CellFmuError::Cell(e.to_string()))?;
        for (vr, value) in set {
            let p = self.find(*vr).ok_or(CellFmuError::UnknownVariable(*vr))?;
            let index = match p.drive {
                // The CANopen drive of that node-ID (a CMMO-ST may have the same number).
                DriveName::Node(n) => specs.iter().position(|s| s.node == n && s.fhpp.is_none()),
                DriveName::Section(k) => Some(k),
            };
            let section = index
                .and_then(|i| file.drive.get_mut(i))
                .ok_or_else(|| CellFmuError::Cell(format!("{}: no such drive", p.name())))?;
            let table = section
                .rest
                .entry(p.key.section())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            let toml::Value::Table(table) = table else {
                return Err(CellFmuError::Cell(format!(
                    "{}: `{}` is not a table",
                    p.drive,
                    p.key.section()
                )));
            };
            table.insert(p.key.name().into(), toml::Value::Float(*value));
        }
        Ok(())
    }

    /// The units the parameters name, each once.
    pub fn units(&self) -> Vec<(&'static str, &'static str)> {
        let mut units: Vec<(&'static str, &'static str)> = Vec::new();
        for p in &self.list {
            let u = p.key.unit();
            if !units.contains(&u) {
                units.push(u);
            }
        }
        units
    }

    /// The parameters as `ModelVariables` elements.
    pub fn write_variables(&self, x: &mut String) {
        for p in &self.list {
            let _ = writeln!(
                x,
                r#"    <Float64 name="{}" valueReference="{}" causality="parameter" variability="fixed" description="{}" unit="{}" start="{:?}"/>"#,
                p.name(),
                p.value_reference,
                p.key.description(),
                p.key.unit().0,
                p.start
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(text: &str) -> CellFile {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn a_servo_drive_has_its_motor_keys_as_parameters_with_the_cells_values() {
        let file =
            cell("[[drive]]\ndevice = \"cmmp-as\"\nnode = 3\n[drive.motor]\ninertia = 4e-5\n");
        let rig = VirtualRig::new(&file, crate::vendors::VENDORS.runtime).unwrap();
        let p = Parameters::of(&rig, &rig.nodes(), &[], []);
        let names: Vec<String> = p.list.iter().map(Parameter::name).collect();
        assert_eq!(
            names,
            [
                "node3.motor.inertia",
                "node3.motor.viscous_friction",
                "node3.motor.coulomb_friction"
            ]
        );
        assert_eq!(p.list[0].start, 4e-5);
        assert_eq!(p.list[0].value_reference, FIRST_VALUE_REFERENCE);
        assert!(p.list.iter().all(|p| is_parameter(p.value_reference)));
    }

    #[test]
    fn a_cmmo_st_has_its_stepper_keys_as_parameters_named_by_its_place() {
        let mut file = cell(
            "[[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n\
             [[drive]]\ndevice = \"cmmo-st\"\n[drive.stepper]\nload_inertia = 3e-5\n",
        );
        let vendors = crate::vendors::VENDORS.runtime;
        let steppers: Vec<_> = file
            .drives(vendors)
            .unwrap()
            .iter()
            .enumerate()
            .filter_map(|(k, s)| s.fhpp.as_ref().map(|f| (k, f.settings.stepper)))
            .collect();
        let rig = VirtualRig::new(&file, vendors).unwrap();
        let p = Parameters::of(&rig, &rig.nodes(), &steppers, []);
        let names: Vec<String> = p.list.iter().map(Parameter::name).collect();
        assert_eq!(
            names[3..],
            [
                "drive1.stepper.load_inertia",
                "drive1.stepper.viscous_friction",
                "drive1.stepper.coulomb_friction",
                "drive1.stepper.holding_torque"
            ]
        );
        assert_eq!(p.list[3].start, 3e-5);
        assert_eq!(p.list[6].start, 0.5);
        // The second drive of the table: the next range of value references.
        assert_eq!(p.list[3].value_reference, FIRST_VALUE_REFERENCE + STRIDE);
        assert!(p.units().contains(&Key::HoldingTorque.unit()));
        // Set, it is the key of the CMMO-ST's own section (the CMMP-AS at node 1 keeps its).
        p.apply(&mut file, vendors, &[(p.list[3].value_reference, 8e-5)])
            .unwrap();
        let specs = file.drives(vendors).unwrap();
        let stepper = specs[1].fhpp.as_ref().unwrap().settings.stepper;
        assert_eq!(stepper.load_inertia, 8e-5);
        assert!(file.drive[0].rest.get("stepper").is_none());
        // A negative one is refused as the key is.
        p.apply(&mut file, vendors, &[(p.list[3].value_reference, -1.0)])
            .unwrap();
        let e = file.drives(vendors).err().unwrap().to_string();
        assert!(e.contains("stepper.load_inertia"), "{e}");
    }

    #[test]
    fn a_value_set_is_the_cell_files_key_and_checked_as_it() {
        let mut file = cell("[[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n");
        let rig = VirtualRig::new(&file, crate::vendors::VENDORS.runtime).unwrap();
        let p = Parameters::of(&rig, &rig.nodes(), &[], []);
        let vr = p.list[0].value_reference;
        p.apply(&mut file, crate::vendors::VENDORS.runtime, &[(vr, 6e-5)])
            .unwrap();
        let rig = VirtualRig::new(&file, crate::vendors::VENDORS.runtime).unwrap();
        assert_eq!(
            Parameters::of(&rig, &rig.nodes(), &[], []).list[0].start,
            6e-5
        );
        // A negative inertia is refused as the cell file's key is.
        p.apply(&mut file, crate::vendors::VENDORS.runtime, &[(vr, -1.0)])
            .unwrap();
        let e = VirtualRig::new(&file, crate::vendors::VENDORS.runtime)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("inertia"), "{e}");
        assert!(p
            .apply(&mut file, crate::vendors::VENDORS.runtime, &[(vr + 7, 1.0)])
            .is_err());
    }
}
