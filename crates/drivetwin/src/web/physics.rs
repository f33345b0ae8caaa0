//! The plant's physics over REST: the motor's and the power stage's temperatures with the
//! ambient they cool towards, the encoder (connected, disconnected, noisy), and the limit and
//! home switches by name. The drive's own supervision raises its manual's messages from them
//! (`drive::drive::plant_supervision`, `drive::vendors::festo_cmmo_st::plant_supervision`).

use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::routing::{get, put};
use axum::{Json, Router};
use drive::drive::named_switches::NamedSwitch;
use drive::drive::plant_supervision;
use drive::encoder_fault::EncoderFault;
use drive::thermal::ThermalData;
use serde::{Deserialize, Serialize};
use utoipa::{OpenApi, ToSchema};

use super::api::{call, find_drive, ApiError, ApiResult};
use super::AppState;
use crate::cell::control::{PhysicsChange, PlantPhysics};

/// Temperatures and encoder of a drive's plant.
#[derive(Debug, Serialize, ToSchema)]
pub struct PhysicsView {
    pub ambient_c: f64,
    pub motor_temperature_c: f64,
    pub power_stage_temperature_c: f64,
    /// `connected`, `disconnected` or `noisy`.
    pub encoder: String,
    /// The noise amplitude of a noisy encoder, increments of the drive's reading.
    pub noise_increments: Option<u32>,
}

impl From<PlantPhysics> for PhysicsView {
    fn from(p: PlantPhysics) -> Self {
        let (encoder, noise) = match p.encoder {
            EncoderFault::Connected => ("connected", None),
            EncoderFault::Disconnected => ("disconnected", None),
            EncoderFault::Noisy { amplitude } => ("noisy", Some(amplitude)),
        };
        PhysicsView {
            ambient_c: p.ambient_c,
            motor_temperature_c: p.motor_c,
            power_stage_temperature_c: p.power_stage_c,
            encoder: encoder.to_owned(),
            noise_increments: noise,
        }
    }
}

/// The ambient temperature.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AmbientBody {
    /// °C, −50 … 200.
    #[schema(minimum = -50.0, maximum = 200.0)]
    pub celsius: f64,
}

/// The thermal figures (each optional: unset ones stay).
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ThermalBody {
    /// Motor: steady rise at the rated current, K.
    pub motor_rise_k: Option<f64>,
    /// Motor: thermal time constant, s.
    pub motor_time_constant_s: Option<f64>,
    /// Power stage: steady rise at the motor's rated current, K.
    pub stage_rise_k: Option<f64>,
    /// Power stage: thermal time constant, s.
    pub stage_time_constant_s: Option<f64>,
}

/// The encoder's state.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EncoderBody {
    /// `connected` (or `ok`), `disconnected`, `noisy`.
    pub fault: String,
    /// For `noisy`: each reading off by up to ± this many increments (default 100).
    pub noise_increments: Option<u32>,
}

/// A switch's state.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SwitchBody {
    /// `true` actuated, `false` released, `null` back to the simulated travel.
    pub actuated: Option<bool>,
}

// The checks of the bodies that need no cell, shared by the handlers below and the fuzz target
// `http_body` (after `super::api::parse_body`).

impl AmbientBody {
    pub fn check(&self) -> Result<(), ApiError> {
        if !(self.celsius.is_finite() && (-50.0..=200.0).contains(&self.celsius)) {
            return Err(ApiError::bad(format!(
                "celsius {}: a finite number within −50 … 200",
                self.celsius
            )));
        }
        Ok(())
    }
}

impl ThermalBody {
    /// The figures given over the defaults; each within 0 … 10⁶.
    pub fn data(&self) -> Result<ThermalData, ApiError> {
        let fields = [
            ("motor_rise_k", self.motor_rise_k),
            ("motor_time_constant_s", self.motor_time_constant_s),
            ("stage_rise_k", self.stage_rise_k),
            ("stage_time_constant_s", self.stage_time_constant_s),
        ];
        for (name, v) in fields {
            if let Some(v) = v.filter(|v| !(v.is_finite() && (0.0..=1e6).contains(v))) {
                return Err(ApiError::bad(format!("{name} {v}: within 0 … 10⁶")));
            }
        }
        let d = ThermalData::default();
        Ok(ThermalData {
            motor_rise_k: self.motor_rise_k.unwrap_or(d.motor_rise_k),
            motor_time_constant_s: self
                .motor_time_constant_s
                .unwrap_or(d.motor_time_constant_s),
            stage_rise_k: self.stage_rise_k.unwrap_or(d.stage_rise_k),
            stage_time_constant_s: self
                .stage_time_constant_s
                .unwrap_or(d.stage_time_constant_s),
        })
    }
}

