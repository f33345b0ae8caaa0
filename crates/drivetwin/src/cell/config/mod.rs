//! The cell file (`--config CELL.toml`): which drives, which personalities and node-IDs,
//! which transports. Everything has a default, so `drivetwin run` alone starts the default
//! cell: one CMMP-AS, node 1, heartbeat 1000 ms, socketcand on 127.0.0.1:29536.
//!
//! The file is `[[bus]]` tables ([`bus_section`]) and `[[drive]]` tables
//! ([`drive_section`]): the keys every drive has, and flat beside them the keys of its device:
//! the CiA 402 keys of every CiA 402 drive ([`cia402`]) and the device's own section, which
//! its vendor folder reads ([`device_keys::DeviceSection`], handed in as
//! [`DeviceSections`]: `drivetwin::vendors::VENDORS.runtime.cell_sections`). The runtime knows no vendor.
//! [`CellFile::drives`] checks each drive against its device ([`DriveSpec`]).

pub mod bus_section;
pub mod cia402;
pub mod device_keys;
pub mod drive_section;
mod drive_spec;
pub mod load_fmu;
mod objects;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::cell::bus_rate::{self, BitrateSetting, BusNode, BusRate};
use crate::cell::device_model::{is_cia402, is_fhpp};

pub use bus_section::{BusSection, Buses, DisturbSection, DEFAULT_CHANNEL, DEFAULT_SOCKETCAND};
pub use cia402::{Cia402Keys, MotorSection, TravelSection};
pub use device_keys::{
    DeviceSection, DeviceSections, DriveContext, FieldbusProfile, FieldbusSettings, Key, OwnRate,
    OwnSettings, Ports, SectionError,
};
pub use drive_section::{DriveSection, ThermalSection};
pub use drive_spec::DriveSpec;
pub use objects::parse_key;

/// The default cell commissions a heartbeat so a master that joins later sees the node.
pub const DEFAULT_HEARTBEAT_MS: u16 = 1000;

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Toml {
        path: PathBuf,
        source: toml::de::Error,
    },
    #[error("unknown device {0:?} (known: {1})")]
    UnknownDevice(String, String),
    #[error("drive {node}: object key {key:?}: {what}")]
    Object { node: u8, key: String, what: String },
    /// A key of other devices on a drive whose device does not have it.
    #[error(
        "{}drive {node} ({}): `{}` is a key of the {}, not of this device: {} has no {}",
        in_file(&at.file), at.device, at.key.key, at.key.owners, at.device, at.key.what
    )]
    ForeignKey { node: u8, at: Box<ForeignKeyAt> },
    /// A drive's keys that do not read: a key of no device (as serde words an unknown
    /// field), or a value of the wrong type; `what` names the drive.
    #[error("{}{what}", in_file(file))]
    DriveKeys { file: Option<PathBuf>, what: String },
    #[error("node-ID {0} is used twice")]
    DuplicateNode(u8),
    #[error("drive {0}: its switches select FHPP over CANopen (M0 DIN9 HIGH), which the twin does not simulate for the CMMP-AS")]
    FhppOverCan(u8),
    #[error("drive {node}: bus {name:?} is not a [[bus]] of the cell (its buses: {known})")]
    UnknownBus {
        node: u8,
        name: String,
        known: String,
    },
    #[error("drive {node}: {source}")]
    Interfaces {
        node: u8,
        source: crate::cell::interfaces::InterfaceError,
    },
    #[error("drive {node}: [[drive.diagnostic]] {number:?}: {what}")]
    Diagnostic {
        node: u8,
        number: String,
        what: String,
    },
    #[error(transparent)]
    BusRate(#[from] bus_rate::Disagreement),
    /// A drive's EDS / DCF (`eds`, `--eds`) refused, with its file, line, section and key.
    #[error(transparent)]
    Eds(#[from] devdesc::eds::EdsError),
}

/// A key of other devices on a drive of `device`, in the cell file `file` (if read from one).
#[derive(Debug)]
pub struct ForeignKeyAt {
    pub file: Option<PathBuf>,
    pub device: String,
    pub key: device_keys::ForeignKey,
}

/// `path: ` before a message about a cell file read from `path`.
fn in_file(path: &Option<PathBuf>) -> String {
    path.as_ref()
        .map(|p| format!("{}: ", p.display()))
        .unwrap_or_default()
}

/// How a CMMO-ST of the cell (an FHPP drive) is served and simulated.
#[derive(Debug, Clone, Default)]
pub struct FhppSpec {
    pub settings: drive::vendors::FhppSettings,
    /// Its Modbus TCP server address, if the cell file gives one.
    pub modbus: Option<String>,
    pub watchdog_ms: Option<u16>,
}

#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct CellFile {
    /// `[bus]` (one bus) or `[[bus]]` entries (several CAN buses).
    #[serde(default)]
    pub bus: Buses,
    #[serde(default)]
    pub drive: Vec<DriveSection>,
    /// `[[ethercat_line]]`: faults of an EtherCAT chain's line at their times
    /// ([`crate::cell::ethercat_line`]).
    #[serde(default)]
    pub ethercat_line: Vec<crate::cell::ethercat_line::TimedLineAction>,
    /// The file it was read from ([`CellFile::load`]), which its refusals name.
    #[serde(skip)]
    pub path: Option<PathBuf>,
}

