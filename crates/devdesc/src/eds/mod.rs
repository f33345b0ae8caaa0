//! Reading a CiA 306 electronic data sheet (EDS) or device configuration file (DCF) into the
//! same checked description a device file gives ([`Device`]): objects, data types, access,
//! defaults (with `$NODEID` arithmetic; a DCF's `ParameterValue` wins over `DefaultValue`),
//! limits, the PDO mapping flag and the mapping objects' sizes. What a device file says
//! beyond CiA 306 (behaviour of the CiA 301 objects) follows from the index, as CiA 301
//! defines it.
//!
//! The vocabulary is the one [`od::eds`] writes: [`DataType`] codes, [`Access`] names, REAL
//! defaults as bit patterns, so a file `drivetwin eds` wrote reads back as it was.
//!
//! Everything refused names file, line, section and key ([`EdsError`]).

pub mod error;
pub mod ini;
pub mod number;

use std::path::Path;

use od::{Access, Behaviour, DataType, Limit, ObjectKind, Value};

pub use self::error::{EdsError, Location};
use self::ini::{Ini, Section};
use crate::model::{BusFaults, Device, Ent, Obj};
use crate::schema::{BrakeSection, PlantSection};

/// A read EDS or DCF.
#[derive(Debug, Clone)]
pub struct Eds {
    pub device: Device,
    /// `[DeviceComissioning] NodeID` of a DCF.
    pub node_id: Option<u8>,
    /// `[DeviceComissioning] Baudrate` of a DCF: the CAN bit rate the device is commissioned
    /// to, and where the file says so.
    pub bit_rate: Option<BitRate>,
    /// Where the device type 1000h's value is (for [`Eds::require_cia402`]).
    device_type_at: Location,
    /// Where the profile's objects are listed (`[OptionalObjects] SupportedObjects`).
    profile_objects_at: Location,
}

/// A DCF's commissioned CAN bit rate (CiA 306 §4.7 `[DeviceComissioning] Baudrate`, kbit/s).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BitRate {
    pub kbit: u16,
    /// The `Baudrate` line.
    pub at: Location,
}

/// The bit rates CiA 306 names (the `BaudRate_…` keys of `[DeviceInfo]`), kbit/s.
const BIT_RATES_KBIT: [u16; 8] = [10, 20, 50, 125, 250, 500, 800, 1000];

/// The objects every CiA 402 drive has (CiA 402 §6: controlword, statusword, modes of
/// operation and its display).
const CIA402_OBJECTS: [u16; 4] = [0x6040, 0x6041, 0x6060, 0x6061];

impl Eds {
    /// Refuses a file whose device type 1000h does not name CiA 402 (bits 0–15 = 402, CiA 301
    /// §7.5.2.1), or that lacks one of the objects every drive has: the controlword 6040h,
    /// the statusword 6041h, the modes 6060h and their display 6061h.
    pub fn require_cia402(&self) -> Result<(), EdsError> {
        if self.device.profile != od::Profile::Cia402 {
            return Err(EdsError::Invalid {
                at: self.device_type_at.clone(),
                what:
                    "the device type 1000h does not name CiA 402 (bits 0-15 = 0192h): not a drive"
                        .into(),
            });
        }
        let has = |index: u16| self.device.objects.iter().any(|o| o.index == index);
        match CIA402_OBJECTS.iter().find(|i| !has(**i)) {
            None => Ok(()),
            Some(missing) => Err(EdsError::Missing {
                at: self.profile_objects_at.clone(),
                what: format!("object {missing:04X}h, which every CiA 402 drive has (CiA 402 §6)"),
            }),
        }
    }
}

/// Reads the EDS or DCF at `path`. A file that is not UTF-8 is read as Latin-1, the encoding
/// of most EDS tools.
pub fn load_file(path: &Path) -> Result<Eds, EdsError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| EdsError::Io {
        file: file.clone(),
        source,
    })?;
    let text = match String::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => e.into_bytes().iter().map(|&b| char::from(b)).collect(),
    };
    parse(&text, &file)
}

/// The object lists of CiA 306 §4.5, in the order a device lists them.
const OBJECT_LISTS: [&str; 3] = ["MandatoryObjects", "OptionalObjects", "ManufacturerObjects"];

