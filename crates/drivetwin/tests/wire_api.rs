//! The wire's REST API against a running cell loop (a CMMP-AS on CAN, a CMMO-ST on Modbus TCP):
//! faults started, listed and ended on a bus and a Modbus server, bad input as a 4xx with a
//! message, a pcap trace of a bus started and stopped, the paths in the OpenAPI document.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod web_rig;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use http_body_util::BodyExt;
use serde_json::{json, Value};
use tower::ServiceExt;
use web_rig::Running;

fn cell() -> Running {
    web_rig::cmmp_and_cmmo_st()
}

async fn send(
    app: &axum::Router,
    method: &str,
    path: &str,
    body: Option<Value>,
) -> (StatusCode, Value) {
    web_rig::send(app, method, path, body, None).await
}

fn app(running: &Running) -> axum::Router {
    web_rig::app(running, None)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn faults_started_listed_and_ended() {
    let cell = cell();
    let app = app(&cell);
    let (status, f) = send(
        &app,
        "POST",
        "/api/wire/bus/0/faults",
        Some(json!({"fault": "cable-break", "node": 1, "for": "10s"})),
    )
    .await;
    assert_eq!(status, StatusCode::CREATED, "{f}");
    assert_eq!(f["fault"], "cable-break");
    assert_eq!(f["node"], 1);
    let (status, f2) = send(
        &app,
        "POST",
        "/api/wire/bus/0/faults",
        Some(json!({"fault": "stop-sync"})),
    )
    .await;
    assert_eq!(status, StatusCode::CREATED);
    assert_eq!(f2["cob_id"], 0x80);
    assert_eq!(f2["reach"], "bus");
    let (_, list) = send(&app, "GET", "/api/wire/bus/0/faults", None).await;
    assert_eq!(list.as_array().map(Vec::len), Some(2));
    let path = format!("/api/wire/bus/0/faults/{}", f["id"]);
    let (status, list) = send(&app, "DELETE", &path, None).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(list.as_array().map(Vec::len), Some(1));
    let (status, e) = send(&app, "DELETE", &path, None).await;
    assert_eq!(status, StatusCode::NOT_FOUND, "{e}");
    let (status, list) = send(&app, "DELETE", "/api/wire/bus/0/faults", None).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(list, json!([]));

    // The Modbus server: drop every request; a delay too.
    let (status, f) = send(
        &app,
        "POST",
        "/api/wire/modbus/0/faults",
        Some(json!({"fault": "drop"})),
    )
    .await;
    assert_eq!(status, StatusCode::CREATED, "{f}");
    let (status, f) = send(
        &app,
        "POST",
        "/api/wire/modbus/0/faults",
        Some(json!({"fault": "delay", "delay": "5ms"})),
    )
    .await;
    assert_eq!(status, StatusCode::CREATED, "{f}");
}

/// One Modbus TCP request (FC 03, the first holding register) on `s`; how long the answer
/// took.
fn modbus_round_trip(s: &mut std::net::TcpStream, transaction: u8) -> std::time::Duration {
    use std::io::{Read, Write};
    let t0 = std::time::Instant::now();
    // MBAP: transaction, protocol 0, length 6, unit 1; FC 03, address 0, 1 register.
    s.write_all(&[0, transaction, 0, 0, 0, 6, 1, 3, 0, 0, 0, 1])
        .expect("send");
    // The answer: registers or an exception, whichever the drive gives; its MBAP length says.
    let mut mbap = [0u8; 7];
    s.read_exact(&mut mbap).expect("answer");
    let rest = usize::from(u16::from_be_bytes([mbap[4], mbap[5]])).saturating_sub(1);
    let mut pdu = vec![0u8; rest];
    s.read_exact(&mut pdu).expect("answer's PDU");
    assert_eq!(mbap[1], transaction, "{mbap:?}");
    t0.elapsed()
}

/// A `delay` on the Modbus server holds each request back: the answer comes that much later,
/// and at once again when the fault ends (the CMMO-ST serves one connection: one stream).
#[test]
fn a_delayed_modbus_request_is_answered_late() {
    use drivetwin::cell::wire_faults::{FaultSpec, FrontEnd, WireRequest};
    use std::time::Duration;
    let cell = cell();
    let addr = cell.modbus.expect("the CMMO-ST's server");
    let mut s = std::net::TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    let quick = modbus_round_trip(&mut s, 1);
    assert!(quick < Duration::from_millis(150), "{quick:?}");
    let spec: FaultSpec =
        serde_json::from_value(json!({"fault": "delay", "delay": "200ms"})).expect("spec");
    let fault = spec.to_fault().expect("fault");
    cell.handle
        .wire(WireRequest::Add {
            front: FrontEnd::Modbus(0),
            fault,
        })
        .expect("added");
    let late = modbus_round_trip(&mut s, 2);
    assert!(
        late >= Duration::from_millis(200),
        "held back 200 ms: {late:?}"
    );
    cell.handle
        .wire(WireRequest::Clear {
            front: FrontEnd::Modbus(0),
        })
        .expect("cleared");
    let quick = modbus_round_trip(&mut s, 3);
    assert!(quick < Duration::from_millis(150), "{quick:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_faults_get_4xx_with_a_message() {
    let cell = cell();
    let app = app(&cell);
    for (path, body, want) in [
        (
            "/api/wire/bus/9/faults",
            json!({"fault": "drop"}),
            StatusCode::NOT_FOUND,
        ),
        (
            "/api/wire/ethercat/0/faults",
            json!({"fault": "drop"}),
            StatusCode::NOT_FOUND,
        ),
        (
            "/api/wire/serial/0/faults",
            json!({"fault": "drop"}),
            StatusCode::NOT_FOUND,
        ),
        (
            "/api/wire/bus/x/faults",
            json!({"fault": "drop"}),
            StatusCode::BAD_REQUEST,
        ),
        (
            "/api/wire/bus/0/faults",
            json!({"fault": "melt"}),
            StatusCode::BAD_REQUEST,
        ),
        (
            "/api/wire/bus/0/faults",
            json!({"fault": "drop", "share": 1.5}),
            StatusCode::BAD_REQUEST,
        ),
        (
            "/api/wire/bus/0/faults",
            json!({"fault": "delay"}),
            StatusCode::BAD_REQUEST,
        ),
        (
            "/api/wire/bus/0/faults",
            json!({"fault": "drop", "node": 0}),
            StatusCode::BAD_REQUEST,
        ),
        (
            "/api/wire/bus/0/faults",
            json!({"fault": "drop", "for": "1 fortnight"}),
            StatusCode::BAD_REQUEST,
        ),
        (
            "/api/wire/modbus/0/faults",
            json!({"fault": "drop", "node": 1}),
            StatusCode::BAD_REQUEST,
        ),
    ] {
        let (status, e) = send(&app, "POST", path, Some(body.clone())).await;
        assert_eq!(status, want, "{path} {body}: {e}");
        assert!(e["error"].is_string(), "{e}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_trace_of_a_bus_started_and_stopped() {
    let cell = cell();
    let app = app(&cell);
    let name = format!("wire-api-{}.pcap", std::process::id());
    let file = std::env::temp_dir().join(&name);
    let (status, t) = send(
        &app,
        "POST",
        "/api/buses/0/trace",
        Some(json!({ "name": name })),
    )
    .await;
    assert_eq!(status, StatusCode::CREATED, "{t}");
    assert_eq!(t["path"], file.display().to_string());
    let (status, _) = send(&app, "POST", "/api/buses/0/trace", Some(json!({}))).await;
    assert_eq!(status, StatusCode::CONFLICT);
    // Something on the bus: the node's heartbeat, every 20 ms.
    cell.handle
        .write(0, 0x1017, 0, &20u16.to_le_bytes())
        .expect("1017h");
    std::thread::sleep(std::time::Duration::from_millis(100));
    let (status, _) = send(&app, "DELETE", "/api/buses/0/trace", None).await;
    assert_eq!(status, StatusCode::NO_CONTENT);
    let bytes = std::fs::read(&file).expect("pcap");
    // pcap global header (24 bytes), then records of 16 + 16 bytes per CAN frame.
    assert_eq!(bytes.get(..4), Some(&[0xD4, 0xC3, 0xB2, 0xA1][..]));
    assert!(
        bytes.len() >= 24 + 32 * 3,
        "heartbeats traced: {} bytes",
        bytes.len()
    );
    let _ = std::fs::remove_file(&file);
    let (status, _) = send(&app, "DELETE", "/api/buses/0/trace", None).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    let (status, e) = send(
        &app,
        "POST",
        "/api/buses/0/trace",
        Some(json!({"name": "x.txt"})),
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST, "{e}");
    for bad in ["../x.pcap", "/tmp/x.pcap", ".x.pcap", "a b.pcap"] {
        let (status, e) = send(
            &app,
            "POST",
            "/api/buses/0/trace",
            Some(json!({ "name": bad })),
        )
        .await;
        assert_eq!(status, StatusCode::BAD_REQUEST, "{bad}: {e}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_wire_is_in_the_openapi_document() {
    let cell = cell();
    let app = app(&cell);
    let (status, doc) = send(&app, "GET", "/api/openapi.json", None).await;
    assert_eq!(status, StatusCode::OK);
    assert!(doc["paths"]["/api/wire/{front}/{index}/faults"]["post"].is_object());
    assert!(doc["paths"]["/api/buses/{bus}/trace"]["delete"].is_object());
    assert!(doc["components"]["schemas"]["FaultSpec"].is_object());
    assert!(doc["paths"]["/api/scenarios"]["post"].is_object());
    assert!(doc["paths"]["/api/scenarios/{id}"]["get"].is_object());
}

async fn send_text(app: &axum::Router, path: &str, text: &str) -> (StatusCode, Value) {
    let req = Request::builder()
        .method("POST")
        .uri(path)
        .header("content-type", "application/toml")
        .body(Body::from(text.to_owned()))
        .expect("request");
    let res = app.clone().oneshot(req).await.expect("answer");
    let status = res.status();
    let bytes = res.into_body().collect().await.expect("body").to_bytes();
    (status, serde_json::from_slice(&bytes).expect("JSON"))
}

/// A scenario on the live cell through the API: heartbeats seen, a cut cable silences them, the
/// report names each expectation.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scenario_runs_on_the_live_cell() {
    let cell = cell();
    let app = app(&cell);
    let text = r#"
        name = "live"
        [[step]]
        at = "0s"
        write = "1017:00"
        value = 20

        [[step]]
        at = "0s"
        name = "node 1 beats"
        expect_frame = "701"
        within = "200ms"

        [[step]]
        at = "300ms"
        fault = "cable-break"
        node = 1
        for = "300ms"

        [[step]]
        at = "320ms"
        name = "silence while the cable is cut"
        absent = true
        expect_frame = "701"
        within = "200ms"

        [[step]]
        at = "320ms"
        name = "the drive is enabled (it is not)"
        expect_state = "operation enabled"
        within = "50ms"
    "#;
    let (status, run) = send_text(&app, "/api/scenarios", text).await;
    assert_eq!(status, StatusCode::ACCEPTED, "{run}");
    assert_eq!(run["status"], "running");
    let path = format!("/api/scenarios/{}", run["id"]);
    let mut done = Value::Null;
    for _ in 0..100 {
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
        let (_, r) = send(&app, "GET", &path, None).await;
        if r["status"] == "done" {
            done = r;
            break;
        }
    }
    let report = &done["report"];
    assert_eq!(report["passed"], false, "{done}");
    let outcomes: Vec<(String, bool)> = report["expectations"]
        .as_array()
        .expect("expectations")
        .iter()
        .map(|o| {
            (
                o["name"].as_str().unwrap_or("").to_owned(),
                o["passed"] == true,
            )
        })
        .collect();
    assert_eq!(
        outcomes,
        [
            ("node 1 beats".to_owned(), true),
            ("silence while the cable is cut".to_owned(), true),
            ("the drive is enabled (it is not)".to_owned(), false),
        ],
        "{done}"
    );
    let (status, e) = send_text(&app, "/api/scenarios", "[[step]]\nat = \"1s\"\n").await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(
        e["error"].as_str().is_some_and(|t| t.contains("step 1")),
        "{e}"
    );
    let (status, _) = send(&app, "GET", "/api/scenarios/999", None).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
}

/// One Modbus TCP request (FC 03, 4 input bytes of the FHPP status); the answer, if any
/// within `wait`.
fn modbus_request(
    stream: &mut std::net::TcpStream,
    tid: u16,
    wait: std::time::Duration,
) -> Option<Vec<u8>> {
    use std::io::{Read, Write};
    let [t0, t1] = tid.to_be_bytes();
    stream
        .write_all(&[t0, t1, 0, 0, 0, 6, 1, 0x03, 0, 0, 0, 4])
        .expect("write");
    stream.set_read_timeout(Some(wait)).expect("timeout");
    let mut buf = [0u8; 64];
    match stream.read(&mut buf) {
        Ok(n) if n > 0 => Some(buf[..n].to_vec()),
        _ => None,
    }
}

/// A Modbus server's wire: a dropped request gets no answer (the master's timeout), as a
/// corrupted one (the Ethernet FCS discards it); cleared, the server answers again.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_modbus_servers_requests_dropped_and_corrupted() {
    let cell = cell();
    let app = app(&cell);
    let mut stream =
        std::net::TcpStream::connect(cell.modbus.expect("a Modbus drive")).expect("connect");
    let short = std::time::Duration::from_millis(300);
    let answer = modbus_request(&mut stream, 1, std::time::Duration::from_secs(2)).expect("answer");
    assert_eq!(&answer[..2], &[0, 1]);
    for (tid, fault) in [
        (2u16, json!({"fault": "drop", "frames": 1})),
        (3, json!({"fault": "corrupt", "frames": 1})),
    ] {
        let (status, f) = send(&app, "POST", "/api/wire/modbus/0/faults", Some(fault)).await;
        assert_eq!(status, StatusCode::CREATED, "{f}");
        assert_eq!(modbus_request(&mut stream, tid, short), None, "{f}");
    }
    // Each fault took its one request: the next is answered.
    let answer = modbus_request(&mut stream, 4, std::time::Duration::from_secs(2)).expect("answer");
    assert_eq!(&answer[..2], &[0, 4]);
    let (status, f) = send(
        &app,
        "POST",
        "/api/wire/modbus/0/faults",
        Some(json!({"fault": "cable-break"})),
    )
    .await;
    assert_eq!(status, StatusCode::CREATED, "{f}");
    assert_eq!(modbus_request(&mut stream, 5, short), None);
    let (status, _) = send(&app, "DELETE", "/api/wire/modbus/0/faults", None).await;
    assert_eq!(status, StatusCode::OK);
    let answer = modbus_request(&mut stream, 6, std::time::Duration::from_secs(2)).expect("answer");
    assert_eq!(&answer[..2], &[0, 6]);
}
