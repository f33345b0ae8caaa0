//! A `[[drive]]` of the cell file: the keys every drive has, and beside them, flat, the keys
//! of its device (a CiA 402 drive's motor and travel, a vendor's switches and ports), kept as
//! written until the drive is checked ([`super::device_keys`]): then a key of another device
//! is refused naming the devices it belongs to, a key of none as an unknown field.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::Deserialize;

use crate::cell::diagnostics::{PlannedDiagnostic, PlannedPhysics};
use crate::cell::interfaces::InterfaceName;

/// One `[[drive]]`.
#[derive(Debug, Clone)]
pub struct DriveSection {
    pub device: String,
    /// A CiA 402 drive from its EDS or DCF (CiA 306) instead of a built-in `device`: the
    /// file's dictionary on the engine's standard behaviour ([`crate::cell::eds_drive`]). A
    /// relative path is relative to the cell file.
    pub eds: Option<PathBuf>,
    /// Its node-ID as the file names it (1 where it names none).
    pub node: u8,
    /// Whether the file names `node`. Without it the drive is at its device's default
    /// node-ID: 1 for the built-in devices, a DCF's `[DeviceComissioning] NodeID`.
    pub node_given: bool,
    /// Commissioning values, `"IIII:SS" = value` (hex index and sub-index).
    pub objects: BTreeMap<String, toml::Value>,
    /// The `[[bus]]` (by name or channel) the drive's CANopen node is on; default the first.
    pub bus: Option<String>,
    /// The drive's interfaces, e.g. `["canopen", "ci-terminal"]`; default what its profile
    /// and keys imply. Checked against what the real device offers
    /// ([`crate::cell::interfaces`]).
    pub interfaces: Option<Vec<InterfaceName>>,
    /// Testing only: allow interface combinations the real device does not have (e.g. a
    /// CMMP-AS on CANopen and EtherCAT at once).
    pub allow_unreal_interfaces: bool,
    /// The network interface of the EtherCAT chain the drive is a slave of (its position:
    /// its order among the drives of that chain in the file); implies `"ethercat"` in
    /// `interfaces`. Without it, a drive with `"ethercat"` is on the chain of `--ethercat`.
    pub ethercat: Option<String>,
    /// Diagnostic messages raised (or cleared) at a time of the cell's clock:
    /// `[[drive.diagnostic]]` with `at_ms`, `number` ("08-2", as the drive's manual prints
    /// it) and `action` (`raise`, the default, or `clear`). CANopen drives.
    pub diagnostic: Vec<PlannedDiagnostic>,
    /// The plant's physics changed at a time of the cell's clock: `[[drive.plant]]` with
    /// `at_ms` and one of `ambient_c`, `encoder` (+ `noise`), `switch` (+ `actuated`,
    /// `release`).
    pub plant: Vec<PlannedPhysics>,
    /// `[drive.thermal]`: the ambient temperature and the thermal figures of motor and power
    /// stage (`drive::thermal`).
    pub thermal: Option<ThermalSection>,
    /// `[drive.load]`: a co-simulation FMU as the load (CiA 402 drives).
    pub load: Option<super::load_fmu::LoadSection>,
    /// The keys of its device, by `device` (or `eds`), as written: read by the CiA 402 keys
    /// and the device's section when the drive is checked ([`super::device_keys`]).
    pub rest: toml::Table,
}

/// The keys every drive has ([`DriveSection`]'s fields but `rest`), for the refusal of a key
/// that no device has.
pub const COMMON_KEYS: [&str; 12] = [
    "device",
    "eds",
    "node",
    "objects",
    "bus",
    "interfaces",
    "allow_unreal_interfaces",
    "ethercat",
    "diagnostic",
    "plant",
    "thermal",
    "load",
];