/// Reads an EDS or DCF from `text`; `file` names it in errors and gives the device its name.
pub fn parse(text: &str, file: &str) -> Result<Eds, EdsError> {
    // A byte-order mark some editors write is not part of the first line.
    let ini = Ini::parse(text.strip_prefix('\u{feff}').unwrap_or(text), file)?;
    let info = ini.section("DeviceInfo").ok_or_else(|| EdsError::Missing {
        at: Location {
            file: file.to_owned(),
            line: 1,
            section: "DeviceInfo".into(),
            key: String::new(),
        },
        what: "the [DeviceInfo] section".into(),
    })?;
    if let Some(k) = info.key("CompactPDO") {
        if number_of(&ini, info, "CompactPDO")? != Some(0) {
            return Err(EdsError::Unsupported {
                at: ini.at(info, &k.name),
                what: "CompactPDO (PDO objects left out of the file): list them".into(),
            });
        }
    }
    // Every listed object, in index order; a section of an object no list names is refused.
    let mut listed: Vec<(u16, Location)> = Vec::new();
    for list in OBJECT_LISTS {
        let Some(s) = ini.section(list) else {
            continue;
        };
        let count = number_of(&ini, s, "SupportedObjects")?.ok_or_else(|| EdsError::Missing {
            at: ini.at(s, "SupportedObjects"),
            what: "the number of objects".into(),
        })?;
        for n in 1..=count {
            let key = n.to_string();
            let at = ini.at(s, &key);
            let value = s.value(&key).ok_or_else(|| EdsError::Missing {
                at: at.clone(),
                what: format!("entry {n} of SupportedObjects={count}"),
            })?;
            let index = number::integer(value)
                .and_then(|i| u16::try_from(i).ok())
                .ok_or_else(|| EdsError::Invalid {
                    at: at.clone(),
                    what: format!("{value:?} is not an object index"),
                })?;
            if let Some((_, first)) = listed.iter().find(|(i, _)| *i == index) {
                return Err(EdsError::Invalid {
                    at,
                    what: format!("{index:04X}h is listed twice (also line {})", first.line),
                });
            }
            listed.push((index, at));
        }
        if let Some(extra) = s
            .keys
            .iter()
            .find(|k| k.name.parse::<u64>().is_ok_and(|n| n == 0 || n > count))
        {
            return Err(EdsError::Invalid {
                at: ini.at(s, &extra.name),
                what: format!("beyond SupportedObjects={count}"),
            });
        }
    }
    for s in &ini.sections {
        if let Some(index) = object_section(&s.name).or(sub_section(&s.name).map(|(i, _)| i)) {
            if !listed.iter().any(|(i, _)| *i == index) {
                return Err(EdsError::Invalid {
                    at: ini.at(s, ""),
                    what: format!("object {index:04X}h is in none of {OBJECT_LISTS:?}"),
                });
            }
        }
    }
    let mut objects = Vec::with_capacity(listed.len());
    let mut defaults_at = Vec::new();
    for (index, at) in &listed {
        objects.push(object(&ini, *index, at, &mut defaults_at)?);
    }
    objects.sort_by_key(|o| o.index);
    let dummy_usage = dummy_usage(&ini)?;
    check_mappings(&objects, &defaults_at, dummy_usage)?;

    let default_of = |index: u16, sub: u8| {
        objects
            .iter()
            .find(|o| o.index == index)
            .and_then(|o| o.entries.iter().find(|e| e.sub == sub))
            .and_then(|e| Value::decode(e.data_type, &e.default))
            .and_then(|v| match v {
                Value::Unsigned(u) => u32::try_from(u).ok(),
                _ => None,
            })
    };
    let device_type = default_of(0x1000, 0);
    let device_type_at = defaults_at
        .iter()
        .find(|(i, s, _)| (*i, *s) == (0x1000, 0))
        .map(|(_, _, at)| at.clone())
        .or_else(|| ini.section("1000").map(|s| ini.at(s, "DefaultValue")))
        .unwrap_or_else(|| ini.at(info, ""));
    let profile = if device_type.is_some_and(|t| t & 0xFFFF == 402) {
        od::Profile::Cia402
    } else {
        od::Profile::Plain
    };
    let info_number = |key: &str| -> Result<Option<u32>, EdsError> {
        number_of(&ini, info, key)?
            .map(|n| {
                u32::try_from(n).map_err(|_| EdsError::Invalid {
                    at: ini.at(info, key),
                    what: "not an UNSIGNED32".into(),
                })
            })
            .transpose()
    };
    let text_of = |key: &str| info.value(key).unwrap_or("").to_owned();
    let mut baud_rates = Vec::new();
    for rate in BIT_RATES_KBIT {
        if number_of(&ini, info, &format!("BaudRate_{rate}"))? == Some(1) {
            baud_rates.push(rate);
        }
    }
    let lss = number_of(&ini, info, "LSS_Supported")? == Some(1);
    let bit_rate = commissioned_bit_rate(&ini, &baud_rates)?;
    let node_id = match ini.section("DeviceComissioning") {
        Some(c) => match number_of(&ini, c, "NodeID")? {
            Some(n @ 1..=127) => Some(n as u8),
            Some(n) => {
                return Err(EdsError::Invalid {
                    at: ini.at(c, "NodeID"),
                    what: format!("node-ID {n}: 1…127"),
                })
            }
            None => None,
        },
        None => None,
    };
    let device = Device {
        name: device_name(file),
        product_name: text_of("ProductName"),
        vendor_name: text_of("VendorName"),
        vendor_id: info_number("VendorNumber")?
            .or_else(|| default_of(0x1018, 1))
            .unwrap_or(0),
        product_code: info_number("ProductNumber")?
            .or_else(|| default_of(0x1018, 2))
            .unwrap_or(0),
        revision: info_number("RevisionNumber")?
            .or_else(|| default_of(0x1018, 3))
            .unwrap_or(0),
        order_code: text_of("OrderCode"),
        description: ini
            .section("FileInfo")
            .and_then(|s| s.value("Description"))
            .unwrap_or("")
            .to_owned(),
        profile,
        default_node_id: node_id.unwrap_or(1),
        baud_rates,
        rotary_switches: 0,
        can_bit_rate: None,
        serial_bit_rate: None,
        serial_ports: Vec::new(),
        fieldbus_switches: false,
        ethercat: None,
        fhpp: None,
        // An EDS says nothing of them (CiA 306): CiA 301's usage.
        bus_faults: BusFaults::default(),
        // Nor of a brake delay or a plant message: CiA 402 names no object of either.
        brake: BrakeSection::default(),
        plant: PlantSection::default(),
        interfaces: vec!["canopen".into()],
        interfaces_one_of: Vec::new(),
        interfaces_rule: "a CANopen device (its EDS)".into(),
        cia301: od::Cia301Options {
            lss_unsupported: !lss,
            dummy_usage,
            ..od::Cia301Options::default()
        },
        objects,
        diagnostics: Vec::new(),
    };
    let profile_objects_at = OBJECT_LISTS
        .iter()
        .rev()
        .skip(1)
        .find_map(|l| ini.section(l))
        .map_or_else(|| ini.at(info, ""), |s| ini.at(s, "SupportedObjects"));
    Ok(Eds {
        device,
        node_id,
        bit_rate,
        device_type_at,
        profile_objects_at,
    })
}

