//! The REST API: drives with their personality and state, objects by index and sub-index
//! with what the device description says of them, the plant, inputs and load. Every handler
//! answers bad input with a 4xx and a message (JSON [`ApiError`]), never a 5xx or a panic;
//! an SDO abort becomes its code and its CiA 301 text.

use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post, put};
use axum::{Json, Router};
use od::{AbortCode, DataType, DeviceDescription, Entry, Limit};
use serde::{Deserialize, Serialize};
use utoipa::{OpenApi, ToSchema};

use super::AppState;
use crate::cell::control::{
    ControlError, ControlHandle, DisplayState, DriveInfo, Interface, Plant, PlantSample,
};
use crate::value_text;
use drive::device_control::State as Cia402State;
use drive::drive::refusal::{Refusal, Request};
use drive::statusword::Statusword;

/// The JSON body of every refusal.
#[derive(Debug, Serialize, ToSchema)]
pub struct ApiError {
    #[serde(skip)]
    pub status: StatusCode,
    /// What went wrong, for a person.
    pub error: String,
    /// The SDO abort code (CiA 301 §7.2.4.3.17) when the drive refused, as `0x06090030`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub abort_code: Option<String>,
    /// The abort code's CiA 301 text.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub abort_text: Option<String>,
    /// Why the drive refused, with its manual's rule (an input owns the object, a hardware
    /// enable is missing, the mode is not the device's, …).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<Box<ReasonView>>,
}

/// Why a drive does not take a command, as the drive says it.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct ReasonView {
    /// For programs: `input_owns_object`, `input_inactive`, `hardware_enable_missing`,
    /// `mode_not_supported`, `device_state`, `fault_cause_present`, `device_control`.
    pub kind: String,
    /// The reason, for a person (e.g. "DIN1 has the function Enable (2010h:03): …").
    pub text: String,
    /// The manual's rule, with its section.
    pub rule: String,
}

impl From<Refusal> for ReasonView {
    fn from(r: Refusal) -> ReasonView {
        ReasonView {
            kind: r.kind().to_owned(),
            text: r.to_string(),
            rule: r.rule().to_owned(),
        }
    }
}

impl ApiError {
    pub fn new(status: StatusCode, error: impl Into<String>) -> ApiError {
        ApiError {
            status,
            error: error.into(),
            abort_code: None,
            abort_text: None,
            reason: None,
        }
    }

    /// The refusal with the drive's reason: a 409 whose message starts with the reason, the
    /// drive's own answer (an SDO abort, a state not reached) after it.
    pub fn with_reason(self, reason: ReasonView) -> ApiError {
        let error = if self.error.is_empty() {
            reason.text.clone()
        } else {
            format!("{}; {}", reason.text, self.error)
        };
        ApiError {
            status: StatusCode::CONFLICT,
            error,
            reason: Some(Box::new(reason)),
            ..self
        }
    }

    /// `self` with the drive's reason for refusing `request`, where the drive names one.
    pub(super) fn asking(self, h: &ControlHandle, drive: usize, request: Request) -> ApiError {
        match h.refusal(drive, request) {
            Ok(Some(r)) => self.with_reason(r.into()),
            _ => self,
        }
    }

    pub(crate) fn bad(error: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::BAD_REQUEST, error)
    }

    pub(crate) fn not_found(error: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::NOT_FOUND, error)
    }

    fn abort(code: AbortCode) -> ApiError {
        let text = code.description().unwrap_or("unknown abort code");
        // An object or sub-index the drive does not have is "not found"; every other refusal
        // is the drive's answer to a well-formed request: a conflict with its state or rules.
        let status = if code == AbortCode::NO_OBJECT || code == AbortCode::NO_SUB_INDEX {
            StatusCode::NOT_FOUND
        } else {
            StatusCode::CONFLICT
        };
        ApiError {
            status,
            error: format!("SDO abort {:#010X}: {text}", code.0),
            abort_code: Some(format!("{:#010X}", code.0)),
            abort_text: Some(text.to_owned()),
            reason: None,
        }
    }
}

impl From<ControlError> for ApiError {
    fn from(e: ControlError) -> ApiError {
        match e {
            ControlError::Abort(code) => ApiError::abort(code),
            ControlError::NoDrive(_)
            | ControlError::NoPlant(_)
            | ControlError::NoNode { .. }
            | ControlError::NoPanel(_)
            | ControlError::NoSupply(_)
            | ControlError::NoSwitch { .. } => ApiError::not_found(e.to_string()),
            ControlError::Stopped => ApiError::new(StatusCode::SERVICE_UNAVAILABLE, e.to_string()),
            ControlError::Diagnostic(d) => super::diagnostics::refusal(d),
        }
    }
}

