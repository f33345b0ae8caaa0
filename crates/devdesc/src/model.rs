//! A checked, normalised description: what the code generator and tools work from.

use std::path::Path;

use od::{Access, Behaviour, DataType, Limit, ObjectKind, Value};

use crate::schema::{
    BrakeSection, DiagnosticSection, EntryFields, File, ObjectKey, ObjectSection, PlantSection,
    ProfileName, SerialPortSection, SerialPortsSection,
};

#[derive(Debug, thiserror::Error)]
pub enum DescError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Toml {
        path: String,
        source: toml::de::Error,
    },
    #[error("object {index:04X}h sub {sub}: {what}")]
    Entry { index: u16, sub: u8, what: String },
    #[error("object {index:04X}h: {what}")]
    Object { index: u16, what: String },
    #[error("device: {0}")]
    Device(String),
    #[error("diagnostic {number}: {what}")]
    Diagnostic { number: String, what: String },
    /// A mistake in the content of the file at `path` (the parser's own errors name it
    /// already).
    #[error("{path}: {source}")]
    InFile {
        path: String,
        source: Box<DescError>,
    },
}

#[derive(Debug, Clone)]
pub struct Device {
    pub name: String,
    pub product_name: String,
    pub vendor_name: String,
    pub vendor_id: u32,
    pub product_code: u32,
    pub revision: u32,
    pub order_code: String,
    pub description: String,
    pub profile: od::Profile,
    pub default_node_id: u8,
    pub baud_rates: Vec<u16>,
    pub rotary_switches: u8,
    /// The object whose code sets the CAN bit rate: its index, name and `(code, kbit/s)`.
    pub can_bit_rate: Option<CanBitRate>,
    /// The objects whose code sets a serial line speed, and the `(code, bit/s)` table.
    pub serial_bit_rate: Option<SerialBitRate>,
    /// `[device.serial_ports]`, checked: each port's interface and its objects.
    pub serial_ports: Vec<(String, crate::schema::SerialPortSection)>,
    pub interfaces: Vec<String>,
    pub interfaces_one_of: Vec<String>,
    pub interfaces_rule: String,
    pub fieldbus_switches: bool,
    pub ethercat: Option<crate::schema::EthercatSection>,
    pub fhpp: Option<crate::schema::FhppSection>,
    /// `[device.bus_faults]`, or CiA 301's usage for a file without one (an EDS too).
    pub bus_faults: BusFaults,
    /// `[device.brake]`, checked (empty lists for a file without one, an EDS too).
    pub brake: crate::schema::BrakeSection,
    /// `[device.plant]`, checked (no message or object for a file without one, an EDS too).
    pub plant: crate::schema::PlantSection,
    pub cia301: od::Cia301Options,
    pub objects: Vec<Obj>,
    pub diagnostics: Vec<Diag>,
}

/// The reactions to each change of the CAN controller's error state
/// (`od::BusFaultReactions`, owned).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BusFaults {
    pub on_passive: Vec<od::BusFaultReaction>,
    pub on_active: Vec<od::BusFaultReaction>,
    pub on_bus_off: Vec<od::BusFaultReaction>,
    pub on_recovered: Vec<od::BusFaultReaction>,
}

impl Default for BusFaults {
    /// CiA 301's usage ([`od::BusFaultReactions::CIA_301`]).
    fn default() -> Self {
        let r = od::BusFaultReactions::CIA_301;
        BusFaults {
            on_passive: r.on_passive.to_vec(),
            on_active: r.on_active.to_vec(),
            on_bus_off: r.on_bus_off.to_vec(),
            on_recovered: r.on_recovered.to_vec(),
        }
    }
}

impl From<&crate::schema::BusFaultsSection> for BusFaults {
    fn from(s: &crate::schema::BusFaultsSection) -> Self {
        let list = |v: &[crate::schema::BusFaultReactionText]| v.iter().map(|r| r.0).collect();
        BusFaults {
            on_passive: list(&s.on_passive),
            on_active: list(&s.on_active),
            on_bus_off: list(&s.on_bus_off),
            on_recovered: list(&s.on_recovered),
        }
    }
}

/// `can_bit_rate` of a device file, checked: an UNSIGNED8 object of the file, each code once.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CanBitRate {
    pub index: u16,
    pub name: String,
    pub codes: Vec<(u8, u16)>,
}

/// `can_bit_rate` names an UNSIGNED8 object at sub-index 0 of the file, each code once, each
/// bit rate one the device supports (`baud_rates`).
fn check_can_bit_rate(
    section: Option<&crate::schema::CanBitRateSection>,
    baud_rates: &[u16],
    objects: &[Obj],
) -> Result<Option<CanBitRate>, DescError> {
    let Some(c) = section else {
        return Ok(None);
    };
    let err = |what: String| DescError::Device(format!("can_bit_rate: {what}"));
    let entry = objects
        .iter()
        .find(|o| o.index == c.object)
        .and_then(|o| o.entries.iter().find(|e| e.sub == 0));
    match entry {
        Some(e) if e.data_type == DataType::Unsigned8 => {}
        _ => {
            return Err(err(format!(
                "object {:04X}h sub 0 is no UNSIGNED8 of this file",
                c.object
            )))
        }
    }
    let mut codes: Vec<(u8, u16)> = Vec::with_capacity(c.codes.len());
    for [code, kbit] in &c.codes {
        let code = u8::try_from(*code).map_err(|_| err(format!("code {code} is no UNSIGNED8")))?;
        if codes.iter().any(|(c, _)| *c == code) {
            return Err(err(format!("code {code} listed twice")));
        }
        if !baud_rates.contains(kbit) {
            return Err(err(format!("{kbit} kbit/s is not in baud_rates")));
        }
        codes.push((code, *kbit));
    }
    if codes.is_empty() {
        return Err(err("no codes".into()));
    }
    Ok(Some(CanBitRate {
        index: c.object,
        name: c.name.clone(),
        codes,
    }))
}

/// `serial_bit_rate` of a device file, checked: UNSIGNED16 objects of the file, each code
/// and each bit rate once.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SerialBitRate {
    pub objects: Vec<u16>,
    pub codes: Vec<(u16, u32)>,
}

/// `serial_bit_rate` names UNSIGNED16 objects at sub-index 0 of the file, each once, whose
/// defaults are codes of the table; each code and each bit rate is listed once, so that a
/// code gives one bit rate and a bit rate one code.
fn check_serial_bit_rate(
    section: Option<&crate::schema::SerialBitRateSection>,
    objects: &[Obj],
) -> Result<Option<SerialBitRate>, DescError> {
    let Some(s) = section else {
        return Ok(None);
    };
    let err = |what: String| DescError::Device(format!("serial_bit_rate: {what}"));
    let mut codes: Vec<(u16, u32)> = Vec::with_capacity(s.codes.len());
    for [code, bit_rate] in &s.codes {
        let code =
            u16::try_from(*code).map_err(|_| err(format!("code {code} is no UNSIGNED16")))?;
        if codes.iter().any(|(c, _)| *c == code) {
            return Err(err(format!("code {code} listed twice")));
        }
        if codes.iter().any(|(_, b)| b == bit_rate) {
            return Err(err(format!("{bit_rate} bit/s listed twice")));
        }
        if *bit_rate == 0 {
            return Err(err(format!("code {code}: 0 bit/s")));
        }
        codes.push((code, *bit_rate));
    }
    if codes.is_empty() {
        return Err(err("no codes".into()));
    }
    if s.objects.is_empty() {
        return Err(err("no objects".into()));
    }
    for (i, index) in s.objects.iter().enumerate() {
        if s.objects
            .get(..i)
            .is_some_and(|before| before.contains(index))
        {
            return Err(err(format!("object {index:04X}h listed twice")));
        }
        let entry = objects
            .iter()
            .find(|o| o.index == *index)
            .and_then(|o| o.entries.iter().find(|e| e.sub == 0));
        let Some(e) = entry.filter(|e| e.data_type == DataType::Unsigned16) else {
            return Err(err(format!(
                "object {index:04X}h sub 0 is no UNSIGNED16 of this file"
            )));
        };
        let default = match e.default.as_slice() {
            [lo, hi] => u16::from_le_bytes([*lo, *hi]),
            _ => 0,
        };
        if !codes.iter().any(|(c, _)| *c == default) {
            return Err(err(format!(
                "object {index:04X}h's default {default} is no code of the table"
            )));
        }
    }
    Ok(Some(SerialBitRate {
        objects: s.objects.clone(),
        codes,
    }))
}

