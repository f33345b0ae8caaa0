//! The cell file (`--config CELL.toml`): which drives, which personalities and node-IDs,
//! which transports. Everything has a default, so `drivetwin run` alone starts the default
//! cell: one CMMP-AS, node 1, heartbeat 1000 ms, socketcand on 127.0.0.1:29536.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use drive::vendors::kinco::dip_switches::{self as kinco_dip_switches, Station};
use drive::vendors::nanotec::rotary_switches::{power_on, RotarySwitches};
use od::{DataType, Value};
use serde::Deserialize;

use crate::cell::bus_rate::{
    self, BitrateSetting, BusNode, BusRate, NodeRate, RateCode, RateObject,
};
use crate::cell::can_drive::Commissioning;
use crate::cell::device_model::{is_cia402, is_fhpp};
use crate::cell::fieldbus_switches::{
    m3_power_on, FieldbusSettings, M0Fieldbus, M0Inputs, Profile, BIT_RATES_KBIT,
};
use crate::cell::interfaces::InterfaceName;
use crate::cell::param_store::StoredValue;
use drive::drive::DriveSettings;
use drive::motor::MotorData;
use drive::stepper::{StepperData, StepperMode};
use drive::travel::{HomeSwitch, TravelSettings};
use drive::vendors::festo_cmmo_st::axis_mechanics::AxisMechanics;
use drive::vendors::festo_cmmo_st::device::FhppSettings;

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

#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct CellFile {
    /// `[bus]` (one bus) or `[[bus]]` entries (several CAN buses).
    #[serde(default)]
    pub bus: Buses,
    #[serde(default)]
    pub drive: Vec<DriveSection>,
}

/// The cell's CAN buses.
#[derive(Debug, Clone)]
pub enum Buses {
    One(BusSection),
    Many(Vec<BusSection>),
}

/// `[bus]` or `[[bus]]`, by the value's shape, so a bad key reports its own error (an
/// untagged enum would only say that neither form matched).
impl<'de> Deserialize<'de> for Buses {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        match toml::Value::deserialize(d)? {
            v @ toml::Value::Array(_) => Vec::<BusSection>::deserialize(v).map(Buses::Many),
            v => BusSection::deserialize(v).map(Buses::One),
        }
        .map_err(D::Error::custom)
    }
}

impl Default for Buses {
    fn default() -> Self {
        Buses::One(BusSection::default())
    }
}

impl Buses {
    pub fn all(&self) -> &[BusSection] {
        match self {
            Buses::One(b) => std::slice::from_ref(b),
            Buses::Many(v) => v,
        }
    }

    pub fn all_mut(&mut self) -> &mut [BusSection] {
        match self {
            Buses::One(b) => std::slice::from_mut(b),
            Buses::Many(v) => v,
        }
    }

    /// The first bus (the one `--socketcand`, `--channel` and `--socketcan` set), made if
    /// the file has none.
    pub fn first_mut(&mut self) -> &mut BusSection {
        if let Buses::Many(v) = self {
            if v.is_empty() {
                v.push(BusSection::default());
            }
        }
        match self {
            Buses::One(b) => b,
            #[allow(clippy::indexing_slicing, reason = "made non-empty above")]
            Buses::Many(v) => &mut v[0],
        }
    }

