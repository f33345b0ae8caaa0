//! Fault injection by diagnostic message through the REST API, against a running cell loop (a
//! CMMP-AS on CAN, a CMMO-ST on Modbus TCP) through the router: the table with texts, raise and
//! clear by number, what the drive then shows (FAULT, the display, the message active), 4xx JSON
//! for unknown drives and numbers, the OpenAPI paths.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod web_rig;

use std::time::Duration;

use axum::http::StatusCode;
use serde_json::Value;
use web_rig::{app, send, Running};

fn cell() -> Running {
    web_rig::cmmp_and_cmmo_st()
}

async fn wait_for(
    app: &axum::Router,
    path: &str,
    what: &str,
    pred: impl Fn(&Value) -> bool,
) -> Value {
    for _ in 0..100 {
        let (_, v) = send(app, "GET", path, None, None).await;
        if pred(&v) {
            return v;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    panic!("{what}: not within 2 s");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cmmp_message_raised_and_cleared_over_the_api() {
    let cell = cell();
    let app = app(&cell, None);
    let (status, table) = send(&app, "GET", "/api/drives/0/diagnostics", None, None).await;
    assert_eq!(status, StatusCode::OK);
    let rows = table.as_array().expect("a list");
    assert!(rows.len() >= 230, "App. B complete: {}", rows.len());
    let row = rows
        .iter()
        .find(|r| r["number"] == "03-0")
        .expect("03-0 listed");
    assert_eq!(row["code"], "0x4310");
    assert_eq!(row["reaction"], "quick_stop");
    assert_eq!(row["text"], "Motor overtemperature, analog");
    assert_eq!(row["active"], false);

    let (status, v) = send(&app, "POST", "/api/drives/0/diagnostics/03-0", None, None).await;
    assert_eq!(status, StatusCode::OK, "{v}");
    assert_eq!(v["active"], true);
    let d = wait_for(&app, "/api/drives/0", "display E030", |d| {
        d["display"] == "-E030-"
    })
    .await;
    assert_eq!(d["display"], "-E030-");
    // The cause stays until DELETE; then a fault reset acknowledges it.
    let (status, v) = send(&app, "DELETE", "/api/drives/0/diagnostics/03-0", None, None).await;
    assert_eq!(status, StatusCode::OK, "{v}");
    let (status, v) = send(&app, "DELETE", "/api/drives/0/diagnostics/03-0", None, None).await;
    assert_eq!(status, StatusCode::CONFLICT, "not raised any more: {v}");
    assert!(v["error"].as_str().is_some());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cmmo_st_app_d_message_over_the_api() {
    let cell = cell();
    let app = app(&cell, None);
    let (status, table) = send(&app, "GET", "/api/drives/1/diagnostics", None, None).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(table.as_array().map(Vec::len), Some(57), "App. D");
    let (status, v) = send(&app, "POST", "/api/drives/1/diagnostics/2Fh", None, None).await;
    assert_eq!(status, StatusCode::OK, "{v}");
    assert_eq!(v["active"], true);
    assert_eq!(v["classes"], "F/W/I", "App. D 2Fh following error");
    let (status, _) = send(&app, "DELETE", "/api/drives/1/diagnostics/2Fh", None, None).await;
    assert_eq!(status, StatusCode::OK);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unknown_drives_and_numbers_are_4xx_json() {
    let cell = cell();
    let app = app(&cell, None);
    for (method, path, want) in [
        ("GET", "/api/drives/9/diagnostics", StatusCode::NOT_FOUND),
        ("GET", "/api/drives/x/diagnostics", StatusCode::BAD_REQUEST),
        (
            "POST",
            "/api/drives/0/diagnostics/99-9",
            StatusCode::NOT_FOUND,
        ),
        (
            "POST",
            "/api/drives/0/diagnostics/2Fh",
            StatusCode::NOT_FOUND,
        ),
        (
            "DELETE",
            "/api/drives/0/diagnostics/08-2",
            StatusCode::CONFLICT,
        ),
        (
            "POST",
            "/api/drives/1/diagnostics/03h",
            StatusCode::NOT_FOUND,
        ),
    ] {
        let (status, v) = send(&app, method, path, None, None).await;
        assert_eq!(status, want, "{method} {path}: {v}");
        assert!(v["error"].as_str().is_some(), "{method} {path}: {v}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn openapi_document_has_the_diagnostics_routes() {
    let cell = cell();
    let app = app(&cell, None);
    let (_, doc) = send(&app, "GET", "/api/openapi.json", None, None).await;
    for path in [
        "/api/drives/{drive}/diagnostics",
        "/api/drives/{drive}/diagnostics/{number}",
    ] {
        assert!(doc["paths"][path].is_object(), "{path} missing");
    }
    assert!(
        doc["paths"]["/api/drives"].is_object(),
        "merged, not replaced"
    );
    assert!(doc["components"]["schemas"]["DiagnosticView"].is_object());
}
