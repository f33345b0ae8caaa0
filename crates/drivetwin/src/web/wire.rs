//! The wire's REST API: faults on a front end (a CAN bus, a Modbus server, an EtherCAT chain)
//! and pcap traces of a bus, started and stopped while the cell runs
//! ([`crate::cell::wire_faults`]).

use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::routing::{delete, post};
use axum::{Json, Router};
use serde::{Deserialize, Serialize};
use utoipa::{OpenApi, ToSchema};

use super::api::ApiError;
use super::AppState;
use crate::cell::control::ControlHandle;
use crate::cell::wire_faults::{
    ActiveFault, FaultKind, FaultSpec, FrontEnd, Reach, WireAnswer, WireError, WireRequest,
};

type ApiResult<T> = Result<Json<T>, ApiError>;

fn bad(error: impl Into<String>) -> ApiError {
    ApiError::new(StatusCode::BAD_REQUEST, error)
}

impl From<WireError> for ApiError {
    fn from(e: WireError) -> ApiError {
        let status = match e {
            WireError::Stopped => StatusCode::SERVICE_UNAVAILABLE,
            WireError::NoFrontEnd(_) | WireError::NoTrace(_) => StatusCode::NOT_FOUND,
            WireError::Fault(crate::cell::wire_faults::WireFaultError::NoFault(_)) => {
                StatusCode::NOT_FOUND
            }
            WireError::Tracing(_) => StatusCode::CONFLICT,
            WireError::Fault(_) | WireError::Trace(_) => StatusCode::BAD_REQUEST,
        };
        ApiError::new(status, e.to_string())
    }
}

/// Runs a blocking call on the control handle off the runtime's workers.
async fn call<T: Send + 'static>(
    handle: &ControlHandle,
    f: impl FnOnce(&ControlHandle) -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    let handle = handle.clone();
    tokio::task::spawn_blocking(move || f(&handle))
        .await
        .map_err(|_| ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "the request was lost"))?
}

fn front_end(kind: &str, index: &str) -> Result<FrontEnd, ApiError> {
    let n: usize = index
        .parse()
        .map_err(|_| bad(format!("{index:?}: not an index (0, 1, …)")))?;
    match kind {
        "bus" => Ok(FrontEnd::Bus(n)),
        "modbus" => Ok(FrontEnd::Modbus(n)),
        "ethercat" => Ok(FrontEnd::Ethercat(n)),
        // One socketcand client, by its TCP port.
        "client" => u16::try_from(n)
            .map(FrontEnd::Client)
            .map_err(|_| bad(format!("{index:?}: a client's TCP port (1 … 65535)"))),
        other => Err(ApiError::new(
            StatusCode::NOT_FOUND,
            format!("{other:?}: a front end is bus, modbus, ethercat or client"),
        )),
    }
}

/// A fault while it is active.
#[derive(Debug, Serialize, ToSchema)]
pub struct FaultView {
    pub id: u32,
    /// drop, delay, corrupt or cable-break (a stopped SYNC is a drop of 080h).
    pub fault: String,
    /// The node whose frames it takes; none: `reach`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub node: Option<u8>,
    /// node, outside or bus.
    pub reach: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cob_id: Option<u16>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub share: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delay_ms: Option<f64>,
    /// Frames it takes still.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frames_left: Option<u32>,
    /// When it ends, on the cell's clock (seconds).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub until_s: Option<f64>,
}

impl From<&ActiveFault> for FaultView {
    fn from(a: &ActiveFault) -> FaultView {
        let f = a.fault;
        let (fault, share, delay_ms) = match f.kind {
            FaultKind::Drop { share } => ("drop", Some(share), None),
            FaultKind::Delay { by } => ("delay", None, Some(by.as_secs_f64() * 1e3)),
            FaultKind::Corrupt { share } => ("corrupt", Some(share), None),
            FaultKind::CableBreak => ("cable-break", None, None),
        };
        let (node, reach) = match f.reach {
            Reach::Node(n) => (Some(n), "node"),
            Reach::Outside => (None, "outside"),
            Reach::Bus => (None, "bus"),
        };
        FaultView {
            id: a.id,
            fault: fault.into(),
            node,
            reach: reach.into(),
            cob_id: f.cob_id,
            share,
            delay_ms,
            frames_left: a.left,
            until_s: a.until.map(|t| t.as_nanos() as f64 / 1e9),
        }
    }
}

fn faults_of(h: &ControlHandle, front: FrontEnd) -> Result<Vec<FaultView>, ApiError> {
    match h.wire(WireRequest::List { front })? {
        WireAnswer::Faults(f) => Ok(f.iter().map(FaultView::from).collect()),
        _ => Err(ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "unexpected answer",
        )),
    }
}

