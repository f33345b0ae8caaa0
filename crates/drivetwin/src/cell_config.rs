//! The cell file (`--config CELL.toml`): which drives, which personalities and node-IDs,
//! which transports. Everything has a default, so `drivetwin run` alone starts the default
//! cell: one CMMP-AS, node 1, heartbeat 1000 ms, socketcand on 127.0.0.1:29536.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use od::{DataType, Value};
use serde::Deserialize;

use crate::can_drive::Commissioning;
use crate::device_model::is_cia402;
use drive::drive::DriveSettings;
use drive::motor::MotorData;
use drive::travel::{HomeSwitch, TravelSettings};

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
    /// Motor and load of a CiA 402 drive (SI units); unset fields keep the EMMS-AS defaults.
    #[serde(default)]
    pub motor: MotorSection,
    /// Limit switches, home switch, index pulse and hard stops of a CiA 402 drive's axis.
    #[serde(default)]
    pub travel: TravelSection,
    /// How long a mode change takes (6061h reads −1 meanwhile), ms.
    pub mode_change_time_ms: Option<f64>,
    /// TCP address (loopback only) of the drive's CI terminal, the debug console whose SDO
    /// simulation the CMMP-AS manual describes (§3.2.3); none by default.
    pub ci_terminal: Option<String>,
}

/// `[drive.motor]`: overrides of [`MotorData`].
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct MotorSection {
    pub torque_constant: Option<f64>,
    pub resistance: Option<f64>,
    pub inductance: Option<f64>,
    pub inertia: Option<f64>,
    pub viscous_friction: Option<f64>,
    pub coulomb_friction: Option<f64>,
    pub load_torque: Option<f64>,
    pub brake_holding_torque: Option<f64>,
    pub rated_current: Option<f64>,
    pub peak_current: Option<f64>,
    pub i2t_time: Option<f64>,
    pub max_speed_rpm: Option<f64>,
}

impl MotorSection {
    pub fn motor(&self) -> MotorData {
        let d = MotorData::default();
        MotorData {
            torque_constant: self.torque_constant.unwrap_or(d.torque_constant),
            resistance: self.resistance.unwrap_or(d.resistance),
            inductance: self.inductance.unwrap_or(d.inductance),
            inertia: self.inertia.unwrap_or(d.inertia),
            viscous_friction: self.viscous_friction.unwrap_or(d.viscous_friction),
            coulomb_friction: self.coulomb_friction.unwrap_or(d.coulomb_friction),
            load_torque: self.load_torque.unwrap_or(d.load_torque),
            brake_holding_torque: self.brake_holding_torque.unwrap_or(d.brake_holding_torque),
            rated_current: self.rated_current.unwrap_or(d.rated_current),
            peak_current: self.peak_current.unwrap_or(d.peak_current),
            i2t_time: self.i2t_time.unwrap_or(d.i2t_time),
            max_speed_rpm: self.max_speed_rpm.unwrap_or(d.max_speed_rpm),
            increments_per_rev: d.increments_per_rev,
        }
    }

    fn check(&self) -> Result<(), String> {
        let positive = [
            ("torque_constant", self.torque_constant),
            ("resistance", self.resistance),
            ("inductance", self.inductance),
            ("inertia", self.inertia),
            ("rated_current", self.rated_current),
            ("peak_current", self.peak_current),
            ("i2t_time", self.i2t_time),
            ("max_speed_rpm", self.max_speed_rpm),
        ];
        for (name, v) in positive {
            if let Some(v) = v {
                if !(v.is_finite() && v > 0.0) {
                    return Err(format!("motor.{name} must be a positive number"));
                }
            }
        }
        for (name, v) in [
            ("viscous_friction", self.viscous_friction),
            ("coulomb_friction", self.coulomb_friction),
            ("brake_holding_torque", self.brake_holding_torque),
            ("load_torque", self.load_torque),
        ] {
            if let Some(v) = v {
                if !v.is_finite() || (name != "load_torque" && v < 0.0) {
                    return Err(format!("motor.{name} must be a finite number ≥ 0"));
                }
            }
        }
        Ok(())
    }
}