/// `[device.serial_ports]`: a table for each serial interface of `interfaces` and none for
/// another; each port's bit-rate objects are objects of `serial_bit_rate`, its loop-enable and
/// protocol objects integer entries of the file, the protocol's two values distinct, the
/// protocol object's default one of them.
fn check_serial_ports(
    section: Option<&SerialPortsSection>,
    interfaces: &[String],
    rates: Option<&SerialBitRate>,
    objects: &[Obj],
) -> Result<Vec<(String, SerialPortSection)>, DescError> {
    const TABLE: &str = "[device.serial_ports]";
    let empty = SerialPortsSection::default();
    let s = section.unwrap_or(&empty);
    let mut ports = Vec::new();
    for (name, port) in [("rs232", &s.rs232), ("rs485", &s.rs485)] {
        let listed = interfaces.iter().any(|i| i == name);
        let Some(p) = port else {
            if listed {
                return Err(DescError::Device(format!(
                    "interfaces lists {name:?}, but {TABLE} has no {name} table"
                )));
            }
            continue;
        };
        if !listed {
            return Err(DescError::Device(format!(
                "{TABLE} {name}: the device has no {name:?} interface"
            )));
        }
        let key = |k: &str| format!("{name}.{k}");
        for (k, index) in [
            ("bit_rate", Some(p.bit_rate)),
            ("bit_rate_now", p.bit_rate_now),
        ] {
            let Some(index) = index else { continue };
            if !rates.is_some_and(|r| r.objects.contains(&index)) {
                return Err(DescError::Device(format!(
                    "{TABLE} {}: object {index:04X}h is no object of serial_bit_rate",
                    key(k)
                )));
            }
        }
        if let Some(o) = p.loop_enable {
            integer_entry(TABLE, &key("loop_enable"), o, false, objects)?;
        }
        if let Some(pr) = &p.protocol {
            integer_entry(TABLE, &key("protocol"), pr.object, false, objects)?;
            if pr.modbus_rtu == pr.telegrams {
                return Err(DescError::Device(format!(
                    "{TABLE} {}: modbus_rtu and telegrams are both {}",
                    key("protocol"),
                    pr.telegrams
                )));
            }
            let default = objects
                .iter()
                .find(|o| o.index == pr.object.0)
                .and_then(|o| o.entries.iter().find(|e| e.sub == pr.object.1))
                .map(|e| {
                    e.default
                        .iter()
                        .rev()
                        .fold(0u64, |acc, b| acc << 8 | u64::from(*b))
                });
            if !default
                .is_some_and(|v| v == u64::from(pr.modbus_rtu) || v == u64::from(pr.telegrams))
            {
                return Err(DescError::Device(format!(
                    "{TABLE} {}: the default of object {:04X}h sub {:02X}h is neither modbus_rtu nor telegrams",
                    key("protocol"),
                    pr.object.0,
                    pr.object.1
                )));
            }
        }
        ports.push((name.to_owned(), p.clone()));
    }
    Ok(ports)
}

/// The entry `key` of a device file's table `table` names: an integer entry of the file
/// (`signed`: a signed one).
fn integer_entry(
    table: &str,
    key: &str,
    (index, sub): ObjectKey,
    signed: bool,
    objects: &[Obj],
) -> Result<(), DescError> {
    let err = |what: &str| {
        DescError::Device(format!(
            "{table} {key}: object {index:04X}h sub {sub:02X}h {what}"
        ))
    };
    let entry = objects
        .iter()
        .find(|o| o.index == index)
        .and_then(|o| o.entries.iter().find(|e| e.sub == sub));
    let Some(e) = entry else {
        return Err(err("is not in this file"));
    };
    let t = e.data_type;
    let integer = t.is_numeric() && !t.is_real() && t != DataType::Boolean;
    match (integer, signed) {
        (true, false) => Ok(()),
        (true, true) if t.is_signed() => Ok(()),
        (_, false) => Err(err(&format!("is {}, no integer", t.name()))),
        (_, true) => Err(err(&format!("is {}, no signed integer", t.name()))),
    }
}

/// `[device.brake]`: each delay's objects are integer entries of the file, each once.
fn check_brake(section: Option<&BrakeSection>, objects: &[Obj]) -> Result<BrakeSection, DescError> {
    let Some(b) = section else {
        return Ok(BrakeSection::default());
    };
    for (key, list) in [
        ("release", &b.release),
        ("motion", &b.motion),
        ("engage", &b.engage),
    ] {
        for (i, o) in list.iter().enumerate() {
            integer_entry("[device.brake]", key, *o, false, objects)?;
            if list.get(..i).is_some_and(|before| before.contains(o)) {
                return Err(DescError::Device(format!(
                    "[device.brake] {key}: object {:04X}h sub {:02X}h listed twice",
                    o.0, o.1
                )));
            }
        }
    }
    Ok(b.clone())
}

/// A message a device file's table `table` names under `key` is a row of its diagnostic
/// table (compared as [`od::DeviceDescription::diagnostic`] finds it).
fn diagnostic_row(table: &str, key: &str, number: &str, rows: &[Diag]) -> Result<(), DescError> {
    if rows.iter().any(|d| d.number.eq_ignore_ascii_case(number)) {
        return Ok(());
    }
    Err(DescError::Device(format!(
        "{table} {key}: message {number:?} is no [[diagnostic]] row of this file"
    )))
}

/// `[device.plant]`: its messages are rows of the file's diagnostic table, its limits
/// integer entries of the file, its temperatures signed integer entries (a temperature may
/// be below 0 °C). Each key is one the profile's supervision reads: the CiA 402 engine has no
/// stage warning, no lower stage limit (those are an FHPP device's); an FHPP device supervises
/// no motor temperature (the CMMO-ST has no sensor); a key the profile does not read is
/// refused.
fn check_plant(
    section: Option<&PlantSection>,
    profile: od::Profile,
    objects: &[Obj],
    rows: &[Diag],
) -> Result<PlantSection, DescError> {
    let Some(p) = section else {
        return Ok(PlantSection::default());
    };
    const TABLE: &str = "[device.plant]";
    let fhpp = profile == od::Profile::Fhpp;
    let cia402 = !fhpp;
    let any = true;
    let given = |key: &str, present: bool, read: bool| {
        if present && !read {
            return Err(DescError::Device(format!(
                "{TABLE} {key}: the {profile:?} profile's supervision has no such condition"
            )));
        }
        Ok(())
    };
    for (key, number, read) in [
        ("motor_warning", &p.motor_warning, cia402),
        ("motor_over", &p.motor_over, cia402),
        ("stage_warning", &p.stage_warning, fhpp),
        ("stage_over", &p.stage_over, any),
        ("stage_under", &p.stage_under, fhpp),
        ("encoder_lost", &p.encoder_lost, any),
        ("encoder_implausible", &p.encoder_implausible, any),
    ] {
        given(key, number.is_some(), read)?;
        if let Some(n) = number {
            diagnostic_row(TABLE, key, n, rows)?;
        }
    }
    for (key, object, signed, read) in [
        ("motor_limit", p.motor_limit, false, cia402),
        ("stage_limit", p.stage_limit, false, any),
        ("stage_low_limit", p.stage_low_limit, true, fhpp),
        ("motor_temperature", p.motor_temperature, true, cia402),
        ("stage_temperature", p.stage_temperature, true, any),
    ] {
        given(key, object.is_some(), read)?;
        if let Some(o) = object {
            integer_entry(TABLE, key, o, signed, objects)?;
        }
    }
    Ok(p.clone())
}

/// `[device.fhpp]` goes with the FHPP profile; each PNU it names is a parameter (object
/// 2000h + PNU) with a writable subindex, listed once and in order, and the record list
/// (PNU 401, record control byte 1) has a subindex for every record.
fn check_fhpp(
    fhpp: bool,
    section: Option<&crate::schema::FhppSection>,
    objects: &[Obj],
) -> Result<(), DescError> {
    let Some(f) = section else {
        return match fhpp {
            true => Err(DescError::Device(
                "profile \"fhpp\" needs a [device.fhpp] section".into(),
            )),
            false => Ok(()),
        };
    };
    if !fhpp {
        return Err(DescError::Device(
            "[device.fhpp] belongs to a device of profile \"fhpp\"".into(),
        ));
    }
    let object = |pnu: u16| {
        0x2000u16
            .checked_add(pnu)
            .and_then(|index| objects.iter().find(|o| o.index == index))
    };
    if let Some(w) = f.stage_off_pnus.windows(2).find(|w| w.first() >= w.get(1)) {
        return Err(DescError::Device(format!(
            "[device.fhpp] stage_off_pnus: {w:?} is out of order or twice"
        )));
    }
    if let Some(bad) = f.stage_off_pnus.iter().find(|p| {
        !object(**p).is_some_and(|o| o.entries.iter().any(|e| e.sub > 0 && e.access.writable()))
    }) {
        return Err(DescError::Device(format!(
            "[device.fhpp] stage_off_pnus: PNU {bad} is no writable parameter"
        )));
    }
    let last_record = object(401)
        .and_then(|o| o.entries.iter().map(|e| e.sub).max())
        .unwrap_or(0);
    if f.records == 0 || f.records > last_record {
        return Err(DescError::Device(format!(
            "[device.fhpp] records = {}: the record list (PNU 401) has subindices 1…{last_record}",
            f.records
        )));
    }
    Ok(())
}