/// The faults active on a front end.
#[utoipa::path(get, path = "/api/wire/{front}/{index}/faults", tag = "wire",
    params(("front" = String, Path, description = "bus, modbus or ethercat"),
        ("index" = u32, Path, description = "the bus, Modbus drive or EtherCAT chain (from 0)")),
    responses((status = 200, body = [FaultView]), (status = 400, body = ApiError), (status = 404, body = ApiError)))]
async fn list_faults(
    State(s): State<AppState>,
    Path((front, index)): Path<(String, String)>,
) -> ApiResult<Vec<FaultView>> {
    let front = front_end(&front, &index)?;
    call(&s.handle, move |h| faults_of(h, front))
        .await
        .map(Json)
}

/// Starts a fault on a front end: `{"fault": "cable-break", "node": 1, "for": "2s"}`,
/// `{"fault": "drop", "share": 0.5}`, `{"fault": "delay", "delay": "5ms"}`,
/// `{"fault": "corrupt", "frames": 3}`, `{"fault": "corrupt", "share": 0.25}`,
/// `{"fault": "stop-sync"}`. Without a node the fault takes what the front end's clients
/// send in (`"reach": "bus"`: every frame).
#[utoipa::path(post, path = "/api/wire/{front}/{index}/faults", tag = "wire",
    params(("front" = String, Path, description = "bus, modbus, ethercat or client"),
        ("index" = u32, Path, description = "the bus, Modbus drive or EtherCAT chain (from 0), or a socketcand client's TCP port")),
    request_body = FaultSpec,
    responses((status = 201, body = FaultView), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError), (status = 410, body = ApiError), (status = 415, body = ApiError)))]
async fn add_fault(
    State(s): State<AppState>,
    Path((front, index)): Path<(String, String)>,
    body: Result<Json<FaultSpec>, JsonRejection>,
) -> Result<(StatusCode, Json<FaultView>), ApiError> {
    let front = front_end(&front, &index)?;
    let Json(spec) = body?;
    let fault = spec.to_fault().map_err(bad)?;
    if matches!(front, FrontEnd::Modbus(_) | FrontEnd::Ethercat(_))
        && (matches!(fault.reach, Reach::Node(_)) || fault.cob_id.is_some())
    {
        return Err(bad("a node and a cob_id are a CAN bus's"));
    }
    if matches!(front, FrontEnd::Client(_)) && matches!(fault.reach, Reach::Node(_)) {
        // Decision: a client's fault takes the frames to and from that client (a cob_id
        // narrows it); a node's frames are a bus fault's.
        return Err(bad("a client's fault takes no node (a cob_id narrows it)"));
    }
    call(&s.handle, move |h| {
        let id = match h.wire(WireRequest::Add { front, fault })? {
            WireAnswer::Added(id) => id,
            _ => {
                return Err(ApiError::new(
                    StatusCode::SERVICE_UNAVAILABLE,
                    "unexpected answer",
                ))
            }
        };
        faults_of(h, front)?
            .into_iter()
            .find(|f| f.id == id)
            // Ended already (a fault of no time).
            .ok_or_else(|| ApiError::new(StatusCode::GONE, format!("fault {id} has ended")))
    })
    .await
    .map(|v| (StatusCode::CREATED, Json(v)))
}

/// Ends every fault of a front end.
#[utoipa::path(delete, path = "/api/wire/{front}/{index}/faults", tag = "wire",
    params(("front" = String, Path, description = "bus, modbus or ethercat"),
        ("index" = u32, Path, description = "the bus, Modbus drive or EtherCAT chain (from 0)")),
    responses((status = 200, body = [FaultView]), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError)))]
async fn clear_faults(
    State(s): State<AppState>,
    Path((front, index)): Path<(String, String)>,
) -> ApiResult<Vec<FaultView>> {
    let front = front_end(&front, &index)?;
    call(&s.handle, move |h| {
        h.wire(WireRequest::Clear { front })?;
        faults_of(h, front)
    })
    .await
    .map(Json)
}

/// Ends one fault.
#[utoipa::path(delete, path = "/api/wire/{front}/{index}/faults/{id}", tag = "wire",
    params(("front" = String, Path, description = "bus, modbus or ethercat"),
        ("index" = u32, Path, description = "the bus, Modbus drive or EtherCAT chain (from 0)"),
        ("id" = u32, Path, description = "the fault's id")),
    responses((status = 200, body = [FaultView]), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError)))]
async fn remove_fault(
    State(s): State<AppState>,
    Path((front, index, id)): Path<(String, String, String)>,
) -> ApiResult<Vec<FaultView>> {
    let front = front_end(&front, &index)?;
    let id: u32 = id
        .parse()
        .map_err(|_| bad(format!("{id:?}: not a fault id")))?;
    call(&s.handle, move |h| {
        h.wire(WireRequest::Remove { front, id })?;
        faults_of(h, front)
    })
    .await
    .map(Json)
}