/// A block of eight switches numbered from 1 with those of `on` ON (`[0]` is switch 1);
/// `bad` names a number outside 1…8.
pub fn eight_switches(on: &[u8], bad: impl Fn(u8) -> String) -> Result<[bool; 8], String> {
    let mut block = [false; 8];
    for &n in on {
        let slot = usize::from(n)
            .checked_sub(1)
            .and_then(|i| block.get_mut(i))
            .ok_or_else(|| bad(n))?;
        *slot = true;
    }
    Ok(block)
}

impl CellFile {
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut file: CellFile = toml::from_str(&text).map_err(|source| ConfigError::Toml {
            path: path.to_path_buf(),
            source,
        })?;
        let dir = path.parent().unwrap_or(Path::new(""));
        for d in &mut file.drive {
            if let Some(eds) = d.eds.as_mut().filter(|p| p.is_relative()) {
                *eds = dir.join(&*eds);
            }
            if let Some(load) = d.load.as_mut().filter(|l| l.fmu.is_relative()) {
                load.fmu = dir.join(&load.fmu);
            }
        }
        file.path = Some(path.to_path_buf());
        Ok(file)
    }

    /// The default cell with one drive from its EDS or DCF (`--eds`), as [`CellFile::single`]:
    /// the heartbeat where the file has 1017h.
    pub fn single_eds(eds: &Path, node: Option<u8>) -> Result<Self, ConfigError> {
        let desc = crate::cell::eds_drive::load(eds)?;
        let mut file = Self::single("", node.unwrap_or(1));
        if let Some(d) = file.drive.first_mut() {
            // Without --node, a DCF's `[DeviceComissioning] NodeID` (CiA 306), as in a cell
            // file without `node`.
            d.node_given = node.is_some();
            d.device = drive_section::default_device();
            d.eds = Some(eds.to_path_buf());
            if desc.entry(0x1017, 0).is_none() {
                d.objects.clear();
            }
        }
        Ok(file)
    }

    /// The default cell with one drive: heartbeat 1000 ms, and for a CiA 402 drive the
    /// CiA 402 FAULT statusword (6510h:F0 bit 7; the CMMP-AS default 000Fh makes CiA 402
    /// masters such as python-canopen's BaseNode402 read FAULT as FAULT REACTION ACTIVE).
    pub fn single(device: &str, node: u8) -> Self {
        let mut objects = BTreeMap::new();
        if !devices::by_name(device).is_some_and(is_fhpp) {
            objects.insert(
                "1017:00".to_string(),
                toml::Value::Integer(i64::from(DEFAULT_HEARTBEAT_MS)),
            );
        }
        // Only where the personality has 6510h:F0 (the CMMP-AS; the Nanotec has no 6510h).
        if devices::by_name(device).is_some_and(|d| is_cia402(d) && d.entry(0x6510, 0xF0).is_some())
        {
            objects.insert("6510:F0".to_string(), toml::Value::Integer(0x0080));
        }
        let mut drive = DriveSection::new(device, node);
        drive.objects = objects;
        CellFile {
            bus: Buses::default(),
            drive: vec![drive],
            ethercat_line: Vec::new(),
            path: None,
        }
    }
}

impl CellFile {
    /// The bit rate of each bus (of [`Buses::all`]) with the drives of `specs` on it: its
    /// `bitrate`, else its nodes' ([`bus_rate::resolve`]; refused where they differ). The
    /// nodes are the CANopen drives whose switches leave CAN on.
    pub fn bus_rates(&self, specs: &[DriveSpec]) -> Result<Vec<BusRate>, ConfigError> {
        self.bus
            .all()
            .iter()
            .enumerate()
            .map(|(i, section)| {
                let nodes: Vec<BusNode> = specs
                    .iter()
                    .filter(|s| s.bus == i && s.canopen && s.fhpp.is_none())
                    .filter(|s| s.on_can().unwrap_or(false))
                    .filter_map(|s| {
                        s.bit_rate.clone().map(|rate| BusNode {
                            device: s.desc.name,
                            node: s.node,
                            rate,
                        })
                    })
                    .collect();
                Ok(bus_rate::resolve(section.label(), section.bitrate, &nodes)?)
            })
            .collect()
    }

    /// Sets the bit rate of every bus (`drivetwin run --bitrate`).
    pub fn set_bitrate(&mut self, setting: BitrateSetting) {
        for b in self.bus.all_mut() {
            b.bitrate = Some(setting);
        }
    }
}