/// `[DummyUsage]` (CiA 306): `Dummy000n=1` lets the dummy object 000nh (the static data type
/// of that index in CiA 301's object dictionary) be mapped into a PDO, `=0` or no key does
/// not; a mapping the file does not allow is refused with 0604 0041h (CiA 301: object cannot
/// be mapped to the PDO). `None` for a file without the section.
///
/// Decision: a file without `[DummyUsage]` says nothing about dummies, and the drive takes a
/// dummy 0002h–0007h in an RPDO as a drive without a list does (never stricter than a device
/// the file may describe); a file with the section is taken at its word. Bit n of the result for 000nh. A value other
/// than 0 or 1, or a key other than `Dummy0001`…`Dummy0007`, is refused.
fn dummy_usage(ini: &Ini) -> Result<Option<u8>, EdsError> {
    let Some(s) = ini.section("DummyUsage") else {
        return Ok(None);
    };
    let mut usage = 0u8;
    for k in &s.keys {
        let at = ini.at(s, &k.name);
        let n = k
            .name
            .get(..5)
            .filter(|p| p.eq_ignore_ascii_case("Dummy"))
            .and_then(|_| k.name.get(5..))
            .filter(|d| d.len() == 4 && d.bytes().all(|b| b.is_ascii_hexdigit()))
            .and_then(|d| u16::from_str_radix(d, 16).ok())
            .filter(|n| (0x0001..=0x0007).contains(n))
            .ok_or_else(|| EdsError::Invalid {
                at: at.clone(),
                what: "not a dummy object: Dummy0001 ... Dummy0007 (CiA 306 [DummyUsage])".into(),
            })?;
        match number::integer(&k.value) {
            Some(0) => {}
            Some(1) => usage |= 1 << n,
            _ => {
                return Err(EdsError::Invalid {
                    at,
                    what: format!("{:?}: 0 (not mappable) or 1 (mappable)", k.value),
                })
            }
        }
    }
    Ok(Some(usage))
}

