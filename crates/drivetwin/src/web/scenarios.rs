//! Scenarios against the live cell: `POST /api/scenarios` with a scenario file's TOML starts
//! a run on the cell's own clock, on a thread of its own that reaches the cell through the
//! control handle ([`crate::scenario::live`]); `GET /api/scenarios/{id}` answers its state
//! and, once it has ended, its report. The file's `cell` is not used: the run is the live
//! cell's.

use std::sync::{Mutex, OnceLock};
use std::time::Duration;

use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::routing::{get, post};
use axum::{Json, Router};
use serde::Serialize;
use utoipa::{OpenApi, ToSchema};

use super::api::ApiError;
use super::AppState;
use crate::scenario::live::LiveRig;
use crate::scenario::report::{Outcome, Report};
use crate::scenario::{runner, Scenario};

/// Runs kept (the oldest ended run goes first).
pub const MAX_RUNS: usize = 64;
/// Runs at the same time at most.
pub const MAX_RUNNING: usize = 4;
/// The longest run the API starts.
pub const MAX_LENGTH: Duration = Duration::from_secs(3600);
/// The largest scenario text taken.
pub const MAX_TEXT: usize = 256 * 1024;

#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct ScenarioRun {
    pub id: u32,
    pub name: String,
    /// running or done.
    pub status: String,
    /// How long the run lasts, seconds.
    pub length_s: f64,
    /// The report, once the run has ended.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub report: Option<Report>,
    /// Why the run could not start on the cell.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

#[derive(Default)]
struct Runs {
    next: u32,
    runs: Vec<ScenarioRun>,
}

fn runs() -> &'static Mutex<Runs> {
    static RUNS: OnceLock<Mutex<Runs>> = OnceLock::new();
    RUNS.get_or_init(Mutex::default)
}

fn lock() -> std::sync::MutexGuard<'static, Runs> {
    // A panic while the lock was held leaves plain data: use it.
    runs().lock().unwrap_or_else(|e| e.into_inner())
}

fn bad(error: impl Into<String>) -> ApiError {
    ApiError::new(StatusCode::BAD_REQUEST, error)
}

/// Starts a scenario (the TOML of a scenario file, sent as text) on the live cell.
#[utoipa::path(post, path = "/api/scenarios", tag = "scenarios",
    request_body(content = String, content_type = "text/plain",
        description = "a scenario file (its `cell` is not used: the run is the live cell's)"),
    responses((status = 202, body = ScenarioRun), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 413, body = ApiError), (status = 429, body = ApiError)))]
async fn start(
    State(s): State<AppState>,
    body: axum::body::Bytes,
) -> Result<(StatusCode, Json<ScenarioRun>), ApiError> {
    if body.len() > MAX_TEXT {
        return Err(ApiError::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!("a scenario of at most {MAX_TEXT} bytes"),
        ));
    }
    let text = std::str::from_utf8(&body).map_err(|_| bad("the scenario is not UTF-8 text"))?;
    let scenario = Scenario::parse(text, "scenario", None).map_err(|e| bad(e.to_string()))?;
    if scenario.until > MAX_LENGTH {
        return Err(bad(format!(
            "a run of at most {} s on the live cell",
            MAX_LENGTH.as_secs()
        )));
    }
    let run = {
        let mut r = lock();
        if r.runs.iter().filter(|x| x.status == "running").count() >= MAX_RUNNING {
            return Err(ApiError::new(
                StatusCode::TOO_MANY_REQUESTS,
                format!("{MAX_RUNNING} scenarios are running; wait for one to end"),
            ));
        }
        if r.runs.len() >= MAX_RUNS {
            if let Some(i) = r.runs.iter().position(|x| x.status != "running") {
                r.runs.remove(i);
            }
        }
        r.next = r.next.wrapping_add(1);
        let run = ScenarioRun {
            id: r.next,
            name: scenario.name.clone(),
            status: "running".into(),
            length_s: scenario.until.as_secs_f64(),
            report: None,
            error: None,
        };
        r.runs.push(run.clone());
        run
    };
    let id = run.id;
    let handle = s.handle.clone();
    let spawned = std::thread::Builder::new()
        .name(format!("scenario-{id}"))
        .spawn(move || {
            let result = LiveRig::new(handle).map(|mut rig| runner::run(&scenario, &mut rig));
            let mut r = lock();
            if let Some(x) = r.runs.iter_mut().find(|x| x.id == id) {
                x.status = "done".into();
                match result {
                    Ok(report) => x.report = Some(report),
                    Err(e) => x.error = Some(e),
                }
            }
        });
    if let Err(e) = spawned {
        let mut r = lock();
        r.runs.retain(|x| x.id != id);
        return Err(ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            format!("no thread for the run: {e}"),
        ));
    }
    Ok((StatusCode::ACCEPTED, Json(run)))
}

/// The runs kept, without their reports.
#[utoipa::path(get, path = "/api/scenarios", tag = "scenarios",
    responses((status = 200, body = [ScenarioRun])))]
async fn list() -> Json<Vec<ScenarioRun>> {
    let r = lock();
    Json(
        r.runs
            .iter()
            .map(|x| ScenarioRun {
                report: None,
                ..x.clone()
            })
            .collect(),
    )
}

/// A run: running, or done with its report.
#[utoipa::path(get, path = "/api/scenarios/{id}", tag = "scenarios",
    params(("id" = u32, Path, description = "the run's id")),
    responses((status = 200, body = ScenarioRun), (status = 400, body = ApiError), (status = 404, body = ApiError)))]
async fn get_run(Path(id): Path<String>) -> Result<Json<ScenarioRun>, ApiError> {
    let id: u32 = id
        .parse()
        .map_err(|_| bad(format!("{id:?}: not a run id")))?;
    let r = lock();
    r.runs
        .iter()
        .find(|x| x.id == id)
        .cloned()
        .map(Json)
        .ok_or_else(|| ApiError::new(StatusCode::NOT_FOUND, format!("no scenario run {id}")))
}

#[derive(OpenApi)]
#[openapi(
    paths(start, list, get_run),
    components(schemas(ScenarioRun, Report, Outcome))
)]
pub struct ScenarioDoc;

pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/api/scenarios", post(start).get(list))
        .route("/api/scenarios/{id}", get(get_run))
}