    /// The index of the bus a drive names (by `name`, else by `channel`); the first without
    /// a name.
    pub fn index(&self, name: Option<&str>) -> Option<usize> {
        match name {
            None => Some(0),
            Some(n) => self.all().iter().position(|b| b.label() == n),
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BusSection {
    /// What drives call the bus (`bus = "..."`); default its channel.
    pub name: Option<String>,
    /// socketcand server address; "" turns the server off.
    #[serde(default = "default_socketcand")]
    pub socketcand: String,
    #[serde(default = "default_channel")]
    pub channel: String,
    /// A SocketCAN interface to bridge (real hardware or vcan).
    pub socketcan: Option<String>,
    /// Bit rate, bit/s: frames take the bus for their bit time and wait for the arbitration
    /// (`cell::bus_timing`). Without it the bus runs at the rate its nodes are set to (their
    /// switches and objects), and nodes set to different rates are refused
    /// ([`crate::cell::bus_rate`]); with it a node set to another rate stays silent, as on a
    /// real bus. `"instant"`: frames cross at once (fast tests, latency benchmarks).
    pub bitrate: Option<BitrateSetting>,
    /// A frame that waits longer than this for the bus counts as late (default 1000 µs).
    pub late_after_us: Option<u32>,
    /// Join the socketcand server at this address as a client: the bus is that server's
    /// bus (one plant over several processes or machines).
    pub join: Option<String>,
    /// socketcand clients served at once (default 128); more are refused.
    pub max_clients: Option<usize>,
    /// Where every frame of this bus is written (candump `.log`, else pcap); `--trace` is the
    /// first bus's.
    pub trace: Option<PathBuf>,
    /// Planned disturbances: `[[bus.disturb]]` with `at_ms`, `node` and `frames` (that many
    /// of the node's next transmissions fail with an error frame: 16 make it error passive,
    /// 32 take it off the bus).
    #[serde(default)]
    pub disturb: Vec<DisturbSection>,
}

/// One planned disturbance of a node's transmissions.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct DisturbSection {
    pub at_ms: u64,
    pub node: u8,
    pub frames: u32,
}

impl BusSection {
    /// What drives call the bus: its name, else its channel.
    pub fn label(&self) -> &str {
        self.name.as_deref().unwrap_or(&self.channel)
    }

    /// A frame that waits longer than this for the bus counts as late.
    pub fn late_after(&self) -> std::time::Duration {
        std::time::Duration::from_micros(u64::from(self.late_after_us.unwrap_or(1000)))
    }
}

impl Default for BusSection {
    fn default() -> Self {
        BusSection {
            name: None,
            socketcand: default_socketcand(),
            channel: default_channel(),
            socketcan: None,
            bitrate: None,
            late_after_us: None,
            join: None,
            max_clients: None,
            trace: None,
            disturb: Vec::new(),
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
    /// A CiA 402 drive from its EDS or DCF (CiA 306) instead of a built-in `device`: the
    /// file's dictionary on the engine's standard behaviour ([`crate::cell::eds_drive`]). A
    /// relative path is relative to the cell file.
    pub eds: Option<PathBuf>,
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
    /// A CMMO-ST's Modbus TCP server address (default 127.0.0.1:1502; every CMMO-ST of a
    /// cell needs its own).
    pub modbus: Option<String>,
    /// A CMMO-ST's Modbus connection watchdog, ms (0 = off, the factory setting).
    pub modbus_timeout_ms: Option<u16>,
    /// A CMMO-ST's stepper motor, load and control mode.
    #[serde(default)]
    pub stepper: StepperSection,
    /// A CMMO-ST's axis: end stops, reference switch, index pulse (homing).
    #[serde(default)]
    pub axis: AxisSection,
    /// The CMMP-AS switch positions or input levels that give node number, bit rate and
    /// CAN activation (manual §2.3–2.4); when given, its node number wins over `node`.
    pub switches: Option<SwitchesSection>,
    /// A Nanotec's motor (2004h:07, §1.2 "Motortyp"): `"stepper"` (the default),
    /// `"bldc-hall"` or `"bldc-hall-encoder"`; see [`NanotecMotorType`].
    pub motor_type: Option<NanotecMotorType>,
    /// A Nanotec's hexadecimal rotary switches (§1.1.1): node-ID and bit rate at power-on;
    /// when they give a node-ID it wins over `node`.
    pub rotary_switches: Option<RotarySwitchesSection>,
    /// A Kinco FD3's DIP switches SW1…SW8 (§3.8): the station number at power-on; when they
    /// give one it wins over `node`.
    pub dip_switches: Option<DipSwitchesSection>,
    /// TCP address (loopback only) of the drive's CI terminal, the debug console whose SDO
    /// simulation the CMMP-AS manual describes (§3.2.3); none by default.
    pub ci_terminal: Option<String>,
    /// The `[[bus]]` (by name or channel) the drive's CANopen node is on; default the first.
    pub bus: Option<String>,
    /// The drive's interfaces, e.g. `["canopen", "ci-terminal"]`; default what its profile
    /// and keys imply. Checked against what the real device offers
    /// ([`crate::cell::interfaces`]).
    pub interfaces: Option<Vec<InterfaceName>>,
    /// Testing only: allow interface combinations the real device does not have (e.g. a
    /// CMMP-AS on CANopen and EtherCAT at once).
    #[serde(default)]
    pub allow_unreal_interfaces: bool,
    /// The network interface of the EtherCAT chain the drive is a slave of (its position:
    /// its order among the drives of that chain in the file); implies `"ethercat"` in
    /// `interfaces`. Without it, a drive with `"ethercat"` is on the chain of `--ethercat`.
    pub ethercat: Option<String>,
    /// Diagnostic messages raised (or cleared) at a time of the cell's clock:
    /// `[[drive.diagnostic]]` with `at_ms`, `number` ("08-2", as the drive's manual prints
    /// it) and `action` (`raise`, the default, or `clear`). CANopen drives.
    #[serde(default)]
    pub diagnostic: Vec<crate::cell::diagnostics::PlannedDiagnostic>,
    /// The plant's physics changed at a time of the cell's clock: `[[drive.plant]]` with
    /// `at_ms` and one of `ambient_c`, `encoder` (+ `noise`), `switch` (+ `actuated`,
    /// `release`).
    #[serde(default)]
    pub plant: Vec<crate::cell::diagnostics::PlannedPhysics>,
    /// `[drive.thermal]`: the ambient temperature and the thermal figures of motor and power
    /// stage (`drive::thermal`).
    pub thermal: Option<ThermalSection>,
    /// The drive's RS232 port (a Kinco's X3, the 10-byte telegrams): a path made a link to a
    /// pty of the twin, or a real serial device. Drives that name one path form a ring.
    pub rs232: Option<String>,
    /// The drive's RS485 port (a Kinco FD3's, Modbus RTU): as `rs232`; drives that name one
    /// path share the line, each answering its station number (= node-ID).
    pub rs485: Option<String>,
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

/// `[drive.stepper]`: the CMMO-ST's motor and load; unset fields keep the defaults of
/// [`StepperData`] (an EMMS-ST-42-class motor with a light load, closed loop).
#[derive(Debug, Clone, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StepperSection {
    /// `"closed-loop"` (the CMMO-ST with its encoder) or `"open-loop"` (steps are lost when
    /// the load exceeds the pull-out torque).
    pub mode: Option<StepperModeName>,
    pub holding_torque: Option<f64>,
    pub load_inertia: Option<f64>,
    pub load_torque: Option<f64>,
    pub coulomb_friction: Option<f64>,
    pub viscous_friction: Option<f64>,
    pub supply_voltage: Option<f64>,
}

/// `motor_type` of a Nanotec drive: the motor connected and the 2004h:07 it starts with
/// (Nanotec §1.2 "Motortyp", §11.5 sub 7: 0 stepper with or without quadrature encoder, 1 BLDC
/// with Hall sensors, 2 BLDC with Hall sensors and quadrature encoder).
///
/// A BLDC is `drive::bldc`'s default (DB57-like: 4 pole pairs, the DB57 Hall sequence that the
/// default 2004h:0C = 243015h turns) with `[drive.motor]` as its electrical and mechanical
/// data; it starts with 2004h:07 = 1 / 2 and the BLDC load-angle curve of Appendix 18.2 in
/// 200Ch:01 … 07. Values of `[drive.objects]` and a stored set still win, as for every
/// commissioning value.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum NanotecMotorType {
    Stepper,
    BldcHall,
    #[serde(alias = "bldc-encoder")]
    BldcHallEncoder,
}

impl NanotecMotorType {
    /// The value of 2004h:07.
    pub fn code(self) -> u8 {
        match self {
            NanotecMotorType::Stepper => 0,
            NanotecMotorType::BldcHall => 1,
            NanotecMotorType::BldcHallEncoder => 2,
        }
    }

    /// The commissioning values the motor type sets: 2004h:07 and, for a BLDC, the load-angle
    /// curve of Appendix 18.2 (200Ch:01 … 07), as the drive loads it when 2004h:07 selects a
    /// BLDC over SDO.
    fn commissioning(self) -> Vec<Commissioning> {
        let mut v = vec![Commissioning {
            index: 0x2004,
            sub: 7,
            bytes: vec![self.code()],
        }];
        if self != NanotecMotorType::Stepper {
            let curve = drive::vendors::nanotec::default_load_angles(self.code());
            v.extend((1u8..).zip(curve).map(|(sub, a)| Commissioning {
                index: 0x200C,
                sub,
                bytes: a.to_le_bytes().to_vec(),
            }));
        }
        v
    }
}

/// `mode` of `[drive.stepper]`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum StepperModeName {
    ClosedLoop,
    OpenLoop,
}

impl StepperSection {
    /// The stepper data and mode, or what is wrong with them.
    pub fn stepper(&self) -> Result<(StepperData, StepperMode), String> {
        let d = StepperData::default();
        for (name, v, positive) in [
            ("holding_torque", self.holding_torque, true),
            ("supply_voltage", self.supply_voltage, true),
            ("load_inertia", self.load_inertia, false),
            ("coulomb_friction", self.coulomb_friction, false),
            ("viscous_friction", self.viscous_friction, false),
        ] {
            if let Some(v) = v {
                if !(v.is_finite() && (v > 0.0 || (!positive && v == 0.0))) {
                    let bound = if positive { "> 0" } else { "≥ 0" };
                    return Err(format!("stepper.{name} must be a number {bound}"));
                }
            }
        }
        if self.load_torque.is_some_and(|v| !v.is_finite()) {
            return Err("stepper.load_torque must be a finite number".into());
        }
        let data = StepperData {
            holding_torque: self.holding_torque.unwrap_or(d.holding_torque),
            load_inertia: self.load_inertia.unwrap_or(d.load_inertia),
            load_torque: self.load_torque.unwrap_or(d.load_torque),
            coulomb_friction: self.coulomb_friction.unwrap_or(d.coulomb_friction),
            viscous_friction: self.viscous_friction.unwrap_or(d.viscous_friction),
            supply_voltage: self.supply_voltage.unwrap_or(d.supply_voltage),
            ..d
        };
        let mode = match self.mode {
            Some(StepperModeName::OpenLoop) => StepperMode::OpenLoop,
            Some(StepperModeName::ClosedLoop) | None => StepperMode::ClosedLoop,
        };
        Ok((data, mode))
    }
}

/// Something fitted to the axis at a place, or `"none"`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum Fitted<T> {
    At(T),
    Absent(String),
}

impl<T: Copy> Fitted<T> {
    fn get(&self, name: &str) -> Result<Option<T>, String> {
        match self {
            Fitted::At(v) => Ok(Some(*v)),
            Fitted::Absent(s) if s == "none" => Ok(None),
            Fitted::Absent(s) => Err(format!(
                "axis.{name}: {s:?} is neither a place nor \"none\""
            )),
        }
    }
}

/// `[drive.axis]`: the CMMO-ST's axis in motor revolutions from the power-on position; unset
/// fields keep [`AxisMechanics::default`] (stops at −3 / +47, a reference cam −0.05 … 0.05,
/// index pulse at 0.3 of each revolution). `"none"` removes a part (an endless axis, no
/// switch, an encoder without index).
#[derive(Debug, Clone, Deserialize, Default, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AxisSection {
    pub end_stops: Option<Fitted<[f64; 2]>>,
    pub reference_switch: Option<Fitted<[f64; 2]>>,
    pub index_pulse: Option<Fitted<f64>>,
}