/// A DCF's `[DeviceComissioning] Baudrate` (CiA 306 §4.7, the section's spelling), kbit/s:
/// one of the rates CiA 306 names, and one `[DeviceInfo]` marks supported (`BaudRate_…=1`)
/// where it marks any.
fn commissioned_bit_rate(ini: &Ini, supported: &[u16]) -> Result<Option<BitRate>, EdsError> {
    let Some(c) = ini.section("DeviceComissioning") else {
        return Ok(None);
    };
    let Some(n) = number_of(ini, c, "Baudrate")? else {
        return Ok(None);
    };
    let at = ini.at(c, "Baudrate");
    let kbit = u16::try_from(n)
        .ok()
        .filter(|k| BIT_RATES_KBIT.contains(k))
        .ok_or_else(|| EdsError::Invalid {
            at: at.clone(),
            what: format!("{n} kbit/s: one of {BIT_RATES_KBIT:?} (CiA 306)"),
        })?;
    if !supported.is_empty() && !supported.contains(&kbit) {
        return Err(EdsError::Invalid {
            at,
            what: format!(
                "{kbit} kbit/s, but [DeviceInfo] has no BaudRate_{kbit}=1 (it supports {supported:?})"
            ),
        });
    }
    Ok(Some(BitRate { kbit, at }))
}

/// The device's name from the file's: the stem in lower case, letters, digits and `-`.
fn device_name(file: &str) -> String {
    let stem = Path::new(file)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut name: String = stem
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect();
    name = name.trim_matches('-').to_owned();
    if name.is_empty() {
        "eds".into()
    } else {
        name
    }
}

/// `[1018]` → 1018h; `None` for other sections (sub-indices, `[1018sub1]`, included).
fn object_section(name: &str) -> Option<u16> {
    (name.len() == 4 && name.bytes().all(|b| b.is_ascii_hexdigit()))
        .then(|| u16::from_str_radix(name, 16).ok())
        .flatten()
}

/// `[1018sub1]` → (1018h, 1).
fn sub_section(name: &str) -> Option<(u16, u8)> {
    let index = name.get(..4)?;
    let tag = name.get(4..7)?;
    let sub = name.get(7..)?;
    if !tag.eq_ignore_ascii_case("sub")
        || sub.is_empty()
        || sub.len() > 2
        || !index.bytes().all(|b| b.is_ascii_hexdigit())
        || !sub.bytes().all(|b| b.is_ascii_hexdigit())
    {
        return None;
    }
    Some((
        u16::from_str_radix(index, 16).ok()?,
        u8::from_str_radix(sub, 16).ok()?,
    ))
}

/// The integer value of `key` in `s`, if given; refused if it is not an integer.
fn number_of(ini: &Ini, s: &Section, key: &str) -> Result<Option<u64>, EdsError> {
    let Some(v) = s.value(key) else {
        return Ok(None);
    };
    number::integer(v)
        .and_then(|i| u64::try_from(i).ok())
        .map(Some)
        .ok_or_else(|| EdsError::Invalid {
            at: ini.at(s, key),
            what: format!("{v:?} is not a number"),
        })
}

/// CiA 306 object codes.
const DOMAIN: u64 = 0x2;
const DEFTYPE: u64 = 0x5;
const DEFSTRUCT: u64 = 0x6;
const VAR: u64 = 0x7;
const ARRAY: u64 = 0x8;
const RECORD: u64 = 0x9;

/// Where each entry's default is written: for the checks that need the file's line.
type DefaultsAt = Vec<(u16, u8, Location)>;

