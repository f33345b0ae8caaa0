//! The REST API of an EtherCAT chain's line ([`crate::cell::ethercat_line`]): a cable pulled
//! and plugged back, a slave switched off and on, a slave's clock off nominal, while a master
//! runs the chain.

use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::routing::get;
use axum::{Json, Router};
use utoipa::OpenApi;

use super::api::ApiError;
use super::AppState;
use crate::cell::ethercat_line::{LineAction, LineControlError, LineStatus, SlaveClock};

impl From<LineControlError> for ApiError {
    fn from(e: LineControlError) -> ApiError {
        let status = match e {
            LineControlError::NoChain(_) => StatusCode::NOT_FOUND,
            LineControlError::Refused(_) => StatusCode::BAD_REQUEST,
            LineControlError::Stopped => StatusCode::SERVICE_UNAVAILABLE,
        };
        ApiError::new(status, e.to_string())
    }
}

fn chain_index(text: &str) -> Result<usize, ApiError> {
    text.parse().map_err(|_| {
        ApiError::new(
            StatusCode::BAD_REQUEST,
            format!("{text:?}: not a chain index (0, 1, …)"),
        )
    })
}

async fn call(
    s: &AppState,
    chain: usize,
    action: Option<LineAction>,
) -> Result<LineStatus, ApiError> {
    let handle = s.handle.clone();
    tokio::task::spawn_blocking(move || handle.ethercat_line(chain, action))
        .await
        .map_err(|_| ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "the request was lost"))?
        .map_err(ApiError::from)
}

/// The chain's line: how many slaves a frame reaches, the pulled cable, the slaves without
/// power, the clocks off nominal, every slave's AL state.
#[utoipa::path(get, path = "/api/ethercat/{chain}/line", tag = "wire",
    params(("chain" = u32, Path, description = "the EtherCAT chain (from 0)")),
    responses((status = 200, body = LineStatus), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError)))]
async fn get_line(
    State(s): State<AppState>,
    Path(chain): Path<String>,
) -> Result<Json<LineStatus>, ApiError> {
    call(&s, chain_index(&chain)?, None).await.map(Json)
}

/// Changes the line: `{"action": "pull-cable", "after": 32}`, `{"action": "plug-cable"}`,
/// `{"action": "power-off", "slave": 3}`, `{"action": "power-on", "slave": 3}`,
/// `{"action": "clock", "slave": 1, "drift_ppm": 50, "jitter_ns": 20, "seed": 1}`.
#[utoipa::path(post, path = "/api/ethercat/{chain}/line", tag = "wire",
    params(("chain" = u32, Path, description = "the EtherCAT chain (from 0)")),
    request_body = LineAction,
    responses((status = 200, body = LineStatus), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError), (status = 415, body = ApiError)))]
async fn change_line(
    State(s): State<AppState>,
    Path(chain): Path<String>,
    body: Result<Json<LineAction>, JsonRejection>,
) -> Result<Json<LineStatus>, ApiError> {
    let chain = chain_index(&chain)?;
    let Json(action) = body?;
    call(&s, chain, Some(action)).await.map(Json)
}

#[derive(OpenApi)]
#[openapi(
    paths(get_line, change_line),
    components(schemas(LineAction, LineStatus, SlaveClock))
)]
pub struct LineDoc;

pub fn routes() -> Router<AppState> {
    Router::new().route(
        "/api/ethercat/{chain}/line",
        get(get_line).post(change_line),
    )
}