/// What to call a trace.
#[derive(Debug, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TraceBody {
    /// A file name (letters, digits, `-`, `_`, `.`) ending in `.pcap` (LINKTYPE_CAN_SOCKETCAN)
    /// or `.log` (candump), made in the system's temporary directory; none: a new pcap there.
    pub name: Option<String>,
}

/// Decision: a client names the file, never its directory: the console (loopback, or a
/// token) must not let a request write anywhere the process may (it often runs as root on
/// a test machine). The answer gives the whole path.
fn trace_name(name: &str) -> Result<&str, ApiError> {
    let plain = !name.starts_with('.')
        && name.len() <= 128
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'));
    let kind = name.ends_with(".pcap") || name.ends_with(".log");
    if plain && kind {
        Ok(name)
    } else {
        Err(bad(format!(
            "trace name {name:?}: a file name of letters, digits, '-', '_', '.' ending in .pcap \
             or .log (no directory)"
        )))
    }
}

#[derive(Debug, Serialize, ToSchema)]
pub struct TraceView {
    pub bus: usize,
    /// The file being written.
    pub path: String,
}

fn parse_bus(bus: &str) -> Result<usize, ApiError> {
    bus.parse()
        .map_err(|_| bad(format!("bus {bus:?}: not a bus index (0, 1, …)")))
}

/// Starts a trace of every frame of a bus; answers the file's path.
#[utoipa::path(post, path = "/api/buses/{bus}/trace", tag = "wire",
    params(("bus" = u32, Path, description = "the bus's index")),
    request_body = TraceBody,
    responses((status = 201, body = TraceView), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError), (status = 409, body = ApiError), (status = 415, body = ApiError)))]
async fn start_trace(
    State(s): State<AppState>,
    Path(bus): Path<String>,
    body: Result<Json<TraceBody>, JsonRejection>,
) -> Result<(StatusCode, Json<TraceView>), ApiError> {
    let bus = parse_bus(&bus)?;
    let Json(body) = body?;
    let path = match body.name {
        Some(n) => std::env::temp_dir().join(trace_name(&n)?),
        None => {
            let stamp = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap_or_default()
                .as_millis();
            std::env::temp_dir().join(format!(
                "drivetwin-{}-bus{bus}-{stamp}.pcap",
                std::process::id()
            ))
        }
    };
    let shown = path.display().to_string();
    call(&s.handle, move |h| {
        h.wire(WireRequest::StartTrace { bus, path })?;
        Ok(())
    })
    .await?;
    Ok((StatusCode::CREATED, Json(TraceView { bus, path: shown })))
}

/// Stops the trace of a bus (the file is complete when this answers).
#[utoipa::path(delete, path = "/api/buses/{bus}/trace", tag = "wire",
    params(("bus" = u32, Path, description = "the bus's index")),
    responses((status = 204), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError)))]
async fn stop_trace(
    State(s): State<AppState>,
    Path(bus): Path<String>,
) -> Result<StatusCode, ApiError> {
    let bus = parse_bus(&bus)?;
    call(&s.handle, move |h| {
        h.wire(WireRequest::StopTrace { bus })?;
        Ok(())
    })
    .await?;
    Ok(StatusCode::NO_CONTENT)
}

#[derive(OpenApi)]
#[openapi(
    paths(
        list_faults,
        add_fault,
        clear_faults,
        remove_fault,
        start_trace,
        stop_trace
    ),
    components(schemas(
        FaultSpec,
        FaultView,
        TraceBody,
        TraceView,
        crate::cell::wire_faults::FaultName,
        crate::cell::wire_faults::ReachName
    ))
)]
pub struct WireDoc;

/// The main document with the wire's (and the scenarios') paths.
pub fn merged(mut doc: utoipa::openapi::OpenApi) -> utoipa::openapi::OpenApi {
    doc.merge(WireDoc::openapi());
    doc.merge(super::ethercat_line::LineDoc::openapi());
    doc.merge(super::scenarios::ScenarioDoc::openapi());
    doc.merge(super::physics::PhysicsDoc::openapi());
    doc.merge(super::load_fmu::LoadFmuDoc::openapi());
    doc
}

pub fn routes() -> Router<AppState> {
    Router::new()
        .route(
            "/api/wire/{front}/{index}/faults",
            post(add_fault).get(list_faults).delete(clear_faults),
        )
        .route(
            "/api/wire/{front}/{index}/faults/{id}",
            delete(remove_fault),
        )
        .route(
            "/api/buses/{bus}/trace",
            post(start_trace).delete(stop_trace),
        )
        .merge(super::scenarios::routes())
}