fn object(
    ini: &Ini,
    index: u16,
    listed_at: &Location,
    defaults_at: &mut DefaultsAt,
) -> Result<Obj, EdsError> {
    let section = ini
        .section(&format!("{index:04X}"))
        .ok_or_else(|| EdsError::Missing {
            at: listed_at.clone(),
            what: format!("the section [{index:04X}] of the object listed here"),
        })?;
    let name = parameter_name(ini, section)?;
    let code = number_of(ini, section, "ObjectType")?.unwrap_or(VAR);
    let subs: Vec<&Section> = ini
        .sections
        .iter()
        .filter(|s| sub_section(&s.name).is_some_and(|(i, _)| i == index))
        .collect();
    let kind = match code {
        VAR | DOMAIN => ObjectKind::Var,
        ARRAY => ObjectKind::Array,
        RECORD => ObjectKind::Record,
        DEFTYPE | DEFSTRUCT => {
            return Err(EdsError::Unsupported {
                at: ini.at(section, "ObjectType"),
                what: "type definitions (DEFTYPE, DEFSTRUCT); dummy mapping needs [DummyUsage]"
                    .into(),
            })
        }
        other => {
            return Err(EdsError::Invalid {
                at: ini.at(section, "ObjectType"),
                what: format!("0x{other:X} is no object code (7 VAR, 8 ARRAY, 9 RECORD)"),
            })
        }
    };
    let mut entries = Vec::new();
    if kind == ObjectKind::Var {
        if let Some(s) = subs.first() {
            return Err(EdsError::Invalid {
                at: ini.at(s, ""),
                what: format!("{index:04X}h is a VAR (ObjectType=0x7): it has no sub-indices"),
            });
        }
        entries.push(entry(ini, section, index, 0, &name, None, defaults_at)?);
    } else if let Some(n) = number_of(ini, section, "CompactSubObj")?.filter(|n| *n > 0) {
        entries = compact(
            ini,
            section,
            index,
            &name,
            n,
            kind,
            subs.first().copied(),
            defaults_at,
        )?;
    } else {
        let declared = number_of(ini, section, "SubNumber")?.ok_or_else(|| EdsError::Missing {
            at: ini.at(section, "SubNumber"),
            what: "SubNumber (or CompactSubObj) of an ARRAY / RECORD".into(),
        })?;
        if declared as usize != subs.len() {
            return Err(EdsError::Invalid {
                at: ini.at(section, "SubNumber"),
                what: format!(
                    "SubNumber={declared} but the file has {} [{index:04X}subN] sections",
                    subs.len()
                ),
            });
        }
        for s in &subs {
            let sub = sub_section(&s.name).map_or(0, |(_, sub)| sub);
            let sub_name = parameter_name(ini, s)?;
            if let Some(code) = number_of(ini, s, "ObjectType")? {
                if code != VAR && code != DOMAIN {
                    return Err(EdsError::Invalid {
                        at: ini.at(s, "ObjectType"),
                        what: format!("a sub-index is a VAR (0x7), not 0x{code:X}"),
                    });
                }
            }
            entries.push(entry(ini, s, index, sub, &sub_name, None, defaults_at)?);
        }
        entries.sort_by_key(|e| e.sub);
        let Some(first) = entries.first() else {
            return Err(EdsError::Missing {
                at: ini.at(section, "SubNumber"),
                what: format!("the sub-indices [{index:04X}sub0] …"),
            });
        };
        if first.sub != 0 {
            return Err(EdsError::Missing {
                at: ini.at(section, "SubNumber"),
                what: format!("[{index:04X}sub0], the number of entries (CiA 301 §7.4.5)"),
            });
        }
        if first.data_type != DataType::Unsigned8 {
            let s = subs
                .iter()
                .find(|s| sub_section(&s.name).is_some_and(|(_, sub)| sub == 0))
                .copied()
                .unwrap_or(section);
            return Err(EdsError::Invalid {
                at: ini.at(s, "DataType"),
                what: "sub-index 0 of an ARRAY / RECORD is an UNSIGNED8".into(),
            });
        }
    }
    Ok(Obj {
        index,
        name,
        kind,
        min_max: None,
        entries,
    })
}

fn parameter_name(ini: &Ini, s: &Section) -> Result<String, EdsError> {
    s.value("ParameterName")
        .filter(|n| !n.is_empty())
        .map(str::to_owned)
        .ok_or_else(|| EdsError::Missing {
            at: ini.at(s, "ParameterName"),
            what: "ParameterName".into(),
        })
}

