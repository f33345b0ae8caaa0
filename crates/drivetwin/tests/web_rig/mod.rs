//! The rig of the web API tests: a cell loop running on its thread, the console's router on
//! its control handle, requests through tower's `oneshot` with their JSON answers.
#![allow(dead_code)] // each test file uses a part of it

use std::net::{SocketAddr, TcpListener};
use std::sync::Arc;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use drivetwin::can::socketcand::ServerConfig;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::control::ControlHandle;
use drivetwin::cell::station::Station;
use drivetwin::cell_loop::{CanBus, CellLoop, FrontEnds, StopHandle};
use drivetwin::modbus_tcp::cell_drive::ModbusDrive;
use drivetwin::modbus_tcp::server::ModbusConfig;
use drivetwin::vendors::festo_cmmo_st::modbus_server::FhppModbus;
use drivetwin::web::{self, AppState};
use http_body_util::BodyExt;
use serde_json::Value;
use tower::ServiceExt;

/// A cell loop on its thread; stopped and joined when dropped.
pub struct Running {
    pub handle: ControlHandle,
    /// The Modbus TCP server of the cell's first Modbus drive, if it has one.
    pub modbus: Option<SocketAddr>,
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

/// Runs `cell` with the front ends of `front` on a thread of its own.
pub fn start(cell: CanCell, front: FrontEnds, modbus: Option<SocketAddr>) -> Running {
    // The drives' displays as the binary shows them.
    let front = FrontEnds {
        views: drivetwin::vendors::VENDORS.runtime.views,
        ..front
    };
    let cell_loop = CellLoop::new(cell, front).expect("loop");
    let handle = cell_loop.control_handle();
    let stop = cell_loop.stop_handle();
    let thread = std::thread::spawn(move || {
        cell_loop.run().expect("runs");
    });
    Running {
        handle,
        modbus,
        stop,
        thread: Some(thread),
    }
}

/// A CiA 402 drive with its motor, as a cell file makes it.
pub fn station(device: &str, node: u8) -> Station {
    let desc = devices::by_name(device).expect("a personality of the workspace");
    Station::with_settings(desc, node, None, vec![], Some(Default::default())).expect("drive")
}

/// A cell of the CAN drives `drives` on one bus, and that bus's socketcand server on a free
/// loopback port.
pub fn bus(drives: Vec<Station>) -> (CanCell, Vec<CanBus>) {
    let can = TcpListener::bind("127.0.0.1:0").expect("bind");
    let bus = CanBus {
        socketcand: Some((can, ServerConfig::new("vcan0"))),
        ..CanBus::default()
    };
    (CanCell::one_bus(drives), vec![bus])
}

/// The CAN drives `drives` on one bus with its socketcand server, beside the front ends of
/// `more` (a Modbus drive at `modbus`, plans), running.
pub fn on_one_bus(drives: Vec<Station>, more: FrontEnds, modbus: Option<SocketAddr>) -> Running {
    let (cell, buses) = bus(drives);
    start(cell, FrontEnds { buses, ..more }, modbus)
}

/// Drive 0 a CMMP-AS (node 1) on CAN, drive 1 a CMMO-ST on Modbus TCP.
pub fn cmmp_and_cmmo_st() -> Running {
    cmmp_and_cmmo_st_with(FrontEnds::default())
}

/// [`cmmp_and_cmmo_st`] with the front ends of `more` beside them (the cell file's plans).
pub fn cmmp_and_cmmo_st_with(more: FrontEnds) -> Running {
    let cmmo = devices::by_name("cmmo-st").expect("cmmo-st");
    let od = od::ObjectDictionary::new(cmmo, 1, vec![0u8; cmmo.storage_size]).expect("od");
    let dev = drive::vendors::festo_cmmo_st::device::FhppDevice::new(od, Default::default());
    let mb = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = mb.local_addr().expect("addr");
    let modbus = vec![ModbusDrive::new(
        mb,
        Box::new(FhppModbus::new(dev, None)),
        ModbusConfig::default(),
    )];
    on_one_bus(
        vec![station("cmmp-as", 1)],
        FrontEnds { modbus, ..more },
        Some(addr),
    )
}

/// Drive 0 a Kinco FD3 (node 2) at factory defaults, drive 1 a CMMP-AS (node 1), on one bus.
pub fn kinco_and_cmmp() -> Running {
    on_one_bus(
        vec![station("kinco-fd3", 2), station("cmmp-as", 1)],
        FrontEnds::default(),
        None,
    )
}

/// Drive 0 a Nanotec SMCI47-S (node 34) alone on a bus.
pub fn nanotec() -> Running {
    on_one_bus(
        vec![station("nanotec-smci47s", 34)],
        FrontEnds::default(),
        None,
    )
}

/// The console's router on `running`, with the write token `token` (`None`: loopback, none).
pub fn app(running: &Running, token: Option<&str>) -> axum::Router {
    web::router(AppState {
        handle: running.handle.clone(),
        token: token.map(Arc::from),
        pages: drivetwin::vendors::VENDORS.web_pages,
    })
}

/// A PUT of `body` to `path`, without a token.
pub async fn put(app: &axum::Router, path: &str, body: Value) -> (StatusCode, Value) {
    send(app, "PUT", path, Some(body), None).await
}

/// One request; the status and the JSON answer (`Null` for an empty body).
pub async fn send(
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
    if bytes.is_empty() {
        return (status, Value::Null);
    }
    let json = serde_json::from_slice(&bytes).unwrap_or_else(|_| {
        panic!(
            "{method} {path}: {status}, not JSON: {}",
            String::from_utf8_lossy(&bytes)
        )
    });
    (status, json)
}