/// A checked `[[diagnostic]]` row.
#[derive(Debug, Clone)]
pub struct Diag {
    pub number: String,
    pub code: Option<u16>,
    pub register: u8,
    pub reaction: od::Reaction,
    pub text: String,
    pub display: String,
    pub classes: String,
    pub reactions: String,
    pub memory: String,
    pub ack: String,
    pub source: String,
}

#[derive(Debug, Clone)]
pub struct Obj {
    pub index: u16,
    pub name: String,
    pub kind: ObjectKind,
    pub min_max: Option<(u8, u8)>,
    pub entries: Vec<Ent>,
}

#[derive(Debug, Clone)]
pub struct Ent {
    pub index: u16,
    pub sub: u8,
    pub name: String,
    pub data_type: DataType,
    pub access: Access,
    pub pdo: bool,
    pub default: Vec<u8>,
    pub default_plus_node_id: bool,
    pub min: Option<Limit>,
    pub max: Option<Limit>,
    pub unit: String,
    pub behaviour: Behaviour,
    pub storable: bool,
    pub kept_on_restore: bool,
    pub allowed_bits: Option<u64>,
    pub capacity: u32,
    /// LED panel addresses (Kinco `d3.01`, `EA02`, `tn01`, `F001`); empty for most devices.
    pub panel: Vec<String>,
    /// Modbus register (Kinco RTU map, §12.3); a value of more than 16 bits takes the next
    /// registers too.
    pub modbus: Option<u16>,
}

impl Ent {
    /// A plain entry: no PDO mapping, limits, unit, storage or panel; its capacity the
    /// type's size (one byte for a variable-size type).
    pub fn plain(
        index: u16,
        sub: u8,
        name: String,
        data_type: DataType,
        access: Access,
        default: Vec<u8>,
    ) -> Ent {
        Ent {
            index,
            sub,
            name,
            data_type,
            access,
            pdo: false,
            default,
            default_plus_node_id: false,
            min: None,
            max: None,
            unit: String::new(),
            behaviour: Behaviour::Plain,
            storable: false,
            kept_on_restore: false,
            allowed_bits: None,
            capacity: data_type.fixed_size().map_or(1, |n| n as u32),
            panel: Vec::new(),
            modbus: None,
        }
    }
}

