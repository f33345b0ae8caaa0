//! A drive's parameter set as the console's parameter table shows it, and as a file: every
//! entry with its group, unit, range, default and whether the value differs from the default;
//! exported as a CiA 306 device configuration file (DCF: the device's EDS with
//! `[DeviceComissioning]` and one `ParameterValue` per entry) and imported from one.
//!
//! Decision: the DCF is the file of every drive. The manuals name their tools' own files (the
//! CMMP-AS's FCT project and DCO file, the Kinco's `.cdi` value list, the CMMO-ST's parameter
//! file) but give no layout that could be written from their text (the CMMO-ST's "header +
//! data area + CRC", its figure missing); `docs/decisions.md` says so.
//!
//! An import is all or nothing: every value is checked first (entry known, writable, of its
//! type, within its range and allowed bits: the checks of an SDO download, CiA 301
//! §7.2.4.3.17), and only a set without refusal is written, through the same path an SDO
//! download takes; should the drive still refuse a write (a state it is in), what was written
//! is written back.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use axum::extract::{Path, State};
use axum::http::header::{CONTENT_DISPOSITION, CONTENT_TYPE};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use devdesc::eds::ini::Ini;
use devdesc::eds::number;
use od::{AbortCode, DataType, DeviceDescription, Entry, Limit, ObjectKind, Value};
use serde::Serialize;
use utoipa::{OpenApi, ToSchema};

use super::api::{call, find_drive, ApiError};
use super::AppState;
use crate::cell::control::{ControlHandle, DriveInfo, Interface};
use crate::value_text;

type ApiResult<T> = Result<Json<T>, ApiError>;

/// The controlword is a command, not a parameter: an import never writes it (CiA 402 §8.4.1),
/// whatever its device file says of storing it.
const CONTROLWORD: u16 = 0x6040;

/// Which part of the dictionary an entry is in: the parameter groups of store and restore
/// (1010h / 1011h sub 2–4, CiA 301 §7.5.2.13).
pub fn group(index: u16) -> &'static str {
    match index {
        0x1000..=0x1FFF => "communication",
        0x2000..=0x5FFF => "manufacturer",
        0x6000..=0x9FFF => "profile",
        _ => "other",
    }
}

/// One entry of the parameter table.
#[derive(Debug, Serialize, ToSchema)]
pub struct ParameterView {
    /// `0x6040`.
    pub index: String,
    pub sub: u8,
    pub name: String,
    /// The object's name (the record's, for a sub-index of a record).
    pub object: String,
    /// `communication` (1000h–1FFFh), `manufacturer` (2000h–5FFFh), `profile` (6000h–9FFFh).
    pub group: String,
    /// CiA 301 type name.
    #[serde(rename = "type")]
    pub data_type: String,
    /// `ro`, `wo`, `rw`, `const`.
    pub access: String,
    pub unit: String,
    #[schema(value_type = Option<f64>)]
    pub min: Option<serde_json::Value>,
    #[schema(value_type = Option<f64>)]
    pub max: Option<serde_json::Value>,
    /// The default of the device file, as text (with the node-ID added where the file says
    /// `$NODEID+…`); `null` where the file gives none.
    pub default: Option<String>,
    /// The value as text; `null` when not readable.
    pub value: Option<String>,
    /// Whether the value of a writable entry differs from the default; `null` when either is
    /// unknown or the entry is read-only.
    pub differs: Option<bool>,
    /// Saved by 1010h, and written by an import.
    pub parameter: bool,
    /// Why the value could not be read.
    pub read_error: Option<String>,
}

/// The dictionary the drive serves on its interface (an EDS drive on EtherCAT: its slave's).
fn description(info: &DriveInfo) -> Result<&'static DeviceDescription, ApiError> {
    let ethercat_only = matches!(info.interface, Interface::Ethercat { .. });
    crate::cell::eds_drive::served(info.device, ethercat_only)
        .ok_or_else(|| ApiError::not_found(format!("no device description {:?}", info.device)))
}