impl From<JsonRejection> for ApiError {
    fn from(e: JsonRejection) -> ApiError {
        // A body that is not JSON of the right shape is a bad request (400); only a missing
        // JSON content type keeps its own 415.
        let status = match e {
            JsonRejection::MissingJsonContentType(_) => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            _ => StatusCode::BAD_REQUEST,
        };
        ApiError::new(status, e.body_text())
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.status, Json(self)).into_response()
    }
}

pub(crate) type ApiResult<T> = Result<Json<T>, ApiError>;

/// Runs a blocking call on the control handle off the runtime's workers.
pub(crate) async fn call<T: Send + 'static>(
    handle: &ControlHandle,
    f: impl FnOnce(&ControlHandle) -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    let handle = handle.clone();
    tokio::task::spawn_blocking(move || f(&handle))
        .await
        .map_err(|_| ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "the request was lost"))?
}

// ---------------------------------------------------------------------------------- drives

/// A drive of the cell, with what its statusword says.
#[derive(Debug, Serialize, ToSchema)]
pub struct DriveView {
    /// Its place in the cell (CAN drives in cell order, then the Modbus drives).
    pub index: usize,
    /// The device file's name (`cmmp-as`, `cmmo-st`, …).
    pub device: String,
    pub product: String,
    pub vendor: String,
    /// `cia402`, `fhpp` or `plain`.
    pub profile: String,
    /// `canopen` or `modbus-tcp`.
    pub interface: String,
    /// The CANopen node-ID.
    pub node: Option<u8>,
    /// 6041h, when the drive has it.
    pub statusword: Option<u16>,
    /// The CiA 402 state the statusword shows.
    pub state: Option<String>,
    /// The statusword bit by bit.
    pub status_bits: Vec<StatusBit>,
    /// What the 7-segment display shows.
    pub display: Option<String>,
}

#[derive(Debug, Serialize, ToSchema)]
pub struct StatusBit {
    pub bit: u8,
    pub name: String,
    pub set: bool,
}

/// The dictionary the drive serves on its interface (an EDS drive on EtherCAT: its slave's).
fn description(info: &DriveInfo) -> Result<&'static DeviceDescription, ApiError> {
    let ethercat_only = matches!(info.interface, Interface::Ethercat { .. });
    crate::cell::eds_drive::served(info.device, ethercat_only)
        .ok_or_else(|| ApiError::not_found(format!("no device description {:?}", info.device)))
}

fn profile_name(desc: &DeviceDescription) -> String {
    format!("{:?}", desc.profile).to_ascii_lowercase()
}

pub(crate) fn display_text(d: &DisplayState) -> String {
    d.text().to_owned()
}

/// The CiA 402 state the console shows for a statusword, `None` for bits no state has.
///
/// **Decision:** 000Fh is FAULT REACTION ACTIVE in CiA 402 Tab. 30, but a CMMP-AS without
/// 6510h:F0 bit 7 shows FAULT itself as 000Fh (CMMP-AS Tab. 6.6 footnote); the reaction lasts
/// milliseconds, so the console shows FAULT, the state a person must act on.
pub(super) fn console_state(sw: u16) -> Option<Cia402State> {
    Statusword(sw).state().map(|s| match s {
        Cia402State::FaultReactionActive => Cia402State::Fault,
        s => s,
    })
}

fn drive_view(h: &ControlHandle, info: &DriveInfo) -> Result<DriveView, ApiError> {
    let desc = description(info)?;
    let statusword = desc
        .entry(0x6041, 0)
        .and_then(|_| h.read(info.index, 0x6041, 0).ok())
        .and_then(|b| Some(u16::from_le_bytes([*b.first()?, *b.get(1)?])));
    let (interface, node) = match info.interface {
        Interface::CanOpen { node } => ("canopen", Some(node)),
        Interface::ModbusTcp => ("modbus-tcp", None),
        Interface::Ethercat { .. } => ("ethercat", None),
    };
    let display = h
        .plant(info.index)
        .ok()
        .and_then(|s| s.display)
        .map(|d| display_text(&d));
    Ok(DriveView {
        index: info.index,
        device: info.device.to_owned(),
        product: info.product.to_owned(),
        vendor: desc.vendor_name.to_owned(),
        profile: profile_name(desc),
        interface: interface.to_owned(),
        node,
        statusword,
        state: statusword
            .and_then(console_state)
            .map(|s| s.name().to_owned()),
        status_bits: statusword
            .map(|sw| {
                Statusword::BIT_NAMES
                    .iter()
                    .zip(0u8..)
                    .map(|(name, bit)| StatusBit {
                        bit,
                        name: (*name).to_owned(),
                        set: sw & (1 << bit) != 0,
                    })
                    .collect()
            })
            .unwrap_or_default(),
        display,
    })
}

