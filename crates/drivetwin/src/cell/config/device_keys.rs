//! Which keys of a `[[drive]]` belong to which device: the CiA 402 keys of every CiA 402
//! drive ([`super::cia402`]), each built-in device's section of its own (a file per vendor
//! beside this one: [`super::cmmp_as`], [`super::nanotec`], [`super::kinco`],
//! [`super::cmmo_st`]), and the refusal of a key written on a drive whose device does not
//! have it, naming the devices that do.

use std::path::Path;

use serde::Deserialize;

use super::cia402::{self, Cia402Keys};
use super::cmmo_st::{self, CmmoStKeys};
use super::cmmp_as::{self, CmmpAsKeys};
use super::drive_section::COMMON_KEYS;
use super::kinco::{self, KincoCd3Keys, KincoFd3Keys};
use super::nanotec::{self, NanotecKeys};
use crate::cell::device_model::is_cia402;

/// A key of a device's section: its name in the cell file and what it is, for the refusal
/// on another device ("cmmp-as has no rotary switches (Nanotec §1.1.1)").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Key {
    pub name: &'static str,
    pub what: &'static str,
}

/// A section of keys a built-in device has of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Section {
    CmmpAs,
    Nanotec,
    KincoFd3,
    KincoCd3,
    CmmoSt,
}

/// Each built-in device's section of its own, by its device file's name. A device not listed
/// has none (the test bench); a CiA 402 device has the CiA 402 keys besides.
pub const DEVICE_SECTIONS: [(&str, Section); 6] = [
    ("cmmp-as", Section::CmmpAs),
    ("nanotec-pd4n", Section::Nanotec),
    ("nanotec-smci47s", Section::Nanotec),
    ("kinco-fd3", Section::KincoFd3),
    ("kinco-cd3", Section::KincoCd3),
    ("cmmo-st", Section::CmmoSt),
];

impl Section {
    /// The section of the built-in device `name`, if it has one.
    pub fn of(name: &str) -> Option<Section> {
        DEVICE_SECTIONS
            .iter()
            .find(|(device, _)| *device == name)
            .map(|(_, s)| *s)
    }

    /// Its keys.
    pub fn keys(self) -> &'static [Key] {
        match self {
            Section::CmmpAs => &cmmp_as::KEYS,
            Section::Nanotec => &nanotec::KEYS,
            Section::KincoFd3 => &kinco::FD3_KEYS,
            Section::KincoCd3 => &kinco::CD3_KEYS,
            Section::CmmoSt => &cmmo_st::KEYS,
        }
    }

    fn has(self, key: &str) -> bool {
        self.keys().iter().any(|k| k.name == key)
    }

    /// Its keys of `table` (each one of [`Section::keys`]) read into its struct.
    fn parse(self, table: toml::Table) -> Result<VendorKeys, toml::de::Error> {
        let v = toml::Value::Table(table);
        Ok(match self {
            Section::CmmpAs => VendorKeys::CmmpAs(CmmpAsKeys::deserialize(v)?),
            Section::Nanotec => VendorKeys::Nanotec(NanotecKeys::deserialize(v)?),
            Section::KincoFd3 => VendorKeys::KincoFd3(KincoFd3Keys::deserialize(v)?),
            Section::KincoCd3 => VendorKeys::KincoCd3(KincoCd3Keys::deserialize(v)?),
            Section::CmmoSt => VendorKeys::CmmoSt(CmmoStKeys::deserialize(v)?),
        })
    }
}

/// A device's own keys, as its section reads them.
#[derive(Debug, Clone, Default)]
pub enum VendorKeys {
    /// A device without a section of its own (the test bench, a drive from its EDS).
    #[default]
    None,
    CmmpAs(CmmpAsKeys),
    Nanotec(NanotecKeys),
    KincoFd3(KincoFd3Keys),
    KincoCd3(KincoCd3Keys),
    CmmoSt(CmmoStKeys),
}

impl VendorKeys {
    fn of(section: Option<Section>) -> Self {
        match section {
            None => VendorKeys::None,
            Some(Section::CmmpAs) => VendorKeys::CmmpAs(CmmpAsKeys::default()),
            Some(Section::Nanotec) => VendorKeys::Nanotec(NanotecKeys::default()),
            Some(Section::KincoFd3) => VendorKeys::KincoFd3(KincoFd3Keys::default()),
            Some(Section::KincoCd3) => VendorKeys::KincoCd3(KincoCd3Keys::default()),
            Some(Section::CmmoSt) => VendorKeys::CmmoSt(CmmoStKeys::default()),
        }
    }
}

/// The keys of a `[[drive]]` beyond the common ones ([`super::drive_section::COMMON_KEYS`]).
#[derive(Debug, Clone, Default)]
pub struct DeviceKeys {
    /// The CiA 402 keys, on a CiA 402 drive.
    pub cia402: Option<Cia402Keys>,
    /// The device's own keys.
    pub vendor: VendorKeys,
    /// Keys written that other devices have, refused when the drive is checked
    /// ([`CellFile::drives`](super::CellFile::drives)).
    pub foreign: Vec<ForeignKey>,
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

/// The sections a `[[drive]]` reads its keys into: the CiA 402 keys or not, and its
/// device's own section, if it has one.
#[derive(Debug, Clone, Copy)]
struct Owner {
    cia402: bool,
    section: Option<Section>,
}

impl Owner {
    /// The sections of a drive of `device`, or from its `eds` (the CiA 402 keys). An unknown
    /// device has none: [`CellFile::drives`](super::CellFile::drives) refuses the device.
    fn of(device: &str, eds: Option<&Path>) -> Self {
        match (eds, devices::by_name(device)) {
            (Some(_), _) => Owner {
                cia402: true,
                section: None,
            },
            (None, desc) => Owner {
                cia402: desc.is_some_and(is_cia402),
                section: desc.and_then(|d| Section::of(d.name)),
            },
        }
    }