fn node_of(info: &DriveInfo) -> Option<u8> {
    match info.interface {
        Interface::CanOpen { node } => Some(node),
        _ => None,
    }
}

fn limit_json(l: Option<Limit>) -> Option<serde_json::Value> {
    Some(match l? {
        Limit::Signed(v) => v.into(),
        Limit::Unsigned(v) => v.into(),
        Limit::Real(v) => serde_json::Number::from_f64(v)?.into(),
    })
}

/// The bytes the entry holds after a reset to its default, `None` where the file gives none.
pub fn default_bytes(e: &Entry, node: Option<u8>) -> Option<Vec<u8>> {
    if e.default.is_empty() && e.data_type.fixed_size().is_some() {
        return None;
    }
    if !e.default_plus_node_id {
        return Some(e.default.to_vec());
    }
    let base = match Value::decode(e.data_type, e.default)? {
        Value::Unsigned(u) => u,
        _ => return Some(e.default.to_vec()),
    };
    let mut b = [0u8; 8];
    let n = Value::Unsigned(base + u64::from(node.unwrap_or(0))).encode(e.data_type, &mut b)?;
    b.get(..n).map(<[u8]>::to_vec)
}

/// Whether an import writes the entry: it is saved by 1010h (the parameter set) and is not a
/// command.
pub fn is_parameter(e: &Entry) -> bool {
    e.storable && e.access.writable() && e.index != CONTROLWORD
}

fn parameter_view(
    e: &Entry,
    desc: &DeviceDescription,
    node: Option<u8>,
    read: Option<Result<Vec<u8>, ApiError>>,
) -> ParameterView {
    let default = default_bytes(e, node);
    let (value, read_error) = match &read {
        Some(Ok(bytes)) => (Some(bytes.clone()), None),
        Some(Err(err)) => (None, Some(err.error.clone())),
        None => (None, None),
    };
    ParameterView {
        index: format!("0x{:04X}", e.index),
        sub: e.sub,
        name: e.name.to_owned(),
        object: desc.object(e.index).map_or(e.name, |o| o.name).to_owned(),
        group: group(e.index).to_owned(),
        data_type: e.data_type.name().to_owned(),
        access: e.access.eds_name().to_ascii_lowercase(),
        unit: e.unit.to_owned(),
        min: limit_json(e.min),
        max: limit_json(e.max),
        default: default
            .as_deref()
            .and_then(|d| value_text::decode(e.data_type, d)),
        // A read-only entry's value is the drive's state, not a setting: no mark.
        differs: match (&value, &default) {
            (Some(v), Some(d)) if e.access.writable() => Some(v != d),
            _ => None,
        },
        value: value
            .as_deref()
            .and_then(|v| value_text::decode(e.data_type, v)),
        parameter: is_parameter(e),
        read_error,
    }
}

/// Every entry of the drive's dictionary with its default, its value and whether they differ.
#[utoipa::path(get, path = "/api/drives/{drive}/parameters", tag = "parameters",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = [ParameterView]), (status = 404, body = ApiError), (status = 400, body = ApiError)))]
async fn list(
    State(s): State<AppState>,
    Path(drive): Path<String>,
) -> ApiResult<Vec<ParameterView>> {
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        let desc = description(&info)?;
        let node = node_of(&info);
        Ok(desc
            .entries()
            .map(|e| {
                let read = e
                    .access
                    .readable()
                    .then(|| h.read(info.index, e.index, e.sub).map_err(ApiError::from));
                parameter_view(e, desc, node, read)
            })
            .collect())
    })
    .await
    .map(Json)
}

// ---------------------------------------------------------------------------------- export

