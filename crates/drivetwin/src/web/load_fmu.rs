//! A drive's load FMU over REST (docs/cosimulation.md): `GET /api/drives/{drive}/load` shows
//! it (the FMU, its mapping table, the mapped variables' values as last exchanged, its steps
//! and slow steps), `PUT /api/drives/{drive}/load/fmu` couples one while the cell runs (the
//! keys of the cell file's `[drive.load]`), `DELETE` uncouples it. `PUT
//! /api/drives/{drive}/load` stays the constant load torque (`super::api`).

use std::collections::BTreeMap;
use std::path::PathBuf;

use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::routing::{get, put};
use axum::{Json, Router};
use serde::{Deserialize, Serialize};
use utoipa::{OpenApi, ToSchema};

use super::api::{call, find_drive, ApiError, ApiResult};
use super::AppState;
use crate::cell::load_control::{LoadControlError, LoadState};
use crate::cosim::{FmuLoadError, LoadMapping, LoadValue};

/// A mapped variable and its value as last exchanged.
#[derive(Debug, Serialize, ToSchema)]
pub struct MappedVariableView {
    /// `torque`, `speed`, `angle`, `load_torque`, `position`, or a switch's name.
    pub role: String,
    /// The FMU's variable.
    pub variable: String,
    /// A Float64 variable's value.
    pub value: Option<f64>,
    /// A Boolean variable's value.
    pub level: Option<bool>,
}

/// The coupled FMU.
#[derive(Debug, Serialize, ToSchema)]
pub struct FmuView {
    pub fmu: String,
    /// `2.0` or `3.0`.
    pub fmi_version: String,
    pub mapping: LoadFmuBody,
    pub variables: Vec<MappedVariableView>,
    /// `doStep` calls made.
    pub steps: u64,
    /// Of them, those longer in wall time than the virtual time they advanced.
    pub slow_steps: u64,
    /// The longest `doStep`, µs of wall time.
    pub worst_step_us: f64,
}

/// A drive's load FMU.
#[derive(Debug, Serialize, ToSchema)]
pub struct LoadView {
    /// The coupled FMU; `null`: none (the motor model's own load torque).
    pub fmu: Option<FmuView>,
    /// Why the FMU stopped the drive, once it has.
    pub failure: Option<String>,
}

/// A load FMU and its mapping table: the keys of the cell file's `[drive.load]`.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LoadFmuBody {
    /// The `.fmu` archive (FMI 2.0 or 3.0 co-simulation); relative: to drivetwin's working
    /// directory.
    pub fmu: String,
    /// Float64 input ← the motor's torque, N·m.
    pub torque: Option<String>,
    /// Float64 input ← the shaft speed, rad/s.
    pub speed: Option<String>,
    /// Float64 input ← the shaft angle, rad.
    pub angle: Option<String>,
    /// Float64 output → the load torque on the shaft, N·m.
    pub load_torque: String,
    /// Float64 output → the load's position.
    pub position: Option<String>,
    /// Boolean outputs → the drive's switches: `home`, `limit_positive`, `limit_negative` →
    /// FMU variable.
    #[serde(default)]
    pub switches: BTreeMap<String, String>,
    /// Float64 parameters set before the FMU initialises: variable → value.
    #[serde(default)]
    pub parameters: BTreeMap<String, f64>,
}

impl LoadFmuBody {
    /// The mapping; every name non-empty, every parameter finite.
    pub fn mapping(&self) -> Result<LoadMapping, ApiError> {
        if self.fmu.is_empty() || self.fmu.contains('\0') {
            return Err(ApiError::bad("fmu: the path of an .fmu archive"));
        }
        if let Some((name, v)) = self.parameters.iter().find(|(_, v)| !v.is_finite()) {
            return Err(ApiError::bad(format!("parameter {name} = {v}: not finite")));
        }
        Ok(LoadMapping {
            fmu: PathBuf::from(&self.fmu),
            torque: self.torque.clone(),
            speed: self.speed.clone(),
            angle: self.angle.clone(),
            load_torque: self.load_torque.clone(),
            position: self.position.clone(),
            switches: self.switches.clone(),
            parameters: self.parameters.clone(),
        })
    }

