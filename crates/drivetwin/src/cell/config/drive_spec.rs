//! A drive of the cell file checked against its device and ready to build ([`DriveSpec`]):
//! its node-ID (the file's, or its switches'), commissioning values, simulated motor or
//! stepper, interfaces, the CAN bit rate it is set to, and its planned diagnostics and
//! physics.

use std::path::Path;

use drive::drive::DriveSettings;
use drive::motor::MotorData;
use od::Value;

use super::device_keys::{
    self, DriveContext, FieldbusProfile, FieldbusSettings, KeyRefusal, OwnRate, Ports,
};
use super::drive_section::default_device;
use super::objects::{encode_toml, parse_key};
use super::{BusSection, CellFile, Cia402Keys, ConfigError, DriveSection, FhppSpec, ForeignKeyAt};
use crate::cell::bus_rate::{NodeRate, RateObject};
use crate::cell::device_model::{is_cia402, is_fhpp};
use crate::cell::interfaces::InterfaceName;
use crate::cell::param_store::StoredValue;
use crate::cell::station::Commissioning;
use crate::cell::Vendors;

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
    /// The fieldbus settings its switches or inputs select, if its section names them.
    pub fieldbus: Option<FieldbusSettings>,
    /// The CAN bit rate its switches and objects set, and what sets it; `None`: none of its
    /// own (no CAN interface, an object that holds no code of a rate, the test bench).
    pub bit_rate: Option<NodeRate>,
    /// The object that sets that rate, which a stored set may change
    /// ([`DriveSpec::load_stored_rate`]).
    pub rate_object: Option<RateObject>,
    /// Its CI terminal and serial ports, as its section names them.
    pub ports: Ports,
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
            Some(f) if f.profile == FieldbusProfile::Fhpp => {
                Err(ConfigError::FhppOverCan(self.node))
            }
            Some(f) => Ok(f.can_active),
        }
    }
}

impl CellFile {
    /// Its drives, each checked against its device and ready to build, each device's own
    /// keys read by its section of `vendors` (`drivetwin::vendors::VENDORS.runtime`).
    pub fn drives(&self, vendors: Vendors) -> Result<Vec<DriveSpec>, ConfigError> {
        let sections = vendors.cell_sections;
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
            let keys = device_keys::split(desc, d.eds.as_deref(), d.node, &d.rest, sections)
                .map_err(|refusal| match refusal {
                    KeyRefusal::Foreign(key) => ConfigError::ForeignKey {
                        node: d.node,
                        at: Box::new(ForeignKeyAt {
                            file: self.path.clone(),
                            device: desc.name.to_owned(),
                            key,
                        }),
                    },
                    KeyRefusal::Unreadable(what) => ConfigError::DriveKeys {
                        file: self.path.clone(),
                        what,
                    },
                })?;
            let mut own = match keys.own {
                Some((section, table)) => {
                    let context = DriveContext { desc, drive: d };
                    (section.read)(table, &context).map_err(|e| match e {
                        device_keys::SectionError::Read(e) => ConfigError::DriveKeys {
                            file: self.path.clone(),
                            what: format!("drive {} ({}): {e}", d.node, desc.name),
                        },
                        device_keys::SectionError::Key { key, what } => ConfigError::Object {
                            node: d.node,
                            key: key.into(),
                            what,
                        },
                    })?
                }
                None => device_keys::OwnSettings::default(),
            };
            let fieldbus = own.fieldbus;
            let node = own.node.unwrap_or(match d.node_given {
                true => d.node,
                false => desc.default_node_id,
            });
            let (bit_rate, rate_object) = node_rate(desc, d, own.rate.take())?;
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
            let fhpp = if is_fhpp(desc) {
                Some(own.fhpp.take().unwrap_or_default())
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
            let mut commissioning = Vec::new();
            if d.load.is_some() && !is_cia402(desc) && !is_fhpp(desc) {
                return Err(ConfigError::Object {
                    node: d.node,
                    key: "load".into(),
                    what: format!(
                        "{}: a load FMU is coupled to a CiA 402 or FHPP drive's motor",
                        desc.name
                    ),
                });
            }
            let settings = if is_cia402(desc) {
                let unset = Cia402Keys::default();
                let k = keys.cia402.as_ref().unwrap_or(&unset);
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
                // A drive that takes no motion command: a power stage that cannot be
                // switched on.
                if own.no_enables {
                    s.enables_present = false;
                }
                if own.bldc.is_some() {
                    s.bldc = own.bldc;
                }
                if own.stepper.is_some() {
                    s.stepper = own.stepper;
                }
                commissioning.append(&mut own.commissioning);
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
            commissioning.append(&mut own.commissioning_last);
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
                ports: own.ports,
                bus,
                canopen,
                ethercat,
                diagnostics: d.diagnostic.clone(),
                physics,
                load: d.load.clone(),
            });
        }
        Ok(specs)
    }
}

/// The CAN bit rate a drive's switches and objects set ([`NodeRate`]): a DCF's
/// `[DeviceComissioning] Baudrate`; none for a device without CAN bit rates (its device file
/// lists none); else its section's (`own`), or the object the device file's `can_bit_rate`
/// names. With it, the object that sets the rate, if one does.
fn node_rate(
    desc: &'static od::DeviceDescription,
    d: &DriveSection,
    own: Option<OwnRate>,
) -> Result<(Option<NodeRate>, Option<RateObject>), ConfigError> {
    if let Some(rate) = crate::cell::eds_drive::bit_rate_of(desc) {
        return Ok((Some(NodeRate::dcf(&rate)), None));
    }
    if desc.baud_rates.is_empty() {
        return Ok((None, None));
    }
    let object = match (own, &desc.can_bit_rate) {
        (Some(OwnRate::Fixed(rate)), _) => return Ok((Some(rate), None)),
        (Some(OwnRate::Object(object)), _) => object,
        (None, Some(codes)) => {
            let context = DriveContext { desc, drive: d };
            let code = context
                .rate_code(codes.index)
                .map_err(|what| ConfigError::Object {
                    node: d.node,
                    key: "objects".into(),
                    what,
                })?;
            RateObject::of_device(codes, code)
        }
        (None, None) => return Ok((None, None)),
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