pub(crate) fn find_drive(h: &ControlHandle, drive: &str) -> Result<DriveInfo, ApiError> {
    let index: usize = drive
        .parse()
        .map_err(|_| ApiError::bad(format!("drive {drive:?}: not a drive index (0, 1, …)")))?;
    h.drives()?
        .into_iter()
        .find(|d| d.index == index)
        .ok_or_else(|| ApiError::not_found(format!("no drive {index} in the cell")))
}

/// The cell's drives.
#[utoipa::path(get, path = "/api/drives", tag = "drives",
    responses((status = 400, body = ApiError), (status = 200, body = [DriveView])))]
async fn list_drives(State(s): State<AppState>) -> ApiResult<Vec<DriveView>> {
    call(&s.handle, |h| {
        h.drives()?.iter().map(|d| drive_view(h, d)).collect()
    })
    .await
    .map(Json)
}

/// One CAN bus of the cell.
#[derive(Debug, Serialize, ToSchema)]
pub struct BusView {
    pub index: usize,
    /// CANopen nodes of the cell on it.
    pub drives: usize,
    /// Bit rate, bit/s (`null`: the instant bus, `bitrate = "instant"`; frames cross at once).
    pub bitrate: Option<u32>,
    /// Bus load, percent: the bit time asked of the bus over the last second (two complete
    /// 500 ms windows on fixed boundaries of the cell's clock, so steady traffic reads the
    /// same whenever it is asked); more than 100 means it falls behind.
    pub load_percent: Option<f64>,
    /// Frames that crossed the bus.
    pub frames: Option<u64>,
    /// Frames that waited longer than the bus's late limit (`late_after_us`).
    pub late: Option<u64>,
    /// Frames lost to full transmit queues.
    pub dropped: Option<u64>,
    /// The longest wait of a frame for the bus, µs.
    pub longest_wait_us: Option<u64>,
    /// Nodes whose CAN controller counts errors.
    pub node_errors: Vec<NodeErrorView>,
}

/// A node's CAN controller (ISO 11898-1 fault confinement).
#[derive(Debug, Serialize, ToSchema)]
pub struct NodeErrorView {
    pub node: u8,
    /// `error active`, `error passive` or `bus off`.
    pub state: String,
    /// Transmit and receive error counters.
    pub tec: u16,
    pub rec: u16,
}

fn bus_views(h: &ControlHandle) -> Result<Vec<BusView>, ApiError> {
    Ok(h.buses()?
        .into_iter()
        .map(|b| BusView {
            index: b.index,
            drives: b.drives,
            bitrate: b.timing.map(|t| t.bitrate),
            load_percent: b.timing.map(|t| t.load_percent),
            frames: b.timing.map(|t| t.frames),
            late: b.timing.map(|t| t.late),
            dropped: b.timing.map(|t| t.dropped),
            longest_wait_us: b
                .timing
                .map(|t| u64::try_from(t.longest_wait.as_micros()).unwrap_or(u64::MAX)),
            node_errors: b
                .node_errors
                .iter()
                .map(|(node, state, tec, rec)| NodeErrorView {
                    node: *node,
                    state: state.name().to_owned(),
                    tec: *tec,
                    rec: *rec,
                })
                .collect(),
        })
        .collect())
}

/// The cell's CAN buses and their load.
#[utoipa::path(get, path = "/api/buses", tag = "buses",
    responses((status = 400, body = ApiError), (status = 200, body = [BusView])))]
async fn list_buses(State(s): State<AppState>) -> ApiResult<Vec<BusView>> {
    call(&s.handle, bus_views).await.map(Json)
}

/// A disturbance of one node's transmissions.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct DisturbBody {
    /// The node-ID whose next transmissions fail.
    #[schema(minimum = 1, maximum = 127)]
    pub node: u8,
    /// How many fail with an error frame (16: error passive, 32: bus off).
    #[schema(minimum = 1, maximum = 1000)]
    pub frames: u32,
}