pub fn load_file(path: &Path) -> Result<Device, DescError> {
    let text = std::fs::read_to_string(path).map_err(|source| DescError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse(&text, &path.display().to_string())
}

/// The device of the file at `path` (only named in errors) holding `text`, checked; a
/// mistake is refused with the file, and the table and key or the object where it stands.
pub fn parse(text: &str, path: &str) -> Result<Device, DescError> {
    check(text, path).map_err(|e| match e {
        e @ (DescError::Io { .. } | DescError::Toml { .. } | DescError::InFile { .. }) => e,
        other => DescError::InFile {
            path: path.to_string(),
            source: Box::new(other),
        },
    })
}

fn check(text: &str, path: &str) -> Result<Device, DescError> {
    let file: File = toml::from_str(text).map_err(|source| DescError::Toml {
        path: path.to_string(),
        source,
    })?;
    let d = file.device;
    if d.name.is_empty()
        || !d
            .name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-')
    {
        return Err(DescError::Device(format!(
            "name {:?} must be letters, digits and '-'",
            d.name
        )));
    }
    if d.rotary_switches > 2 {
        return Err(DescError::Device(
            "rotary_switches must be 0, 1 or 2".into(),
        ));
    }
    if !(1..=127).contains(&d.default_node_id) {
        return Err(DescError::Device("default_node_id must be 1…127".into()));
    }
    let mut objects = Vec::with_capacity(file.object.len());
    for o in &file.object {
        objects.push(object(o)?);
    }
    objects.sort_by_key(|o| o.index);
    unique_addresses(&objects)?;
    for pair in objects.windows(2) {
        if let [a, b] = pair {
            if a.index == b.index {
                return Err(DescError::Object {
                    index: a.index,
                    what: "defined twice".into(),
                });
            }
        }
    }
    // The profile and the device type 1000h must agree (CiA 301: bits 0…15 are the device
    // profile number, 402 = 0192h for a drive).
    let device_type_profile = objects
        .iter()
        .find(|o| o.index == 0x1000)
        .and_then(|o| o.entries.first())
        .and_then(|e| e.default.get(..2))
        .and_then(|b| <[u8; 2]>::try_from(b).ok())
        .map(u16::from_le_bytes);
    let profile = match d.profile {
        ProfileName::Cia402 => od::Profile::Cia402,
        ProfileName::Fhpp => od::Profile::Fhpp,
        ProfileName::Plain => od::Profile::Plain,
    };
    // Decision: a device whose 1000h does not carry its profile (Nanotec §9.6 prints 00000008h,
    // "stepper motor") says so with `device_type_carries_profile = false`; its `profile` decides.
    if d.device_type_carries_profile
        && (profile == od::Profile::Cia402) != (device_type_profile == Some(402))
    {
        return Err(DescError::Device(format!(
            "profile {:?} does not agree with the device type 1000h",
            d.profile
        )));
    }
    // Without `interfaces`: the profile's fieldbus.
    let fhpp = profile == od::Profile::Fhpp;
    let interfaces = d
        .interfaces
        .unwrap_or_else(|| vec![if fhpp { "modbus-tcp" } else { "canopen" }.to_owned()]);
    const KNOWN: &[&str] = &[
        "canopen",
        "ethercat",
        "modbus-tcp",
        "ci-terminal",
        "rs232",
        "rs485",
    ];
    if let Some(bad) = interfaces
        .iter()
        .chain(&d.interfaces_one_of)
        .find(|i| !KNOWN.contains(&i.as_str()))
    {
        return Err(DescError::Device(format!(
            "interface {bad:?}: one of {KNOWN:?}"
        )));
    }
    if let Some(bad) = d.interfaces_one_of.iter().find(|i| !interfaces.contains(i)) {
        return Err(DescError::Device(format!(
            "interfaces_one_of {bad:?} is not in interfaces"
        )));
    }
    let has_ethercat = interfaces.iter().any(|i| i == "ethercat");
    if has_ethercat != d.ethercat.is_some() {
        return Err(DescError::Device(
            "an `ethercat` interface and a [device.ethercat] section go together".into(),
        ));
    }
    if let Some(e) = &d.ethercat {
        let rx = e
            .rx_assigned
            .iter()
            .find(|i| !(0x1600..=0x17FF).contains(*i));
        let tx = e
            .tx_assigned
            .iter()
            .find(|i| !(0x1A00..=0x1BFF).contains(*i));
        if let Some(bad) = rx.or(tx) {
            return Err(DescError::Device(format!(
                "[device.ethercat] assigns {bad:04X}h, which is no PDO mapping object of its direction"
            )));
        }
    }
    check_fhpp(fhpp, d.fhpp.as_ref(), &objects)?;
    let can_bit_rate = check_can_bit_rate(d.can_bit_rate.as_ref(), &d.baud_rates, &objects)?;
    let serial_bit_rate = check_serial_bit_rate(d.serial_bit_rate.as_ref(), &objects)?;
    let serial_ports = check_serial_ports(
        d.serial_ports.as_ref(),
        &interfaces,
        serial_bit_rate.as_ref(),
        &objects,
    )?;
    let interfaces_rule = d.interfaces_rule.unwrap_or_else(|| {
        if fhpp {
            "its fieldbus is Modbus TCP"
        } else {
            "a CANopen device"
        }
        .to_owned()
    });
    let diagnostics = diagnostics(&file.diagnostic)?;
    if let Some(n) = d
        .ethercat
        .as_ref()
        .and_then(|e| e.watchdog_diagnostic.as_deref())
    {
        diagnostic_row("[device.ethercat]", "watchdog_diagnostic", n, &diagnostics)?;
    }
    let brake = check_brake(d.brake.as_ref(), &objects)?;
    let plant = check_plant(d.plant.as_ref(), profile, &objects, &diagnostics)?;
    Ok(Device {
        name: d.name,
        product_name: d.product_name,
        vendor_name: d.vendor_name,
        vendor_id: d.vendor_id,
        product_code: d.product_code,
        revision: d.revision,
        order_code: d.order_code,
        description: d.description,
        profile,
        default_node_id: d.default_node_id,
        baud_rates: d.baud_rates,
        rotary_switches: d.rotary_switches,
        can_bit_rate,
        serial_bit_rate,
        serial_ports,
        interfaces,
        interfaces_one_of: d.interfaces_one_of,
        interfaces_rule,
        fieldbus_switches: d.fieldbus_switches,
        ethercat: d.ethercat,
        fhpp: d.fhpp,
        bus_faults: d
            .bus_faults
            .as_ref()
            .map(BusFaults::from)
            .unwrap_or_default(),
        brake,
        plant,
        cia301: od::Cia301Options {
            pdo_params_locked_while_valid: d.pdo_params_locked_while_valid,
            pdo_config_outside_operational: d.pdo_config_outside_operational,
            tpdo_transmit_mask_index: d.tpdo_transmit_mask_index,
            tpdo_254_cyclic_inhibit: d.tpdo_254_cyclic_inhibit,
            pdo_refuses_type_254: d.pdo_refuses_type_254,
            pdo_map_length_filled: d.pdo_map_length_filled,
            nmt_command_answered_with_state: d.nmt_command_answered_with_state,
            life_guard_emcy_code: d.life_guard_emcy_code,
            restore_writes_stored_set: d.restore_writes_stored_set,
            life_time_max_ms: d.life_time_max_ms,
            pdo_valid_without_mapping: d.pdo_valid_without_mapping,
            lss_unsupported: d.lss_unsupported,
            dummy_usage: None,
        },
        objects,
        diagnostics,
    })
}

/// The `[[diagnostic]]` rows, checked: a number once, a known reaction.
fn diagnostics(rows: &[DiagnosticSection]) -> Result<Vec<Diag>, DescError> {
    let mut out: Vec<Diag> = Vec::with_capacity(rows.len());
    for r in rows {
        let err = |what: &str| DescError::Diagnostic {
            number: r.number.clone(),
            what: what.into(),
        };
        if r.number.is_empty() || r.text.is_empty() {
            return Err(err("number and text must not be empty"));
        }
        if out.iter().any(|d| d.number.eq_ignore_ascii_case(&r.number)) {
            return Err(err("defined twice"));
        }
        let reaction = match r.reaction.as_str() {
            "ps_off" => od::Reaction::PsOff,
            "quick_stop" => od::Reaction::QuickStop,
            "configurable" => od::Reaction::Configurable,
            "warning" => od::Reaction::Warning,
            "ignore" => od::Reaction::Ignore,
            "unstated" => od::Reaction::Unstated,
            _ => return Err(err(
                "reaction must be ps_off, quick_stop, configurable, warning, ignore or unstated",
            )),
        };
        if !matches!(r.memory.as_str(), "" | "always" | "optional") {
            return Err(err("memory must be always or optional"));
        }
        if !matches!(r.ack.as_str(), "" | "immediately" | "after_cause" | "reset") {
            return Err(err("ack must be immediately, after_cause or reset"));
        }
        if !r.reactions.chars().all(|c| ('A'..='G').contains(&c)) {
            return Err(err("reactions are letters A…G"));
        }
        out.push(Diag {
            number: r.number.clone(),
            code: r.code,
            register: r.register,
            reaction,
            text: r.text.clone(),
            display: r.display.clone(),
            classes: r.classes.clone(),
            reactions: r.reactions.clone(),
            memory: r.memory.clone(),
            ack: r.ack.clone(),
            source: r.source.clone(),
        });
    }
    Ok(out)
}

fn object(o: &ObjectSection) -> Result<Obj, DescError> {
    let kind = match o.kind.as_deref().unwrap_or("var") {
        "var" => ObjectKind::Var,
        "array" => ObjectKind::Array,
        "record" => ObjectKind::Record,
        other => {
            return Err(DescError::Object {
                index: o.index,
                what: format!("unknown kind {other:?}"),
            })
        }
    };
    let mut entries = Vec::new();
    if kind == ObjectKind::Var {
        if !o.sub.is_empty() {
            return Err(DescError::Object {
                index: o.index,
                what: "a var has no [[object.sub]]; use kind = \"record\" or \"array\"".into(),
            });
        }
        entries.push(entry(o.index, 0, &o.name, &o.var_fields())?);
    } else {
        if o.data_type.is_some() || o.default.is_some() || o.access.is_some() {
            return Err(DescError::Object {
                index: o.index,
                what: "type/access/default belong to the [[object.sub]] entries".into(),
            });
        }
        for s in &o.sub {
            entries.push(entry(o.index, s.sub, &s.name, &s.fields())?);
        }
        entries.sort_by_key(|e| e.sub);
        for pair in entries.windows(2) {
            if let [a, b] = pair {
                if a.sub == b.sub {
                    return Err(DescError::Entry {
                        index: o.index,
                        sub: a.sub,
                        what: "defined twice".into(),
                    });
                }
            }
        }
        let highest = entries.last().map(|e| e.sub).unwrap_or(0);
        if entries.first().map(|e| e.sub) != Some(0) {
            entries.insert(
                0,
                Ent::plain(
                    o.index,
                    0,
                    "highest_sub_index_supported".into(),
                    DataType::Unsigned8,
                    Access::ReadOnly,
                    vec![highest],
                ),
            );
        } else if entries.len() == 1 {
            return Err(DescError::Object {
                index: o.index,
                what: "an array or record needs entries besides sub 0".into(),
            });
        }
    }
    let min_max = match o.min_max_subs {
        None => None,
        Some([lo, hi]) => {
            let numeric = |sub: u8| {
                entries
                    .iter()
                    .find(|e| e.sub == sub)
                    .map(|e| e.data_type.is_numeric())
            };
            if numeric(lo) != Some(true) || numeric(hi) != Some(true) || lo == hi {
                return Err(DescError::Object {
                    index: o.index,
                    what: format!("min_max_subs [{lo}, {hi}]: two numeric sub-indices"),
                });
            }
            Some((lo, hi))
        }
    };
    Ok(Obj {
        index: o.index,
        name: o.name.clone(),
        kind,
        min_max,
        entries,
    })
}

fn entry(index: u16, sub: u8, name: &str, f: &EntryFields) -> Result<Ent, DescError> {
    let err = |what: String| DescError::Entry { index, sub, what };
    let type_name = f
        .data_type
        .as_deref()
        .ok_or_else(|| err("missing type".into()))?;
    let data_type =
        DataType::from_name(type_name).ok_or_else(|| err(format!("unknown type {type_name:?}")))?;
    let access_name = f
        .access
        .as_deref()
        .ok_or_else(|| err("missing access".into()))?;
    let access = Access::from_name(access_name)
        .ok_or_else(|| err(format!("unknown access {access_name:?}")))?;
    let behaviour = match f.behaviour.as_deref().unwrap_or("plain") {
        "plain" => Behaviour::Plain,
        "store_signature" => Behaviour::StoreSignature,
        "restore_signature" => Behaviour::RestoreSignature,
        "error_history_count" => Behaviour::ErrorHistoryCount,
        "reads_zero" => Behaviour::ReadsZero,
        "pdo_cob_id" => Behaviour::PdoCobId,
        "pdo_transmission_type" => Behaviour::PdoTransmissionType,
        "pdo_inhibit_time" => Behaviour::PdoInhibitTime,
        "pdo_event_timer" => Behaviour::PdoEventTimer,
        "pdo_sync_start" => Behaviour::PdoSyncStart,
        "pdo_map_count" => Behaviour::PdoMapCount,
        "pdo_map_entry" => Behaviour::PdoMapEntry,
        other => return Err(err(format!("unknown behaviour {other:?}"))),
    };
    let capacity = match data_type.fixed_size() {
        Some(n) => {
            if f.size.is_some() {
                return Err(err("size is only for strings and domains".into()));
            }
            n as u32
        }
        None => f
            .size
            .filter(|s| (1..=65535).contains(s))
            .ok_or_else(|| err("strings and domains need size = 1…65535".into()))?,
    };
    let (default, default_plus_node_id) = match &f.default {
        None => (vec![0u8; data_type.fixed_size().unwrap_or(0)], false),
        Some(v) => encode_default(data_type, v).map_err(err)?,
    };
    if default.len() > capacity as usize {
        return Err(err(format!(
            "default is {} bytes, more than size {capacity}",
            default.len()
        )));
    }
    let min = f
        .min
        .as_ref()
        .map(|v| limit(data_type, v))
        .transpose()
        .map_err(err)?;
    let max = f
        .max
        .as_ref()
        .map(|v| limit(data_type, v))
        .transpose()
        .map_err(err)?;
    if let (Some(lo), Some(hi)) = (min, max) {
        if Value::from_limit(lo).compare(hi) == Some(std::cmp::Ordering::Greater) {
            return Err(err("min is above max".into()));
        }
    }
    if !default_plus_node_id {
        if let Some(v) = Value::decode(data_type, &default) {
            if min.is_some_and(|m| v.compare(m) == Some(std::cmp::Ordering::Less))
                || max.is_some_and(|m| v.compare(m) == Some(std::cmp::Ordering::Greater))
            {
                return Err(err(format!("default {v} is outside min/max")));
            }
        }
    }
    let allowed_bits = match f.allowed_bits {
        Some(_) if data_type.is_signed() || !data_type.is_numeric() || data_type.is_real() => {
            return Err(err("allowed_bits is for unsigned types".into()))
        }
        other => other,
    };
    let panel = f.panel.as_ref().map(|p| p.keys()).unwrap_or_default();
    if let Some(k) = panel.iter().find(|k| !is_panel_key(k)) {
        return Err(err(format!(
            "panel address {k:?} is none of d1.00…d7.99, EA0n, tn0n, F001…F007"
        )));
    }
    let modbus = f.modbus;
    if modbus.is_some() && !matches!(data_type.fixed_size(), Some(1 | 2 | 4)) {
        return Err(err(
            "a Modbus register holds an 8-, 16- or 32-bit value".into()
        ));
    }
    let storable = f.storable.unwrap_or(
        access.writable()
            && !matches!(
                behaviour,
                Behaviour::StoreSignature
                    | Behaviour::RestoreSignature
                    | Behaviour::ErrorHistoryCount
                    | Behaviour::ReadsZero
            ),
    );
    Ok(Ent {
        index,
        sub,
        name: name.to_string(),
        data_type,
        access,
        pdo: f.pdo.unwrap_or(false),
        default,
        default_plus_node_id,
        min,
        max,
        unit: f.unit.clone().unwrap_or_default(),
        behaviour,
        storable,
        kept_on_restore: f.kept_on_restore.unwrap_or(false),
        allowed_bits,
        capacity,
        panel,
        modbus,
    })
}

/// Whether `key` is a panel address of the manual's forms: `d1.25` (menu group 1…7, two
/// digits), `EA00`…`EA09`, `tn00`…`tn09`, `F001`…`F007`.
pub fn is_panel_key(key: &str) -> bool {
    let b = key.as_bytes();
    match b {
        [b'd', g, b'.', x, y] => {
            (b'1'..=b'7').contains(g) && x.is_ascii_digit() && y.is_ascii_digit()
        }
        [b'E', b'A', b'0', x] | [b't', b'n', b'0', x] => x.is_ascii_digit(),
        [b'F', b'0', b'0', x] => (b'1'..=b'7').contains(x),
        _ => false,
    }
}

/// A panel address or a Modbus register names one entry only.
fn unique_addresses(objects: &[Obj]) -> Result<(), DescError> {
    let mut panel = std::collections::BTreeMap::new();
    let mut modbus = std::collections::BTreeMap::new();
    for e in objects.iter().flat_map(|o| &o.entries) {
        for k in &e.panel {
            if let Some((i, s)) = panel.insert(k.clone(), (e.index, e.sub)) {
                return Err(DescError::Entry {
                    index: e.index,
                    sub: e.sub,
                    what: format!("panel address {k} is also {i:04X}h sub {s}"),
                });
            }
        }
        if let Some(r) = e.modbus {
            // A 32-bit value also takes register r + 1.
            let words = e.capacity.div_ceil(2).max(1) as u16;
            for w in 0..words {
                let reg = r.wrapping_add(w);
                if let Some((i, s)) = modbus.insert(reg, (e.index, e.sub)) {
                    return Err(DescError::Entry {
                        index: e.index,
                        sub: e.sub,
                        what: format!("Modbus register {reg:04X}h is also {i:04X}h sub {s}"),
                    });
                }
            }
        }
    }
    Ok(())
}

/// A TOML integer, or a string holding a hex/decimal number.
fn number(v: &toml::Value) -> Result<Value, String> {
    match v {
        toml::Value::Integer(i) => Ok(Value::Signed(*i)),
        toml::Value::Float(f) if f.is_finite() => Ok(Value::Real(*f)),
        toml::Value::Boolean(b) => Ok(Value::Bool(*b)),
        toml::Value::String(s) => {
            let t = s.trim();
            let parsed = if let Some(hex) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
                u64::from_str_radix(&hex.replace('_', ""), 16).ok()
            } else {
                t.parse::<u64>().ok()
            };
            parsed
                .map(Value::Unsigned)
                .ok_or_else(|| format!("{s:?} is not a number"))
        }
        other => Err(format!("{other} is not a number")),
    }
}