/// An ARRAY written with `CompactSubObj=n` (CiA 306 §4.6.4): sub-index 0 holds n, sub-indices
/// 1…n share the object's type, access and default; `[IIIIName]` and `[IIIIValue]` name and
/// set single ones.
#[allow(clippy::too_many_arguments)]
fn compact(
    ini: &Ini,
    section: &Section,
    index: u16,
    name: &str,
    n: u64,
    kind: ObjectKind,
    explicit_sub: Option<&Section>,
    defaults_at: &mut DefaultsAt,
) -> Result<Vec<Ent>, EdsError> {
    if kind != ObjectKind::Array {
        return Err(EdsError::Invalid {
            at: ini.at(section, "CompactSubObj"),
            what: "CompactSubObj is for an ARRAY (ObjectType=0x8)".into(),
        });
    }
    if let Some(s) = explicit_sub {
        return Err(EdsError::Invalid {
            at: ini.at(s, ""),
            what: "an ARRAY with CompactSubObj has no [IIIIsubN] sections".into(),
        });
    }
    let n = u8::try_from(n)
        .ok()
        .filter(|n| *n < 255)
        .ok_or_else(|| EdsError::Invalid {
            at: ini.at(section, "CompactSubObj"),
            what: "at most 254 sub-indices".into(),
        })?;
    let names = ini.section(&format!("{index:04X}Name"));
    let values = ini.section(&format!("{index:04X}Value"));
    let mut entries = vec![Ent::plain(
        index,
        0,
        "Number of entries".into(),
        DataType::Unsigned8,
        Access::ReadOnly,
        vec![n],
    )];
    for sub in 1..=n {
        let key = sub.to_string();
        let sub_name = names
            .and_then(|s| s.value(&key))
            .map_or_else(|| format!("{name}{sub}"), str::to_owned);
        let value = values.and_then(|s| s.key(&key).map(|k| (s, k.name.as_str())));
        entries.push(entry(
            ini,
            section,
            index,
            sub,
            &sub_name,
            value,
            defaults_at,
        )?);
    }
    Ok(entries)
}