impl AxisSection {
    /// The axis, or what is wrong with it.
    pub fn mechanics(&self) -> Result<AxisMechanics, String> {
        let d = AxisMechanics::default();
        let pair = |name: &str, v: &Option<Fitted<[f64; 2]>>, dflt: Option<(f64, f64)>| {
            let Some(v) = v else {
                return Ok(dflt);
            };
            match v.get(name)? {
                None => Ok(None),
                Some([lo, hi]) if lo.is_finite() && hi.is_finite() && lo <= hi => {
                    Ok(Some((lo, hi)))
                }
                Some(_) => Err(format!("axis.{name} must be [low, high] with low ≤ high")),
            }
        };
        let end_stops = pair("end_stops", &self.end_stops, d.end_stops)?;
        if end_stops.is_some_and(|(lo, hi)| lo == hi || lo.abs().max(hi.abs()) > 1e6) {
            return Err("axis.end_stops must lie apart, within ±10^6 revolutions".into());
        }
        let reference_switch = pair(
            "reference_switch",
            &self.reference_switch,
            d.reference_switch,
        )?;
        let index_pulse = match &self.index_pulse {
            None => d.index_pulse,
            Some(v) => match v.get("index_pulse")? {
                Some(f) if (0.0..1.0).contains(&f) => Some(f),
                Some(_) => {
                    return Err(
                        "axis.index_pulse must lie in 0 … 1 (a fraction of a revolution)".into(),
                    )
                }
                None => None,
            },
        };
        Ok(AxisMechanics {
            end_stops,
            reference_switch,
            index_pulse,
        })
    }
}

/// How a CMMO-ST of the cell is served and simulated.
#[derive(Debug, Clone)]
pub struct FhppSpec {
    pub settings: FhppSettings,
    /// Its Modbus TCP server address, if the cell file gives one.
    pub modbus: Option<String>,
    pub watchdog_ms: Option<u16>,
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

/// `[drive.rotary_switches]`: `left` and `right` on a two-switch Nanotec (SMCI47-S; the value
/// is 16 · right + left, see `drive::vendors::nanotec::rotary_switches`), `switch` on a
/// one-switch one (PD4-N).
/// The EEPROM values they may select are 2009h (node-ID) and 2005h (bit rate) of
/// `[drive.objects]`, else the defaults.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotarySwitchesSection {
    pub left: Option<u8>,
    pub right: Option<u8>,
    pub switch: Option<u8>,
}

impl RotarySwitchesSection {
    /// The switches of a device that has `count` of them.
    fn switches(&self, count: u8) -> Result<RotarySwitches, String> {
        let s = match (count, self.left, self.right, self.switch) {
            (2, left, right, None) => RotarySwitches::Two {
                left: left.unwrap_or(0),
                right: right.unwrap_or(0),
            },
            (1, None, None, Some(p)) => RotarySwitches::One(p),
            (2, ..) => return Err("two switches: `left` and `right`, no `switch`".into()),
            (1, ..) => return Err("one switch: `switch`, no `left`/`right`".into()),
            _ => return Err("the device has no rotary switches".into()),
        };
        s.checked().map_err(|e| e.to_string())
    }
}

/// `[drive.dip_switches]`: the DIP switches SW1…SW8 of a Kinco FD3 that are ON (`on = [1,
/// 2]` is station 3; none ON: the stored station number 2F80h:01 of `[drive.objects]`, else
/// its default). The table of §3.8 (Tab. 3-8) gives the station number only; the CAN bit rate
/// is CAN_Baudrate 2F81h.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DipSwitchesSection {
    #[serde(default)]
    pub on: Vec<u8>,
}

impl DipSwitchesSection {
    /// The station number the switches select, or `None` for the stored one (all OFF).
    fn station(&self) -> Result<Option<u8>, String> {
        let sw = eight_switches(&self.on, |n| format!("SW{n}: the FD3 has SW1…SW8"))?;
        match kinco_dip_switches::station(sw) {
            Station::Stored => Ok(None),
            Station::Switches(s) => kinco_dip_switches::can_node_id(s).map(Some).ok_or(format!(
                "station {s}: a CANopen node-ID is 1…127 (§11.1); the twin runs the FD3 as a \
                 CANopen node, so 128…255 (RS232 / RS485 only) is not simulated"
            )),
        }
    }
}