    fn from_mapping(m: &LoadMapping) -> Self {
        LoadFmuBody {
            fmu: m.fmu.display().to_string(),
            torque: m.torque.clone(),
            speed: m.speed.clone(),
            angle: m.angle.clone(),
            load_torque: m.load_torque.clone(),
            position: m.position.clone(),
            switches: m.switches.clone(),
            parameters: m.parameters.clone(),
        }
    }
}

impl From<LoadState> for LoadView {
    fn from(s: LoadState) -> Self {
        LoadView {
            fmu: s.coupled.map(|c| FmuView {
                fmu: c.fmu,
                fmi_version: c.fmi_version.to_owned(),
                mapping: LoadFmuBody::from_mapping(&c.mapping),
                variables: c
                    .values
                    .into_iter()
                    .map(|(role, variable, v)| {
                        let (value, level) = match v {
                            LoadValue::Float64(x) => (Some(x), None),
                            LoadValue::Boolean(b) => (None, Some(b)),
                        };
                        MappedVariableView {
                            role,
                            variable,
                            value,
                            level,
                        }
                    })
                    .collect(),
                steps: c.report.steps,
                slow_steps: c.report.slow_steps,
                worst_step_us: c.report.worst_step_ns as f64 / 1000.0,
            }),
            failure: s.failure,
        }
    }
}

impl From<LoadControlError> for ApiError {
    fn from(e: LoadControlError) -> ApiError {
        match e {
            LoadControlError::Control(c) => c.into(),
            // The drive cannot take a load: a conflict with what it is.
            LoadControlError::Load(FmuLoadError::NoShaft { .. }) => {
                ApiError::new(StatusCode::CONFLICT, e.to_string())
            }
            // The FMU or its table is refused: the request's own fault.
            LoadControlError::Load(_) => ApiError::bad(e.to_string()),
        }
    }
}

/// The drive's load FMU: the FMU, its mapping table, the mapped variables' values as last
/// exchanged, its steps and slow steps.
#[utoipa::path(get, path = "/api/drives/{drive}/load", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = LoadView), (status = 400, body = ApiError),
        (status = 404, body = ApiError)))]
async fn show(State(s): State<AppState>, Path(drive): Path<String>) -> ApiResult<LoadView> {
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        Ok(LoadView::from(h.load(info.index)?))
    })
    .await
    .map(Json)
}

/// Couples a load FMU (FMI 2.0 or 3.0 co-simulation) to the drive's shaft while the cell runs,
/// in place of any other: refused as the cell file's `[drive.load]` is (400: the archive does
/// not open, a mapped variable is missing or of the wrong type; 409: the drive has no motor
/// shaft). It starts at the drive's next plant cycle.
#[utoipa::path(put, path = "/api/drives/{drive}/load/fmu", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    request_body = LoadFmuBody,
    responses((status = 200, body = LoadView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError),
        (status = 409, body = ApiError), (status = 415, body = ApiError)))]
async fn couple(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<LoadFmuBody>, JsonRejection>,
) -> ApiResult<LoadView> {
    let Json(body) = body?;
    let mapping = body.mapping()?;
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        Ok(LoadView::from(h.couple_load(info.index, &mapping)?))
    })
    .await
    .map(Json)
}

/// Uncouples the drive's load FMU: its switches go back to the travel, the load torque to
/// 0 N·m. Without one, nothing changes.
#[utoipa::path(delete, path = "/api/drives/{drive}/load/fmu", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = LoadView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError)))]
async fn uncouple(State(s): State<AppState>, Path(drive): Path<String>) -> ApiResult<LoadView> {
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        Ok(LoadView::from(h.uncouple_load(info.index)?))
    })
    .await
    .map(Json)
}

#[derive(OpenApi)]
#[openapi(
    paths(show, couple, uncouple),
    components(schemas(LoadView, FmuView, MappedVariableView, LoadFmuBody))
)]
pub struct LoadFmuDoc;

pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/api/drives/{drive}/load", get(show))
        .route("/api/drives/{drive}/load/fmu", put(couple).delete(uncouple))
}