impl EncoderBody {
    /// The encoder state named (a noisy one 100 increments unless given).
    pub fn fault(&self) -> Result<EncoderFault, ApiError> {
        plant_supervision::encoder_fault(&self.fault, self.noise_increments.unwrap_or(100))
            .ok_or_else(|| {
                ApiError::bad(format!(
                    "fault {:?}: one of connected, disconnected, noisy",
                    self.fault
                ))
            })
    }
}

async fn change(s: AppState, drive: String, change: PhysicsChange) -> ApiResult<PhysicsView> {
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        Ok(PhysicsView::from(h.physics(info.index, change)?))
    })
    .await
    .map(Json)
}

/// The drive's temperatures and encoder.
#[utoipa::path(get, path = "/api/drives/{drive}/physics", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = PhysicsView), (status = 400, body = ApiError),
        (status = 404, body = ApiError)))]
async fn show(State(s): State<AppState>, Path(drive): Path<String>) -> ApiResult<PhysicsView> {
    change(s, drive, PhysicsChange::None).await
}

/// Sets the ambient temperature: motor and power stage heat or cool towards it, the drive's
/// supervision raises its manual's temperature messages (CMMP-AS 18-0 / 03-0 / 04-0, CMMO-ST
/// 33h / 15h / 16h, Nanotec 0002h, Kinco Motor / Controller Temperature).
#[utoipa::path(put, path = "/api/drives/{drive}/ambient", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    request_body = AmbientBody,
    responses((status = 200, body = PhysicsView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError),
        (status = 415, body = ApiError)))]
async fn set_ambient(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<AmbientBody>, JsonRejection>,
) -> ApiResult<PhysicsView> {
    let Json(body) = body?;
    body.check()?;
    change(s, drive, PhysicsChange::Ambient(body.celsius)).await
}

/// Sets the thermal figures (time constants, rises) of the motor and the power stage.
#[utoipa::path(put, path = "/api/drives/{drive}/thermal", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    request_body = ThermalBody,
    responses((status = 200, body = PhysicsView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError),
        (status = 415, body = ApiError)))]
async fn set_thermal(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<ThermalBody>, JsonRejection>,
) -> ApiResult<PhysicsView> {
    let Json(body) = body?;
    let data = body.data()?;
    change(s, drive, PhysicsChange::Thermal(data)).await
}

/// Faults or repairs the encoder: `disconnected` (the reading stands still; CMMP-AS 08-0,
/// Kinco Encoder not connected, CMMO-ST 06h), `noisy` (count errors; beyond 1024 increments
/// the drive calls it an encoder error), `connected`.
#[utoipa::path(put, path = "/api/drives/{drive}/encoder", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    request_body = EncoderBody,
    responses((status = 200, body = PhysicsView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError),
        (status = 415, body = ApiError)))]
async fn set_encoder(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<EncoderBody>, JsonRejection>,
) -> ApiResult<PhysicsView> {
    let Json(body) = body?;
    let fault = body.fault()?;
    change(s, drive, PhysicsChange::Encoder(fault)).await
}

/// Actuates, releases or gives back to the travel a limit or home switch by name
/// (`limit_positive`, `limit_negative`, `home`; also `E0` / `E1`, `P limit+` / `P limit-`,
/// `home_signal`): forced on the input whose function it is (CMMP-AS 6510h:12 / :13, the Kinco's
/// DIN function codes 2010h:03 … :09), at the level the drive reads as actuated.
#[utoipa::path(put, path = "/api/drives/{drive}/switches/{name}", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell"),
        ("name" = String, Path, description = "limit_positive, limit_negative or home")),
    request_body = SwitchBody,
    responses((status = 200, body = PhysicsView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError),
        (status = 415, body = ApiError)))]
async fn set_switch(
    State(s): State<AppState>,
    Path((drive, name)): Path<(String, String)>,
    body: Result<Json<SwitchBody>, JsonRejection>,
) -> ApiResult<PhysicsView> {
    let Json(body) = body?;
    let switch = NamedSwitch::parse(&name).ok_or_else(|| {
        ApiError::not_found(format!(
            "switch {name:?}: one of limit_positive, limit_negative, home"
        ))
    })?;
    change(s, drive, PhysicsChange::Switch(switch, body.actuated)).await
}

#[derive(OpenApi)]
#[openapi(
    paths(show, set_ambient, set_thermal, set_encoder, set_switch),
    components(schemas(PhysicsView, AmbientBody, ThermalBody, EncoderBody, SwitchBody))
)]
pub struct PhysicsDoc;

pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/api/drives/{drive}/physics", get(show))
        .route("/api/drives/{drive}/ambient", put(set_ambient))
        .route("/api/drives/{drive}/thermal", put(set_thermal))
        .route("/api/drives/{drive}/encoder", put(set_encoder))
        .route("/api/drives/{drive}/switches/{name}", put(set_switch))
}