/// A `[[drive]]` as written: the common keys, and the rest for its device's sections.
///
/// The common keys are fields of their own (not a flattened struct), so that the TOML
/// reader still points at the line of a bad value.
#[derive(Deserialize)]
struct Written {
    #[serde(default = "default_device")]
    device: String,
    eds: Option<PathBuf>,
    node: Option<u8>,
    #[serde(default)]
    objects: BTreeMap<String, toml::Value>,
    bus: Option<String>,
    interfaces: Option<Vec<InterfaceName>>,
    #[serde(default)]
    allow_unreal_interfaces: bool,
    ethercat: Option<String>,
    #[serde(default)]
    diagnostic: Vec<PlannedDiagnostic>,
    #[serde(default)]
    plant: Vec<PlannedPhysics>,
    thermal: Option<ThermalSection>,
    load: Option<super::load_fmu::LoadSection>,
    #[serde(flatten)]
    rest: toml::Table,
}

impl<'de> Deserialize<'de> for DriveSection {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let w = Written::deserialize(d)?;
        let node = w.node.unwrap_or(1);
        Ok(DriveSection {
            device: w.device,
            eds: w.eds,
            node,
            node_given: w.node.is_some(),
            objects: w.objects,
            bus: w.bus,
            interfaces: w.interfaces,
            allow_unreal_interfaces: w.allow_unreal_interfaces,
            ethercat: w.ethercat,
            diagnostic: w.diagnostic,
            plant: w.plant,
            thermal: w.thermal,
            load: w.load,
            rest: w.rest,
        })
    }
}

impl DriveSection {
    /// A drive of `device` at `node` with no keys but these.
    pub fn new(device: &str, node: u8) -> Self {
        DriveSection {
            device: device.to_owned(),
            eds: None,
            node,
            node_given: true,
            objects: BTreeMap::new(),
            bus: None,
            interfaces: None,
            allow_unreal_interfaces: false,
            ethercat: None,
            diagnostic: Vec::new(),
            plant: Vec::new(),
            thermal: None,
            load: None,
            rest: toml::Table::new(),
        }
    }
}

/// `[drive.thermal]`: unset figures keep the defaults of `drive::thermal::ThermalData`.
#[derive(Debug, Clone, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ThermalSection {
    /// °C, −50 … 200 (default 25).
    pub ambient_c: Option<f64>,
    pub motor_rise_k: Option<f64>,
    pub motor_time_constant_s: Option<f64>,
    pub stage_rise_k: Option<f64>,
    pub stage_time_constant_s: Option<f64>,
}

impl ThermalSection {
    /// The changes it makes at power-on.
    pub fn changes(&self) -> Result<Vec<crate::cell::control::PhysicsChange>, String> {
        use crate::cell::control::PhysicsChange;
        let d = drive::thermal::ThermalData::default();
        let mut figures = [
            ("motor_rise_k", self.motor_rise_k, d.motor_rise_k),
            (
                "motor_time_constant_s",
                self.motor_time_constant_s,
                d.motor_time_constant_s,
            ),
            ("stage_rise_k", self.stage_rise_k, d.stage_rise_k),
            (
                "stage_time_constant_s",
                self.stage_time_constant_s,
                d.stage_time_constant_s,
            ),
        ]
        .into_iter()
        .map(|(name, v, default)| match v {
            Some(v) if !(v.is_finite() && (0.0..=1e6).contains(&v)) => {
                Err(format!("thermal.{name} {v}: within 0 … 10⁶"))
            }
            v => Ok(v.unwrap_or(default)),
        })
        .collect::<Result<Vec<f64>, String>>()?
        .into_iter();
        let mut next = || figures.next().unwrap_or(0.0);
        let data = drive::thermal::ThermalData {
            motor_rise_k: next(),
            motor_time_constant_s: next(),
            stage_rise_k: next(),
            stage_time_constant_s: next(),
        };
        let mut out = vec![PhysicsChange::Thermal(data)];
        if let Some(c) = self.ambient_c {
            if !(c.is_finite() && (-50.0..=200.0).contains(&c)) {
                return Err(format!("thermal.ambient_c {c}: °C within −50 … 200"));
            }
            out.push(PhysicsChange::Ambient(c));
        }
        Ok(out)
    }
}

pub(super) fn default_device() -> String {
    "cmmp-as".into()
}