/// One entry from `s` (a VAR's section, a `[IIIIsubN]`, or a compact array's section).
/// `value` is a `[IIIIValue]` key that sets this entry's value in a DCF.
fn entry(
    ini: &Ini,
    s: &Section,
    index: u16,
    sub: u8,
    name: &str,
    value: Option<(&Section, &str)>,
    defaults_at: &mut DefaultsAt,
) -> Result<Ent, EdsError> {
    let invalid = |key: &str, what: String| EdsError::Invalid {
        at: ini.at(s, key),
        what,
    };
    let code = number_of(ini, s, "DataType")?.ok_or_else(|| EdsError::Missing {
        at: ini.at(s, "DataType"),
        what: "DataType".into(),
    })?;
    let data_type = data_type(code).map_err(|e| match e {
        TypeError::Unsupported(what) => EdsError::Unsupported {
            at: ini.at(s, "DataType"),
            what,
        },
        TypeError::Unknown(what) => invalid("DataType", what),
    })?;
    let access_text = s.value("AccessType").ok_or_else(|| EdsError::Missing {
        at: ini.at(s, "AccessType"),
        what: "AccessType".into(),
    })?;
    let access = Access::from_name(&access_text.to_ascii_lowercase()).ok_or_else(|| {
        invalid(
            "AccessType",
            format!("{access_text:?}: one of ro, wo, rw, rwr, rww, const"),
        )
    })?;
    let pdo = match number_of(ini, s, "PDOMapping")? {
        None | Some(0) => false,
        Some(1) => true,
        Some(n) => return Err(invalid("PDOMapping", format!("{n}: 0 or 1"))),
    };
    // A DCF's ParameterValue (or `[IIIIValue]`) is the value configured: the twin starts with it.
    let (value_section, value_key) = match value {
        Some((vs, key)) => (vs, key.to_owned()),
        None if s.key("ParameterValue").is_some() => (s, "ParameterValue".to_owned()),
        None => (s, "DefaultValue".to_owned()),
    };
    let default_text = value_section.value(&value_key).unwrap_or("");
    let default_at = ini.at(value_section, &value_key);
    let bad_default = |what: String| EdsError::Invalid {
        at: default_at.clone(),
        what,
    };
    let (default, plus_node) = match data_type {
        DataType::VisibleString => {
            let bytes: Option<Vec<u8>> = default_text
                .chars()
                .map(|c| u8::try_from(u32::from(c)).ok())
                .collect();
            (
                bytes.ok_or_else(|| bad_default("a VISIBLE_STRING is 8-bit text".into()))?,
                false,
            )
        }
        DataType::OctetString | DataType::Domain => {
            (number::hex_bytes(default_text).map_err(bad_default)?, false)
        }
        t => match number::node_relative(default_text) {
            Ok(Some(constant)) => {
                if t.is_real() || t == DataType::Boolean {
                    return Err(EdsError::Unsupported {
                        at: default_at,
                        what: format!("$NODEID in a {} value", t.name()),
                    });
                }
                (number::encode(t, constant).map_err(bad_default)?, true)
            }
            Ok(None) if default_text.is_empty() => (vec![0; t.fixed_size().unwrap_or(0)], false),
            Ok(None) => (number::encode(t, default_text).map_err(bad_default)?, false),
            Err(what) => {
                return Err(EdsError::Unsupported {
                    at: default_at,
                    what,
                })
            }
        },
    };
    defaults_at.push((index, sub, default_at.clone()));
    let limit = |key: &str| -> Result<Option<Limit>, EdsError> {
        match s.value(key).filter(|v| !v.is_empty()) {
            None => Ok(None),
            Some(_) if !data_type.is_numeric() => Err(EdsError::Invalid {
                at: ini.at(s, key),
                what: format!("a {} has no limits", data_type.name()),
            }),
            Some(v) => number::limit(data_type, v).map(Some).map_err(|what| {
                if what.contains("$NODEID") {
                    EdsError::Unsupported {
                        at: ini.at(s, key),
                        what,
                    }
                } else {
                    EdsError::Invalid {
                        at: ini.at(s, key),
                        what,
                    }
                }
            }),
        }
    };
    let min = limit("LowLimit")?;
    let max = limit("HighLimit")?;
    if let (Some(lo), Some(hi)) = (min, max) {
        if Value::from_limit(lo).compare(hi) == Some(std::cmp::Ordering::Greater) {
            return Err(invalid("HighLimit", "below LowLimit".into()));
        }
    }
    if !plus_node {
        if let Some(v) = Value::decode(data_type, &default) {
            let below = min.is_some_and(|m| v.compare(m) == Some(std::cmp::Ordering::Less));
            let above = max.is_some_and(|m| v.compare(m) == Some(std::cmp::Ordering::Greater));
            if below || above {
                return Err(EdsError::Invalid {
                    at: default_at,
                    what: format!("{v} is outside LowLimit / HighLimit"),
                });
            }
        }
    }
    let behaviour = behaviour(index, sub);
    // Decision: CiA 306 has no "saved by 1010h" flag. A writable entry is a parameter and is
    // saved, except the CiA 301 command objects and what a master may write through an RPDO
    // (controlword, set-points: process data, not configuration).
    let storable = access.writable()
        && !pdo
        && !matches!(
            behaviour,
            Behaviour::StoreSignature | Behaviour::RestoreSignature | Behaviour::ErrorHistoryCount
        );
    // Decision: a string or domain may hold its default; a writable one up to 255 bytes more
    // (CiA 306 gives no maximum length).
    let capacity = match data_type.fixed_size() {
        Some(n) => n as u32,
        None if access.writable() => (default.len() as u32).max(255),
        None => (default.len() as u32).max(1),
    };
    Ok(Ent {
        index,
        sub,
        name: name.to_owned(),
        data_type,
        access,
        pdo,
        default,
        default_plus_node_id: plus_node,
        min,
        max,
        unit: String::new(),
        behaviour,
        storable,
        kept_on_restore: false,
        allowed_bits: None,
        capacity,
        panel: Vec::new(),
        modbus: None,
    })
}

enum TypeError {
    Unsupported(String),
    Unknown(String),
}

/// The CiA 301 §7.1 type of code `code`.
fn data_type(code: u64) -> Result<DataType, TypeError> {
    if let Some(t) = DataType::ALL.iter().find(|t| u64::from(t.code()) == code) {
        return Ok(*t);
    }
    let name = match code {
        0x000B => "UNICODE_STRING",
        0x000C => "TIME_OF_DAY",
        0x000D => "TIME_DIFFERENCE",
        0x0010 => "INTEGER24",
        0x0012 => "INTEGER40",
        0x0013 => "INTEGER48",
        0x0014 => "INTEGER56",
        0x0016 => "UNSIGNED24",
        0x0018 => "UNSIGNED40",
        0x0019 => "UNSIGNED48",
        0x001A => "UNSIGNED56",
        _ => {
            return Err(TypeError::Unknown(format!(
                "0x{code:04X} is no CiA 301 data type"
            )))
        }
    };
    Err(TypeError::Unsupported(format!("data type {name}")))
}