/// A value as CiA 306 §4.6.3 writes it: unsigned in hex, signed in decimal, REAL as a decimal
/// number, VISIBLE_STRING as it is, OCTET_STRING in hex digits.
pub fn value_literal(t: DataType, bytes: &[u8]) -> Option<String> {
    match t {
        DataType::VisibleString => {
            let text = String::from_utf8_lossy(bytes);
            // A line of the file: no line break in it.
            Some(text.replace(['\r', '\n'], " "))
        }
        DataType::OctetString => Some(value_text::hex(bytes)),
        DataType::Domain => None,
        DataType::Real32 => {
            let raw: [u8; 4] = bytes.try_into().ok()?;
            Some(f32::from_le_bytes(raw).to_string())
        }
        t => Some(match Value::decode(t, bytes)? {
            Value::Unsigned(u) => format!("0x{u:X}"),
            Value::Bool(b) => u8::from(b).to_string(),
            Value::Signed(s) => s.to_string(),
            Value::Real(r) => r.to_string(),
        }),
    }
}

/// The entry a section of a DCF describes: `[6040]` a VAR, `[1018sub1]` a sub-index.
fn section_entry(desc: &DeviceDescription, name: &str) -> Option<&'static Entry> {
    let lower = name.to_ascii_lowercase();
    match lower.split_once("sub") {
        Some((i, s)) => desc.entry(
            u16::from_str_radix(i, 16).ok()?,
            u8::from_str_radix(s, 16).ok()?,
        ),
        None => {
            let index = u16::from_str_radix(&lower, 16).ok()?;
            let o = desc.object(index)?;
            (o.kind == ObjectKind::Var)
                .then(|| desc.entry(index, 0))
                .flatten()
        }
    }
}

/// `mm-dd-yyyy` of the system clock (CiA 306 §4.2's CreationDate).
fn today() -> String {
    let days = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() / 86_400) as i64;
    // Days since 1970-01-01 to the civil date (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{m:02}-{d:02}-{y:04}")
}

/// The DCF of `desc` with `values` (the drive's bytes by index and sub-index) as each entry's
/// `ParameterValue` and the node's commissioning (CiA 306 §4.7).
pub fn dcf_text(
    desc: &DeviceDescription,
    node: Option<u8>,
    date: &str,
    values: &BTreeMap<(u16, u8), Vec<u8>>,
) -> Result<String, std::fmt::Error> {
    let mut eds = String::new();
    od::eds::write_eds(&mut eds, desc, date)?;
    let mut out = String::with_capacity(eds.len() + values.len() * 24 + 128);
    let mut current: Option<&Entry> = None;
    for line in eds.lines() {
        if line.is_empty() {
            if let Some(e) = current.take() {
                if let Some(text) = values
                    .get(&(e.index, e.sub))
                    .and_then(|b| value_literal(e.data_type, b))
                {
                    writeln!(out, "ParameterValue={text}")?;
                }
            }
        } else if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            current = section_entry(desc, name);
        }
        match line.strip_prefix("FileName=") {
            Some(name) => writeln!(out, "FileName={}.dcf", name.trim_end_matches(".eds"))?,
            None => writeln!(out, "{line}")?,
        }
    }
    writeln!(out, "[DeviceComissioning]")?;
    writeln!(out, "NodeID=0x{:X}", node.unwrap_or(0))?;
    writeln!(out, "NodeName={}", desc.product_name)?;
    writeln!(out, "Baudrate=1000")?;
    writeln!(out, "NetNumber=0")?;
    writeln!(out, "NetworkName=drivetwin")?;
    writeln!(out, "LSS_SerialNumber=0")?;
    Ok(out)
}

/// Every readable entry's bytes.
fn read_all(
    h: &ControlHandle,
    info: &DriveInfo,
    desc: &DeviceDescription,
) -> BTreeMap<(u16, u8), Vec<u8>> {
    desc.entries()
        .filter(|e| e.access.readable())
        .filter_map(|e| Some(((e.index, e.sub), h.read(info.index, e.index, e.sub).ok()?)))
        .collect()
}