    /// Its keys, every one unset.
    fn unset(self) -> DeviceKeys {
        DeviceKeys {
            cia402: self.cia402.then(Cia402Keys::default),
            vendor: VendorKeys::of(self.section),
            foreign: Vec::new(),
        }
    }
}

impl DeviceKeys {
    /// The keys of a drive of built-in `device` (unknown: none) with every key unset.
    pub fn of_device(device: &str) -> Self {
        Owner::of(device, None).unset()
    }

    /// The keys of a drive from its EDS or DCF (the CiA 402 keys), every key unset.
    pub fn of_eds() -> Self {
        Owner::of("", Some(Path::new(""))).unset()
    }

    /// The keys `rest` of drive `node` (of `device`, or from its `eds`) that are not common
    /// keys, each read into the section of the device that has it. A key of another device
    /// is kept as [`ForeignKey`] for [`CellFile::drives`](super::CellFile::drives) to refuse
    /// with the drive's device; a key of no device is refused here as an unknown field.
    pub fn parse(
        device: &str,
        eds: Option<&Path>,
        node: u8,
        rest: toml::Table,
    ) -> Result<Self, String> {
        let owner = Owner::of(device, eds);
        let label = || match eds {
            Some(path) => path.display().to_string(),
            None => device.to_owned(),
        };
        let mut servo = toml::Table::new();
        let mut own = toml::Table::new();
        let mut foreign = Vec::new();
        for (key, value) in rest {
            if owner.cia402 && cia402::KEYS.iter().any(|k| k.name == key) {
                servo.insert(key, value);
            } else if owner.section.is_some_and(|s| s.has(&key)) {
                own.insert(key, value);
            } else {
                match foreign_key(&key) {
                    Some(f) => foreign.push(f),
                    None => return Err(unknown_key(&key, node, &label(), owner)),
                }
            }
        }
        let bad = |e: toml::de::Error| format!("drive {node} ({}): {e}", label());
        let cia402 = match owner.cia402 {
            true => Some(Cia402Keys::deserialize(toml::Value::Table(servo)).map_err(bad)?),
            false => None,
        };
        let vendor = match owner.section {
            Some(s) => s.parse(own).map_err(bad)?,
            None => VendorKeys::None,
        };
        Ok(DeviceKeys {
            cia402,
            vendor,
            foreign,
        })
    }

    /// The CMMP-AS's keys, on a CMMP-AS.
    pub fn cmmp_as(&self) -> Option<&CmmpAsKeys> {
        match &self.vendor {
            VendorKeys::CmmpAs(k) => Some(k),
            _ => None,
        }
    }

    /// A Nanotec's keys, on a Nanotec.
    pub fn nanotec(&self) -> Option<&NanotecKeys> {
        match &self.vendor {
            VendorKeys::Nanotec(k) => Some(k),
            _ => None,
        }
    }

    /// A Kinco FD3's keys, on an FD3.
    pub fn kinco_fd3(&self) -> Option<&KincoFd3Keys> {
        match &self.vendor {
            VendorKeys::KincoFd3(k) => Some(k),
            _ => None,
        }
    }

    /// The CMMO-ST's keys, on a CMMO-ST.
    pub fn cmmo_st(&self) -> Option<&CmmoStKeys> {
        match &self.vendor {
            VendorKeys::CmmoSt(k) => Some(k),
            _ => None,
        }
    }

    /// The RS232 port, on a device that has one.
    pub fn rs232(&self) -> Option<&str> {
        match &self.vendor {
            VendorKeys::KincoFd3(k) => k.rs232.as_deref(),
            VendorKeys::KincoCd3(k) => k.rs232.as_deref(),
            _ => None,
        }
    }

    /// The RS485 port, on a device that has one.
    pub fn rs485(&self) -> Option<&str> {
        self.kinco_fd3().and_then(|k| k.rs485.as_deref())
    }
}

/// `key` as a key of other devices: the devices that have it and what it is; `None` for a
/// key no device has.
fn foreign_key(key: &str) -> Option<ForeignKey> {
    let servo = cia402::KEYS.iter().find(|k| k.name == key);
    let what = servo.or_else(|| {
        DEVICE_SECTIONS
            .iter()
            .flat_map(|(_, s)| s.keys())
            .find(|k| k.name == key)
    })?;
    let mut owners: Vec<&str> = devices::ALL
        .iter()
        .filter(|d| {
            (servo.is_some() && is_cia402(d)) || Section::of(d.name).is_some_and(|s| s.has(key))
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
fn unknown_key(key: &str, node: u8, label: &str, owner: Owner) -> String {
    let mut expected: Vec<&str> = COMMON_KEYS.to_vec();
    if owner.cia402 {
        expected.extend(cia402::KEYS.iter().map(|k| k.name));
    }
    if let Some(s) = owner.section {
        expected.extend(s.keys().iter().map(|k| k.name));
    }
    let expected: Vec<String> = expected.iter().map(|k| format!("`{k}`")).collect();
    format!(
        "drive {node} ({label}): unknown field `{key}`, expected one of {}",
        expected.join(", ")
    )
}
