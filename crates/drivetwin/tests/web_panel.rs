//! The Kinco LED panel through the REST API (issue 13 point 4, issue 16 "displays"): a Kinco
//! FD3 (drive 0) and a CMMP-AS (drive 1) on one CAN bus of a running cell loop, through the
//! router: the monitor display, key presses walking F003 to d3.47 Jog_RPM and changing it
//! (seen by an object read), 4xx for a drive without panel and a bad key, the OpenAPI paths.

use std::net::TcpListener;
use std::sync::Arc;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use drivetwin::can::drive::CanDrive;
use drivetwin::can::socketcand::ServerConfig;
use drivetwin::cell::control::ControlHandle;
use drivetwin::cell::poll_loop::{CanBus, CellLoop, FrontEnds, StopHandle};
use drivetwin::cell::Cell;
use drivetwin::web::{self, AppState};
use http_body_util::BodyExt;
use serde_json::Value;
use tower::ServiceExt;

struct Running {
    handle: ControlHandle,
    stop: StopHandle,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Running {
    fn drop(&mut self) {
        self.stop.stop();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn cell() -> Running {
    let cmmp = devices::by_name("cmmp-as").expect("cmmp-as");
    let drive =
        CanDrive::with_settings(cmmp, 1, None, vec![], Some(Default::default())).expect("drive");
    let kinco = devices::by_name("kinco-fd3").expect("kinco-fd3");
    let fd3 =
        CanDrive::with_settings(kinco, 2, None, vec![], Some(Default::default())).expect("drive");
    let can = TcpListener::bind("127.0.0.1:0").expect("bind");
    let front = FrontEnds {
        buses: vec![CanBus {
            socketcand: Some((can, ServerConfig::new("vcan0"))),
            ..CanBus::new(Cell::new(vec![fd3, drive]))
        }],
        ..FrontEnds::default()
    };
    let cell_loop = CellLoop::with_buses(front).expect("loop");
    let handle = cell_loop.control_handle();
    let stop = cell_loop.stop_handle();
    let thread = std::thread::spawn(move || {
        cell_loop.run().expect("runs");
    });
    Running {
        handle,
        stop,
        thread: Some(thread),
    }
}

async fn send(
    app: &axum::Router,
    method: &str,
    path: &str,
    body: Option<Value>,
    token: Option<&str>,
) -> (StatusCode, Value) {
    let mut req = Request::builder().method(method).uri(path);
    if let Some(t) = token {
        req = req.header(web::auth::TOKEN_HEADER, t);
    }
    let req = match body {
        Some(b) => req
            .header("content-type", "application/json")
            .body(Body::from(b.to_string())),
        None => req.body(Body::empty()),
    }
    .expect("request");
    let res = app.clone().oneshot(req).await.expect("answer");
    let status = res.status();
    let bytes = res.into_body().collect().await.expect("body").to_bytes();
    let json = serde_json::from_slice(&bytes).unwrap_or_else(|_| {
        panic!(
            "{method} {path}: {status}, not JSON: {}",
            String::from_utf8_lossy(&bytes)
        )
    });
    (status, json)
}

fn app(running: &Running, token: Option<&str>) -> axum::Router {
    web::router(AppState {
        handle: running.handle.clone(),
        token: token.map(Arc::from),
    })
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
