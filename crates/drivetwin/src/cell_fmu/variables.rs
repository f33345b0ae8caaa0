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
//! Value reference 0 is the independent variable `time`; drive `i`'s variables follow from
//! `1 + i · STRIDE` in the table's order.

/// How many digital inputs each drive shows (the bits of its forced-input mask).
pub const DIGITAL_INPUTS: u8 = 16;

/// Variables per drive.
pub const STRIDE: u32 = 7 + DIGITAL_INPUTS as u32;

/// FMI 3.0 data types of the variables.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Type {
    Float64,
    Boolean,
    UInt16,
    Int32,
    String,
}

/// What a variable is of its drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    LoadTorque,
    DigitalInput(u8),
    Position,
    Velocity,
    Current,
    Statusword,
    PositionActual,
    Display,
}

impl Role {
    /// The roles in value-reference order.
    fn all() -> impl Iterator<Item = Role> {
        std::iter::once(Role::LoadTorque)
            .chain((0..DIGITAL_INPUTS).map(Role::DigitalInput))
            .chain([
                Role::Position,
                Role::Velocity,
                Role::Current,
                Role::Statusword,
                Role::PositionActual,
                Role::Display,
            ])
    }

    fn offset(self) -> u32 {
        match self {
            Role::LoadTorque => 0,
            Role::DigitalInput(k) => 1 + u32::from(k),
            Role::Position => 1 + u32::from(DIGITAL_INPUTS),
            Role::Velocity => 2 + u32::from(DIGITAL_INPUTS),
            Role::Current => 3 + u32::from(DIGITAL_INPUTS),
            Role::Statusword => 4 + u32::from(DIGITAL_INPUTS),
            Role::PositionActual => 5 + u32::from(DIGITAL_INPUTS),
            Role::Display => 6 + u32::from(DIGITAL_INPUTS),
        }
    }

    fn from_offset(offset: u32) -> Option<Role> {
        Role::all().find(|r| r.offset() == offset)
    }

    pub fn data_type(self) -> Type {
        match self {
            Role::LoadTorque | Role::Position | Role::Velocity | Role::Current => Type::Float64,
            Role::DigitalInput(_) => Type::Boolean,
            Role::Statusword => Type::UInt16,
            Role::PositionActual => Type::Int32,
            Role::Display => Type::String,
        }
    }

    pub fn is_input(self) -> bool {
        matches!(self, Role::LoadTorque | Role::DigitalInput(_))
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
            Role::Position => "position".into(),
            Role::Velocity => "velocity".into(),
            Role::Current => "current".into(),
            Role::Statusword => "statusword".into(),
            Role::PositionActual => "position_actual".into(),
            Role::Display => "display".into(),
        }
    }

    pub fn description(self) -> String {
        match self {
            Role::LoadTorque => "load torque on the motor shaft".into(),
            Role::DigitalInput(k) => format!("digital input {k}, forced to this level once set"),
            Role::Position => "motor shaft angle".into(),
            Role::Velocity => "motor shaft angular velocity".into(),
            Role::Current => "winding current".into(),
            Role::Statusword => "statusword (6041h)".into(),
            Role::PositionActual => "position actual value (6064h)".into(),
            Role::Display => "what the drive's display shows (empty without one)".into(),
        }
    }
}

/// One variable: its drive (index in [`Variables::nodes`]), its role and value reference.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Variable {
    pub drive: usize,
    pub node: u8,
    pub role: Role,
    pub value_reference: u32,
}

impl Variable {
    pub fn name(&self) -> String {
        format!("node{}.{}", self.node, self.role.name())
    }
}

/// The variables of a cell whose CANopen drives have the node-IDs `nodes`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Variables {
    pub nodes: Vec<u8>,
}

impl Variables {
    /// Refuses a node-ID that is on two buses (the names would be the same).
    pub fn new(nodes: Vec<u8>) -> Result<Variables, super::CellFmuError> {
        if nodes.is_empty() {
            return Err(super::CellFmuError::NoDrive);
        }
        for (i, n) in nodes.iter().enumerate() {
            if nodes.iter().skip(i + 1).any(|m| m == n) {
                return Err(super::CellFmuError::DuplicateNode(*n));
            }
        }
        Ok(Variables { nodes })
    }

    /// Every variable, in value-reference order.
    pub fn all(&self) -> impl Iterator<Item = Variable> + '_ {
        self.nodes.iter().enumerate().flat_map(|(drive, node)| {
            Role::all().map(move |role| Variable {
                drive,
                node: *node,
                role,
                value_reference: value_reference(drive, role),
            })
        })
    }

    /// The drive and role of value reference `vr`, if it is one of these variables.
    pub fn find(&self, vr: u32) -> Option<(usize, Role)> {
        let index = vr.checked_sub(1)?;
        let drive = usize::try_from(index / STRIDE).ok()?;
        if drive >= self.nodes.len() {
            return None;
        }
        Role::from_offset(index % STRIDE).map(|r| (drive, r))
    }
}

/// The value reference of drive `drive`'s variable `role`.
pub fn value_reference(drive: usize, role: Role) -> u32 {
    let drive = u32::try_from(drive).unwrap_or(u32::MAX / STRIDE - 1);
    1 + drive * STRIDE + role.offset()
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
    fn a_node_id_on_two_buses_is_refused() {
        assert!(matches!(
            Variables::new(vec![1, 1]),
            Err(crate::cell_fmu::CellFmuError::DuplicateNode(1))
        ));
        assert!(Variables::new(vec![]).is_err());
    }
}
