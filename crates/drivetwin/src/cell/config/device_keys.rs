//! Which keys of a `[[drive]]` belong to which device: the CiA 402 keys of every CiA 402
//! drive ([`super::cia402`]), and the sections of keys that devices have of their own
//! ([`DeviceSection`]: switches, ports, an FHPP drive's stepper), which their vendor folders
//! provide and the binary hands to [`CellFile::drives`](super::CellFile::drives) as
//! [`DeviceSections`]. The runtime knows no vendor: it splits a drive's keys, gives a section
//! its own, and refuses a key written on a drive whose device does not have it, naming the
//! devices that do.

use std::path::Path;

use serde::Deserialize;

use super::cia402::{self, Cia402Keys};
use super::drive_section::{DriveSection, COMMON_KEYS};
use super::objects::parse_key;
use super::FhppSpec;
use crate::cell::bus_rate::{NodeRate, RateCode, RateObject};
use crate::cell::device_model::is_cia402;
use crate::cell::station::Commissioning;

/// A key of a device's section: its name in the cell file and what it is, for the refusal
/// on another device ("cmmp-as has no rotary switches (Nanotec §1.1.1)").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Key {
    pub name: &'static str,
    pub what: &'static str,
}

/// A section of keys that some devices have of their own, read by their vendor folder: flat
/// on `[[drive]]` beside the common keys, as the cell file has always written them.
#[derive(Debug, Clone, Copy)]
pub struct DeviceSection {
    /// The device files (`[device] name`) whose drives have it.
    pub devices: &'static [&'static str],
    /// Its keys, with what each is.
    pub keys: &'static [Key],
    /// Reads a drive's keys of this section (each one of `keys`; none written: an empty
    /// table) and checks them against the drive: what they set.
    pub read: fn(toml::Table, &DriveContext<'_>) -> Result<OwnSettings, SectionError>,
}

/// The devices' sections a cell file is read with (`drivetwin::vendors::VENDORS.runtime.cell_sections`).
pub type DeviceSections = &'static [DeviceSection];

impl DeviceSection {
    fn has(&self, key: &str) -> bool {
        self.keys.iter().any(|k| k.name == key)
    }
}

/// The section of the device named `name` among `sections`, if it has one.
pub fn section_of(sections: DeviceSections, name: &str) -> Option<&'static DeviceSection> {
    sections.iter().find(|s| s.devices.contains(&name))
}

/// Why a section refused its keys.
#[derive(Debug, thiserror::Error)]
pub enum SectionError {
    /// The keys do not read as the section's (a field it does not have within one of its
    /// tables, a value of the wrong type): serde's refusal.
    #[error(transparent)]
    Read(#[from] toml::de::Error),
    /// Key `key` has a value the drive cannot take.
    #[error("{key}: {what}")]
    Key { key: &'static str, what: String },
}

impl SectionError {
    /// The refusal of key `key` with `what` is wrong.
    pub fn key(key: &'static str) -> impl Fn(String) -> SectionError + Copy {
        move |what| SectionError::Key { key, what }
    }
}

/// What a section's reader sees of its drive.
#[derive(Debug, Clone, Copy)]
pub struct DriveContext<'a> {
    /// The drive's device.
    pub desc: &'static od::DeviceDescription,
    /// The drive as the file writes it.
    pub drive: &'a DriveSection,
}

impl DriveContext<'_> {
    /// The value of an 8-bit entry at power-on: `[drive.objects]`'s, else the device's default.
    pub fn stored_u8(&self, index: u16, sub: u8) -> Result<u8, String> {
        let key = format!("{index:04X}:{sub:02X}");
        match self
            .drive
            .objects
            .iter()
            .find(|(k, _)| parse_key(k) == Some((index, sub)))
        {
            Some((_, toml::Value::Integer(v))) => {
                u8::try_from(*v).map_err(|_| format!("{key} = {v} is not a u8"))
            }
            Some(_) => Err(format!("{key} must be an integer")),
            None => Ok(self
                .desc
                .entry(index, sub)
                .and_then(|e| e.default.first().copied())
                .unwrap_or(0)),
        }
    }