/// The drive's parameter set as a DCF (CiA 306): its EDS with each entry's value as
/// `ParameterValue` and `[DeviceComissioning]`.
#[utoipa::path(get, path = "/api/drives/{drive}/parameters/dcf", tag = "parameters",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, description = "the DCF", content_type = "text/plain", body = String),
        (status = 404, body = ApiError), (status = 400, body = ApiError)))]
async fn export(State(s): State<AppState>, Path(drive): Path<String>) -> Response {
    let made = call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        let desc = description(&info)?;
        let values = read_all(h, &info, desc);
        let text = dcf_text(desc, node_of(&info), &today(), &values)
            .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?;
        Ok((format!("{}-drive{}.dcf", desc.name, info.index), text))
    })
    .await;
    match made {
        Ok((file, text)) => (
            [
                (CONTENT_TYPE, "text/plain; charset=utf-8".to_owned()),
                (
                    CONTENT_DISPOSITION,
                    format!("attachment; filename=\"{file}\""),
                ),
            ],
            text,
        )
            .into_response(),
        Err(e) => e.into_response(),
    }
}

// ---------------------------------------------------------------------------------- import

/// A value of the file the drive would refuse, or that is not the drive's.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct RefusedValue {
    /// `0x6083`.
    pub index: String,
    pub sub: u8,
    /// The file's section.
    pub section: String,
    /// The file's `ParameterValue`.
    pub value: String,
    /// Why.
    pub reason: String,
    /// The SDO abort code the drive answers such a write with, as `0x06090031`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub abort_code: Option<String>,
}

/// What an import did.
#[derive(Debug, Serialize, ToSchema)]
pub struct ImportReport {
    /// Entries written (`6083:00`), in file order.
    pub written: Vec<String>,
    /// Parameters whose value was already the file's.
    pub unchanged: usize,
    /// Entries of the file that are not parameters (read-only, a command, not saved by
    /// 1010h): left as they are.
    pub skipped: usize,
}

/// The refusal of an import: nothing was written.
#[derive(Debug, Serialize, ToSchema)]
pub struct ImportRefused {
    pub error: String,
    pub refused: Vec<RefusedValue>,
}

/// One write an import will make.
#[derive(Debug, Clone, PartialEq)]
pub struct Planned {
    pub entry: &'static Entry,
    pub bytes: Vec<u8>,
}

/// What an import of `text` into a drive with `current` values would write, or every value it
/// refuses (all of them, not the first).
pub fn plan(
    text: &str,
    desc: &'static DeviceDescription,
    node: Option<u8>,
    current: &BTreeMap<(u16, u8), Vec<u8>>,
) -> Result<(Vec<Planned>, ImportReport), ImportRefused> {
    let ini = Ini::parse(text, "the DCF").map_err(|e| ImportRefused {
        error: e.to_string(),
        refused: Vec::new(),
    })?;
    let mut planned = Vec::new();
    let mut refused = Vec::new();
    let mut report = ImportReport {
        written: Vec::new(),
        unchanged: 0,
        skipped: 0,
    };
    for section in &ini.sections {
        let Some(value) = section.value("ParameterValue") else {
            continue;
        };
        let refuse =
            |reason: String, abort: Option<AbortCode>, index: String, sub: u8| RefusedValue {
                index,
                sub,
                section: section.name.clone(),
                value: value.to_owned(),
                reason,
                abort_code: abort.map(|a| format!("0x{:08X}", a.0)),
            };
        let Some(e) = section_entry(desc, &section.name) else {
            refused.push(refuse(
                format!("[{}] is not an entry of {}", section.name, desc.name),
                Some(AbortCode::NO_OBJECT),
                section.name.clone(),
                0,
            ));
            continue;
        };
        let index = format!("0x{:04X}", e.index);
        if !is_parameter(e) {
            report.skipped += 1;
            continue;
        }
        match checked_bytes(e, value, node) {
            Ok(bytes) if current.get(&(e.index, e.sub)) == Some(&bytes) => report.unchanged += 1,
            Ok(bytes) => planned.push(Planned { entry: e, bytes }),
            Err((reason, abort)) => refused.push(refuse(reason, abort, index, e.sub)),
        }
    }
    if !refused.is_empty() {
        return Err(ImportRefused {
            error: format!(
                "{} value(s) of the file refused; nothing was written",
                refused.len()
            ),
            refused,
        });
    }
    Ok((planned, report))
}