/// `[drive.travel]`: overrides of [`TravelSettings`], in motor encoder increments (65536 per
/// revolution; the encoder reads 0 at power-on). Unset fields keep the defaults: limit
/// switches from −20 / +64 revolutions, hard stops at −22 / +66, home cam 40000 … 90000, index
/// at 16384 (see [`TravelSettings::default`]).
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct TravelSection {
    pub negative_stop: Option<i64>,
    pub negative_limit: Option<i64>,
    pub home_switch_low: Option<i64>,
    pub home_switch_high: Option<i64>,
    pub positive_limit: Option<i64>,
    pub positive_stop: Option<i64>,
    pub index_phase: Option<u32>,
    /// Longest homing search step, increments (0: no limit; beyond it error 11-6).
    pub homing_max_distance: Option<i64>,
}

/// Positions beyond ±2^40 increments (16 million revolutions) are refused: far from any
/// axis, and safe from overflow in the position arithmetic.
const TRAVEL_LIMIT: i64 = 1 << 40;

impl TravelSection {
    /// The travel and the homing search limit, or what is wrong with them.
    pub fn travel(&self) -> Result<(TravelSettings, i64), String> {
        let d = TravelSettings::default();
        let pick = |v: Option<i64>, dflt: Option<i64>| v.or(dflt);
        let home = d.home_switch.map(|h| HomeSwitch {
            low: self.home_switch_low.unwrap_or(h.low),
            high: self.home_switch_high.unwrap_or(h.high),
        });
        let t = TravelSettings {
            negative_stop: pick(self.negative_stop, d.negative_stop),
            negative_limit: pick(self.negative_limit, d.negative_limit),
            home_switch: home,
            positive_limit: pick(self.positive_limit, d.positive_limit),
            positive_stop: pick(self.positive_stop, d.positive_stop),
            index_phase: self.index_phase.or(d.index_phase),
        };
        let order = [
            ("negative_stop", t.negative_stop),
            ("negative_limit", t.negative_limit),
            ("positive_limit", t.positive_limit),
            ("positive_stop", t.positive_stop),
        ];
        for (name, v) in order.iter().chain(
            [
                ("home_switch_low", home.map(|h| h.low)),
                ("home_switch_high", home.map(|h| h.high)),
            ]
            .iter(),
        ) {
            if v.is_some_and(|v| v.abs() > TRAVEL_LIMIT) {
                return Err(format!("travel.{name} must lie within ±2^40 increments"));
            }
        }
        for w in order.windows(2) {
            if let [(a, Some(x)), (b, Some(y))] = w {
                if x >= y {
                    return Err(format!("travel.{a} must lie below travel.{b}"));
                }
            }
        }
        if home.is_some_and(|h| h.low > h.high) {
            return Err("travel.home_switch_low must not lie above home_switch_high".into());
        }
        if t.index_phase
            .is_some_and(|p| p >= drive::motor::INCREMENTS_PER_REV)
        {
            return Err("travel.index_phase must lie within one revolution (0 … 65535)".into());
        }
        let max = self
            .homing_max_distance
            .unwrap_or(DriveSettings::default().homing_max_distance);
        if !(0..=TRAVEL_LIMIT).contains(&max) {
            return Err("travel.homing_max_distance must lie within 0 … 2^40".into());
        }
        Ok((t, max))
    }
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
    /// For CiA 402 personalities: the simulated drive and motor.
    pub settings: Option<DriveSettings>,
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