    /// The code object `index` (sub-index 0) sets a bit rate with at power-on: its default,
    /// and the cell file's value where `[drive.objects]` names one.
    pub fn rate_code(&self, index: u16) -> Result<RateCode, String> {
        let default = self
            .desc
            .entry(index, 0)
            .and_then(|e| e.default.first().copied())
            .unwrap_or(0);
        let set = self
            .drive
            .objects
            .keys()
            .any(|k| parse_key(k) == Some((index, 0)));
        let value = self.stored_u8(index, 0)?;
        Ok(RateCode::new(default, set.then_some(value)))
    }
}

/// The CAN bit rate a section sets.
#[derive(Debug, Clone)]
pub enum OwnRate {
    /// A rate of the device's switches or factory setting, named by what sets it.
    Fixed(NodeRate),
    /// The rate an object's code sets (and a stored set may change).
    Object(RateObject),
}

/// A drive's serial and terminal ports, as its section names them: addresses and paths.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Ports {
    /// `ci_terminal`: the TCP address of a debug terminal (`drivetwin::vendors::CI_TERMINAL`).
    pub ci_terminal: Option<String>,
    /// `rs232`: the path of the drive's RS232 port.
    pub rs232: Option<String>,
    /// `rs485`: the path of the drive's RS485 port.
    pub rs485: Option<String>,
}

/// The data profile a drive speaks on its fieldbus, as its switches or inputs select it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldbusProfile {
    Cia402,
    /// FHPP, which the twin does not serve over CAN.
    Fhpp,
}

/// What a drive's switches or inputs select at power-on (the CMMP-AS's DIP switches or
/// fieldbus inputs, read by its vendor folder): the node-ID, the CAN bit rate, the data
/// profile and whether CAN is on at all.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FieldbusSettings {
    pub node_id: u8,
    pub bit_rate_kbit: u16,
    pub profile: FieldbusProfile,
    /// CANopen activated; a drive whose CAN is off stays silent on its bus.
    pub can_active: bool,
}

/// What a device's own keys set on its drive; unset: the runtime's defaults.
#[derive(Debug, Clone, Default)]
pub struct OwnSettings {
    /// The node-ID its switches select, which wins over `node`.
    pub node: Option<u8>,
    /// The fieldbus settings its switches or inputs select (node-ID, bit rate, CAN on,
    /// profile).
    pub fieldbus: Option<FieldbusSettings>,
    /// The CAN bit rate it is set to; `None`: the device file's `can_bit_rate` object, if
    /// any.
    pub rate: Option<OwnRate>,
    /// Commissioning values after the motor's nameplate, before `[drive.objects]`.
    pub commissioning: Vec<Commissioning>,
    /// Commissioning values after `[drive.objects]` (what the switches make an object read).
    pub commissioning_last: Vec<Commissioning>,
    /// The power stage cannot be enabled (a drive that takes no motion command).
    pub no_enables: bool,
    /// A BLDC motor instead of the servo motor, on a CiA 402 drive.
    pub bldc: Option<drive::bldc::BldcData>,
    /// A stepper's motor and load, on a CiA 402 drive with a stepper.
    pub stepper: Option<drive::stepper::StepperData>,
    /// How an FHPP drive is simulated and served.
    pub fhpp: Option<FhppSpec>,
    /// Its ports.
    pub ports: Ports,
}

/// A drive's keys beyond the common ones, split: the CiA 402 keys read, its section's to read.
#[derive(Debug)]
pub(super) struct SplitKeys {
    pub cia402: Option<Cia402Keys>,
    pub own: Option<(&'static DeviceSection, toml::Table)>,
}

/// A refusal of a drive's keys, with the label it names the drive by.
#[derive(Debug)]
pub(super) enum KeyRefusal {
    /// A key of other devices.
    Foreign(ForeignKey),
    /// A key of no device, or keys that do not read: the message.
    Unreadable(String),
}

/// A key of other devices written on a drive.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ForeignKey {
    pub key: String,
    /// The devices that have it ("the kinco-fd3", "the cmmp-as, … and drives from an EDS").
    pub owners: String,
    /// What it is ([`Key::what`]).
    pub what: &'static str,
}