fn encode_default(t: DataType, v: &toml::Value) -> Result<(Vec<u8>, bool), String> {
    match t {
        DataType::VisibleString => match v {
            toml::Value::String(s) if s.is_ascii() => Ok((s.as_bytes().to_vec(), false)),
            _ => Err("a VISIBLE_STRING default is an ASCII string".into()),
        },
        DataType::OctetString | DataType::Domain => match v {
            toml::Value::String(s) => hex_bytes(s).map(|b| (b, false)),
            _ => Err("an OCTET_STRING/DOMAIN default is a hex string".into()),
        },
        _ => {
            let (v, plus_node) = match v {
                toml::Value::String(s) if s.trim().starts_with("$NODEID") => {
                    let rest = s.trim().trim_start_matches("$NODEID").trim();
                    let rest = rest.strip_prefix('+').unwrap_or(rest).trim();
                    let n = if rest.is_empty() {
                        Value::Unsigned(0)
                    } else {
                        number(&toml::Value::String(rest.to_string()))?
                    };
                    (n, true)
                }
                other => (number(other)?, false),
            };
            let mut buf = [0u8; 8];
            let n = v
                .encode(t, &mut buf)
                .ok_or_else(|| format!("default {v} does not fit {}", t.name()))?;
            let bytes = buf.get(..n).ok_or("default longer than 8 bytes")?;
            Ok((bytes.to_vec(), plus_node))
        }
    }
}

fn hex_bytes(s: &str) -> Result<Vec<u8>, String> {
    let s: String = s.chars().filter(|c| !c.is_whitespace()).collect();
    if !s.len().is_multiple_of(2) {
        return Err("odd number of hex digits".into());
    }
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).map_err(|e| e.to_string()))
        .collect()
}