/// Fault injection on the bus: the node's next transmissions fail with an error frame; its
/// controller counts them (ISO 11898-1) and the drive reacts as its manual says.
#[utoipa::path(post, path = "/api/buses/{bus}/disturb", tag = "buses",
    params(("bus" = u32, Path, description = "the bus's index in the cell")),
    request_body = DisturbBody,
    responses((status = 415, body = ApiError), (status = 200, body = [BusView]), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError)))]
async fn disturb(
    State(s): State<AppState>,
    Path(bus): Path<String>,
    body: Result<Json<DisturbBody>, JsonRejection>,
) -> ApiResult<Vec<BusView>> {
    let Json(body) = body?;
    let bus: usize = bus
        .parse()
        .map_err(|_| ApiError::bad(format!("bus {bus:?}: not a bus index (0, 1, …)")))?;
    body.check()?;
    call(&s.handle, move |h| {
        h.disturb(bus, body.node, body.frames)?;
        bus_views(h)
    })
    .await
    .map(Json)
}

/// One drive.
#[utoipa::path(get, path = "/api/drives/{drive}", tag = "drives",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = DriveView), (status = 404, body = ApiError), (status = 400, body = ApiError)))]
async fn get_drive(State(s): State<AppState>, Path(drive): Path<String>) -> ApiResult<DriveView> {
    call(&s.handle, move |h| drive_view(h, &find_drive(h, &drive)?))
        .await
        .map(Json)
}

fn cia402_drive(h: &ControlHandle, drive: &str) -> Result<DriveInfo, ApiError> {
    let info = find_drive(h, drive)?;
    let desc = description(&info)?;
    if desc.entry(0x6040, 0).is_none() {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            format!(
                "drive {} ({}) has no CiA 402 controlword; its FHPP control is under /api/drives/{}/motion",
                info.index, info.device, info.index
            ),
        ));
    }
    Ok(info)
}

/// Enables the drive's power stage: CiA 402 controlword steps to OPERATION ENABLED (a fault
/// reset first). A drive that does not get there answers 409 with its reason.
#[utoipa::path(post, path = "/api/drives/{drive}/enable", tag = "drives",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 400, body = ApiError), (status = 200, body = DriveView), (status = 404, body = ApiError), (status = 409, body = ApiError)))]
async fn enable(State(s): State<AppState>, Path(drive): Path<String>) -> ApiResult<DriveView> {
    call(&s.handle, move |h| {
        let info = cia402_drive(h, &drive)?;
        let io = super::motion::Handle {
            handle: h,
            drive: info.index,
        };
        super::motion::enable(&io).map_err(|e| super::motion::refusal(h, info.index, e))?;
        drive_view(h, &info)
    })
    .await
    .map(Json)
}

/// Switches the power stage off: controlword "shutdown" (READY TO SWITCH ON).
#[utoipa::path(post, path = "/api/drives/{drive}/disable", tag = "drives",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 400, body = ApiError), (status = 200, body = DriveView), (status = 404, body = ApiError), (status = 409, body = ApiError)))]
async fn disable(State(s): State<AppState>, Path(drive): Path<String>) -> ApiResult<DriveView> {
    call(&s.handle, move |h| {
        let info = cia402_drive(h, &drive)?;
        let io = super::motion::Handle {
            handle: h,
            drive: info.index,
        };
        super::motion::disable(&io).map_err(|e| super::motion::refusal(h, info.index, e))?;
        drive_view(h, &info)
    })
    .await
    .map(Json)
}

// --------------------------------------------------------------------------------- objects

/// An entry of the object dictionary as its device description has it, with its value.
#[derive(Debug, Serialize, ToSchema)]
pub struct ObjectView {
    /// `0x6040`.
    pub index: String,
    pub sub: u8,
    pub name: String,
    /// The object's name (the record's, for a sub-index of a record).
    pub object: String,
    /// CiA 301 type name (`UNSIGNED16`, …).
    #[serde(rename = "type")]
    pub data_type: String,
    /// `ro`, `wo`, `rw`, `const`.
    pub access: String,
    pub unit: String,
    #[schema(value_type = Option<f64>)]
    pub min: Option<serde_json::Value>,
    #[schema(value_type = Option<f64>)]
    pub max: Option<serde_json::Value>,
    pub pdo_mappable: bool,
    /// The value as text (numbers in decimal, strings as they are, octets in hex); `null` when
    /// not read or not readable.
    pub value: Option<String>,
    /// The value's bytes, little-endian, as hex.
    pub raw: Option<String>,
    /// Why the value could not be read.
    pub read_error: Option<String>,
}