/// The keys `rest` of drive `node` of `desc` (from its `eds` or not), each given to the
/// section that has it: the CiA 402 keys on a CiA 402 drive, the device's own section's. A key
/// of no device is refused as an unknown field with the keys the drive has, a key of other
/// devices naming them.
pub(super) fn split(
    desc: &'static od::DeviceDescription,
    eds: Option<&Path>,
    node: u8,
    rest: &toml::Table,
    sections: DeviceSections,
) -> Result<SplitKeys, KeyRefusal> {
    let cia402 = eds.is_some() || is_cia402(desc);
    let section = match eds {
        Some(_) => None,
        None => section_of(sections, desc.name),
    };
    let label = match eds {
        Some(path) => path.display().to_string(),
        None => desc.name.to_owned(),
    };
    let mut servo = toml::Table::new();
    let mut own = toml::Table::new();
    let mut foreign = None;
    for (key, value) in rest {
        if cia402 && cia402::KEYS.iter().any(|k| k.name == key) {
            servo.insert(key.clone(), value.clone());
        } else if section.is_some_and(|s| s.has(key)) {
            own.insert(key.clone(), value.clone());
        } else {
            match foreign_key(key, sections) {
                Some(f) => {
                    foreign.get_or_insert(f);
                }
                None => {
                    return Err(KeyRefusal::Unreadable(unknown_key(
                        key, node, &label, cia402, section,
                    )))
                }
            }
        }
    }
    if let Some(f) = foreign {
        return Err(KeyRefusal::Foreign(f));
    }
    let cia402 = match cia402 {
        true => Some(
            Cia402Keys::deserialize(toml::Value::Table(servo))
                .map_err(|e| KeyRefusal::Unreadable(format!("drive {node} ({label}): {e}")))?,
        ),
        false => None,
    };
    Ok(SplitKeys {
        cia402,
        own: section.map(|s| (s, own)),
    })
}

/// Whether a drive of `desc` has the CiA 402 keys, and its own section among `sections`.
pub fn sections_of(
    desc: &'static od::DeviceDescription,
    sections: DeviceSections,
) -> (bool, Option<&'static DeviceSection>) {
    (is_cia402(desc), section_of(sections, desc.name))
}

/// `key` as a key of other devices: the devices that have it and what it is; `None` for a
/// key no device has.
fn foreign_key(key: &str, sections: DeviceSections) -> Option<ForeignKey> {
    let servo = cia402::KEYS.iter().find(|k| k.name == key);
    let what = servo.or_else(|| sections.iter().flat_map(|s| s.keys).find(|k| k.name == key))?;
    let mut owners: Vec<&str> = devices::ALL
        .iter()
        .filter(|d| {
            (servo.is_some() && is_cia402(d))
                || section_of(sections, d.name).is_some_and(|s| s.has(key))
        })
        .map(|d| d.name)
        .collect();
    if servo.is_some() {
        owners.push("drives from an EDS");
    }
    let owners = match owners.split_last() {
        Some((last, [])) => last.to_string(),
        Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
        None => String::new(),
    };
    Some(ForeignKey {
        key: key.to_owned(),
        owners,
        what: what.what,
    })
}

/// The refusal of `key`, which no device has, on drive `node` (`label`): serde's wording for
/// an unknown field, with the keys the drive has.
fn unknown_key(
    key: &str,
    node: u8,
    label: &str,
    cia402: bool,
    section: Option<&DeviceSection>,
) -> String {
    let mut expected: Vec<&str> = COMMON_KEYS.to_vec();
    if cia402 {
        expected.extend(cia402::KEYS.iter().map(|k| k.name));
    }
    if let Some(s) = section {
        expected.extend(s.keys.iter().map(|k| k.name));
    }
    let expected: Vec<String> = expected.iter().map(|k| format!("`{k}`")).collect();
    format!(
        "drive {node} ({label}): unknown field `{key}`, expected one of {}",
        expected.join(", ")
    )
}