fn limit(t: DataType, v: &toml::Value) -> Result<Limit, String> {
    if !t.is_numeric() {
        return Err("limits are only for numeric types".into());
    }
    let value = number(v)?;
    let mut buf = [0u8; 8];
    value
        .encode(t, &mut buf)
        .ok_or_else(|| format!("limit {value} does not fit {}", t.name()))?;
    Ok(match value {
        Value::Real(r) => Limit::Real(r),
        Value::Signed(s) if s < 0 => Limit::Signed(s),
        Value::Signed(s) => Limit::Unsigned(s as u64),
        Value::Unsigned(u) => Limit::Unsigned(u),
        Value::Bool(b) => Limit::Unsigned(b as u64),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEAD: &str =
        "[device]\nname = \"t\"\nproduct_name = \"p\"\nvendor_name = \"v\"\nvendor_id = 1\nprofile = \"plain\"\n";

    fn err(objects: &str) -> String {
        match parse(&format!("{HEAD}{objects}"), "t.toml") {
            Ok(_) => panic!("accepted: {objects}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn diagnostic_rows_are_checked() {
        let row = |n: &str, r: &str| {
            format!("[[diagnostic]]\nnumber = \"{n}\"\ncode = 0x4310\nreaction = \"{r}\"\ntext = \"x\"\n")
        };
        let d = parse(&format!("{HEAD}{}", row("03-0", "quick_stop")), "t.toml").expect("valid");
        assert_eq!(d.diagnostics.len(), 1);
        assert_eq!(d.diagnostics[0].reaction, od::Reaction::QuickStop);
        assert!(err(&(row("03-0", "ps_off") + &row("03-0", "ps_off"))).contains("defined twice"));
        assert!(err(&row("03-0", "stop")).contains("reaction must be"));
        assert!(err(&format!(
            "{}reactions = \"AZ\"\n",
            row("2Fh", "configurable")
        ))
        .contains("A…G"));
    }

    #[test]
    fn bus_fault_reactions_are_read_and_checked() {
        use od::BusFaultReaction::{Fault, Repeat};
        let section = |on_bus_off: &str| {
            format!(
                "[device.bus_faults]\non_passive = []\non_active = []\non_bus_off = [{on_bus_off}]\non_recovered = [\"repeat 0x8120\"]\n"
            )
        };
        let d = parse(&format!("{HEAD}{}", section("\"fault 0x8120\"")), "t.toml").expect("valid");
        assert_eq!(d.bus_faults.on_passive, []);
        assert_eq!(d.bus_faults.on_bus_off, [Fault(0x8120)]);
        assert_eq!(d.bus_faults.on_recovered, [Repeat(0x8120)]);
        // Without a section: CiA 301's usage.
        let plain = parse(HEAD, "t.toml").expect("valid");
        assert_eq!(plain.bus_faults, BusFaults::default());
        assert_eq!(
            plain.bus_faults.on_passive,
            od::BusFaultReactions::CIA_301.on_passive
        );
        // Refused with the file, the line and the key.
        let refused = |text: String| match parse(&text, "t.toml") {
            Ok(_) => panic!("accepted: {text}"),
            Err(e) => e.to_string(),
        };
        for bad in [
            "\"halt 0x8120\"",
            "\"raise 8120\"",
            "\"raise\"",
            "\"raise 0x0\"",
            "\"raise 0x18120\"",
        ] {
            let e = refused(format!("{HEAD}{}", section(bad)));
            assert!(e.starts_with("t.toml: "), "{e}");
            assert!(e.contains("line 10") && e.contains("on_bus_off"), "{e}");
            assert!(
                e.contains("a reaction is `raise`, `clear`, `fault` or `repeat`"),
                "{e}"
            );
        }
        let e = refused(format!("{HEAD}{}on_reset = []\n", section("")));
        assert!(e.contains("unknown field `on_reset`"), "{e}");
        let e = refused(format!(
            "{HEAD}[device.bus_faults]\non_passive = []\non_active = []\non_bus_off = []\n"
        ));
        assert!(e.contains("missing field `on_recovered`"), "{e}");
    }

    #[test]
    fn node_relative_defaults_and_generated_sub_zero() {
        let d = parse(
            &format!(
                "{HEAD}[[object]]\nindex = 0x1800\nname = \"tpdo\"\nkind = \"record\"\n[[object.sub]]\nsub = 1\nname = \"cob\"\ntype = \"UNSIGNED32\"\naccess = \"rw\"\ndefault = \"$NODEID+0xC0000180\"\n"
            ),
            "t.toml",
        )
        .unwrap();
        let o = &d.objects[0];
        assert_eq!(o.entries.len(), 2);
        assert_eq!(o.entries[0].default, vec![1]);
        assert_eq!(o.entries[1].default, 0xC000_0180u32.to_le_bytes().to_vec());
        assert!(o.entries[1].default_plus_node_id);
    }

    /// A personality that says "plain" but whose 1000h names CiA 402 (or the other way round)
    /// is refused: the twin would build the wrong model behind it.
    #[test]
    fn the_profile_must_agree_with_the_device_type() {
        let device_type = "[[object]]\nindex = 0x1000\nname = \"device_type\"\ntype = \"UNSIGNED32\"\naccess = \"ro\"\ndefault = 0x00020192\n";
        assert!(err(device_type).contains("does not agree with the device type"));
        let cia402 = HEAD.replace("\"plain\"", "\"cia402\"");
        assert!(parse(&format!("{cia402}{device_type}"), "t.toml").is_ok());
        assert!(parse(&cia402, "t.toml").is_err(), "CiA 402 without 1000h");
        // Nanotec §9.6: 1000h = 00000008h; the file says its 1000h carries no profile.
        let nanotec = cia402.replace(
            "profile = \"cia402\"\n",
            "profile = \"cia402\"\ndevice_type_carries_profile = false\n",
        );
        let stepper = device_type.replace("0x00020192", "0x00000008");
        assert!(parse(&format!("{nanotec}{stepper}"), "t.toml").is_ok());
        assert!(parse(&format!("{cia402}{stepper}"), "t.toml").is_err());
    }

    #[test]
    fn allowed_bits_and_min_max_subs_are_checked() {
        let var = |t: &str| {
            format!("[[object]]\nindex = 0x2000\nname = \"x\"\ntype = \"{t}\"\naccess = \"rw\"\nallowed_bits = 0xC0\n")
        };
        assert!(parse(&format!("{HEAD}{}", var("UNSIGNED8")), "t.toml").is_ok());
        assert!(err(&var("INTEGER8")).contains("unsigned"));
        let rec = |subs: &str| {
            format!("[[object]]\nindex = 0x2001\nname = \"r\"\nkind = \"record\"\nmin_max_subs = {subs}\n[[object.sub]]\nsub = 1\nname = \"lo\"\ntype = \"UNSIGNED32\"\naccess = \"rw\"\n[[object.sub]]\nsub = 2\nname = \"hi\"\ntype = \"UNSIGNED32\"\naccess = \"rw\"\n")
        };
        let d = parse(&format!("{HEAD}{}", rec("[1, 2]")), "t.toml").unwrap();
        assert_eq!(d.objects[0].min_max, Some((1, 2)));
        assert!(err(&rec("[1, 3]")).contains("min_max_subs"));
    }

    #[test]
    fn kept_on_restore_is_carried_to_the_entry() {
        let d = parse(
            &format!("{HEAD}[[object]]\nindex = 0x2005\nname = \"baud\"\ntype = \"UNSIGNED8\"\naccess = \"rw\"\nkept_on_restore = true\n"),
            "t.toml",
        )
        .unwrap();
        assert!(d.objects[0].entries[0].kept_on_restore);
        assert!(d.objects[0].entries[0].storable, "still saved by 1010h");
    }

    /// Kinco ch. 9: an object may have several panel addresses; an address and a Modbus
    /// register (a 32-bit value takes two) name one entry only.
    #[test]
    fn panel_addresses_and_modbus_registers_are_checked() {
        let var = |index: u16, t: &str, extra: &str| {
            format!("[[object]]\nindex = 0x{index:04X}\nname = \"x\"\ntype = \"{t}\"\naccess = \"rw\"\n{extra}\n")
        };
        let d = parse(
            &format!(
                "{HEAD}{}{}",
                var(0x2FF0, "UNSIGNED8", "panel = [\"d2.00\", \"d3.00\"]"),
                var(0x60FF, "INTEGER32", "panel = \"tn01\"\nmodbus = 0x6F00")
            ),
            "t.toml",
        )
        .unwrap();
        assert_eq!(d.objects[0].entries[0].panel, ["d2.00", "d3.00"]);
        assert_eq!(d.objects[1].entries[0].modbus, Some(0x6F00));
        assert!(err(&var(0x2000, "UNSIGNED8", "panel = \"d9.01\"")).contains("panel address"));
        assert!(err(&var(0x2000, "VISIBLE_STRING", "size = 4\nmodbus = 1")).contains("Modbus"));
        let twice = format!(
            "{}{}",
            var(0x2000, "UNSIGNED8", "panel = \"d3.01\""),
            var(0x2001, "UNSIGNED8", "panel = \"d3.01\"")
        );
        assert!(err(&twice).contains("d3.01 is also 2000h"));
        let overlap = format!(
            "{}{}",
            var(0x2000, "UNSIGNED32", "modbus = 0x3100"),
            var(0x2001, "UNSIGNED16", "modbus = 0x3101")
        );
        assert!(err(&overlap).contains("3101h is also 2000h"));
    }

    #[test]
    fn mistakes_are_named() {
        let var = |extra: &str| format!("[[object]]\nindex = 0x2000\nname = \"x\"\n{extra}\n");
        assert!(err(&var("type = \"UNSIGNED8\"")).contains("missing access"));
        assert!(err(&var("type = \"UINT8\"\naccess = \"rw\"")).contains("unknown type"));
        assert!(
            err(&var("type = \"UNSIGNED8\"\naccess = \"rw\"\ndefault = 300"))
                .contains("does not fit")
        );
        assert!(err(&var(
            "type = \"UNSIGNED8\"\naccess = \"rw\"\ndefault = 5\nmax = 4"
        ))
        .contains("outside"));
        assert!(err(&var(
            "type = \"UNSIGNED8\"\naccess = \"rw\"\nmin = 5\nmax = 4"
        ))
        .contains("min is above max"));
        assert!(err(&var("type = \"VISIBLE_STRING\"\naccess = \"rw\"")).contains("need size"));
        assert!(err(&var("type = \"UNSIGNED8\"\naccess = \"rw\"\nbogus = 1")).contains("bogus"));
        let twice = format!(
            "{}{}",
            var("type = \"UNSIGNED8\"\naccess = \"rw\""),
            var("type = \"UNSIGNED8\"\naccess = \"rw\"")
        );
        assert!(err(&twice).contains("defined twice"));
    }

    /// An EtherCAT slave's SII and CoE data come with its `ethercat` interface, and PDO
    /// assignments name mapping objects of their direction.
    #[test]
    fn an_ethercat_interface_comes_with_its_section() {
        let section = "[device.ethercat]\ngroup_type = \"g\"\ngroup_name = \"n\"\npdi_control = 5\nmailbox_out = [0x1000, 0x80]\nmailbox_in = [0x1080, 0x80]\noutputs_start = 0x1100\ninputs_start = 0x1180\nrx_assigned = [0x1600]\ntx_assigned = [0x1A00]\nds402_channels = 1\nphysical_ports = 0x11\ncomplete_access = false\nsdo_info = true\nversion = 1\n";
        let with = |interfaces: &str, section: &str| {
            format!("{HEAD}interfaces = [{interfaces}]\n{section}")
        };
        let d = parse(&with("\"ethercat\"", section), "t.toml").expect("valid");
        let e = d.ethercat.expect("section");
        assert!(!d.fieldbus_switches);
        assert_eq!(
            (e.mailbox_in, e.rx_assigned),
            ([0x1080, 0x80], vec![0x1600])
        );
        let go_together = "go together";
        let alone = parse(&with("\"ethercat\"", ""), "t.toml").unwrap_err();
        assert!(alone.to_string().contains(go_together), "{alone}");
        let stray = parse(&with("\"canopen\"", section), "t.toml").unwrap_err();
        assert!(stray.to_string().contains(go_together), "{stray}");
        let crossed = section.replace("rx_assigned = [0x1600]", "rx_assigned = [0x1A00]");
        let crossed = parse(&with("\"ethercat\"", &crossed), "t.toml").unwrap_err();
        assert!(crossed.to_string().contains("1A00h"), "{crossed}");
        // The watchdog's message is a row of the file's diagnostic table.
        let watchdog = format!("{section}watchdog_diagnostic = \"62-5\"\n");
        let row = "[[diagnostic]]\nnumber = \"62-5\"\nreaction = \"configurable\"\ntext = \"x\"\n";
        assert!(parse(&with("\"ethercat\"", &format!("{watchdog}{row}")), "t.toml").is_ok());
        let missing = parse(&with("\"ethercat\"", &watchdog), "t.toml").unwrap_err();
        assert!(
            missing.to_string().contains(
                "[device.ethercat] watchdog_diagnostic: message \"62-5\" is no [[diagnostic]] row"
            ),
            "{missing}"
        );
    }

    /// `serial_bit_rate` names UNSIGNED16 objects of the file whose defaults are codes of
    /// its table, each code and each bit rate once.
    #[test]
    fn the_serial_bit_rate_table_is_checked() {
        let object = |index: u16, t: &str, default: u32| {
            format!("[[object]]\nindex = 0x{index:04X}\nname = \"b{index:X}\"\ntype = \"{t}\"\naccess = \"rw\"\ndefault = {default}\n")
        };
        let file =
            |table: &str, objects: &str| format!("{HEAD}serial_bit_rate = {table}\n{objects}");
        let table =
            |objects: &str, codes: &str| format!("{{ objects = [{objects}], codes = [{codes}] }}");
        let two = object(0x2FE0, "UNSIGNED16", 270) + &object(0x2FE2, "UNSIGNED16", 540);
        let codes = "[540, 19200], [270, 38400]";
        let d = parse(&file(&table("0x2FE0, 0x2FE2", codes), &two), "t.toml").expect("valid");
        let s = d.serial_bit_rate.expect("table");
        assert_eq!(s.objects, [0x2FE0, 0x2FE2]);
        assert_eq!(s.codes, [(540, 19200), (270, 38400)]);
        let refused = |table: &str, objects: &str| match parse(&file(table, objects), "t.toml") {
            Ok(_) => panic!("accepted: {table}"),
            Err(e) => e.to_string(),
        };
        assert!(
            refused(&table("0x2FE0, 0x2FE1", codes), &two).contains("2FE1h sub 0 is no UNSIGNED16")
        );
        let narrow = object(0x2FE0, "UNSIGNED8", 27);
        assert!(refused(&table("0x2FE0", "[27, 38400]"), &narrow).contains("no UNSIGNED16"));
        assert!(refused(&table("0x2FE0, 0x2FE0", codes), &two).contains("listed twice"));
        assert!(
            refused(&table("0x2FE0", "[270, 38400], [270, 19200]"), &two)
                .contains("code 270 listed twice")
        );
        assert!(
            refused(&table("0x2FE0", "[270, 38400], [271, 38400]"), &two)
                .contains("38400 bit/s listed twice")
        );
        assert!(refused(&table("0x2FE0", "[270, 0]"), &two).contains("0 bit/s"));
        assert!(refused(&table("0x2FE0", "[70000, 9600]"), &two).contains("no UNSIGNED16"));
        assert!(refused(&table("0x2FE2", "[270, 38400]"), &two).contains("default 540 is no code"));
        assert!(refused(&table("", codes), &two).contains("no objects"));
        assert!(refused(&table("0x2FE0", ""), &two).contains("no codes"));
    }

    /// `[device.serial_ports]`: a table for each serial interface, its bit-rate objects those
    /// of `serial_bit_rate`, its loop-enable and protocol objects integer entries; a bad entry
    /// is refused with the file, the table and the key.
    #[test]
    fn the_serial_ports_are_checked() {
        let object = |index: u16, sub: u8, t: &str, default: u32| {
            format!("[[object]]\nindex = 0x{index:04X}\nname = \"o{index:X}_{sub}\"\nkind = \"record\"\n[[object.sub]]\nsub = {sub}\nname = \"s{sub}\"\ntype = \"{t}\"\naccess = \"rw\"\ndefault = {default}\n")
        };
        let rate = |index: u16, default: u32| {
            format!("[[object]]\nindex = 0x{index:04X}\nname = \"b{index:X}\"\ntype = \"UNSIGNED16\"\naccess = \"rw\"\ndefault = {default}\n")
        };
        let objects = rate(0x2FE0, 270)
            + &rate(0x2FE1, 270)
            + &rate(0x2FE2, 540)
            + &object(0x6510, 0x0B, "UNSIGNED8", 0)
            + &object(0x6511, 0x0C, "UNSIGNED8", 0)
            + &object(0x6512, 0x01, "REAL32", 0);
        let file = |interfaces: &str, ports: &str| {
            format!(
                "{HEAD}serial_bit_rate = {{ objects = [0x2FE0, 0x2FE1, 0x2FE2], codes = [[540, 19200], [270, 38400]] }}\ninterfaces = [{interfaces}]\n{ports}{objects}"
            )
        };
        let rs232 = "[device.serial_ports.rs232]\nbit_rate = 0x2FE0\nbit_rate_now = 0x2FE1\nloop_enable = [0x6510, 0x0B]\n";
        let rs485 = |protocol: &str| {
            format!("[device.serial_ports.rs485]\nbit_rate = 0x2FE2\nprotocol = {{ object = {protocol} }}\n")
        };
        let good = rs485("[0x6511, 0x0C], modbus_rtu = 0, telegrams = 1");
        let d = parse(
            &file("\"rs232\", \"rs485\"", &(rs232.to_owned() + &good)),
            "t.toml",
        )
        .expect("valid");
        let names: Vec<&str> = d.serial_ports.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["rs232", "rs485"]);
        let leaked = crate::runtime::leak(&d);
        let port = od::SerialPort::find(leaked.serial_ports, "rs485").expect("rs485");
        assert_eq!(port.bit_rate, 0x2FE2);
        assert_eq!(port.protocol.map(|p| p.object), Some((0x6511, 0x0C)));
        let refused =
            |interfaces: &str, ports: &str| match parse(&file(interfaces, ports), "ports.toml") {
                Ok(_) => panic!("accepted: {ports}"),
                Err(e) => e.to_string(),
            };
        let e = refused("\"rs232\", \"rs485\"", rs232);
        assert!(
            e.starts_with("ports.toml: device: interfaces lists \"rs485\""),
            "{e}"
        );
        let e = refused("\"rs485\"", &(rs232.to_owned() + &good));
        assert!(
            e.contains("[device.serial_ports] rs232: the device has no \"rs232\" interface"),
            "{e}"
        );
        let e = refused(
            "\"rs232\"",
            &rs232.replace("bit_rate = 0x2FE0", "bit_rate = 0x6510"),
        );
        assert!(
            e.starts_with("ports.toml: device: [device.serial_ports] rs232.bit_rate: object 6510h is no object of serial_bit_rate"),
            "{e}"
        );
        let e = refused(
            "\"rs232\"",
            &rs232.replace("bit_rate_now = 0x2FE1", "bit_rate_now = 0x2FE5"),
        );
        assert!(e.contains("rs232.bit_rate_now: object 2FE5h"), "{e}");
        let e = refused(
            "\"rs232\"",
            &rs232.replace("[0x6510, 0x0B]", "[0x6510, 0x0C]"),
        );
        assert!(
            e.contains("rs232.loop_enable: object 6510h sub 0Ch is not in this file"),
            "{e}"
        );
        let e = refused(
            "\"rs485\"",
            &rs485("[0x6512, 0x01], modbus_rtu = 0, telegrams = 1"),
        );
        assert!(
            e.contains("rs485.protocol: object 6512h sub 01h is REAL32, no integer"),
            "{e}"
        );
        let e = refused(
            "\"rs485\"",
            &rs485("[0x6511, 0x0C], modbus_rtu = 1, telegrams = 1"),
        );
        assert!(e.contains("modbus_rtu and telegrams are both 1"), "{e}");
        let e = refused(
            "\"rs485\"",
            &rs485("[0x6511, 0x0C], modbus_rtu = 2, telegrams = 1"),
        );
        assert!(e.contains("neither modbus_rtu nor telegrams"), "{e}");
        let e = refused(
            "\"rs485\"",
            &good.replace("bit_rate = 0x2FE2", "bitrate = 0x2FE2"),
        );
        assert!(e.contains("unknown field `bitrate`"), "{e}");
    }

    /// `[device.brake]` and `[device.plant]` name integer entries of the file and rows of its
    /// diagnostic table; a broken entry is refused with the file, the table and the key.
    #[test]
    fn brake_and_plant_name_objects_and_messages_of_the_file() {
        let objects = "[[object]]\nindex = 0x2007\nname = \"brake\"\nkind = \"record\"\n[[object.sub]]\nsub = 1\nname = \"on\"\ntype = \"UNSIGNED16\"\naccess = \"rw\"\n[[object.sub]]\nsub = 2\nname = \"temperature\"\ntype = \"INTEGER16\"\naccess = \"ro\"\n[[object.sub]]\nsub = 3\nname = \"factor\"\ntype = \"REAL32\"\naccess = \"rw\"\n[[object]]\nindex = 0x2008\nname = \"label\"\ntype = \"VISIBLE_STRING\"\naccess = \"ro\"\nsize = 4\n[[diagnostic]]\nnumber = \"04-0\"\nreaction = \"ps_off\"\ntext = \"x\"\n";
        let file = |tables: &str| format!("{HEAD}{tables}{objects}");
        let brake = "[device.brake]\nrelease = [[0x2007, 1]]\nmotion = [[0x2007, 1], [0x2007, 2]]\nonly_with_brake = true\n";
        let plant = "[device.plant]\nstage_over = \"04-0\"\nstage_limit = [0x2007, 1]\nstage_temperature = [0x2007, 2]\n";
        let d = parse(&file(&format!("{brake}{plant}")), "t.toml").expect("valid");
        assert_eq!(d.brake.release, [(0x2007, 1)]);
        assert_eq!(d.brake.motion, [(0x2007, 1), (0x2007, 2)]);
        assert!(d.brake.engage.is_empty() && d.brake.only_with_brake);
        assert_eq!(d.plant.stage_over.as_deref(), Some("04-0"));
        assert_eq!(d.plant.motor_over, None);
        assert_eq!(d.plant.stage_temperature, Some((0x2007, 2)));
        // The generated description carries them, as the run-time one does.
        let source = crate::codegen::generate(&d);
        assert!(source.contains(
            "brake: od::BrakeTiming { release: &[(0x2007, 0x01)], motion: &[(0x2007, 0x01), (0x2007, 0x02)], engage: &[], only_with_brake: true },"
        ), "{source}");
        assert!(source.contains("stage_over: Some(\"04-0\")"), "{source}");
        let leaked = crate::runtime::leak(&d);
        assert_eq!(leaked.brake.motion, [(0x2007, 1), (0x2007, 2)]);
        assert_eq!(leaked.plant.stage_limit, Some((0x2007, 1)));
        // Without the tables: no delay, no message, no object.
        let none = parse(&file(""), "t.toml").expect("valid");
        let leaked = crate::runtime::leak(&none);
        assert_eq!(
            (leaked.brake, leaked.plant),
            (od::BrakeTiming::NONE, od::PlantSupervision::NONE)
        );
        let refused = |tables: &str| match parse(&file(tables), "t.toml") {
            Ok(_) => panic!("accepted: {tables}"),
            Err(e) => e.to_string(),
        };
        for (tables, says) in [
            (
                "[device.brake]\nengage = [[0x2007, 4]]\n",
                "t.toml: device: [device.brake] engage: object 2007h sub 04h is not in this file",
            ),
            (
                "[device.brake]\nmotion = [[0x2007, 3]]\n",
                "t.toml: device: [device.brake] motion: object 2007h sub 03h is REAL32, no integer",
            ),
            (
                "[device.brake]\nrelease = [[0x2008, 0]]\n",
                "t.toml: device: [device.brake] release: object 2008h sub 00h is VISIBLE_STRING, no integer",
            ),
            (
                "[device.brake]\nmotion = [[0x2007, 1], [0x2007, 1]]\n",
                "t.toml: device: [device.brake] motion: object 2007h sub 01h listed twice",
            ),
            (
                "[device.plant]\nmotor_over = \"03-0\"\n",
                "t.toml: device: [device.plant] motor_over: message \"03-0\" is no [[diagnostic]] row of this file",
            ),
            (
                "[device.plant]\nmotor_limit = [0x6510, 0x2F]\n",
                "t.toml: device: [device.plant] motor_limit: object 6510h sub 2Fh is not in this file",
            ),
            (
                "[device.plant]\nmotor_temperature = [0x2007, 1]\n",
                "t.toml: device: [device.plant] motor_temperature: object 2007h sub 01h is UNSIGNED16, no signed integer",
            ),
            (
                "[device.plant]\nstage_under = \"04-0\"\n",
                "t.toml: device: [device.plant] stage_under: the Plain profile's supervision has no such condition",
            ),
            (
                "[device.plant]\nstage_low_limit = [0x2007, 2]\n",
                "t.toml: device: [device.plant] stage_low_limit: the Plain profile's supervision has no such condition",
            ),
        ] {
            assert_eq!(refused(tables), says);
        }
        // The parser's own refusals name the file, the line and the key.
        let e = refused("[device.brake]\nmotion = [[0x2007, 300]]\n");
        assert!(e.starts_with("t.toml: TOML parse error at line 8"), "{e}");
        let e = refused("[device.plant]\nstage_over = \"04-0\"\nmotor_limits = [0x2007, 1]\n");
        assert!(e.contains("unknown field `motor_limits`"), "{e}");
    }

    /// `[device.fhpp]` goes with the FHPP profile and names writable parameters in order,
    /// and no more records than the record list (PNU 401) has subindices.
    #[test]
    fn the_fhpp_section_names_parameters_of_an_fhpp_device() {
        let fhpp_head = HEAD.replace("profile = \"plain\"", "profile = \"fhpp\"");
        let param = |pnu: u16, access: &str, subs: u8| {
            let mut o = format!(
                "[[object]]\nindex = 0x{:04X}\nname = \"p{pnu}\"\nkind = \"array\"\n",
                0x2000 + pnu
            );
            for sub in 1..=subs {
                o += &format!("[[object.sub]]\nsub = {sub}\nname = \"s{sub}\"\ntype = \"UNSIGNED8\"\naccess = \"{access}\"\n");
            }
            o
        };
        let objects = param(127, "rw", 1) + &param(128, "ro", 1) + &param(401, "rw", 4);
        let file = |head: &str, section: &str| format!("{head}{section}{objects}");
        let section = |records: u8, pnus: &str| {
            format!("[device.fhpp]\nrecords = {records}\nstage_off_pnus = [{pnus}]\n")
        };
        let d = parse(&file(&fhpp_head, &section(4, "127")), "t.toml").expect("valid");
        let f = d.fhpp.expect("section");
        assert_eq!((f.records, f.stage_off_pnus), (4, vec![127]));
        let refused = |head: &str, section: &str| match parse(&file(head, section), "t.toml") {
            Ok(_) => panic!("accepted: {section}"),
            Err(e) => e.to_string(),
        };
        assert!(refused(&fhpp_head, "").contains("needs a [device.fhpp]"));
        assert!(refused(HEAD, &section(4, "127")).contains("profile \"fhpp\""));
        assert!(refused(&fhpp_head, &section(4, "128")).contains("PNU 128 is no writable"));
        assert!(refused(&fhpp_head, &section(4, "129")).contains("PNU 129 is no writable"));
        assert!(refused(&fhpp_head, &section(4, "127, 127")).contains("out of order"));
        assert!(refused(&fhpp_head, &section(5, "127")).contains("subindices 1…4"));
        assert!(refused(&fhpp_head, &section(0, "127")).contains("records = 0"));
    }
}
