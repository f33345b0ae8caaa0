//! The cell file (`--config CELL.toml`): which drives, which personalities and node-IDs,
//! which transports. Everything has a default, so `drivetwin run` alone starts the default
//! cell: one CMMP-AS, node 1, heartbeat 1000 ms, socketcand on 127.0.0.1:29536.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use od::{DataType, Value};
use serde::Deserialize;

use crate::can_drive::Commissioning;

pub const DEFAULT_SOCKETCAND: &str = "127.0.0.1:29536";
pub const DEFAULT_CHANNEL: &str = "vcan0";
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
    #[error("node-ID {0} is used twice")]
    DuplicateNode(u8),
}

#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct CellFile {
    #[serde(default)]
    pub bus: BusSection,
    #[serde(default)]
    pub drive: Vec<DriveSection>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BusSection {
    /// socketcand server address; "" turns the server off.
    #[serde(default = "default_socketcand")]
    pub socketcand: String,
    #[serde(default = "default_channel")]
    pub channel: String,
    /// A SocketCAN interface to bridge (real hardware or vcan).
    pub socketcan: Option<String>,
}

impl Default for BusSection {
    fn default() -> Self {
        BusSection {
            socketcand: default_socketcand(),
            channel: default_channel(),
            socketcan: None,
        }
    }
}

fn default_socketcand() -> String {
    DEFAULT_SOCKETCAND.into()
}
fn default_channel() -> String {
    DEFAULT_CHANNEL.into()
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveSection {
    #[serde(default = "default_device")]
    pub device: String,
    #[serde(default = "default_node")]
    pub node: u8,
    /// Commissioning values, `"IIII:SS" = value` (hex index and sub-index).
    #[serde(default)]
    pub objects: BTreeMap<String, toml::Value>,
}

fn default_device() -> String {
    "cmmp-as".into()
}
fn default_node() -> u8 {
    1
}

/// A drive ready to build.
#[derive(Debug, Clone)]
pub struct DriveSpec {
    pub desc: &'static od::DeviceDescription,
    pub node: u8,
    pub commissioning: Vec<Commissioning>,
}

impl CellFile {
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        toml::from_str(&text).map_err(|source| ConfigError::Toml {
            path: path.to_path_buf(),
            source,
        })
    }

    /// The default cell with one drive.
    pub fn single(device: &str, node: u8) -> Self {
        let mut objects = BTreeMap::new();
        objects.insert(
            "1017:00".to_string(),
            toml::Value::Integer(i64::from(DEFAULT_HEARTBEAT_MS)),
        );
        CellFile {
            bus: BusSection::default(),
            drive: vec![DriveSection {
                device: device.to_string(),
                node,
                objects,
            }],
        }
    }

    pub fn drives(&self) -> Result<Vec<DriveSpec>, ConfigError> {
        let mut specs: Vec<DriveSpec> = Vec::new();
        for d in &self.drive {
            let desc = devices::by_name(&d.device).ok_or_else(|| {
                let known: Vec<&str> = devices::ALL.iter().map(|d| d.name).collect();
                ConfigError::UnknownDevice(d.device.clone(), known.join(", "))
            })?;
            if specs.iter().any(|s| s.node == d.node) {
                return Err(ConfigError::DuplicateNode(d.node));
            }
            let mut commissioning = Vec::new();
            for (key, value) in &d.objects {
                let err = |what: String| ConfigError::Object {
                    node: d.node,
                    key: key.clone(),
                    what,
                };
                let (index, sub) =
                    parse_key(key).ok_or_else(|| err("expected \"IIII:SS\" in hex".into()))?;
                let e = desc
                    .entry(index, sub)
                    .ok_or_else(|| err(format!("{} has no such entry", desc.name)))?;
                let bytes = encode_toml(e.data_type, value).map_err(err)?;
                commissioning.push(Commissioning { index, sub, bytes });
            }
            specs.push(DriveSpec {
                desc,
                node: d.node,
                commissioning,
            });
        }
        Ok(specs)
    }
}

/// `"1017:00"` → (0x1017, 0).
pub fn parse_key(key: &str) -> Option<(u16, u8)> {
    let (i, s) = key.split_once(':')?;
    let i = i.trim().trim_start_matches("0x");
    let s = s.trim().trim_start_matches("0x");
    Some((
        u16::from_str_radix(i, 16).ok()?,
        u8::from_str_radix(s, 16).ok()?,
    ))
}

fn encode_toml(t: DataType, v: &toml::Value) -> Result<Vec<u8>, String> {
    match (t, v) {
        (DataType::VisibleString, toml::Value::String(s)) => Ok(s.as_bytes().to_vec()),
        (DataType::OctetString | DataType::Domain, toml::Value::String(s)) => {
            crate::value_text::parse_hex(s).ok_or_else(|| "expected hex digits".into())
        }
        (_, toml::Value::Integer(i)) => encode_value(t, Value::Signed(*i)),
        (_, toml::Value::Float(f)) => encode_value(t, Value::Real(*f)),
        (_, toml::Value::Boolean(b)) => encode_value(t, Value::Bool(*b)),
        _ => Err(format!("value does not fit {}", t.name())),
    }
}

fn encode_value(t: DataType, v: Value) -> Result<Vec<u8>, String> {
    let mut b = [0u8; 8];
    let n = v
        .encode(t, &mut b)
        .ok_or_else(|| format!("{v} does not fit {}", t.name()))?;
    Ok(b.get(..n).unwrap_or(&[]).to_vec())
}
