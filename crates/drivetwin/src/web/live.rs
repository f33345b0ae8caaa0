//! Live plant samples over a WebSocket, with any objects named in the request. The cell loop
//! samples the plant (and reads the named objects) at the rate asked (its subscription,
//! [`ControlHandle::subscribe`]); the console sends what has come in as
//! one JSON message per batch period, so the browser draws at a screen's pace whatever the
//! control rate. A browser that does not keep up loses samples in the loop's bounded queue,
//! never delays the loop.
//!
//! [`ControlHandle::subscribe`]: crate::cell::control::ControlHandle::subscribe

use std::time::Duration;

use axum::extract::rejection::QueryRejection;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, Query, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use super::api::{ApiError, PlantView};
use super::AppState;
use crate::cell::control::{ObjectsSample, PlantSample};

/// The fastest sampling a browser may ask for: the control rate of the drives (1 kHz).
pub const MAX_RATE_HZ: u32 = 1000;

#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct LiveQuery {
    /// Samples per second, 1…1000 (default 100).
    #[param(minimum = 1, maximum = 1000)]
    pub rate_hz: Option<u32>,
    /// Milliseconds between two messages, 20…1000 (default 50).
    #[param(minimum = 20, maximum = 1000)]
    pub batch_ms: Option<u64>,
    /// Objects to sample beside the plant, comma-separated `index:sub` in hex (`60F4:0,6041:0`,
    /// at most 8, of at most 8 bytes each), read on the cell loop with every plant sample.
    pub objects: Option<String>,
}

/// Objects a subscription may name at most.
pub const MAX_OBJECTS: usize = crate::cell::control::MAX_SAMPLED_OBJECTS;

/// An object named in `objects`, resolved against the drive's description.
#[derive(Debug, Clone, Copy)]
struct Named {
    index: u16,
    sub: u8,
    ty: od::DataType,
}

impl Named {
    fn key(&self) -> String {
        format!("{:04X}:{:02X}", self.index, self.sub)
    }
}

/// `60F4:0,6041:0` → the entries, or a message for the 400.
fn named_objects(desc: &od::DeviceDescription, list: &str) -> Result<Vec<Named>, String> {
    let mut out = Vec::new();
    for item in list.split(',').map(str::trim).filter(|i| !i.is_empty()) {
        let (i, s) = item.split_once(':').unwrap_or((item, "0"));
        let index = u16::from_str_radix(i.trim_end_matches(['h', 'H']), 16)
            .map_err(|_| format!("object {item:?}: index:sub in hex, e.g. 60F4:0"))?;
        let sub = u8::from_str_radix(s, 16)
            .map_err(|_| format!("object {item:?}: index:sub in hex, e.g. 60F4:0"))?;
        let e = desc
            .entry(index, sub)
            .ok_or_else(|| format!("object {item:?} is not in {}", desc.name))?;
        if !e.access.readable() {
            return Err(format!("object {item:?} cannot be read"));
        }
        out.push(Named {
            index,
            sub,
            ty: e.data_type,
        });
    }
    if out.len() > MAX_OBJECTS {
        return Err(format!("at most {MAX_OBJECTS} objects"));
    }
    Ok(out)
}

/// One message on the WebSocket: the samples since the last one.
#[derive(Debug, Serialize, ToSchema)]
pub struct SampleBatch {
    pub drive: usize,
    pub samples: Vec<SamplePoint>,
    /// What the drive's display shows at the last sample.
    pub display: Option<String>,
}

/// One sample: the cell's clock and the scope's three signals.
#[derive(Debug, Serialize, ToSchema)]
pub struct SamplePoint {
    /// Seconds on the cell's clock.
    pub t: f64,
    pub position: Option<f64>,
    pub velocity: Option<f64>,
    pub current: Option<f64>,
    /// The named objects' values at this sample (`"60F4:00": -12`).
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub objects: std::collections::BTreeMap<String, f64>,
}

impl From<&PlantSample> for SamplePoint {
    fn from(s: &PlantSample) -> SamplePoint {
        let v = PlantView::from(s);
        SamplePoint {
            t: v.at_s,
            position: v.position,
            velocity: v.velocity,
            current: v.current,
            objects: std::collections::BTreeMap::new(),
        }
    }
}

/// Plant samples of one drive, live: a WebSocket (a GET with `Upgrade: websocket`) of
/// SampleBatch messages; a plain GET answers the latest sample as one batch.
#[utoipa::path(get, path = "/api/drives/{drive}/samples", tag = "plant",
    params(("drive" = u32, Path, description = "the drive's index in the cell"), LiveQuery),
    responses((status = 101, description = "WebSocket of SampleBatch messages (JSON text)"),
        (status = 200, description = "without a WebSocket upgrade: the latest sample", body = SampleBatch),
        (status = 400, body = ApiError), (status = 404, body = ApiError)))]