/// The bytes of `text` for `e`, checked as an SDO download is: type, size, range, allowed
/// bits (CiA 301 §7.2.4.3.17's abort codes).
pub fn checked_bytes(
    e: &Entry,
    text: &str,
    node: Option<u8>,
) -> Result<Vec<u8>, (String, Option<AbortCode>)> {
    let bad = |m: String| (m, Some(AbortCode::INVALID_VALUE));
    if !e.access.writable() {
        return Err((
            format!("{} is read-only", e.name),
            Some(AbortCode::READ_ONLY),
        ));
    }
    let bytes = match e.data_type {
        DataType::VisibleString => text.as_bytes().to_vec(),
        DataType::OctetString | DataType::Domain => number::hex_bytes(text).map_err(bad)?,
        t => match number::node_relative(text).map_err(bad)? {
            Some(constant) => {
                let c = number::integer(constant)
                    .ok_or_else(|| bad(format!("{constant:?} is not a number")))?;
                let v = c + i128::from(node.unwrap_or(0));
                number::encode(t, &v.to_string()).map_err(bad)?
            }
            None => number::encode(t, text).map_err(bad)?,
        },
    };
    if e.data_type.fixed_size().is_none() {
        if bytes.len() > e.capacity as usize {
            return Err((
                format!("{} bytes; {} holds {}", bytes.len(), e.name, e.capacity),
                Some(AbortCode::LENGTH_TOO_HIGH),
            ));
        }
        return Ok(bytes);
    }
    let v = Value::decode(e.data_type, &bytes)
        .ok_or_else(|| bad(format!("{text:?} is not a {}", e.data_type.name())))?;
    if let Some(max) = e.max {
        if v.compare(max) == Some(std::cmp::Ordering::Greater) {
            return Err((
                format!("{v} is above the maximum {}", limit_text(max)),
                Some(AbortCode::VALUE_TOO_HIGH),
            ));
        }
    }
    if let Some(min) = e.min {
        if v.compare(min) == Some(std::cmp::Ordering::Less) {
            return Err((
                format!("{v} is below the minimum {}", limit_text(min)),
                Some(AbortCode::VALUE_TOO_LOW),
            ));
        }
    }
    if let (Some(mask), Value::Unsigned(u)) = (e.allowed_bits, v) {
        if u & !mask != 0 {
            return Err(bad(format!("0x{u:X} sets bits outside 0x{mask:X}")));
        }
    }
    Ok(bytes)
}

fn limit_text(l: Limit) -> String {
    match l {
        Limit::Signed(s) => s.to_string(),
        Limit::Unsigned(u) => u.to_string(),
        Limit::Real(r) => r.to_string(),
    }
}

/// An import's answer: the report, or the refusal with its status.
enum Imported {
    Done(ImportReport),
    Refused(StatusCode, ImportRefused),
}

