//! The Kinco LED panel through the REST API: a Kinco FD3 (drive 0) and a CMMP-AS (drive 1) on one
//! CAN bus of a running cell loop, through the router: the monitor display, key presses walking
//! F003 to d3.47 Jog_RPM and changing it (seen by an object read), 4xx for a drive without panel
//! and a bad key, the OpenAPI paths.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod web_rig;

use axum::http::StatusCode;
use serde_json::Value;
use web_rig::{app, send, Running};

/// Drive 0 a Kinco FD3 (node 2), drive 1 a CMMP-AS (node 1), on one bus.
fn cell() -> Running {
    web_rig::kinco_and_cmmp()
}

async fn key(app: &axum::Router, key: &str) -> Value {
    let (status, v) = send(
        app,
        "POST",
        "/api/drives/0/panel/keys",
        Some(serde_json::json!({ "key": key })),
        None,
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{v}");
    v
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn panel_keys_change_jog_rpm() {
    let cell = cell();
    let app = app(&cell, None);
    let (status, v) = send(&app, "GET", "/api/drives/0/panel", None, None).await;
    assert_eq!(status, StatusCode::OK, "{v}");
    assert_eq!(v["text"], "    0", "monitor: d1.25 Real_Speed_RPM");
    assert_eq!(v["blink"], "steady");
    for _ in 0..3 {
        key(&app, "mode").await;
    }
    let v = key(&app, "set").await;
    assert_eq!(v["text"], " d3.00");
    let mut v = v;
    for _ in 0..60 {
        if v["text"] == " d3.47" {
            break;
        }
        v = key(&app, "up").await;
    }
    assert_eq!(v["text"], " d3.47");
    assert_eq!(v["dots"][2], true);
    let v = key(&app, "set").await;
    assert_eq!(v["text"], "   30");
    key(&app, "mode").await;
    key(&app, "up").await;
    let v = key(&app, "up").await;
    assert_eq!(v["text"], "   50");
    assert_eq!(v["cursor"], 4);
    let v = key(&app, "set").await;
    assert_eq!(v["dots"][4], true, "point 5: changed");
    let jog = cell.handle.read(0, 0x2FF0, 0x23).expect("read");
    assert_eq!(jog, 50i16.to_le_bytes());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn panel_refusals_and_openapi() {
    let cell = cell();
    let app = app(&cell, Some("secret"));
    let (status, _) = send(&app, "GET", "/api/drives/1/panel", None, None).await;
    assert_eq!(status, StatusCode::NOT_FOUND, "a CMMP-AS has no LED panel");
    let body = Some(serde_json::json!({ "key": "left" }));
    let (status, _) = send(
        &app,
        "POST",
        "/api/drives/0/panel/keys",
        body,
        Some("secret"),
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    let body = Some(serde_json::json!({ "key": "mode" }));
    let (status, _) = send(&app, "POST", "/api/drives/0/panel/keys", body.clone(), None).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED, "a key press is a write");
    let (status, v) = send(
        &app,
        "POST",
        "/api/drives/0/panel/keys",
        body,
        Some("secret"),
    )
    .await;
    assert_eq!(
        (status, v["text"].as_str()),
        (StatusCode::OK, Some(" F001"))
    );
    let (_, doc) = send(&app, "GET", "/api/openapi.json", None, None).await;
    assert!(doc["paths"]["/api/drives/{drive}/panel"]["get"].is_object());
    assert!(doc["paths"]["/api/drives/{drive}/panel/keys"]["post"].is_object());
}
