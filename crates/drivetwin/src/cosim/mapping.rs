//! Which variable of a load FMU is which quantity of the shaft: the mapping table of a
//! drive's `[drive.load]` (docs/cosimulation.md). The names are the FMU's own, as its
//! `modelDescription.xml` declares them; every name given must be there, with the type and
//! causality its role needs, or the FMU is refused naming it.

use std::collections::BTreeMap;
use std::path::PathBuf;

/// A drive's load FMU and its variables: as the cell file's `[drive.load]` writes them.
#[derive(Debug, Clone, PartialEq, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadMapping {
    /// The FMU archive (`.fmu`).
    pub fmu: PathBuf,
    /// Float64 input ← the motor's torque, N·m (Kt·i).
    pub torque: Option<String>,
    /// Float64 input ← the shaft speed, rad/s.
    pub speed: Option<String>,
    /// Float64 input ← the shaft angle, rad.
    pub angle: Option<String>,
    /// Float64 output → the load torque on the shaft, N·m, towards negative rotation.
    pub load_torque: String,
    /// Float64 output → the load's position (reported with the load, unit as the FMU says).
    pub position: Option<String>,
    /// Boolean outputs → the drive's switches, by the switch's name (`home`,
    /// `limit_positive`, `limit_negative`): switch name → FMU variable.
    #[serde(default)]
    pub switches: BTreeMap<String, String>,
    /// Float64 parameters set before the FMU is initialised: FMU variable → value
    /// (`[drive.load.parameters]`).
    #[serde(default)]
    pub parameters: BTreeMap<String, f64>,
}

impl LoadMapping {
    /// The inputs the mapping names, as (role, FMU variable).
    pub fn inputs(&self) -> impl Iterator<Item = (&'static str, &str)> {
        [
            ("torque", &self.torque),
            ("speed", &self.speed),
            ("angle", &self.angle),
        ]
        .into_iter()
        .filter_map(|(role, name)| name.as_deref().map(|n| (role, n)))
    }
}
