//! The cell FMU's variables: per CANopen drive of the cell (by its node-ID `N`), in the order
//! of the cell file's buses and drives,
//!
//! | name | type | causality | unit | what |
//! |---|---|---|---|---|
//! | `nodeN.load_torque` | Float64 | input | N·m | the load torque on the motor shaft |
//! | `nodeN.dinK` (K = 0 … 15) | Boolean | input | | digital input K, forced to this level once set |
//! | `nodeN.position` | Float64 | output | rad | the motor shaft's angle (the plant's) |
//! | `nodeN.velocity` | Float64 | output | rad/s | the shaft's angular velocity |
//! | `nodeN.current` | Float64 | output | A | the winding current |
//! | `nodeN.statusword` | UInt16 | output | | 6041h |
//! | `nodeN.position_actual` | Int32 | output | | 6064h, in the drive's position units |
//! | `nodeN.display` | String | output | | what the drive's display shows ("" without one) |
//!
//! A drive with the FHPP register image (the CMMO-ST, FHPP over Modbus) has no CANopen node:
//! its variables are named by its place among the cell file's `[[drive]]` sections, `driveK`
//! (K from 0, as the LS-BUS terminals `canB` count the `[[bus]]` sections; [`DriveName`]). After the CANopen drives and in
//! the cell file's order, it has `driveK.load_torque`, `driveK.reference_switch` (Boolean
//! input: its reference switch, forced once set), `driveK.position`, `driveK.velocity`,
//! `driveK.current`, `driveK.scon` and `driveK.spos` (UInt8 outputs: FHPP status bytes 1 and
//! 2), `driveK.position_actual` (its actual position in its position unit) and
//! `driveK.display`.
//!
//! A drive without a CANopen node (a slave of an EtherCAT chain alone) is named by its place in
//! the cell file, `driveK` after its 0-based `[[drive]]` index ([`DriveName::Section`]), and has a
//! CiA 402 drive's variables; those drives come after the others, in the cell file's order.
//!
//! Value reference 0 is the independent variable `time`; each drive's variables follow the
//! last drive's in the table's order (a CiA 402 drive's take [`STRIDE`], so drive `i` of a cell
//! of CiA 402 drives starts at `1 + i · STRIDE`).

/// How many digital inputs each CiA 402 drive shows (the bits of its forced-input mask).
pub const DIGITAL_INPUTS: u8 = 16;

/// Variables per CiA 402 drive.
pub const STRIDE: u32 = 7 + DIGITAL_INPUTS as u32;

/// The device profile a drive's variables follow.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Profile {
    /// A CANopen drive of the cell's buses (CiA 402 words, 16 digital inputs).
    Cia402,
    /// A drive with the FHPP register image (the CMMO-ST): its status bytes SCON and SPOS
    /// (FHPP §5.4, "status bytes") and its one switch input, the reference switch.
    Fhpp,
}

impl Profile {
    /// Variables of a drive of this profile.
    pub fn stride(self) -> u32 {
        match self {
            Profile::Cia402 => STRIDE,
            Profile::Fhpp => 9,
        }
    }
}

/// FMI 3.0 data types of the variables.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Type {
    Float64,
    Boolean,
    UInt8,
    UInt16,
    Int32,
    String,
}

/// What a variable is of its drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    LoadTorque,
    DigitalInput(u8),
    /// The FHPP drive's reference switch input (homing, §6.2).
    ReferenceSwitch,
    Position,
    Velocity,
    Current,
    Statusword,
    /// FHPP status byte 1, SCON.
    Scon,
    /// FHPP status byte 2, SPOS.
    Spos,
    PositionActual,
    Display,
}

/// A CiA 402 drive's roles, in value-reference order.
const CIA402_ROLES: [Role; STRIDE as usize] = [
    Role::LoadTorque,
    Role::DigitalInput(0),
    Role::DigitalInput(1),
    Role::DigitalInput(2),
    Role::DigitalInput(3),
    Role::DigitalInput(4),
    Role::DigitalInput(5),
    Role::DigitalInput(6),
    Role::DigitalInput(7),
    Role::DigitalInput(8),
    Role::DigitalInput(9),
    Role::DigitalInput(10),
    Role::DigitalInput(11),
    Role::DigitalInput(12),
    Role::DigitalInput(13),
    Role::DigitalInput(14),
    Role::DigitalInput(15),
    Role::Position,
    Role::Velocity,
    Role::Current,
    Role::Statusword,
    Role::PositionActual,
    Role::Display,
];

