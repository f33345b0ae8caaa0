//! Fault injection by diagnostic message: a drive's whole table (its manual's messages with
//! number, CiA code, reaction and text) and which are active; raise or clear any message by
//! the number its manual prints ("08-2", "2Fh", "0800h", "Error_State.9"). The drive then
//! reacts as if it had detected the message itself (`crate::cell::diagnostics`).

use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::routing::get;
use axum::{Json, Router};
use drive::drive::diagnostics::DiagnosticError;
use serde::Serialize;
use utoipa::{OpenApi, ToSchema};

use super::api::{call, find_drive, ApiError, ApiResult};
use super::AppState;
use crate::cell::diagnostics::DiagnosticState;

/// One message of a drive's diagnostic table.
#[derive(Debug, Serialize, ToSchema)]
pub struct DiagnosticView {
    /// As the manual prints it: "08-2" (CMMP-AS), "2Fh" (CMMO-ST), "0800h" (Nanotec),
    /// "Error_State.9" (Kinco).
    pub number: String,
    /// The CiA 301 error code the manual gives, as `0x8611` (none: "–").
    pub code: Option<String>,
    /// The EMCY code it is sent with on CANopen, as `0x8611` (`0x1000` where the manual
    /// gives none; none for the CMMO-ST).
    pub emcy: Option<String>,
    /// Error register 1001h bits besides bit 0.
    pub register: u8,
    /// The manual's default reaction: `ps_off`, `quick_stop`, `configurable`, `warning`,
    /// `ignore` or `unstated`.
    pub reaction: String,
    pub text: String,
    /// What the display shows, where the manual prints it (Kinco LED `020.0`).
    #[serde(skip_serializing_if = "String::is_empty")]
    pub display: String,
    /// CMMO-ST: the classes F/W/I the message may have and the reactions A…G.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub classes: String,
    #[serde(skip_serializing_if = "String::is_empty")]
    pub reactions: String,
    /// Where the manual says so.
    pub source: String,
    /// Raised (by the drive or from outside) and not yet acknowledged or cleared.
    pub active: bool,
}

impl From<&DiagnosticState> for DiagnosticView {
    fn from(s: &DiagnosticState) -> Self {
        let r = s.row;
        DiagnosticView {
            number: r.number.to_owned(),
            code: r.code.map(|c| format!("{c:#06X}")),
            emcy: s.emcy.map(|c| format!("{c:#06X}")),
            register: r.register,
            reaction: reaction_name(r.reaction).to_owned(),
            text: r.text.to_owned(),
            display: r.display.to_owned(),
            classes: r.classes.to_owned(),
            reactions: r.reactions.to_owned(),
            source: r.source.to_owned(),
            active: s.active,
        }
    }
}

fn reaction_name(r: od::Reaction) -> &'static str {
    match r {
        od::Reaction::PsOff => "ps_off",
        od::Reaction::QuickStop => "quick_stop",
        od::Reaction::Configurable => "configurable",
        od::Reaction::Warning => "warning",
        od::Reaction::Ignore => "ignore",
        od::Reaction::Unstated => "unstated",
    }
}

/// The 4xx of a refused raise or clear.
pub(super) fn refusal(e: DiagnosticError) -> ApiError {
    match e {
        DiagnosticError::Unknown => ApiError::new(
            StatusCode::NOT_FOUND,
            "the drive's diagnostic table has no such message (GET …/diagnostics lists them)",
        ),
        DiagnosticError::NotRaised => ApiError::new(
            StatusCode::CONFLICT,
            "the message was not raised from outside",
        ),
        DiagnosticError::Full => ApiError::new(
            StatusCode::CONFLICT,
            "too many messages raised at once (16); clear one first",
        ),
    }
}

/// The drive's diagnostic table with what is active.
#[utoipa::path(get, path = "/api/drives/{drive}/diagnostics", tag = "diagnostics",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = [DiagnosticView]), (status = 400, body = ApiError),
        (status = 404, body = ApiError)))]
async fn list(
    State(s): State<AppState>,
    Path(drive): Path<String>,
) -> ApiResult<Vec<DiagnosticView>> {
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        Ok(h.diagnostics(info.index)?
            .iter()
            .map(DiagnosticView::from)
            .collect())
    })
    .await
    .map(Json)
}

/// The state of one message after a raise or clear.
fn one(
    h: &crate::cell::control::ControlHandle,
    drive: usize,
    number: &str,
) -> Result<DiagnosticView, ApiError> {
    h.diagnostics(drive)?
        .iter()
        .find(|s| s.row.number == number)
        .map(DiagnosticView::from)
        .ok_or_else(|| refusal(DiagnosticError::Unknown))
}

/// Raises message `number` as if the drive had detected it: reaction, EMCY, 1003h,
/// statusword, display. It stays until cleared (DELETE); a fault reset acknowledges it then.
#[utoipa::path(post, path = "/api/drives/{drive}/diagnostics/{number}", tag = "diagnostics",
    params(("drive" = u32, Path, description = "the drive's index in the cell"),
        ("number" = String, Path, description = "the message's number as the manual prints it")),
    responses((status = 200, body = DiagnosticView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError), (status = 409, body = ApiError)))]
async fn raise(
    State(s): State<AppState>,
    Path((drive, number)): Path<(String, String)>,
) -> ApiResult<DiagnosticView> {
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        let row = h.raise_diagnostic(info.index, &number)?;
        one(h, info.index, row.number)
    })
    .await
    .map(Json)
}

/// Clears message `number` raised by POST: its cause is gone (an error then waits for the
/// fault reset, a warning ends).
#[utoipa::path(delete, path = "/api/drives/{drive}/diagnostics/{number}", tag = "diagnostics",
    params(("drive" = u32, Path, description = "the drive's index in the cell"),
        ("number" = String, Path, description = "the message's number as the manual prints it")),
    responses((status = 200, body = DiagnosticView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError), (status = 409, body = ApiError)))]
async fn clear(
    State(s): State<AppState>,
    Path((drive, number)): Path<(String, String)>,
) -> ApiResult<DiagnosticView> {
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        let row = h.clear_diagnostic(info.index, &number)?;
        one(h, info.index, row.number)
    })
    .await
    .map(Json)
}

#[derive(OpenApi)]
#[openapi(paths(list, raise, clear), components(schemas(DiagnosticView)))]
pub struct DiagnosticsDoc;

pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/api/drives/{drive}/diagnostics", get(list))
        .route(
            "/api/drives/{drive}/diagnostics/{number}",
            axum::routing::post(raise).delete(clear),
        )
}