/// Writes the planned values one by one; should the drive refuse one, writes back what was
/// written before it and answers the refusal.
fn apply(
    h: &ControlHandle,
    drive: usize,
    planned: Vec<Planned>,
    current: &BTreeMap<(u16, u8), Vec<u8>>,
    mut report: ImportReport,
) -> Imported {
    let mut done: Vec<&Planned> = Vec::new();
    for p in &planned {
        let e = p.entry;
        if let Err(err) = h.write(drive, e.index, e.sub, &p.bytes) {
            let api = ApiError::from(err);
            for back in done.iter().rev() {
                let b = back.entry;
                if let Some(old) = current.get(&(b.index, b.sub)) {
                    // A write-back the drive refuses too leaves the value it has; the answer
                    // names the refused entry either way.
                    let _ = h.write(drive, b.index, b.sub, old);
                }
            }
            let value = value_literal(e.data_type, &p.bytes).unwrap_or_default();
            return Imported::Refused(
                StatusCode::CONFLICT,
                ImportRefused {
                    error: format!(
                        "the drive refused {:04X}:{:02X}; the {} value(s) written before it were written back",
                        e.index,
                        e.sub,
                        done.len()
                    ),
                    refused: vec![RefusedValue {
                        index: format!("0x{:04X}", e.index),
                        sub: e.sub,
                        section: if e.sub == 0 {
                            format!("{:04X}", e.index)
                        } else {
                            format!("{:04X}sub{:X}", e.index, e.sub)
                        },
                        value,
                        reason: api.error,
                        abort_code: api.abort_code,
                    }],
                },
            );
        }
        done.push(p);
    }
    report.written = planned
        .iter()
        .map(|p| format!("{:04X}:{:02X}", p.entry.index, p.entry.sub))
        .collect();
    Imported::Done(report)
}

/// Imports a DCF (CiA 306) into the drive: every `ParameterValue` of a parameter (an entry
/// 1010h saves) that differs from the drive's value is written as an SDO download would;
/// read-only entries and commands are left alone. All values are checked before the first
/// write; a refused one is answered with its index and reason, and nothing is written.
#[utoipa::path(put, path = "/api/drives/{drive}/parameters/dcf", tag = "parameters",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    request_body(content = String, content_type = "text/plain", description = "a DCF"),
    responses((status = 200, body = ImportReport),
        (status = 400, description = "a value refused (nothing written)", body = ImportRefused),
        (status = 401, body = ApiError),
        (status = 404, body = ApiError),
        (status = 409, description = "the drive refused a write (what was written is written back)", body = ImportRefused)))]
async fn import(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: axum::body::Bytes,
) -> Response {
    let refused = |status: StatusCode, error: String| {
        (
            status,
            Json(ImportRefused {
                error,
                refused: Vec::new(),
            }),
        )
            .into_response()
    };
    let Ok(text) = String::from_utf8(body.to_vec()) else {
        return refused(
            StatusCode::BAD_REQUEST,
            "the DCF is not UTF-8 text".to_owned(),
        );
    };
    let done = call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        let desc = description(&info)?;
        let current = read_all(h, &info, desc);
        Ok(match plan(&text, desc, node_of(&info), &current) {
            Err(refused) => Imported::Refused(StatusCode::BAD_REQUEST, refused),
            Ok((planned, report)) => apply(h, info.index, planned, &current, report),
        })
    })
    .await;
    match done {
        Ok(Imported::Done(report)) => Json(report).into_response(),
        Ok(Imported::Refused(status, r)) => (status, Json(r)).into_response(),
        // One body for every 400 of the import (a drive index that is not one, too).
        Err(e) if e.status == StatusCode::BAD_REQUEST => refused(e.status, e.error),
        Err(e) => e.into_response(),
    }
}

#[derive(OpenApi)]
#[openapi(
    paths(list, export, import),
    components(schemas(ParameterView, RefusedValue, ImportReport, ImportRefused))
)]
pub struct ParametersDoc;

pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/api/drives/{drive}/parameters", get(list))
        .route(
            "/api/drives/{drive}/parameters/dcf",
            get(export).put(import),
        )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cmmp() -> &'static DeviceDescription {
        crate::cell::eds_drive::by_name("cmmp-as").expect("the CMMP-AS is built in")
    }

    fn defaults(desc: &DeviceDescription, node: u8) -> BTreeMap<(u16, u8), Vec<u8>> {
        desc.entries()
            .filter_map(|e| Some(((e.index, e.sub), default_bytes(e, Some(node))?)))
            .collect()
    }

    #[test]
    fn an_exported_dcf_reads_back_as_a_dcf_with_the_values_and_the_node() {
        let desc = cmmp();
        let mut values = defaults(desc, 3);
        values.insert((0x6083, 0), 12_345u32.to_le_bytes().to_vec());
        let text = dcf_text(desc, Some(3), "01-01-2026", &values).unwrap();
        assert!(
            text.contains("[DeviceComissioning]\nNodeID=0x3\n"),
            "{text}"
        );
        assert!(text.contains("FileName=cmmp-as.dcf"));
        let dcf = devdesc::eds::parse(&text, "x.dcf").unwrap();
        assert_eq!(dcf.node_id, Some(3));
        let e = dcf
            .device
            .objects
            .iter()
            .find(|o| o.index == 0x6083)
            .and_then(|o| o.entries.first())
            .unwrap();
        assert_eq!(
            e.default,
            12_345u32.to_le_bytes().to_vec(),
            "ParameterValue wins"
        );
    }

    #[test]
    fn an_import_of_the_export_writes_only_what_differs() {
        let desc = cmmp();
        let mut drive = defaults(desc, 1);
        let mut file = drive.clone();
        file.insert((0x6083, 0), 777u32.to_le_bytes().to_vec());
        let text = dcf_text(desc, Some(1), "01-01-2026", &file).unwrap();
        let (planned, report) = plan(&text, desc, Some(1), &drive).unwrap();
        assert_eq!(planned.len(), 1, "{planned:?}");
        assert_eq!(
            (planned[0].entry.index, planned[0].bytes.clone()),
            (0x6083, 777u32.to_le_bytes().to_vec())
        );
        assert!(report.unchanged > 10 && report.skipped > 0, "{report:?}");
        drive.insert((0x6083, 0), 777u32.to_le_bytes().to_vec());
        assert!(plan(&text, desc, Some(1), &drive).unwrap().0.is_empty());
    }

    #[test]
    fn every_refused_value_is_named_and_nothing_is_planned() {
        let desc = cmmp();
        let text = "[6083]\nParameterValue=hello\n[6041]\nParameterValue=0\n[6060]\nParameterValue=100\n[5FFF]\nParameterValue=1\n";
        let refused = plan(text, desc, Some(1), &BTreeMap::new()).unwrap_err();
        let sections: Vec<&str> = refused.refused.iter().map(|r| r.section.as_str()).collect();
        assert!(
            sections.contains(&"6083") && sections.contains(&"5FFF"),
            "{refused:?}"
        );
        assert!(
            !sections.contains(&"6041"),
            "a read-only entry is skipped, not refused"
        );
        assert!(refused.refused.iter().all(|r| !r.reason.is_empty()));
    }

    #[test]
    fn a_value_above_the_maximum_is_refused_with_the_sdo_abort_code() {
        let e = cmmp()
            .entries()
            .find(|e| {
                e.max.is_some()
                    && e.access.writable()
                    && e.data_type.is_numeric()
                    && !e.data_type.is_real()
            })
            .unwrap();
        let max = match e.max.unwrap() {
            Limit::Unsigned(u) => u as i128,
            Limit::Signed(s) => s as i128,
            Limit::Real(_) => unreachable!(),
        };
        let (_, abort) = checked_bytes(e, &(max + 1).to_string(), Some(1)).unwrap_err();
        assert!(
            matches!(abort, Some(a) if a == AbortCode::VALUE_TOO_HIGH || a == AbortCode::INVALID_VALUE)
        );
    }

    #[test]
    fn node_relative_values_add_the_node() {
        let e = cmmp().entry(0x1800, 1).unwrap();
        assert_eq!(
            checked_bytes(e, "$NODEID+0x180", Some(5)).unwrap(),
            0x185u32.to_le_bytes().to_vec()
        );
    }

    #[test]
    fn the_groups_are_those_of_store_and_restore() {
        assert_eq!(group(0x1018), "communication");
        assert_eq!(group(0x2100), "manufacturer");
        assert_eq!(group(0x607A), "profile");
    }
}
