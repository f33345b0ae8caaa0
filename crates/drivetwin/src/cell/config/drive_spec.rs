//! A drive of the cell file checked against its device and ready to build ([`DriveSpec`]):
//! its node-ID (the file's, or its switches'), commissioning values, simulated motor or
//! stepper, interfaces, the CAN bit rate it is set to, and its planned diagnostics and
//! physics.

use std::path::Path;

use drive::drive::DriveSettings;
use drive::motor::MotorData;
use drive::vendors::festo_cmmo_st::device::FhppSettings;
use drive::vendors::nanotec::rotary_switches::power_on;
use od::Value;

use super::device_keys::Section;
use super::drive_section::default_device;
use super::objects::{encode_toml, parse_key};
use super::{
    BusSection, CellFile, Cia402Keys, CmmoStKeys, ConfigError, DriveSection, FhppSpec,
    NanotecMotorType, SwitchesSection,
};
use crate::cell::bus_rate::{NodeRate, RateCode, RateObject};
use crate::cell::device_model::{is_cia402, is_fhpp};
use crate::cell::fieldbus_switches::{FieldbusSettings, Profile};
use crate::cell::interfaces::InterfaceName;
use crate::cell::param_store::StoredValue;
use crate::cell::station::Commissioning;

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
    /// The index of the bus (of [`super::Buses::all`]) its CANopen node is on.
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
    /// `[drive.load]`: the load FMU and its variables.
    pub load: Option<crate::cosim::mapping::LoadMapping>,
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
    /// Its drives, each checked against its device and ready to build.
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
            if let Some(key) = d.keys.foreign.first() {
                return Err(ConfigError::ForeignKey {
                    node: d.node,
                    device: desc.name.to_owned(),
                    key: key.clone(),
                });
            }
            let fieldbus = match d.keys.cmmp_as().and_then(|k| k.switches.as_ref()) {
                Some(sw) => {
                    let err = key_error(d, "switches");
                    if !desc.fieldbus_switches {
                        return Err(err(format!("{} has no CMMP-AS switches", desc.name)));
                    }
                    Some(sw.settings().map_err(err)?)
                }
                None => None,
            };
            let rotary = match d.keys.nanotec().and_then(|k| k.rotary_switches.as_ref()) {
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
            let station = match d.keys.kinco_fd3().and_then(|k| k.dip_switches.as_ref()) {
                Some(dip) => {
                    let err = key_error(d, "dip_switches");
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
                (None, None) => {
                    let written = match d.node_given {
                        true => d.node,
                        false => desc.default_node_id,
                    };
                    fieldbus.map_or(written, |f| f.node_id)
                }
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
                let unset = CmmoStKeys::default();
                let k = d.keys.cmmo_st().unwrap_or(&unset);
                let (stepper, mode) = k.stepper.stepper().map_err(|w| err("stepper", w))?;
                let mechanics = k.axis.mechanics().map_err(|w| err("axis", w))?;
                Some(FhppSpec {
                    settings: FhppSettings {
                        stepper,
                        mode,
                        mechanics,
                        ..FhppSettings::default()
                    },
                    modbus: k.modbus.clone(),
                    watchdog_ms: k.modbus_timeout_ms,
                })
            } else {
                // The CAN node-IDs of one bus are unique.
                if specs
                    .iter()
                    .any(|s| s.fhpp.is_none() && s.node == node && s.bus == bus)
                {
                    return Err(ConfigError::DuplicateNode(node));
                }
                None
            };
            let motor_type = d.keys.nanotec().and_then(|k| k.motor_type);
            if motor_type.is_some() && !(is_cia402(desc) && desc.entry(0x2004, 7).is_some()) {
                return Err(err(
                    "motor_type",
                    format!("{} has no motor type 2004h:07 (a Nanotec's)", desc.name),
                ));
            }
            let mut commissioning = Vec::new();
            if d.load.is_some() && !is_cia402(desc) {
                return Err(ConfigError::Object {
                    node: d.node,
                    key: "load".into(),
                    what: format!(
                        "{}: a load FMU is coupled to a CiA 402 drive's motor",
                        desc.name
                    ),
                });
            }
            let settings = if is_cia402(desc) {
                let unset = Cia402Keys::default();
                let k = d.keys.cia402.as_ref().unwrap_or(&unset);
                k.motor.check().map_err(|what| ConfigError::Object {
                    node: d.node,
                    key: "motor".into(),
                    what,
                })?;
                let motor = k.motor.motor();
                // The motor's nameplate commissioned as FCT would (before [drive.objects]).
                commissioning.extend(motor_commissioning(desc, &motor));
                let (travel, homing_max_distance) =
                    k.travel.travel().map_err(|what| ConfigError::Object {
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
                if let Some(ms) = k.mode_change_time_ms {
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
                if let Some(t) = motor_type {
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
                load: d.load.as_ref().map(|l| l.mapping()),
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

/// The CAN bit rate a drive's switches and objects set ([`NodeRate`]): the CMMP-AS's
/// switches, a Nanotec's rotary switches and 2005h, a Kinco FD3's 2F81h, a DCF's
/// `[DeviceComissioning] Baudrate`; none for a device
/// without CAN bit rates (its device file lists none) or without rules of its own. With it,
/// the object that sets the rate, if one does.
fn node_rate(
    desc: &od::DeviceDescription,
    d: &DriveSection,
    fieldbus: Option<FieldbusSettings>,
    rotary: Option<drive::vendors::nanotec::rotary_switches::PowerOn>,
) -> Result<(Option<NodeRate>, Option<RateObject>), ConfigError> {
    if let Some(rate) = crate::cell::eds_drive::bit_rate_of(desc) {
        return Ok((Some(NodeRate::dcf(&rate)), None));
    }
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
    let object = match Section::of(desc.name) {
        Some(Section::CmmpAs) => {
            let switches = d.keys.cmmp_as().and_then(|k| k.switches.as_ref());
            let switches = fieldbus.zip(switches.map(SwitchesSection::rate_key));
            return Ok((Some(NodeRate::cmmp_as(switches)), None));
        }
        Some(Section::Nanotec) => RateObject::Nanotec(rotary, code(0x2005)?),
        Some(Section::KincoFd3) => RateObject::Kinco(code(0x2F81)?),
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