fn limit_json(l: Option<Limit>) -> Option<serde_json::Value> {
    Some(match l? {
        Limit::Signed(v) => v.into(),
        Limit::Unsigned(v) => v.into(),
        Limit::Real(v) => serde_json::Number::from_f64(v)?.into(),
    })
}

fn object_view(desc: &DeviceDescription, e: &Entry) -> ObjectView {
    ObjectView {
        index: format!("{:#06X}", e.index).replace("0X", "0x"),
        sub: e.sub,
        name: e.name.to_owned(),
        object: desc.object(e.index).map_or(e.name, |o| o.name).to_owned(),
        data_type: e.data_type.name().to_owned(),
        access: e.access.eds_name().to_ascii_lowercase(),
        unit: e.unit.to_owned(),
        min: limit_json(e.min),
        max: limit_json(e.max),
        pdo_mappable: e.pdo_mappable,
        value: None,
        raw: None,
        read_error: None,
    }
}

fn with_value(mut v: ObjectView, ty: DataType, read: Result<Vec<u8>, ControlError>) -> ObjectView {
    match read {
        Ok(bytes) => {
            v.value = value_text::decode(ty, &bytes);
            v.raw = Some(value_text::hex(&bytes));
        }
        Err(e) => v.read_error = Some(ApiError::from(e).error),
    }
    v
}

/// `6040`, `0x6040`, `6040h` → 0x6040.
fn parse_hex_number(text: &str, what: &str, max: u32) -> Result<u32, ApiError> {
    let t = text.trim();
    let t = t
        .strip_prefix("0x")
        .or_else(|| t.strip_prefix("0X"))
        .unwrap_or(t);
    let t = t
        .strip_suffix('h')
        .or_else(|| t.strip_suffix('H'))
        .unwrap_or(t);
    u32::from_str_radix(t, 16)
        .ok()
        .filter(|v| *v <= max)
        .ok_or_else(|| {
            ApiError::bad(format!(
                "{what} {text:?}: not a hex number up to {max:#X} (e.g. 6040 or 0x6040)"
            ))
        })
}

fn find_entry(
    desc: &'static DeviceDescription,
    index: &str,
    sub: &str,
) -> Result<&'static Entry, ApiError> {
    let i = parse_hex_number(index, "index", 0xFFFF)? as u16;
    let s = parse_hex_number(sub, "sub-index", 0xFF)? as u8;
    desc.entry(i, s).ok_or_else(|| {
        let mut e = ApiError::abort(if desc.object(i).is_some() {
            AbortCode::NO_SUB_INDEX
        } else {
            AbortCode::NO_OBJECT
        });
        e.error = format!("{:#06x}:{s:02x} is not in {}: {}", i, desc.name, e.error);
        e
    })
}

/// Every entry of the drive's object dictionary, with its value.
#[utoipa::path(get, path = "/api/drives/{drive}/objects", tag = "objects",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = [ObjectView]), (status = 404, body = ApiError), (status = 400, body = ApiError)))]
async fn list_objects(
    State(s): State<AppState>,
    Path(drive): Path<String>,
) -> ApiResult<Vec<ObjectView>> {
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        let desc = description(&info)?;
        Ok(desc
            .entries()
            .map(|e| {
                let v = object_view(desc, e);
                if e.access.readable() {
                    with_value(v, e.data_type, h.read(info.index, e.index, e.sub))
                } else {
                    v
                }
            })
            .collect())
    })
    .await
    .map(Json)
}

/// One entry, read as a fieldbus read would.
#[utoipa::path(get, path = "/api/drives/{drive}/objects/{index}/{sub}", tag = "objects",
    params(
        ("drive" = u32, Path, description = "the drive's index in the cell"),
        ("index" = String, Path, description = "hex, e.g. 6040", pattern = "^(0[xX])?[0-9A-Fa-f]{1,4}[hH]?$"),
        ("sub" = String, Path, description = "hex, e.g. 0", pattern = "^(0[xX])?[0-9A-Fa-f]{1,2}[hH]?$")),
    responses((status = 200, body = ObjectView), (status = 400, body = ApiError),
        (status = 404, body = ApiError), (status = 409, body = ApiError)))]
