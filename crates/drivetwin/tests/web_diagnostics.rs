//! Fault injection by diagnostic message through the REST API (issue 16 point 3), against a
//! running cell loop (a CMMP-AS on CAN, a CMMO-ST on Modbus TCP) through the router: the table
//! with texts, raise and clear by number, what the drive then shows (FAULT, the display, the
//! message active), 4xx JSON for unknown drives and numbers, the OpenAPI paths.

use std::net::TcpListener;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use drivetwin::can::drive::CanDrive;
use drivetwin::can::socketcand::ServerConfig;
use drivetwin::cell::control::ControlHandle;
use drivetwin::cell::poll_loop::{CanBus, CellLoop, FrontEnds, StopHandle};
use drivetwin::cell::Cell;
use drivetwin::modbus_tcp::cell_drive::ModbusDrive;
use drivetwin::modbus_tcp::server::ModbusConfig;
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
    let cmmo = devices::by_name("cmmo-st").expect("cmmo-st");
    let od = od::ObjectDictionary::new(cmmo, 1, vec![0u8; cmmo.storage_size]).expect("od");
    let dev = drive::fhpp::device::FhppDevice::new(od, Default::default());
    let can = TcpListener::bind("127.0.0.1:0").expect("bind");
    let mb = TcpListener::bind("127.0.0.1:0").expect("bind");
    let front = FrontEnds {
        buses: vec![CanBus {
            socketcand: Some((can, ServerConfig::new("vcan0"))),
            ..CanBus::new(Cell::new(vec![drive]))
        }],
        modbus: vec![ModbusDrive::new(
            mb,
            Arc::new(Mutex::new(dev)),
            ModbusConfig::default(),
            None,
        )],
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