/// An FHPP drive's roles, in value-reference order.
const FHPP_ROLES: [Role; 9] = [
    Role::LoadTorque,
    Role::ReferenceSwitch,
    Role::Position,
    Role::Velocity,
    Role::Current,
    Role::Scon,
    Role::Spos,
    Role::PositionActual,
    Role::Display,
];

impl Role {
    /// The roles of a drive of `profile`, in value-reference order: a table, so that a get
    /// or set of the importer finds its variable without building anything.
    fn all(profile: Profile) -> &'static [Role] {
        match profile {
            Profile::Cia402 => &CIA402_ROLES,
            Profile::Fhpp => &FHPP_ROLES,
        }
    }

    fn offset(self, profile: Profile) -> Option<u32> {
        Role::all(profile)
            .iter()
            .position(|r| *r == self)
            .and_then(|i| u32::try_from(i).ok())
    }

    fn from_offset(profile: Profile, offset: u32) -> Option<Role> {
        Role::all(profile)
            .get(usize::try_from(offset).ok()?)
            .copied()
    }

    pub fn data_type(self) -> Type {
        match self {
            Role::LoadTorque | Role::Position | Role::Velocity | Role::Current => Type::Float64,
            Role::DigitalInput(_) | Role::ReferenceSwitch => Type::Boolean,
            Role::Scon | Role::Spos => Type::UInt8,
            Role::Statusword => Type::UInt16,
            Role::PositionActual => Type::Int32,
            Role::Display => Type::String,
        }
    }

    pub fn is_input(self) -> bool {
        matches!(
            self,
            Role::LoadTorque | Role::DigitalInput(_) | Role::ReferenceSwitch
        )
    }

    /// The unit's name in the description's `UnitDefinitions`.
    pub fn unit(self) -> Option<&'static str> {
        match self {
            Role::LoadTorque => Some("N.m"),
            Role::Position => Some("rad"),
            Role::Velocity => Some("rad/s"),
            Role::Current => Some("A"),
            _ => None,
        }
    }

    pub fn name(self) -> String {
        match self {
            Role::LoadTorque => "load_torque".into(),
            Role::DigitalInput(k) => format!("din{k}"),
            Role::ReferenceSwitch => "reference_switch".into(),
            Role::Position => "position".into(),
            Role::Velocity => "velocity".into(),
            Role::Current => "current".into(),
            Role::Statusword => "statusword".into(),
            Role::Scon => "scon".into(),
            Role::Spos => "spos".into(),
            Role::PositionActual => "position_actual".into(),
            Role::Display => "display".into(),
        }
    }

    pub fn description(self) -> String {
        match self {
            Role::LoadTorque => "load torque on the motor shaft".into(),
            Role::DigitalInput(k) => format!("digital input {k}, forced to this level once set"),
            Role::ReferenceSwitch => {
                "reference switch input (homing), forced to this level once set".into()
            }
            Role::Position => "motor shaft angle".into(),
            Role::Velocity => "motor shaft angular velocity".into(),
            Role::Current => "winding current".into(),
            Role::Statusword => "statusword (6041h)".into(),
            Role::Scon => "FHPP status byte 1, SCON".into(),
            Role::Spos => "FHPP status byte 2, SPOS".into(),
            Role::PositionActual => {
                "position actual value (6064h; FHPP: the actual position), in the drive's position unit".into()
            }
            Role::Display => "what the drive's display shows (empty without one)".into(),
        }
    }
}

/// What a drive's variables are named by: the first part of their names.
///
/// **Decision:** a CANopen drive by its node-ID (`nodeN`), unique on the cell's buses and
/// what a CANopen master knows it by; a drive without a CANopen node (the CMMO-ST, FHPP over
/// Modbus TCP) by its place among the cell file's `[[drive]]` sections (`driveK`, from 0, as
/// the terminals `canB` count the `[[bus]]` sections). A CMMO-ST's `node` key names no node on
/// any bus (its default, 1, is a CANopen drive's default as well), and its Modbus address is a
/// socket that changes with the machine it runs on; its place in the file is what the
/// importer and the cell file's reader both see.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveName {
    /// A CANopen drive: `nodeN`.
    Node(u8),
    /// A drive without a CANopen node: `driveK`, K its `[[drive]]` section's index.
    Section(usize),
}