/// A block of eight switches numbered from 1 with those of `on` ON (`[0]` is switch 1);
/// `bad` names a number outside 1…8.
fn eight_switches(on: &[u8], bad: impl Fn(u8) -> String) -> Result<[bool; 8], String> {
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
    /// What sets the bit rate, for messages: the switches, the inputs or FCT.
    fn rate_key(&self) -> &'static str {
        match (self.variant, self.via_din) {
            (SwitchVariant::M3, _) => "[drive.switches] DIP6/DIP7",
            (SwitchVariant::M0, true) => "[drive.switches] DIN12/DIN13",
            (SwitchVariant::M0, false) => "[drive.switches] fct_bit_rate_kbit",
        }
    }

    /// The settings at power-on.
    pub fn settings(&self) -> Result<FieldbusSettings, String> {
        match self.variant {
            SwitchVariant::M3 => {
                let dip =
                    eight_switches(&self.on, |n| format!("DIP {n}: the M3 block has DIP 1…8"))?;
                Ok(m3_power_on(self.base_address, dip))
            }
            SwitchVariant::M0 => {
                let mut i = M0Inputs::default();
                for &n in &self.on {
                    match n {
                        0..=3 => {
                            if let Some(din) = i.din0_3.get_mut(usize::from(n)) {
                                *din = true;
                            }
                        }
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
#[derive(Debug, Clone, Deserialize, Default, PartialEq)]
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
#[derive(Debug, Clone, Deserialize, Default, PartialEq)]
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
    /// For FHPP personalities (the CMMO-ST): the stepper, its axis and its Modbus server.
    pub fhpp: Option<FhppSpec>,
    /// From `[drive.switches]`, if given.
    pub fieldbus: Option<FieldbusSettings>,
    /// The CAN bit rate its switches and objects set, and what sets it; `None`: none of its
    /// own (no CAN interface, a Nanotec whose 2005h holds no code, the test bench).
    pub bit_rate: Option<NodeRate>,
    /// The object that sets that rate (Kinco 2F81h, Nanotec 2005h), which a stored set may
    /// change ([`DriveSpec::load_stored_rate`]).
    pub rate_object: Option<RateObject>,
    /// The index of the bus (of [`Buses::all`]) its CANopen node is on.
    pub bus: usize,
    /// A CANopen node on its bus (false: EtherCAT only, or the CMMO-ST).
    pub canopen: bool,
    /// An EtherCAT slave: `Some(chain)`, the chain's network interface when the cell file
    /// names it (else `--ethercat`'s).
    pub ethercat: Option<Option<String>>,
    /// `[[drive.diagnostic]]`: messages planned on the cell's clock (checked against the
    /// device's table).
    pub diagnostics: Vec<crate::cell::diagnostics::PlannedDiagnostic>,
    /// `[drive.thermal]` (at 0) and `[[drive.plant]]`: the plant's physics changed at a time
    /// of the cell's clock, ms.
    pub physics: Vec<(u64, crate::cell::control::PhysicsChange)>,
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
        let mut file: CellFile = toml::from_str(&text).map_err(|source| ConfigError::Toml {
            path: path.to_path_buf(),
            source,
        })?;
        let dir = path.parent().unwrap_or(Path::new(""));
        for d in &mut file.drive {
            if let Some(eds) = d.eds.as_mut().filter(|p| p.is_relative()) {
                *eds = dir.join(&*eds);
            }
        }
        Ok(file)
    }

    /// The default cell with one drive from its EDS or DCF (`--eds`), as [`CellFile::single`]:
    /// the heartbeat where the file has 1017h.
    pub fn single_eds(eds: &Path, node: u8) -> Result<Self, ConfigError> {
        let desc = crate::cell::eds_drive::load(eds)?;
        let mut file = Self::single("", node);
        if let Some(d) = file.drive.first_mut() {
            d.device = default_device();
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
        CellFile {
            bus: Buses::default(),
            drive: vec![DriveSection {
                device: device.to_string(),
                eds: None,
                node,
                objects,
                motor: MotorSection::default(),
                travel: TravelSection::default(),
                mode_change_time_ms: None,
                modbus: None,
                modbus_timeout_ms: None,
                stepper: StepperSection::default(),
                axis: AxisSection::default(),
                switches: None,
                motor_type: None,
                rotary_switches: None,
                dip_switches: None,
                ci_terminal: None,
                bus: None,
                interfaces: None,
                allow_unreal_interfaces: false,
                ethercat: None,
                rs232: None,
                rs485: None,
                diagnostic: Vec::new(),
                plant: Vec::new(),
                thermal: None,
            }],
        }
    }

    pub fn drives(&self) -> Result<Vec<DriveSpec>, ConfigError> {
        let mut specs: Vec<DriveSpec> = Vec::new();
        for d in &self.drive {
            let desc = match &d.eds {
                Some(_) if d.device != default_device() => {
                    return Err(ConfigError::Object {
                        node: d.node,
                        key: "eds".into(),
                        what: format!("a drive is `device = {:?}` or `eds`, not both", d.device),
                    })
                }
                Some(eds) => crate::cell::eds_drive::load(eds)?,
                None => devices::by_name(&d.device).ok_or_else(|| {
                    let known: Vec<&str> = devices::ALL.iter().map(|d| d.name).collect();
                    ConfigError::UnknownDevice(d.device.clone(), known.join(", "))
                })?,
            };
            let fieldbus = match &d.switches {
                Some(sw) => {
                    let err = key_error(d, "switches");
                    if !desc.fieldbus_switches {
                        return Err(err(format!("{} has no CMMP-AS switches", desc.name)));
                    }
                    Some(sw.settings().map_err(err)?)
                }
                None => None,
            };
            let rotary = match &d.rotary_switches {
                Some(rs) => {
                    let err = key_error(d, "rotary_switches");
                    let switches = rs.switches(desc.rotary_switches).map_err(err)?;
                    let eeprom = |index| stored_u8(desc, d, index, 0).map_err(err);
                    let p = power_on(switches, eeprom(0x2009)?, eeprom(0x2005)?);
                    if !(1..=127).contains(&p.node_id) {
                        return Err(err(format!("node-ID {} from 2009h", p.node_id)));
                    }
                    if !p.motion_allowed {
                        tracing::warn!(
                            node = p.node_id,
                            "2005h holds no bit-rate code (130…135): the controller answers on \
                             CAN but accepts no motion commands (Nanotec §1.1.3 step 7)"
                        );
                    }
                    Some(p)
                }
                None => None,
            };
            let station = match &d.dip_switches {
                Some(dip) => {
                    let err = key_error(d, "dip_switches");
                    if desc.name != "kinco-fd3" {
                        return Err(err(format!(
                            "{} has no DIP switches SW1…SW8 (Kinco §3.8: the FD3's)",
                            desc.name
                        )));
                    }
                    // All OFF: the stored station number 2F80h:01 (§3.8).
                    match dip.station().map_err(err)? {
                        Some(s) => Some(s),
                        None => match stored_u8(desc, d, 0x2F80, 1).map_err(err)? {
                            s @ 1..=127 => Some(s),
                            s => return Err(err(format!("station {s} from 2F80h:01"))),
                        },
                    }
                }
                None => None,
            };
            let node = match (rotary, station) {
                (Some(p), _) => p.node_id,
                (None, Some(s)) => s,
                (None, None) => fieldbus.map_or(d.node, |f| f.node_id),
            };
            let (bit_rate, rate_object) = node_rate(desc, d, fieldbus, rotary)?;
            let bus = self
                .bus
                .index(d.bus.as_deref())
                .ok_or_else(|| ConfigError::UnknownBus {
                    node,
                    name: d.bus.clone().unwrap_or_default(),
                    known: self
                        .bus
                        .all()
                        .iter()
                        .map(BusSection::label)
                        .collect::<Vec<_>>()
                        .join(", "),
                })?;
            // Decision: without `interfaces` a drive's interfaces follow from its profile's
            // fieldbus, `ci_terminal` and `modbus`, checked below.
            if let Some(interfaces) = &d.interfaces {
                crate::cell::interfaces::check(desc.name, interfaces, d.allow_unreal_interfaces)
                    .map_err(|source| ConfigError::Interfaces { node, source })?;
            }
            let (canopen, ethercat) = match (&d.interfaces, &d.ethercat) {
                (Some(i), chain) => {
                    if chain.is_some() && !i.contains(&InterfaceName::Ethercat) {
                        return Err(ConfigError::Object {
                            node: d.node,
                            key: "ethercat".into(),
                            what: "names a chain, but `interfaces` has no \"ethercat\"".into(),
                        });
                    }
                    let on_ethercat = i.contains(&InterfaceName::Ethercat);
                    // Without a fieldbus named, a CiA 301 / 402 device is on CAN as before.
                    let canopen = i.contains(&InterfaceName::Canopen)
                        || (!on_ethercat
                            && !is_fhpp(desc)
                            && !i.contains(&InterfaceName::ModbusTcp));
                    (canopen, on_ethercat.then(|| chain.clone()))
                }
                (None, Some(chain)) => {
                    crate::cell::interfaces::check(
                        desc.name,
                        &[InterfaceName::Ethercat],
                        d.allow_unreal_interfaces,
                    )
                    .map_err(|source| ConfigError::Interfaces { node, source })?;
                    (false, Some(Some(chain.clone())))
                }
                (None, None) => (!is_fhpp(desc), None),
            };
            let err = |key: &str, what: String| ConfigError::Object {
                node: d.node,
                key: key.into(),
                what,
            };
            let fhpp = if is_fhpp(desc) {
                if d.travel != TravelSection::default()
                    || d.motor != MotorSection::default()
                    || d.mode_change_time_ms.is_some()
                    || d.ci_terminal.is_some()
                {
                    return Err(err(
                        "motor",
                        "motor, travel, mode_change_time_ms and ci_terminal are a CMMP-AS's; \
                         the CMMO-ST has [drive.stepper] and [drive.axis]"
                            .into(),
                    ));
                }
                let (stepper, mode) = d.stepper.stepper().map_err(|w| err("stepper", w))?;
                let mechanics = d.axis.mechanics().map_err(|w| err("axis", w))?;
                Some(FhppSpec {
                    settings: FhppSettings {
                        stepper,
                        mode,
                        mechanics,
                        ..FhppSettings::default()
                    },
                    modbus: d.modbus.clone(),
                    watchdog_ms: d.modbus_timeout_ms,
                })
            } else {
                if d.stepper != StepperSection::default()
                    || d.axis != AxisSection::default()
                    || d.modbus.is_some()
                    || d.modbus_timeout_ms.is_some()
                {
                    return Err(err(
                        "stepper",
                        format!("{}: stepper, axis and modbus are the CMMO-ST's", desc.name),
                    ));
                }
                // The CAN node-IDs of one bus are unique.
                if specs
                    .iter()
                    .any(|s| s.fhpp.is_none() && s.node == node && s.bus == bus)
                {
                    return Err(ConfigError::DuplicateNode(node));
                }
                None
            };
            if d.motor_type.is_some() && !(is_cia402(desc) && desc.entry(0x2004, 7).is_some()) {
                return Err(err(
                    "motor_type",
                    format!("{} has no motor type 2004h:07 (a Nanotec's)", desc.name),
                ));
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
                // NT-NODE-07: no bit-rate code in 2005h, the controller takes no motion
                // command: modelled as a power stage that cannot be switched on.
                if rotary.is_some_and(|p| !p.motion_allowed) {
                    s.enables_present = false;
                }
                if let Some(t) = d.motor_type {
                    if t != NanotecMotorType::Stepper {
                        s.bldc = Some(drive::bldc::BldcData::default());
                    }
                    commissioning.extend(t.commissioning());
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
            // §11.10: with a node-ID from the switches, 2009h reads the switch value.
            if let Some(p) = rotary.filter(|p| p.node_id_from_switches) {
                commissioning.push(Commissioning {
                    index: 0x2009,
                    sub: 0,
                    bytes: vec![p.node_id],
                });
            }
            for p in &d.diagnostic {
                let err = |what: &str| ConfigError::Diagnostic {
                    node,
                    number: p.number.clone(),
                    what: what.to_owned(),
                };
                if desc.diagnostic(&p.number).is_none() {
                    return Err(err(&format!("{} has no such message", desc.name)));
                }
            }
            let plant_err = |what: String| ConfigError::Object {
                node,
                key: "plant".into(),
                what,
            };
            let mut physics = Vec::new();
            if let Some(t) = &d.thermal {
                for c in t.changes().map_err(plant_err)? {
                    physics.push((0, c));
                }
            }
            for p in &d.plant {
                physics.push((p.at_ms, p.change().map_err(plant_err)?));
            }
            specs.push(DriveSpec {
                desc,
                node,
                commissioning,
                settings,
                fhpp,
                fieldbus,
                bit_rate,
                rate_object,
                bus,
                canopen,
                ethercat,
                diagnostics: d.diagnostic.clone(),
                physics,
            });
        }
        Ok(specs)
    }
}

/// The error of drive `d`'s key `key`.
fn key_error<'a>(d: &'a DriveSection, key: &'a str) -> impl Fn(String) -> ConfigError + Copy + 'a {
    move |what| ConfigError::Object {
        node: d.node,
        key: key.into(),
        what,
    }
}

/// The value of an 8-bit entry at power-on: `[drive.objects]`'s, else the device's default.
fn stored_u8(
    desc: &od::DeviceDescription,
    d: &DriveSection,
    index: u16,
    sub: u8,
) -> Result<u8, String> {
    let key = format!("{index:04X}:{sub:02X}");
    match d
        .objects
        .iter()
        .find(|(k, _)| parse_key(k) == Some((index, sub)))
    {
        Some((_, toml::Value::Integer(v))) => {
            u8::try_from(*v).map_err(|_| format!("{key} = {v} is not a u8"))
        }
        Some(_) => Err(format!("{key} must be an integer")),
        None => Ok(desc
            .entry(index, sub)
            .and_then(|e| e.default.first().copied())
            .unwrap_or(0)),
    }
}

/// The CAN bit rate a drive's switches and objects set ([`bus_rate::NodeRate`]): the CMMP-AS's
/// switches, a Nanotec's rotary switches and 2005h, a Kinco FD3's 2F81h; none for a device
/// without CAN bit rates (its device file lists none) or without rules of its own. With it,
/// the object that sets the rate, if one does.
fn node_rate(
    desc: &od::DeviceDescription,
    d: &DriveSection,
    fieldbus: Option<FieldbusSettings>,
    rotary: Option<drive::vendors::nanotec::rotary_switches::PowerOn>,
) -> Result<(Option<NodeRate>, Option<RateObject>), ConfigError> {
    if desc.baud_rates.is_empty() {
        return Ok((None, None));
    }
    let err = key_error(d, "objects");
    let code = |index| -> Result<RateCode, ConfigError> {
        let default = desc
            .entry(index, 0)
            .and_then(|e| e.default.first().copied())
            .unwrap_or(0);
        let set = d.objects.keys().any(|k| parse_key(k) == Some((index, 0)));
        let value = stored_u8(desc, d, index, 0).map_err(err)?;
        Ok(RateCode::new(default, set.then_some(value)))
    };
    let object = match desc.name {
        "cmmp-as" => {
            let switches = fieldbus.zip(d.switches.as_ref().map(SwitchesSection::rate_key));
            return Ok((Some(NodeRate::cmmp_as(switches)), None));
        }
        _ if desc.rotary_switches > 0 => RateObject::Nanotec(rotary, code(0x2005)?),
        "kinco-fd3" => RateObject::Kinco(code(0x2F81)?),
        _ => return Ok((None, None)),
    };
    Ok((object.rate(), Some(object)))
}

impl DriveSpec {
    /// Its bit rate with the node's stored parameter set (`--state-dir`), read from `file`:
    /// a saved rate object wins over the cell file's, as the drive loads it at power-on.
    pub fn load_stored_rate(&mut self, stored: &[StoredValue], file: &Path) {
        let Some(object) = self.rate_object.take() else {
            return;
        };
        let index = object.index();
        let saved = stored
            .iter()
            .find(|v| v.index == index && v.sub == 0)
            .and_then(|v| match v.bytes.as_slice() {
                [code] => Some(*code),
                _ => None,
            });
        let object = match saved {
            Some(code) => object.stored(code, file),
            None => object,
        };
        self.bit_rate = object.rate();
        self.rate_object = Some(object);
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
mod cmmo_st_tests {
    use super::*;

    fn spec(text: &str) -> Result<Vec<DriveSpec>, String> {
        let file: CellFile = toml::from_str(text).map_err(|e| e.to_string())?;
        file.drives().map_err(|e| e.to_string())
    }

    #[test]
    fn stepper_axis_and_modbus_of_a_cmmo_st() {
        let drives = spec(
            "[[drive]]\ndevice = \"cmmo-st\"\nmodbus = \"127.0.0.1:1600\"\n\
             modbus_timeout_ms = 200\n[drive.stepper]\nmode = \"open-loop\"\n\
             load_torque = -0.1\nholding_torque = 1.2\n[drive.axis]\nend_stops = \"none\"\n\
             reference_switch = [1.0, 1.25]\nindex_pulse = 0.5\n[drive.objects]\n\
             \"2079:01\" = 65\n",
        )
        .unwrap();
        let f = drives[0].fhpp.as_ref().expect("an FHPP drive");
        assert_eq!(f.modbus.as_deref(), Some("127.0.0.1:1600"));
        assert_eq!(f.watchdog_ms, Some(200));
        assert_eq!(f.settings.mode, StepperMode::OpenLoop);
        assert_eq!(f.settings.stepper.load_torque, -0.1);
        assert_eq!(f.settings.stepper.holding_torque, 1.2);
        let d = StepperData::default();
        assert_eq!(f.settings.stepper.rotor_inertia, d.rotor_inertia);
        assert_eq!(f.settings.mechanics.end_stops, None, "an endless axis");
        assert_eq!(f.settings.mechanics.reference_switch, Some((1.0, 1.25)));
        assert_eq!(f.settings.mechanics.index_pulse, Some(0.5));
        assert_eq!(drives[0].commissioning.len(), 1, "PNU 121:1 commissioned");
        assert!(drives[0].settings.is_none(), "no CiA 402 model");
    }

    #[test]
    fn the_defaults_of_a_cmmo_st() {
        let drives = spec("[[drive]]\ndevice = \"cmmo-st\"\n").unwrap();
        let f = drives[0].fhpp.as_ref().expect("an FHPP drive");
        assert_eq!(f.modbus, None);
        assert_eq!(f.settings.mode, StepperMode::ClosedLoop);
        assert_eq!(f.settings.mechanics, AxisMechanics::default());
        // A CMMO-ST and a CMMP-AS may both say node 1: only CAN drives share a bus.
        let both = spec("[[drive]]\ndevice = \"cmmp-as\"\n[[drive]]\ndevice = \"cmmo-st\"\n");
        assert_eq!(both.map(|d| d.len()), Ok(2));
    }

    #[test]
    fn wrong_sections_and_values_are_refused_with_their_name() {
        let cases = [
            (
                "device = \"cmmp-as\"\n[drive.stepper]\nmode = \"open-loop\"",
                "CMMO-ST",
            ),
            ("device = \"cmmp-as\"\nmodbus = \"127.0.0.1:1\"", "CMMO-ST"),
            (
                "device = \"cmmo-st\"\n[drive.motor]\ninertia = 1.0",
                "[drive.stepper]",
            ),
            (
                "device = \"cmmo-st\"\n[drive.axis]\nend_stops = [2.0, 1.0]",
                "low ≤ high",
            ),
            (
                "device = \"cmmo-st\"\n[drive.axis]\nend_stops = [1.0, 1.0]",
                "apart",
            ),
            (
                "device = \"cmmo-st\"\n[drive.axis]\nindex_pulse = 1.5",
                "0 … 1",
            ),
            (
                "device = \"cmmo-st\"\n[drive.axis]\nreference_switch = \"no\"",
                "\"none\"",
            ),
            (
                "device = \"cmmo-st\"\n[drive.stepper]\nholding_torque = 0.0",
                "> 0",
            ),
            (
                "device = \"cmmo-st\"\n[drive.stepper]\nload_inertia = -1.0",
                "≥ 0",
            ),
            (
                "device = \"cmmo-st\"\n[drive.stepper]\nmode = \"servo\"",
                "unknown variant",
            ),
            (
                "device = \"cmmo-st\"\n[drive.stepper]\nteeth = 50",
                "unknown field",
            ),
        ];
        for (text, expected) in cases {
            let err = spec(&format!("[[drive]]\n{text}\n")).expect_err(text);
            assert!(err.contains(expected), "{text}: {err}");
        }
    }
}

#[cfg(test)]
mod example_tests {
    use super::*;

    /// Every cell file under `examples/` loads and describes its drives.
    #[test]
    fn the_example_cell_files_load() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
        let mut seen = 0;
        for entry in std::fs::read_dir(&dir).expect("examples/") {
            let path = entry.expect("entry").path();
            if path.extension().is_some_and(|e| e == "toml") {
                let file = CellFile::load(&path).unwrap_or_else(|e| panic!("{e}"));
                let drives = file
                    .drives()
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert!(!drives.is_empty(), "{}", path.display());
                // Its buses' rates: named, or the nodes agree.
                file.bus_rates(&drives)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                seen += 1;
            }
        }
        assert!(seen >= 2, "examples/cell.toml and examples/machine.toml");
    }
}

#[cfg(test)]
mod switches_tests {
    use super::*;

    fn nanotec(device: &str, section: &str) -> Result<DriveSpec, ConfigError> {
        spec(&format!(
            "[[drive]]\ndevice = \"{device}\"\nnode = 9\n{section}\n"
        ))
        .map(|mut v| v.remove(0))
    }

    /// NT-NODE-07 from a cell file: switches = node + 128 with no bit-rate code in 2005h: the
    /// drive is built without enables, so it never leaves Switch On Disabled; with a code it
    /// is a normal drive.
    #[test]
    fn nt_node_07_no_bit_rate_code_keeps_the_drive_from_moving() {
        let d = nanotec(
            "nanotec-smci47s",
            "[drive.rotary_switches]\nleft = 5\nright = 8\n[drive.objects]\n\"2005:00\" = 0",
        )
        .unwrap();
        assert_eq!(d.node, 5);
        assert!(!d.settings.expect("a drive").enables_present);
        let d = nanotec(
            "nanotec-smci47s",
            "[drive.rotary_switches]\nleft = 5\nright = 8\n[drive.objects]\n\"2005:00\" = 134",
        )
        .unwrap();
        assert!(d.settings.expect("a drive").enables_present);
    }

    /// `motor_type`: a BLDC connected (the DB57-like default), 2004h:07 and Appendix 18.2's
    /// load-angle curve as commissioning values, `[drive.objects]` after them (so they win);
    /// `stepper` sets 2004h:07 = 0 only; a drive without 2004h:07 refuses the key.
    #[test]
    fn nanotec_motor_type_sets_2004h_07_and_the_bldc() {
        let value = |d: &DriveSpec, index: u16, sub: u8| -> Vec<Vec<u8>> {
            d.commissioning
                .iter()
                .filter(|c| (c.index, c.sub) == (index, sub))
                .map(|c| c.bytes.clone())
                .collect()
        };
        for (name, code) in [
            ("bldc-hall", 1u8),
            ("bldc-hall-encoder", 2),
            ("bldc-encoder", 2),
        ] {
            let d = nanotec("nanotec-smci47s", &format!("motor_type = \"{name}\"")).unwrap();
            assert_eq!(value(&d, 0x2004, 7), vec![vec![code]], "{name}");
            assert_eq!(value(&d, 0x200C, 2), vec![16500u16.to_le_bytes().to_vec()]);
            assert_eq!(value(&d, 0x200C, 7), vec![19000u16.to_le_bytes().to_vec()]);
            assert!(d.settings.expect("a drive").bldc.is_some(), "{name}");
        }
        let d = nanotec("nanotec-pd4n", "motor_type = \"stepper\"").unwrap();
        assert_eq!(value(&d, 0x2004, 7), vec![vec![0]]);
        assert!(value(&d, 0x200C, 1).is_empty());
        assert!(d.settings.expect("a drive").bldc.is_none());
        let d = nanotec(
            "nanotec-pd4n",
            "motor_type = \"bldc-hall\"\n[drive.objects]\n\"200C:02\" = 16000",
        )
        .unwrap();
        assert_eq!(
            value(&d, 0x200C, 2).last(),
            Some(&16000u16.to_le_bytes().to_vec()),
            "[drive.objects] comes last"
        );
        for (device, bad, says) in [
            ("cmmp-as", "motor_type = \"bldc-hall\"", "2004h:07"),
            ("cmmo-st", "motor_type = \"stepper\"", "2004h:07"),
            ("nanotec-pd4n", "motor_type = \"servo\"", "unknown variant"),
        ] {
            let err = nanotec(device, bad).unwrap_err().to_string();
            assert!(err.contains(says), "{device} {bad}: {err}");
        }
    }

    /// NT-NODE-01 from a cell file: SMCI47-S left = 1, right = 2 → node 33 (over `node`), and
    /// 2009h reads 33 (NT-NODE-09); switches 0 → 2009h of [drive.objects] (NT-NODE-02); PD4-N
    /// switch 9 → node 9 − 8 = 1 (NT-NODE-04).
    #[test]
    fn nanotec_rotary_switches_give_the_node_id() {
        let d = nanotec(
            "nanotec-smci47s",
            "[drive.rotary_switches]\nleft = 1\nright = 2",
        )
        .unwrap();
        assert_eq!(d.node, 33);
        assert!(d
            .commissioning
            .iter()
            .any(|c| (c.index, c.sub, c.bytes.as_slice()) == (0x2009, 0, &[33][..])));
        let d = nanotec(
            "nanotec-smci47s",
            "[drive.rotary_switches]\nleft = 0\nright = 0\n[drive.objects]\n\"2009:00\" = 42",
        )
        .unwrap();
        assert_eq!(d.node, 42);
        let d = nanotec("nanotec-pd4n", "[drive.rotary_switches]\nswitch = 9").unwrap();
        assert_eq!(d.node, 1);
        for (device, bad, says) in [
            ("nanotec-pd4n", "left = 1", "one switch"),
            ("nanotec-smci47s", "switch = 1", "two switches"),
            ("nanotec-smci47s", "left = 16", "0…15"),
            ("cmmp-as", "left = 1", "no rotary switches"),
        ] {
            let err = nanotec(device, &format!("[drive.rotary_switches]\n{bad}"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(says), "{device} {bad}: {err}");
        }
    }

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

#[cfg(test)]
mod bus_rate_tests {
    use super::*;

    fn file(text: &str) -> CellFile {
        toml::from_str(text).unwrap_or_else(|e| panic!("{e}"))
    }

    fn rates(text: &str) -> Result<Vec<BusRate>, ConfigError> {
        let f = file(text);
        f.bus_rates(&f.drives()?)
    }

    fn timed(bitrate: u32, from_nodes: bool) -> BusRate {
        BusRate::Timed {
            bitrate,
            from_nodes,
        }
    }

    /// The default cell runs at its CMMP-AS's 125 kbit/s; a Nanotec's at 1 Mbit/s; agreeing
    /// nodes of different personalities give the bus their rate.
    #[test]
    fn the_nodes_rate_without_a_bitrate() {
        let single = CellFile::single("cmmp-as", 1);
        assert_eq!(
            single.bus_rates(&single.drives().unwrap()).unwrap(),
            [timed(125_000, true)]
        );
        assert_eq!(
            rates("[[drive]]\ndevice = \"nanotec-pd4n\"\n").unwrap(),
            [timed(1_000_000, true)]
        );
        // CMMP-AS DIP6 + DIP7 (1 Mbit/s), Nanotec, Kinco 2F81h = 100: all at 1 Mbit/s.
        let agree = "[[drive]]\ndevice = \"cmmp-as\"\n[drive.switches]\nvariant = \"m3\"\n\
                     on = [6, 7, 8]\n\
                     [[drive]]\ndevice = \"nanotec-smci47s\"\nnode = 2\n\
                     [[drive]]\ndevice = \"kinco-fd3\"\nnode = 3\n[drive.objects]\n\
                     \"2F81:00\" = 100\n";
        assert_eq!(rates(agree).unwrap(), [timed(1_000_000, true)]);
        // A bus of test bench nodes (no rate of their own): 1 Mbit/s.
        assert_eq!(
            rates("[[drive]]\ndevice = \"testbench\"\n").unwrap(),
            [timed(bus_rate::WITHOUT_NODE_RATES, true)]
        );
    }

    /// Nodes at different rates and no `bitrate`: refused, naming each node's rate and key.
    /// Drives kept off the bus (DIP8 OFF) or on another bus do not count.
    #[test]
    fn disagreeing_nodes_are_refused() {
        let err = rates(
            "[[drive]]\ndevice = \"cmmp-as\"\n\
             [[drive]]\ndevice = \"nanotec-smci47s\"\nnode = 2\n\
             [drive.rotary_switches]\nleft = 2\nright = 8\n[drive.objects]\n\"2005:00\" = 133\n",
        )
        .unwrap_err();
        let text = err.to_string();
        assert!(matches!(err, ConfigError::BusRate(_)), "{text}");
        assert!(text.contains("cmmp-as node 1: 125 kbit/s"), "{text}");
        assert!(
            text.contains(
                "nanotec-smci47s node 2: 250 kbit/s, set by [drive.objects] \"2005:00\" = 133"
            ),
            "{text}"
        );
        // The CMMP-AS's CAN off: only the Nanotec counts.
        assert_eq!(
            rates(
                "[[drive]]\ndevice = \"cmmp-as\"\n[drive.switches]\nvariant = \"m3\"\n\
                 [[drive]]\ndevice = \"nanotec-smci47s\"\nnode = 2\n"
            )
            .unwrap(),
            [timed(1_000_000, true)]
        );
        // Each bus its own rate.
        let two = "[[bus]]\nname = \"a\"\n[[bus]]\nname = \"b\"\nchannel = \"vcan1\"\n\
                   [[drive]]\ndevice = \"cmmp-as\"\nbus = \"a\"\n\
                   [[drive]]\ndevice = \"nanotec-smci47s\"\nbus = \"b\"\n";
        assert_eq!(
            rates(two).unwrap(),
            [timed(125_000, true), timed(1_000_000, true)]
        );
    }

    /// A named `bitrate` wins over the nodes (a node at another rate is silent); `"instant"`
    /// and `--bitrate` (`set_bitrate`) too.
    #[test]
    fn an_explicit_bitrate_or_instant_wins() {
        let mixed = "[[drive]]\ndevice = \"cmmp-as\"\n\
                     [[drive]]\ndevice = \"kinco-fd3\"\nnode = 2\n";
        assert_eq!(
            rates(&format!("[bus]\nbitrate = 500000\n{mixed}")).unwrap(),
            [timed(500_000, false)]
        );
        assert_eq!(
            rates(&format!("[bus]\nbitrate = \"instant\"\n{mixed}")).unwrap(),
            [BusRate::Instant]
        );
        let mut f = file(mixed);
        f.set_bitrate(BitrateSetting::Instant);
        assert_eq!(
            f.bus_rates(&f.drives().unwrap()).unwrap(),
            [BusRate::Instant]
        );
        let err = toml::from_str::<CellFile>("[bus]\nbitrate = \"fast\"\n").unwrap_err();
        assert!(err.to_string().contains("instant"), "{err}");
    }

    /// The Kinco DIP vectors from a cell file (each named at its assertion; the switch table
    /// itself is `drive::vendors::kinco::dip_switches`): `[drive.dip_switches]` gives the FD3's
    /// station number (node-ID) over `node`; all OFF takes 2F80h:01; 128…255 and other devices
    /// are refused.
    #[test]
    fn kinco_dip_switches_give_the_station_number() {
        let fd3 = |section: &str| {
            let text = format!("[[drive]]\ndevice = \"kinco-fd3\"\nnode = 9\n{section}\n");
            file(&text).drives().map(|mut v| v.remove(0))
        };
        // KINCO-DIP-01: SW1 → 1.
        assert_eq!(fd3("[drive.dip_switches]\non = [1]").unwrap().node, 1);
        // KINCO-DIP-02: SW2 → 2.
        assert_eq!(fd3("[drive.dip_switches]\non = [2]").unwrap().node, 2);
        // KINCO-DIP-03: SW1 + SW2 → 3.
        assert_eq!(fd3("[drive.dip_switches]\non = [1, 2]").unwrap().node, 3);
        // KINCO-DIP-04: SW3 → 4.
        assert_eq!(fd3("[drive.dip_switches]\non = [3]").unwrap().node, 4);
        // KINCO-DIP-06: all OFF → the stored station number 2F80h:01 (default 1).
        assert_eq!(fd3("[drive.dip_switches]\non = []").unwrap().node, 1);
        assert_eq!(
            fd3("[drive.dip_switches]\n[drive.objects]\n\"2F80:01\" = 42")
                .unwrap()
                .node,
            42
        );
        // KINCO-DIP-05: all ON is station 255, RS232 / RS485 only.
        let err = fd3("[drive.dip_switches]\non = [1, 2, 3, 4, 5, 6, 7, 8]")
            .unwrap_err()
            .to_string();
        assert!(err.contains("station 255"), "{err}");
        let err = fd3("[drive.dip_switches]\non = [9]")
            .unwrap_err()
            .to_string();
        assert!(err.contains("SW9"), "{err}");
        // The switches give no bit rate: 2F81h does.
        let d = fd3("[drive.dip_switches]\non = [1]\n[drive.objects]\n\"2F81:00\" = 25").unwrap();
        assert_eq!(d.bit_rate.map(|r| r.kbit), Some(250));
        let err = file("[[drive]]\ndevice = \"kinco-cd3\"\n[drive.dip_switches]\non = [1]\n")
            .drives()
            .unwrap_err()
            .to_string();
        assert!(err.contains("no DIP switches"), "{err}");
    }
}
