//! The cell file (`--config CELL.toml`): which drives, which personalities and node-IDs,
//! which transports. Everything has a default, so `drivetwin run` alone starts the default
//! cell: one CMMP-AS, node 1, heartbeat 1000 ms, socketcand on 127.0.0.1:29536.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use od::{DataType, Value};
use serde::Deserialize;

use crate::can_drive::Commissioning;
use crate::device_model::is_cia402;
use crate::fieldbus_switches::{
    m3_power_on, FieldbusSettings, M0Fieldbus, M0Inputs, Profile, BIT_RATES_KBIT,
};
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
    #[error("drive {0}: its switches select FHPP over CANopen (M0 DIN9 HIGH), which the twin does not simulate for the CMMP-AS")]
    FhppOverCan(u8),
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
    /// The CMMP-AS switch positions or input levels that give node number, bit rate and
    /// CAN activation (manual §2.3–2.4); when given, its node number wins over `node`.
    pub switches: Option<SwitchesSection>,
    /// TCP address (loopback only) of the drive's CI terminal, the debug console whose SDO
    /// simulation the CMMP-AS manual describes (§3.2.3); none by default.
    pub ci_terminal: Option<String>,
}

/// `[drive.switches]`: how a CMMP-AS's fieldbus settings come from its hardware.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwitchesSection {
    /// `m3` (DIP block S1 of the CAN module) or `m0` (digital inputs).
    pub variant: SwitchVariant,
    /// The FCT base node address (default 0).
    #[serde(default)]
    pub base_address: u8,
    /// M3: the DIP switches that are ON (1…8); M0: the inputs that are HIGH (0…3, 8, 9,
    /// 12, 13).
    #[serde(default)]
    pub on: Vec<u8>,
    /// M0: FCT option "fieldbus parameterisation via DIN" (on in the delivery state).
    #[serde(default = "yes")]
    pub via_din: bool,
    /// M0 without the DIN option: the bit rate set in FCT, kbit/s.
    #[serde(default = "default_fct_bit_rate")]
    pub fct_bit_rate_kbit: u16,
}