async fn read_object(
    State(s): State<AppState>,
    Path((drive, index, sub)): Path<(String, String, String)>,
) -> ApiResult<ObjectView> {
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        let desc = description(&info)?;
        let e = find_entry(desc, &index, &sub)?;
        let bytes = h.read(info.index, e.index, e.sub)?;
        Ok(with_value(object_view(desc, e), e.data_type, Ok(bytes)))
    })
    .await
    .map(Json)
}

/// A value to write: `{"value": …}` as text (or a JSON number) in the entry's type, or
/// `{"raw": "E803"}`, its bytes in hex, written as they are.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum WriteBody {
    Value(WriteValue),
    Raw(WriteRaw),
}

#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WriteValue {
    /// `1500`, `-2`, `0x1F`, `1.5`, a string for VISIBLE_STRING, hex for OCTET_STRING.
    #[schema(value_type = String)]
    pub value: serde_json::Value,
}

#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WriteRaw {
    /// The bytes, little-endian, as hex (`E803`).
    pub raw: String,
}

/// Writes one entry with the access rules and effects of a fieldbus write; answers the value
/// read back.
#[utoipa::path(put, path = "/api/drives/{drive}/objects/{index}/{sub}", tag = "objects",
    params(
        ("drive" = u32, Path, description = "the drive's index in the cell"),
        ("index" = String, Path, description = "hex, e.g. 6040", pattern = "^(0[xX])?[0-9A-Fa-f]{1,4}[hH]?$"),
        ("sub" = String, Path, description = "hex, e.g. 0", pattern = "^(0[xX])?[0-9A-Fa-f]{1,2}[hH]?$")),
    request_body = WriteBody,
    responses((status = 415, body = ApiError), (status = 200, body = ObjectView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError), (status = 409, body = ApiError)))]
async fn write_object(
    State(s): State<AppState>,
    Path((drive, index, sub)): Path<(String, String, String)>,
    body: Result<Json<WriteBody>, JsonRejection>,
) -> ApiResult<ObjectView> {
    let Json(body) = body?;
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        let desc = description(&info)?;
        let e = find_entry(desc, &index, &sub)?;
        let bytes = body.bytes(e)?;
        h.write(info.index, e.index, e.sub, &bytes).map_err(|err| {
            // 6060h is a mode change: the drive says why it does not take that mode.
            let request = match (e.index, e.sub, bytes.as_slice()) {
                (0x6060, 0, [m]) => Request::Mode(*m as i8),
                (index, sub, _) => Request::Write { index, sub },
            };
            ApiError::from(err).asking(h, info.index, request)
        })?;
        let v = object_view(desc, e);
        Ok(if e.access.readable() {
            with_value(v, e.data_type, h.read(info.index, e.index, e.sub))
        } else {
            v
        })
    })
    .await
    .map(Json)
}

// ----------------------------------------------------------------------------------- plant

/// The plant of a drive at one time of the cell's clock.
#[derive(Debug, Serialize, ToSchema)]
pub struct PlantView {
    /// The cell's clock, seconds.
    pub at_s: f64,
    /// `servo` (CiA 402 drive) or `stepper` (CMMO-ST).
    pub kind: String,
    /// Servo: encoder increments; stepper: SI units (`null` before homing).
    pub position: Option<f64>,
    /// Servo: rpm.
    pub velocity: Option<f64>,
    /// Servo: motor current, mA.
    pub current: Option<f64>,
    /// Servo: the digital inputs as 60FDh shows them.
    pub digital_inputs: Option<u32>,
    /// Stepper: load torque, N·m.
    pub load_torque_nm: Option<f64>,
    pub display: Option<String>,
}

impl From<&PlantSample> for PlantView {
    fn from(s: &PlantSample) -> PlantView {
        let base = PlantView {
            at_s: s.at.as_secs_f64(),
            kind: String::new(),
            position: None,
            velocity: None,
            current: None,
            digital_inputs: None,
            load_torque_nm: None,
            display: s.display.as_ref().map(display_text),
        };
        match s.plant {
            Plant::Servo {
                position_increments,
                velocity_rpm,
                current_ma,
                digital_inputs,
            } => PlantView {
                kind: "servo".into(),
                position: Some(position_increments as f64),
                velocity: Some(f64::from(velocity_rpm)),
                current: Some(f64::from(current_ma)),
                digital_inputs: Some(digital_inputs),
                ..base
            },
            Plant::Stepper {
                position_si,
                load_torque_nm,
            } => PlantView {
                kind: "stepper".into(),
                position: position_si,
                load_torque_nm: Some(load_torque_nm),
                ..base
            },
        }
    }
}