pub async fn samples(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    query: Result<Query<LiveQuery>, QueryRejection>,
    ws: Result<WebSocketUpgrade, axum::extract::ws::rejection::WebSocketUpgradeRejection>,
) -> Response {
    let Query(q) = match query {
        Ok(q) => q,
        Err(e) => return ApiError::new(StatusCode::BAD_REQUEST, e.body_text()).into_response(),
    };
    let rate = q.rate_hz.unwrap_or(100);
    if !(1..=MAX_RATE_HZ).contains(&rate) {
        return ApiError::new(
            StatusCode::BAD_REQUEST,
            format!("rate_hz {rate}: 1…{MAX_RATE_HZ}"),
        )
        .into_response();
    }
    let batch = q.batch_ms.unwrap_or(50);
    if !(20..=1000).contains(&batch) {
        return ApiError::new(
            StatusCode::BAD_REQUEST,
            format!("batch_ms {batch}: 20…1000"),
        )
        .into_response();
    }
    let Ok(index) = drive.parse::<usize>() else {
        return ApiError::new(
            StatusCode::BAD_REQUEST,
            format!("drive {drive:?}: not a drive index (0, 1, …)"),
        )
        .into_response();
    };
    let Ok(ws) = ws else {
        // A plain GET (no WebSocket upgrade): the latest sample, as one batch.
        let handle = s.handle.clone();
        return match tokio::task::spawn_blocking(move || handle.plant(index)).await {
            Ok(Ok(sample)) => Json(SampleBatch {
                drive: index,
                display: PlantView::from(&sample).display,
                samples: vec![SamplePoint::from(&sample)],
            })
            .into_response(),
            Ok(Err(e)) => ApiError::from(e).into_response(),
            Err(_) => ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "the request was lost")
                .into_response(),
        };
    };
    let named = match q.objects.as_deref().filter(|o| !o.trim().is_empty()) {
        None => Vec::new(),
        Some(list) => {
            let handle = s.handle.clone();
            let desc = tokio::task::spawn_blocking(move || {
                handle
                    .drives()
                    .ok()
                    .and_then(|d| d.into_iter().find(|d| d.index == index))
                    .and_then(|d| crate::cell::eds_drive::by_name(d.device))
            })
            .await
            .ok()
            .flatten();
            let Some(desc) = desc else {
                return ApiError::new(
                    StatusCode::NOT_FOUND,
                    format!("no drive {index} in the cell"),
                )
                .into_response();
            };
            match named_objects(desc, list) {
                Ok(n) => n,
                Err(m) => return ApiError::new(StatusCode::BAD_REQUEST, m).into_response(),
            }
        }
    };
    let handle = s.handle.clone();
    let every = Duration::from_micros(1_000_000 / u64::from(rate));
    let wanted: Vec<(u16, u8)> = named.iter().map(|n| (n.index, n.sub)).collect();
    let subscribed = tokio::task::spawn_blocking(move || {
        if wanted.is_empty() {
            handle.subscribe(index, every).map(Source::Plant)
        } else {
            handle
                .subscribe_objects(index, every, &wanted)
                .map(Source::Objects)
        }
    })
    .await;
    let rx = match subscribed {
        Ok(Ok(rx)) => rx,
        Ok(Err(e)) => return ApiError::from(e).into_response(),
        Err(_) => {
            return ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "the request was lost")
                .into_response()
        }
    };
    ws.on_upgrade(move |socket| stream(socket, index, rx, Duration::from_millis(batch), named))
}

/// Where the samples come from: the plant alone, or the plant with named objects, read on
/// the loop at each sample ([`ControlHandle::subscribe_objects`]).
///
/// [`ControlHandle::subscribe_objects`]: crate::cell::control::ControlHandle::subscribe_objects
enum Source {
    Plant(std::sync::mpsc::Receiver<PlantSample>),
    Objects(std::sync::mpsc::Receiver<ObjectsSample>),
}

impl Source {
    /// What has come in, as the browser's points, with the last plant sample.
    fn take(&self, named: &[Named]) -> (Vec<SamplePoint>, Option<PlantSample>) {
        match self {
            Source::Plant(rx) => {
                let got: Vec<PlantSample> = rx.try_iter().collect();
                (
                    got.iter().map(SamplePoint::from).collect(),
                    got.last().copied(),
                )
            }
            Source::Objects(rx) => {
                let got: Vec<ObjectsSample> = rx.try_iter().collect();
                let points = got
                    .iter()
                    .map(|s| {
                        let mut p = SamplePoint::from(&s.plant);
                        for (n, v) in named.iter().zip(s.values.iter()) {
                            let value = v
                                .get()
                                .and_then(|b| crate::value_text::decode(n.ty, b))
                                .and_then(|t| t.parse::<f64>().ok());
                            if let Some(value) = value {
                                p.objects.insert(n.key(), value);
                            }
                        }
                        p
                    })
                    .collect();
                (points, got.last().map(|s| s.plant))
            }
        }
    }
}

async fn stream(
    mut socket: WebSocket,
    drive: usize,
    source: Source,
    period: Duration,
    named: Vec<Named>,
) {
    let mut tick = tokio::time::interval(period);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    loop {
        tokio::select! {
            _ = tick.tick() => {
                let (samples, last) = source.take(&named);
                if samples.is_empty() {
                    continue;
                }
                let message = SampleBatch {
                    drive,
                    display: last.and_then(|s| PlantView::from(&s).display),
                    samples,
                };
                let Ok(text) = serde_json::to_string(&message) else {
                    break;
                };
                if socket.send(Message::Text(text.into())).await.is_err() {
                    break;
                }
            }
            incoming = socket.recv() => match incoming {
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => break,
                Some(Ok(_)) => {}
            },
        }
    }
    // Dropping the receiver ends the subscription at the loop's next sample.
}

pub fn routes() -> Router<AppState> {
    Router::new().route("/api/drives/{drive}/samples", get(samples))
}