impl std::fmt::Display for DriveName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DriveName::Node(n) => write!(f, "node{n}"),
            DriveName::Section(k) => write!(f, "drive{k}"),
        }
    }
}

/// One variable: its drive (index in [`Variables::names`]), its role and value reference.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Variable {
    pub drive: usize,
    pub drive_name: DriveName,
    pub role: Role,
    pub value_reference: u32,
}

impl Variable {
    pub fn name(&self) -> String {
        format!("{}.{}", self.drive_name, self.role.name())
    }
}

/// The variables of a cell whose drives are named `names`, each of its profile.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Variables {
    pub names: Vec<DriveName>,
    /// Each drive's profile, in `names`' order.
    pub profiles: Vec<Profile>,
    /// Each drive's first value reference.
    bases: Vec<u32>,
}

impl Variables {
    /// CiA 402 drives with the node-IDs `nodes`; refuses a node-ID that is on two buses
    /// (the names would be the same).
    pub fn new(nodes: Vec<u8>) -> Result<Variables, super::CellFmuError> {
        Variables::with_profiles(
            nodes
                .into_iter()
                .map(|n| (DriveName::Node(n), Profile::Cia402))
                .collect(),
        )
    }

    /// Drives of their profiles, in this order; refuses a name given twice.
    pub fn with_profiles(
        drives: Vec<(DriveName, Profile)>,
    ) -> Result<Variables, super::CellFmuError> {
        if drives.is_empty() {
            return Err(super::CellFmuError::NoDrive);
        }
        for (i, (n, _)) in drives.iter().enumerate() {
            if drives.iter().skip(i + 1).any(|(m, _)| m == n) {
                return Err(super::CellFmuError::DuplicateName(n.to_string()));
            }
        }
        let (names, profiles): (Vec<DriveName>, Vec<Profile>) = drives.into_iter().unzip();
        let mut bases = Vec::with_capacity(profiles.len());
        let mut next = 1u32;
        for p in &profiles {
            bases.push(next);
            next = next.saturating_add(p.stride());
        }
        Ok(Variables {
            names,
            profiles,
            bases,
        })
    }

    /// Drive `drive`'s name.
    pub fn name(&self, drive: usize) -> Option<DriveName> {
        self.names.get(drive).copied()
    }

    /// Drive `drive`'s profile.
    pub fn profile(&self, drive: usize) -> Profile {
        self.profiles.get(drive).copied().unwrap_or(Profile::Cia402)
    }

    /// Every variable, in value-reference order.
    pub fn all(&self) -> impl Iterator<Item = Variable> + '_ {
        self.names
            .iter()
            .zip(&self.profiles)
            .zip(&self.bases)
            .enumerate()
            .flat_map(|(drive, ((name, profile), base))| {
                Role::all(*profile)
                    .iter()
                    .copied()
                    .zip(*base..)
                    .map(move |(role, vr)| Variable {
                        drive,
                        drive_name: *name,
                        role,
                        value_reference: vr,
                    })
            })
    }

    /// The drive and role of value reference `vr`, if it is one of these variables (a binary
    /// search of the drives' first value references, then the profile's table).
    pub fn find(&self, vr: u32) -> Option<(usize, Role)> {
        let drive = self.bases.partition_point(|b| *b <= vr).checked_sub(1)?;
        let base = *self.bases.get(drive)?;
        Role::from_offset(self.profile(drive), vr - base).map(|r| (drive, r))
    }

    /// The value reference of drive `drive`'s variable `role`.
    pub fn value_reference(&self, drive: usize, role: Role) -> Option<u32> {
        let base = *self.bases.get(drive)?;
        Some(base + role.offset(self.profile(drive))?)
    }
}