/// What CiA 301 makes of an entry beyond storing it, by its index.
fn behaviour(index: u16, sub: u8) -> Behaviour {
    match (index, sub) {
        (0x1003, 0) => Behaviour::ErrorHistoryCount,
        (0x1010, 1..) => Behaviour::StoreSignature,
        (0x1011, 1..) => Behaviour::RestoreSignature,
        (0x1400..=0x15FF | 0x1800..=0x19FF, 1) => Behaviour::PdoCobId,
        (0x1400..=0x15FF | 0x1800..=0x19FF, 2) => Behaviour::PdoTransmissionType,
        (0x1400..=0x15FF | 0x1800..=0x19FF, 3) => Behaviour::PdoInhibitTime,
        (0x1400..=0x15FF | 0x1800..=0x19FF, 5) => Behaviour::PdoEventTimer,
        (0x1800..=0x19FF, 6) => Behaviour::PdoSyncStart,
        (0x1600..=0x17FF | 0x1A00..=0x1BFF, 0) => Behaviour::PdoMapCount,
        (0x1600..=0x17FF | 0x1A00..=0x1BFF, _) => Behaviour::PdoMapEntry,
        _ => Behaviour::Plain,
    }
}

/// The PDO mappings a file sets up must be ones the device could be given (CiA 301
/// §7.5.2.38): each mapped entry exists, may be mapped in that direction, is mapped whole,
/// and one PDO carries at most 64 bits.
fn check_mappings(
    objects: &[Obj],
    defaults_at: &DefaultsAt,
    dummy_usage: Option<u8>,
) -> Result<(), EdsError> {
    let entry = |index: u16, sub: u8| {
        objects
            .iter()
            .find(|o| o.index == index)
            .and_then(|o| o.entries.iter().find(|e| e.sub == sub))
    };
    let at = |index: u16, sub: u8| {
        defaults_at
            .iter()
            .find(|(i, s, _)| (*i, *s) == (index, sub))
            .map(|(_, _, at)| at.clone())
    };
    for o in objects {
        let transmit = match o.index {
            0x1600..=0x17FF => false,
            0x1A00..=0x1BFF => true,
            _ => continue,
        };
        let Some(count_at) = at(o.index, 0) else {
            continue;
        };
        let count = o
            .entries
            .first()
            .and_then(|e| e.default.first())
            .copied()
            .unwrap_or(0);
        let subs = o.entries.iter().filter(|e| e.sub > 0).count();
        if usize::from(count) > subs {
            return Err(EdsError::Invalid {
                at: count_at,
                what: format!("{count} objects mapped, but only {subs} mapping entries"),
            });
        }
        let mut bits = 0u32;
        for e in o.entries.iter().filter(|e| e.sub > 0 && e.sub <= count) {
            let v = match Value::decode(e.data_type, &e.default) {
                Some(Value::Unsigned(v)) => v as u32,
                _ => continue,
            };
            let Some(e_at) = at(o.index, e.sub) else {
                continue;
            };
            let (index, sub, len) = ((v >> 16) as u16, (v >> 8) as u8, v as u8);
            bits += u32::from(len);
            if (0x0001..=0x0007).contains(&index) && sub == 0 && !transmit {
                if dummy_usage.is_some_and(|u| u & (1 << index) == 0) {
                    return Err(EdsError::Invalid {
                        at: e_at,
                        what: format!(
                            "maps the dummy {index:04X}h, which [DummyUsage] does not allow \
                             (Dummy{index:04X}=1)"
                        ),
                    });
                }
                continue;
            }
            let target = entry(index, sub).ok_or_else(|| EdsError::Invalid {
                at: e_at.clone(),
                what: format!("maps {index:04X}h sub {sub}, which the file does not define"),
            })?;
            let direction = if transmit {
                target.access.readable()
            } else {
                target.access.writable()
            };
            if !target.pdo || !direction || u32::from(len) != target.capacity * 8 {
                return Err(EdsError::Invalid {
                    at: e_at,
                    what: format!(
                        "maps {index:04X}h sub {sub} with {len} bits: it needs PDOMapping=1, \
                         {} access and its {} bits",
                        if transmit { "read" } else { "write" },
                        target.capacity * 8
                    ),
                });
            }
        }
        if bits > 64 {
            return Err(EdsError::Invalid {
                at: count_at,
                what: format!("{bits} bits mapped: a PDO carries at most 64"),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
