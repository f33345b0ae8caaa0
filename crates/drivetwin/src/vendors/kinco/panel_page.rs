//! The Kinco CD3 / FD3 LED panel over REST (Kinco CD3 / FD3 manual ch. 4): the five
//! digits as text with their points and blink, and key presses (MODE / SET / ▲ / ▼) as the
//! panel's own keys. A press goes to the drive's panel state machine
//! (`drive::vendors::kinco::panel`); what it changes is changed through the drive's object
//! write, so CANopen, RS232 and Modbus see it at once.

use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::routing::{get, post};
use axum::{Json, Router};
use drive::vendors::kinco::panel::{Blink, PanelDisplay, PanelKey};
use serde::{Deserialize, Serialize};
use utoipa::{OpenApi, ToSchema};

use crate::cell::control::{ControlError, ControlHandle, DisplayState};
use crate::web::api::{call, find_drive, ApiError, ApiResult};
use crate::web::AppState;

/// What the panel shows.
#[derive(Debug, Serialize, ToSchema)]
pub struct PanelView {
    /// The five digits with their points, as `" d3.01"`, `" 020.0"`, `"   30"`.
    pub text: String,
    /// Digits 1…5 from the left, one character each (a space is dark).
    pub digits: Vec<String>,
    /// Points 1…5 lit (point 3: group separator / high half; 4: HEX; 5: changed).
    pub dots: Vec<bool>,
    /// `steady`, `error` (once a second) or `warning` (three quick blinks).
    pub blink: String,
    /// Point 5 blinks: the power stage is enabled.
    pub dot5_blinks: bool,
    /// The digit (1…5) being edited, blinking on the drive.
    pub cursor: Option<u8>,
}

impl From<PanelDisplay> for PanelView {
    fn from(d: PanelDisplay) -> Self {
        PanelView {
            text: d.text().to_string(),
            digits: d.chars.iter().map(|c| char::from(*c).to_string()).collect(),
            dots: (0..5).map(|i| d.dots & (1 << i) != 0).collect(),
            blink: match d.blink {
                Blink::Steady => "steady",
                Blink::Error => "error",
                Blink::Warning => "warning",
            }
            .to_owned(),
            dot5_blinks: d.dot5_blinks,
            cursor: d.cursor,
        }
    }
}

/// A key press.
#[derive(Debug, Deserialize, ToSchema)]
pub struct KeyBody {
    /// `mode`, `set`, `up` or `down`.
    pub key: String,
    /// `click` (down and up at once: a short press, the default), `press` (goes down and
    /// stays: jog runs while ▲ / ▼ is held; MODE / SET held 1 s are a long press) or
    /// `release`.
    #[serde(default)]
    pub action: Option<String>,
}

fn key_of(s: &str) -> Result<PanelKey, ApiError> {
    match s.to_ascii_lowercase().as_str() {
        "mode" => Ok(PanelKey::Mode),
        "set" => Ok(PanelKey::Set),
        "up" => Ok(PanelKey::Up),
        "down" => Ok(PanelKey::Down),
        _ => Err(ApiError::bad(format!(
            "key {s:?}: one of mode, set, up, down"
        ))),
    }
}

/// The key's transitions, down and/or up.
fn transitions(action: Option<&str>) -> Result<&'static [bool], ApiError> {
    match action.unwrap_or("click") {
        "click" => Ok(&[true, false]),
        "press" => Ok(&[true]),
        "release" => Ok(&[false]),
        a => Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            format!("action {a:?}: one of click, press, release"),
        )),
    }
}

/// What the drive's LED panel shows.
#[utoipa::path(get, path = "/api/drives/{drive}/panel", tag = "panel",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = PanelView), (status = 400, body = ApiError),
        (status = 404, body = ApiError)))]
async fn show(State(s): State<AppState>, Path(drive): Path<String>) -> ApiResult<PanelView> {
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        Ok(PanelView::from(panel(h, info.index, None)?))
    })
    .await
    .map(Json)
}

/// A key of the LED panel; the display after it.
#[utoipa::path(post, path = "/api/drives/{drive}/panel/keys", tag = "panel",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    request_body = KeyBody,
    responses((status = 200, body = PanelView), (status = 400, body = ApiError),
        (status = 401, body = ApiError), (status = 404, body = ApiError),
        (status = 415, body = ApiError)))]
async fn key(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<KeyBody>, JsonRejection>,
) -> ApiResult<PanelView> {
    let Json(body) = body?;
    let key = key_of(&body.key)?;
    let steps = transitions(body.action.as_deref())?;
    call(&s.handle, move |h| {
        let info = find_drive(h, &drive)?;
        let mut shown = panel(h, info.index, None)?;
        for pressed in steps {
            shown = panel(h, info.index, Some((key, *pressed)))?;
        }
        Ok(PanelView::from(shown))
    })
    .await
    .map(Json)
}

/// What the LED panel of drive `drive` shows after `key` went down (`true`) or up, at the
/// cell's clock (none: only read it). MODE and SET act when released (a long press: held
/// 1 s or more).
pub fn panel(
    h: &ControlHandle,
    drive: usize,
    key: Option<(PanelKey, bool)>,
) -> Result<PanelDisplay, ControlError> {
    h.with_drive(drive, move |d| {
        let d = d.map_err(|e| match e {
            ControlError::NoPlant(_) => ControlError::NoPanel(drive),
            e => e,
        })?;
        let Some(d) = d.as_kinco_mut() else {
            return Err(ControlError::NoPanel(drive));
        };
        if let Some((key, pressed)) = key {
            d.kinco_panel_key(key, pressed);
        }
        Ok(d.kinco_panel())
    })
}

/// The display of a Kinco: its LED panel's digits with their points; `None` for another
/// drive.
pub fn display(d: &drive::vendors::AnyDrive<Vec<u8>>) -> Option<DisplayState> {
    d.as_kinco()
        .map(|k| DisplayState::new(&k.kinco_panel().text()))
}

#[derive(OpenApi)]
#[openapi(paths(show, key), components(schemas(PanelView, KeyBody)))]
pub struct PanelDoc;

pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/api/drives/{drive}/panel", get(show))
        .route("/api/drives/{drive}/panel/keys", post(key))
}