/// The value reference of CiA 402 drive `drive`'s variable `role` in a cell of CiA 402 drives.
pub fn value_reference(drive: usize, role: Role) -> u32 {
    let drive = u32::try_from(drive).unwrap_or(u32::MAX / STRIDE - 1);
    1 + drive * STRIDE + role.offset(Profile::Cia402).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_references_run_in_table_order_and_find_their_variable() {
        let v = Variables::new(vec![1, 5]).unwrap();
        let all: Vec<Variable> = v.all().collect();
        assert_eq!(all.len(), 2 * STRIDE as usize);
        for (i, var) in all.iter().enumerate() {
            assert_eq!(var.value_reference, 1 + i as u32);
            assert_eq!(v.find(var.value_reference), Some((var.drive, var.role)));
        }
        assert_eq!(all[0].name(), "node1.load_torque");
        assert_eq!(all[STRIDE as usize + 17].name(), "node5.position");
        assert_eq!(v.find(0), None);
        assert_eq!(v.find(1 + 2 * STRIDE), None);
    }

    #[test]
    fn an_fhpp_drive_has_its_status_bytes_and_reference_switch_after_the_cia_402_drives() {
        let v = Variables::with_profiles(vec![
            (DriveName::Node(1), Profile::Cia402),
            (DriveName::Section(1), Profile::Fhpp),
        ])
        .unwrap();
        let all: Vec<Variable> = v.all().collect();
        assert_eq!(all.len(), STRIDE as usize + 9);
        for (i, var) in all.iter().enumerate() {
            assert_eq!(var.value_reference, 1 + i as u32);
            assert_eq!(v.find(var.value_reference), Some((var.drive, var.role)));
        }
        let names: Vec<String> = all
            .iter()
            .skip(STRIDE as usize)
            .map(Variable::name)
            .collect();
        assert_eq!(
            names,
            [
                "drive1.load_torque",
                "drive1.reference_switch",
                "drive1.position",
                "drive1.velocity",
                "drive1.current",
                "drive1.scon",
                "drive1.spos",
                "drive1.position_actual",
                "drive1.display"
            ]
        );
        assert_eq!(v.value_reference(1, Role::Scon), Some(1 + STRIDE + 5));
        assert_eq!(v.value_reference(1, Role::Statusword), None);
        assert_eq!(v.find(1 + STRIDE + 9), None);
    }

    #[test]
    fn a_drive_without_a_canopen_node_is_named_by_its_place_in_the_cell_file() {
        let v = Variables::with_profiles(vec![
            (DriveName::Node(1), Profile::Cia402),
            (DriveName::Section(3), Profile::Cia402),
        ])
        .unwrap();
        assert_eq!(v.names, [DriveName::Node(1), DriveName::Section(3)]);
        let all: Vec<Variable> = v.all().collect();
        assert_eq!(all.len(), 2 * STRIDE as usize);
        for (i, var) in all.iter().enumerate() {
            assert_eq!(var.value_reference, 1 + i as u32);
            assert_eq!(v.find(var.value_reference), Some((var.drive, var.role)));
        }
        let second: Vec<String> = all
            .iter()
            .skip(STRIDE as usize)
            .map(Variable::name)
            .collect();
        assert_eq!(second[0], "drive3.load_torque");
        assert_eq!(second[1], "drive3.din0");
        assert_eq!(
            &second[17..],
            [
                "drive3.position",
                "drive3.velocity",
                "drive3.current",
                "drive3.statusword",
                "drive3.position_actual",
                "drive3.display"
            ]
        );
        // A cell of such drives alone has variables too.
        let alone =
            Variables::with_profiles(vec![(DriveName::Section(0), Profile::Cia402)]).unwrap();
        assert_eq!(alone.all().next().unwrap().name(), "drive0.load_torque");
        assert!(Variables::with_profiles(Vec::new()).is_err());
    }

    #[test]
    fn a_node_id_on_two_buses_is_refused() {
        assert!(matches!(
            Variables::new(vec![1, 1]),
            Err(crate::cell_fmu::CellFmuError::DuplicateName(n)) if n == "node1"
        ));
        // A CMMO-ST named by its section beside a CANopen drive at node 1: both named.
        assert!(Variables::with_profiles(vec![
            (DriveName::Node(1), Profile::Cia402),
            (DriveName::Section(0), Profile::Fhpp),
        ])
        .is_ok());
        assert!(Variables::new(vec![]).is_err());
    }
}