fn yes() -> bool {
    true
}
fn default_fct_bit_rate() -> u16 {
    125
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum SwitchVariant {
    M3,
    M0,
}

impl SwitchesSection {
    /// The settings at power-on.
    pub fn settings(&self) -> Result<FieldbusSettings, String> {
        match self.variant {
            SwitchVariant::M3 => {
                let mut dip = [false; 8];
                for &n in &self.on {
                    let slot = usize::from(n)
                        .checked_sub(1)
                        .and_then(|i| dip.get_mut(i))
                        .ok_or(format!("DIP {n}: the M3 block has DIP 1…8"))?;
                    *slot = true;
                }
                Ok(m3_power_on(self.base_address, dip))
            }
            SwitchVariant::M0 => {
                let mut i = M0Inputs::default();
                for &n in &self.on {
                    match n {
                        0..=3 => i.din0_3[usize::from(n)] = true,
                        8 => i.din8 = true,
                        9 => i.din9 = true,
                        12 => i.din12 = true,
                        13 => i.din13 = true,
                        _ => {
                            return Err(format!(
                                "DIN{n}: the M0 fieldbus inputs are DIN0…3, 8, 9, 12, 13"
                            ))
                        }
                    }
                }
                if !BIT_RATES_KBIT.contains(&self.fct_bit_rate_kbit) {
                    return Err(format!(
                        "fct_bit_rate_kbit {}: one of {BIT_RATES_KBIT:?}",
                        self.fct_bit_rate_kbit
                    ));
                }
                Ok(
                    M0Fieldbus::reset(self.base_address, self.via_din, self.fct_bit_rate_kbit, i)
                        .settings(),
                )
            }
        }
    }
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
    /// From `[drive.switches]`, if given.
    pub fieldbus: Option<FieldbusSettings>,
}

impl DriveSpec {
    /// Whether the drive takes part on CAN: yes without switches; with them, as they say
    /// (M3 DIP8, M0 DIN8). A CMMP-AS whose CAN is off stays silent on the bus.
    pub fn on_can(&self) -> Result<bool, ConfigError> {
        match self.fieldbus {
            None => Ok(true),
            Some(f) if f.profile == Profile::Fhpp => Err(ConfigError::FhppOverCan(self.node)),
            Some(f) => Ok(f.can_active),
        }
    }
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
                switches: None,
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
            let fieldbus = match &d.switches {
                Some(sw) => {
                    let err = |what: String| ConfigError::Object {
                        node: d.node,
                        key: "switches".into(),
                        what,
                    };
                    if desc.name != "cmmp-as" {
                        return Err(err(format!("{} has no CMMP-AS switches", desc.name)));
                    }
                    Some(sw.settings().map_err(err)?)
                }
                None => None,
            };
            let node = fieldbus.map_or(d.node, |f| f.node_id);
            if specs.iter().any(|s| s.node == node) {
                return Err(ConfigError::DuplicateNode(node));
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
                node,
                commissioning,
                settings,
                fieldbus,
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

#[cfg(test)]
mod switches_tests {
    use super::*;

    fn spec(text: &str) -> Result<Vec<DriveSpec>, ConfigError> {
        let file: CellFile = toml::from_str(text).map_err(|source| ConfigError::Toml {
            path: PathBuf::from("cell.toml"),
            source,
        })?;
        file.drives()
    }

    fn drive(switches: &str) -> Result<DriveSpec, ConfigError> {
        spec(&format!(
            "[[drive]]\ndevice = \"cmmp-as\"\nnode = 9\n[drive.switches]\n{switches}\n"
        ))
        .map(|mut v| v.remove(0))
    }

    /// CMMP-NODE-01, CMMP-NODE-05, CMMP-NODE-08 from a cell file: DIP 1, 2, 4, 5 ON → node 27
    /// (over the file's `node`), DIP6 ON → 250 kbit/s, DIP8 ON → on the bus.
    #[test]
    fn m3_dip_switches_give_node_bit_rate_and_activation() {
        let d = drive("variant = \"m3\"\non = [1, 2, 4, 5, 6, 8]").unwrap();
        assert_eq!(d.node, 27);
        let f = d.fieldbus.unwrap();
        assert_eq!((f.bit_rate_kbit, f.can_active), (250, true));
        assert!(d.on_can().unwrap());
        // CMMP-NODE-08: DIP8 OFF → CANopen deactivated; CMMP-NODE-02: all offsets OFF → 1.
        let off = drive("variant = \"m3\"\non = []").unwrap();
        assert_eq!(off.node, 1);
        assert!(!off.on_can().unwrap());
        // CMMP-NODE-03: base 120 + 27 → 127.
        let d = drive("variant = \"m3\"\nbase_address = 120\non = [1, 2, 4, 5, 8]").unwrap();
        assert_eq!(d.node, 127);
    }

    /// CMMP-NODE-04, CMMP-NODE-06, CMMP-NODE-07 from a cell file: M0 DIN0, 1, 3 HIGH → node
    /// 11; DIN13 → 500 kbit/s; DIN8 HIGH → on the bus; DIN9 HIGH (FHPP) is refused.
    #[test]
    fn m0_inputs_give_node_bit_rate_and_activation() {
        let d = drive("variant = \"m0\"\non = [0, 1, 3, 8, 13]").unwrap();
        assert_eq!(d.node, 11);
        assert_eq!(d.fieldbus.unwrap().bit_rate_kbit, 500);
        assert!(d.on_can().unwrap());
        let fhpp = drive("variant = \"m0\"\non = [8, 9]").unwrap();
        assert!(matches!(fhpp.on_can(), Err(ConfigError::FhppOverCan(1))));
        let fct =
            drive("variant = \"m0\"\nvia_din = false\nbase_address = 4\non = [0, 1]").unwrap();
        assert_eq!(fct.node, 4);
        assert!(fct.on_can().unwrap(), "FCT activates CAN");
    }

    #[test]
    fn bad_switches_are_clear_errors() {
        for (bad, says) in [
            ("variant = \"m3\"\non = [9]", "DIP 9"),
            ("variant = \"m3\"\non = [0]", "DIP 0"),
            ("variant = \"m0\"\non = [5]", "DIN5"),
            ("variant = \"m0\"\nfct_bit_rate_kbit = 800", "800"),
        ] {
            let err = drive(bad).unwrap_err().to_string();
            assert!(
                err.contains(says) && err.contains("switches"),
                "{bad}: {err}"
            );
        }
        assert!(drive("variant = \"m5\"").is_err());
        let err = spec("[[drive]]\ndevice = \"testbench\"\n[drive.switches]\nvariant = \"m3\"\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("no CMMP-AS switches"), "{err}");
        // Two drives whose switches give the same node.
        let err = spec(
            "[[drive]]\ndevice = \"cmmp-as\"\n[drive.switches]\nvariant = \"m3\"\non = [1]\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 2\n[drive.switches]\nvariant = \"m3\"\n",
        )
        .unwrap_err();
        assert!(matches!(err, ConfigError::DuplicateNode(1)), "{err}");
    }
}