/// The drive's plant now.
#[utoipa::path(get, path = "/api/drives/{drive}/plant", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = PlantView), (status = 400, body = ApiError), (status = 404, body = ApiError)))]
async fn get_plant(State(s): State<AppState>, Path(drive): Path<String>) -> ApiResult<PlantView> {
    plant_after(&s, drive, |_, _| Ok(())).await
}

/// The drive's plant after `act` on the drive (by its index): the answer of the plant routes.
async fn plant_after(
    s: &AppState,
    drive: String,
    act: impl FnOnce(&ControlHandle, usize) -> Result<(), ControlError> + Send + 'static,
) -> ApiResult<PlantView> {
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        act(h, info.index)?;
        Ok(PlantView::from(&h.plant(info.index)?))
    })
    .await
    .map(Json)
}

/// Digital inputs forced from outside: bit n of `mask` forces DINn to bit n of `levels`.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct InputsBody {
    #[schema(minimum = 0, maximum = 65535)]
    pub mask: u16,
    #[schema(minimum = 0, maximum = 65535)]
    pub levels: u16,
}

/// Forces digital inputs of a CiA 402 drive.
#[utoipa::path(put, path = "/api/drives/{drive}/inputs", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    request_body = InputsBody,
    responses((status = 415, body = ApiError), (status = 200, body = PlantView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError)))]
async fn set_inputs(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<InputsBody>, JsonRejection>,
) -> ApiResult<PlantView> {
    let Json(body) = body?;
    plant_after(&s, drive, move |h, i| {
        h.set_inputs(i, body.mask, body.levels)
    })
    .await
}

/// The load torque on the motor shaft.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LoadBody {
    /// N·m, finite, at most 1000 in magnitude.
    #[schema(minimum = -1000.0, maximum = 1000.0)]
    pub torque_nm: f64,
}

/// The supply voltage of a drive.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SupplyBody {
    /// V, 0 … 1000; `null`: the nominal voltage of the device file.
    #[schema(minimum = 0.0, maximum = 1000.0)]
    pub volts: Option<f64>,
}

/// Sets the drive's supply (DC-link) voltage: it shows in the drive's measured values, limits
/// its current controller, and its own supervision reacts as its manual says (CMMP-AS 02-0
/// undervoltage below 6510h:36 when 6510h:37 = 1).
#[utoipa::path(put, path = "/api/drives/{drive}/supply", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    request_body = SupplyBody,
    responses((status = 415, body = ApiError), (status = 200, body = PlantView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError)))]
async fn set_supply(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<SupplyBody>, JsonRejection>,
) -> ApiResult<PlantView> {
    let Json(body) = body?;
    let millivolts = body.millivolts()?;
    plant_after(&s, drive, move |h, i| h.set_supply(i, millivolts)).await
}

/// Sets the load torque on the drive's motor shaft.
#[utoipa::path(put, path = "/api/drives/{drive}/load", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    request_body = LoadBody,
    responses((status = 415, body = ApiError), (status = 200, body = PlantView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError)))]
async fn set_load(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<LoadBody>, JsonRejection>,
) -> ApiResult<PlantView> {
    let Json(body) = body?;
    body.check()?;
    plant_after(&s, drive, move |h, i| h.set_load(i, body.torque_nm)).await
}

// -------------------------------------------------------------------------- request bodies
//
// The checks of the request bodies that need no cell, shared by the handlers above and the
// fuzz target `http_body` (which feeds any bytes to `parse_body` and then these).

/// A body parsed as the `Json` extractor parses it (serde_json over the same `Deserialize`
/// impls); a body that is not JSON of the right shape is a 400.
pub fn parse_body<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    serde_json::from_slice(bytes).map_err(|e| ApiError::bad(e.to_string()))
}

impl DisturbBody {
    pub fn check(&self) -> Result<(), ApiError> {
        if !(1..=127).contains(&self.node) || !(1..=1000).contains(&self.frames) {
            return Err(ApiError::bad("node 1…127 and frames 1…1000".to_owned()));
        }
        Ok(())
    }
}