    /// The default cell with one drive: heartbeat 1000 ms, and for a CiA 402 drive the
    /// CiA 402 FAULT statusword (6510h:F0 bit 7; the CMMP-AS default 000Fh makes CiA 402
    /// masters such as python-canopen's BaseNode402 read FAULT as FAULT REACTION ACTIVE).
    pub fn single(device: &str, node: u8) -> Self {
        let mut objects = BTreeMap::new();
        objects.insert(
            "1017:00".to_string(),
            toml::Value::Integer(i64::from(DEFAULT_HEARTBEAT_MS)),
        );
        if devices::by_name(device).is_some_and(is_cia402) {
            objects.insert("6510:F0".to_string(), toml::Value::Integer(0x0080));
        }
        CellFile {
            bus: BusSection::default(),
            drive: vec![DriveSection {
                device: device.to_string(),
                node,
                objects,
                motor: MotorSection::default(),
                travel: TravelSection::default(),
                mode_change_time_ms: None,
                ci_terminal: None,
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
            let settings = if is_cia402(desc) {
                d.motor.check().map_err(|what| ConfigError::Object {
                    node: d.node,
                    key: "motor".into(),
                    what,
                })?;
                let motor = d.motor.motor();
                // The motor's nameplate commissioned as FCT would (before [drive.objects]).
                commissioning.extend(motor_commissioning(desc, &motor));
                let (travel, homing_max_distance) =
                    d.travel.travel().map_err(|what| ConfigError::Object {
                        node: d.node,
                        key: "travel".into(),
                        what,
                    })?;
                let mut s = DriveSettings {
                    motor,
                    travel,
                    homing_max_distance,
                    ..DriveSettings::default()
                };
                if let Some(ms) = d.mode_change_time_ms {
                    if !(ms.is_finite() && ms >= 0.0) {
                        return Err(ConfigError::Object {
                            node: d.node,
                            key: "mode_change_time_ms".into(),
                            what: "must be ≥ 0".into(),
                        });
                    }
                    s.mode_change_time = std::time::Duration::from_secs_f64(ms / 1000.0);
                }
                Some(s)
            } else {
                None
            };
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
                settings,
            });
        }
        Ok(specs)
    }
}

/// 6075h, 6073h, 6410h:03 and 6080h from the motor data, within the device's limits.
fn motor_commissioning(desc: &od::DeviceDescription, m: &MotorData) -> Vec<Commissioning> {
    let p = drive::control::ControlParams::for_motor(m);
    let nominal = desc
        .entry(0x6510, 0x40)
        .and_then(|e| Value::decode(e.data_type, e.default))
        .and_then(|v| {
            if let Value::Unsigned(u) = v {
                Some(u as u32)
            } else {
                None
            }
        })
        .unwrap_or(u32::MAX);
    let rated = p.motor_rated_current_ma.min(nominal);
    let values = [
        (0x6075u16, 0u8, Value::Unsigned(rated.into())),
        (0x6073, 0, Value::Unsigned(p.max_current_permille.into())),
        (0x6410, 3, Value::Unsigned(p.iit_time_motor_ms.into())),
        (0x6080, 0, Value::Unsigned(p.max_motor_speed_rpm.into())),
    ];
    values
        .iter()
        .filter_map(|(index, sub, v)| {
            let e = desc.entry(*index, *sub)?;
            let mut b = [0u8; 8];
            let n = v.encode(e.data_type, &mut b)?;
            Some(Commissioning {
                index: *index,
                sub: *sub,
                bytes: b.get(..n)?.to_vec(),
            })
        })
        .collect()
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

#[cfg(test)]
mod travel_tests {
    use super::*;

    fn spec(text: &str) -> Result<Vec<DriveSpec>, ConfigError> {
        let file: CellFile = toml::from_str(text).map_err(|source| ConfigError::Toml {
            path: PathBuf::from("cell.toml"),
            source,
        })?;
        file.drives()
    }

    #[test]
    fn drive_travel_overrides_the_defaults() {
        let drives = spec(
            "[[drive]]\ndevice = \"cmmp-as\"\n[drive.travel]\nnegative_limit = -100000\n\
             home_switch_low = 1000\nindex_phase = 0\nhoming_max_distance = 0\n",
        )
        .unwrap();
        let s = drives[0].settings.unwrap();
        assert_eq!(s.travel.negative_limit, Some(-100_000));
        assert_eq!(
            s.travel.home_switch.map(|h| (h.low, h.high)),
            Some((1000, 90_000))
        );
        assert_eq!(s.travel.index_phase, Some(0));
        assert_eq!(
            s.travel.positive_stop,
            TravelSettings::default().positive_stop
        );
        assert_eq!(s.homing_max_distance, 0);
    }

    #[test]
    fn a_travel_out_of_order_is_refused() {
        for bad in [
            "negative_limit = -2000000",
            "home_switch_low = 100000",
            "index_phase = 65536",
            "positive_stop = 1099511627777",
        ] {
            let text = format!("[[drive]]\ndevice = \"cmmp-as\"\n[drive.travel]\n{bad}\n");
            let err = spec(&text).unwrap_err().to_string();
            assert!(err.contains("travel"), "{bad}: {err}");
        }
    }
}