impl WriteBody {
    /// The bytes to write to entry `e`.
    pub fn bytes(&self, e: &Entry) -> Result<Vec<u8>, ApiError> {
        Ok(match self {
            WriteBody::Raw(WriteRaw { raw }) => value_text::parse_hex(raw)
                .ok_or_else(|| ApiError::bad(format!("raw {raw:?} is not hex")))?,
            WriteBody::Value(WriteValue { value }) => {
                let text = match value {
                    serde_json::Value::String(t) => t.clone(),
                    serde_json::Value::Number(n) => n.to_string(),
                    serde_json::Value::Bool(b) => u8::from(*b).to_string(),
                    other => {
                        return Err(ApiError::bad(format!(
                            "value {other}: a string or a number"
                        )))
                    }
                };
                value_text::encode(e.data_type, &text).map_err(|m| {
                    ApiError::bad(format!("{:#06x}:{:02x} {}: {m}", e.index, e.sub, e.name))
                })?
            }
        })
    }
}

impl SupplyBody {
    /// The voltage in mV, `None`: the nominal one.
    pub fn millivolts(&self) -> Result<Option<u32>, ApiError> {
        match self.volts {
            None => Ok(None),
            Some(v) if v.is_finite() && (0.0..=1000.0).contains(&v) => {
                Ok(Some((v * 1000.0).round() as u32))
            }
            Some(v) => Err(ApiError::bad(format!(
                "volts {v}: a finite number of V within 0 … 1000 (or null: nominal)"
            ))),
        }
    }
}

impl LoadBody {
    pub fn check(&self) -> Result<(), ApiError> {
        if !(self.torque_nm.is_finite() && self.torque_nm.abs() <= 1000.0) {
            return Err(ApiError::bad(format!(
                "torque_nm {}: a finite number of N·m within ±1000",
                self.torque_nm
            )));
        }
        Ok(())
    }
}

// --------------------------------------------------------------------------------- openapi

#[derive(OpenApi)]
#[openapi(
    info(
        title = "drivetwin web console",
        description = "The cell's drives, their objects and plant."
    ),
    paths(
        list_buses,
        disturb,
        list_drives,
        get_drive,
        enable,
        disable,
        list_objects,
        read_object,
        write_object,
        get_plant,
        set_inputs,
        set_load,
        set_supply,
        super::live::samples
    ),
    components(schemas(
        ApiError,
        ReasonView,
        BusView,
        NodeErrorView,
        DisturbBody,
        DriveView,
        StatusBit,
        ObjectView,
        WriteBody,
        PlantView,
        InputsBody,
        LoadBody,
        SupplyBody,
        super::live::SampleBatch,
        super::live::SamplePoint
    ))
)]
pub struct ApiDoc;

async fn openapi(State(s): State<AppState>) -> Response {
    let mut doc = ApiDoc::openapi();
    doc.merge(super::diagnostics::DiagnosticsDoc::openapi());
    doc.merge(super::motion::MotionDoc::openapi());
    doc.merge(super::parameters::ParametersDoc::openapi());
    for pages in s.pages {
        doc.merge((pages.openapi)());
    }
    match super::wire::merged(doc).to_json() {
        Ok(text) => (
            [(axum::http::header::CONTENT_TYPE, "application/json")],
            text,
        )
            .into_response(),
        Err(e) => ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}

async fn no_route() -> ApiError {
    ApiError::not_found("no such API route (see /api/openapi.json)")
}

pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/api/openapi.json", get(openapi))
        .route("/api/buses", get(list_buses))
        .route("/api/buses/{bus}/disturb", post(disturb))
        .route("/api/drives", get(list_drives))
        .route("/api/drives/{drive}", get(get_drive))
        .route("/api/drives/{drive}/enable", post(enable))
        .route("/api/drives/{drive}/disable", post(disable))
        .route("/api/drives/{drive}/objects", get(list_objects))
        .route(
            "/api/drives/{drive}/objects/{index}/{sub}",
            get(read_object).put(write_object),
        )
        .route("/api/drives/{drive}/plant", get(get_plant))
        .route("/api/drives/{drive}/inputs", put(set_inputs))
        .route("/api/drives/{drive}/load", put(set_load))
        .route("/api/drives/{drive}/supply", put(set_supply))
        .route("/api/{*rest}", axum::routing::any(no_route))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_console_shows_000fh_as_fault() {
        assert_eq!(
            console_state(0x0F),
            Some(Cia402State::Fault),
            "CMMP-AS FAULT without 6510h:F0 bit 7"
        );
        assert_eq!(console_state(0x0218), Some(Cia402State::Fault));
        assert_eq!(console_state(0x0637), Some(Cia402State::OperationEnabled));
        assert_eq!(console_state(0x0025), None);
    }
}
