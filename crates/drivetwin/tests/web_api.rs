//! The web console's API against a running cell loop (a CMMP-AS on CAN and a CMMO-ST on
//! Modbus TCP), through the router with tower's `oneshot`: drives and their state, objects
//! with their description, SDO aborts as JSON, bad input as 4xx with a message, the write
//! token, enable and the plant moving, the OpenAPI document.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod web_rig;

use std::net::TcpListener;
use std::time::Duration;

use axum::http::StatusCode;
use drivetwin::web::{self, HttpSetting};
use serde_json::{json, Value};
use web_rig::{app, send, Running};

fn cell() -> Running {
    web_rig::cmmp_and_cmmo_st()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn drives_listed_with_personality_and_state() {
    let cell = cell();
    let app = app(&cell, None);
    let (status, drives) = send(&app, "GET", "/api/drives", None, None).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(drives[0]["device"], "cmmp-as");
    assert_eq!(drives[0]["profile"], "cia402");
    assert_eq!(drives[0]["interface"], "canopen");
    assert_eq!(drives[0]["node"], 1);
    assert_eq!(drives[0]["state"], "SWITCH ON DISABLED", "{}", drives[0]);
    assert_eq!(
        drives[0]["status_bits"][6]["set"], true,
        "bit 6 switch on disabled"
    );
    assert_eq!(drives[1]["device"], "cmmo-st");
    assert_eq!(drives[1]["profile"], "fhpp");
    assert_eq!(drives[1]["interface"], "modbus-tcp");

    let (status, e) = send(&app, "GET", "/api/drives/7", None, None).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert!(e["error"].as_str().expect("message").contains("no drive 7"));
    let (status, e) = send(&app, "GET", "/api/drives/x", None, None).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(e["error"].is_string());
    let (status, _) = send(&app, "GET", "/api/nothing", None, None).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn objects_read_and_written_with_their_description() {
    let cell = cell();
    let app = app(&cell, None);
    let (status, o) = send(&app, "GET", "/api/drives/0/objects/6081/0", None, None).await;
    assert_eq!(status, StatusCode::OK, "{o}");
    assert_eq!(o["index"], "0x6081");
    assert_eq!(o["type"], "UNSIGNED32");
    assert_eq!(o["access"], "rw");
    assert!(o["name"].as_str().is_some_and(|n| !n.is_empty()));

    let (status, o) = send(
        &app,
        "PUT",
        "/api/drives/0/objects/0x607A/0",
        Some(json!({"value": "-4321"})),
        None,
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{o}");
    assert_eq!(o["value"], "-4321");
    assert_eq!(o["raw"], "1FEFFFFF");
    // The same dictionary the fieldbus sees.
    let h = cell.handle.clone();
    let bytes = tokio::task::spawn_blocking(move || h.read(0, 0x607A, 0))
        .await
        .expect("joins")
        .expect("read");
    assert_eq!(bytes, (-4321i32).to_le_bytes());
    let (status, o) = send(
        &app,
        "PUT",
        "/api/drives/0/objects/6060/0",
        Some(json!({"value": 3})),
        None,
    )
    .await;
    assert_eq!((status, &o["value"]), (StatusCode::OK, &json!("3")), "{o}");

    let (status, list) = send(&app, "GET", "/api/drives/0/objects", None, None).await;
    assert_eq!(status, StatusCode::OK);
    let list = list.as_array().expect("array");
    assert!(list.len() > 50, "{}", list.len());
    assert!(list
        .iter()
        .any(|o| o["index"] == "0x607A" && o["value"] == "-4321"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refusals_are_json_with_the_abort_code_and_bad_input_a_4xx() {
    let cell = cell();
    let app = app(&cell, None);
    // 1000h device type is read-only: the drive's SDO abort, as JSON.
    let (status, e) = send(
        &app,
        "PUT",
        "/api/drives/0/objects/1000/0",
        Some(json!({"value": 1})),
        None,
    )
    .await;
    assert_eq!(status, StatusCode::CONFLICT);
    assert_eq!(e["abort_code"], "0x06010002");
    assert_eq!(e["abort_text"], "Attempt to write a read only object");
    // An object the drive does not have.
    let (status, e) = send(&app, "GET", "/api/drives/0/objects/5FFF/0", None, None).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert_eq!(e["abort_code"], "0x06020000");
    for (method, path, body) in [
        ("GET", "/api/drives/0/objects/zz/0", None),
        ("GET", "/api/drives/0/objects/6040/100", None),
        ("GET", "/api/drives/0/objects/123456/0", None),
        (
            "PUT",
            "/api/drives/0/objects/6040/0",
            Some(json!({"value": "70000"})),
        ),
        (
            "PUT",
            "/api/drives/0/objects/6040/0",
            Some(json!({"value": "x"})),
        ),
        ("PUT", "/api/drives/0/objects/6040/0", Some(json!({}))),
        (
            "PUT",
            "/api/drives/0/objects/6040/0",
            Some(json!({"value": 1, "raw": "01"})),
        ),
        (
            "PUT",
            "/api/drives/0/objects/6040/0",
            Some(json!({"raw": "xyz"})),
        ),
        ("PUT", "/api/drives/0/objects/6040/0", Some(json!([1, 2]))),
        ("PUT", "/api/drives/0/load", Some(json!({"torque_nm": 1e9}))),
        (
            "PUT",
            "/api/drives/0/inputs",
            Some(json!({"mask": -1, "levels": 0})),
        ),
    ] {
        let (status, e) = send(&app, method, path, body, None).await;
        assert!(status.is_client_error(), "{method} {path}: {status}");
        assert!(
            e["error"].as_str().is_some_and(|m| !m.is_empty()),
            "{method} {path}: {e}"
        );
    }
    // The CMMO-ST has no CiA 402 controlword: enable is refused with a reason.
    let (status, e) = send(&app, "POST", "/api/drives/1/enable", None, None).await;
    assert_eq!(status, StatusCode::CONFLICT, "{e}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn beyond_loopback_writes_need_the_token() {
    let cell = cell();
    let app = app(&cell, Some("s3cret"));
    let write = || Some(json!({"value": 1000}));
    let path = "/api/drives/0/objects/6081/0";
    let (status, e) = send(&app, "PUT", path, write(), None).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED);
    assert!(e["error"].as_str().expect("message").contains("token"));
    let (status, _) = send(&app, "PUT", path, write(), Some("wrong!")).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED);
    let (status, _) = send(&app, "POST", "/api/drives/0/enable", None, None).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED);
    let (status, o) = send(&app, "PUT", path, write(), Some("s3cret")).await;
    assert_eq!((status, &o["value"]), (StatusCode::OK, &json!("1000")));
    // Reads stay open.
    let (status, _) = send(&app, "GET", path, None, None).await;
    assert_eq!(status, StatusCode::OK);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn enable_in_profile_velocity_and_the_plant_moves() {
    let cell = cell();
    let app = app(&cell, None);
    let put = |path: &'static str, value: Value| {
        let app = app.clone();
        async move { send(&app, "PUT", path, Some(value), None).await }
    };
    assert_eq!(
        put("/api/drives/0/objects/6060/0", json!({"value": 3}))
            .await
            .0,
        StatusCode::OK
    );
    assert_eq!(
        put("/api/drives/0/objects/60FF/0", json!({"value": 1500}))
            .await
            .0,
        StatusCode::OK
    );
    let (status, d) = send(&app, "POST", "/api/drives/0/enable", None, None).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(d["state"], "OPERATION ENABLED", "{d}");
    let (_, before) = send(&app, "GET", "/api/drives/0/plant", None, None).await;
    tokio::time::sleep(Duration::from_millis(300)).await;
    let (status, after) = send(&app, "GET", "/api/drives/0/plant", None, None).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(after["kind"], "servo");
    assert!(after["at_s"].as_f64() > before["at_s"].as_f64());
    assert!(
        after["velocity"].as_f64().is_some_and(|v| v > 100.0),
        "{after}"
    );
    assert!(
        after["position"].as_f64() > before["position"].as_f64(),
        "{before} → {after}"
    );
    let (status, d) = send(&app, "POST", "/api/drives/0/disable", None, None).await;
    assert_eq!(
        (status, &d["state"]),
        (StatusCode::OK, &json!("READY TO SWITCH ON"))
    );
    let (status, p) = send(
        &app,
        "PUT",
        "/api/drives/1/load",
        Some(json!({"torque_nm": 0.2})),
        None,
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{p}");
    assert_eq!(p["kind"], "stepper");
}

/// The supply voltage set through the API is what the CMMP-AS measures (6079h, 6510h:34), and below
/// 6510h:36 with 6510h:37 = 1 its own supervision raises 02-0 (3220h) and the drive faults; back at
/// the nominal voltage the fault reset acknowledges it (the CMMP-AS manual's extract, part 2 §5.4).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_low_supply_is_measured_and_faults_the_cmmp_as() {
    let cell = cell();
    let app = app(&cell, None);
    let put = |path: &'static str, value: Value| {
        let app = app.clone();
        async move { send(&app, "PUT", path, Some(value), None).await }
    };
    for (path, value) in [
        ("/api/drives/0/objects/6510/36", 200_000),
        ("/api/drives/0/objects/6510/37", 1),
    ] {
        let (status, v) = put(path, json!({ "value": value })).await;
        assert_eq!(status, StatusCode::OK, "{path}: {v}");
    }
    let (status, d) = send(&app, "POST", "/api/drives/0/enable", None, None).await;
    assert_eq!(
        (status, &d["state"]),
        (StatusCode::OK, &json!("OPERATION ENABLED"))
    );
    let (status, p) = put("/api/drives/0/supply", json!({"volts": 150.0})).await;
    assert_eq!(status, StatusCode::OK, "{p}");
    let mut state = Value::Null;
    for _ in 0..100 {
        let (_, d) = send(&app, "GET", "/api/drives/0", None, None).await;
        state = d["state"].clone();
        if state != json!("OPERATION ENABLED") {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert!(
        state.as_str().is_some_and(|s| s.contains("FAULT")),
        "undervoltage faults the drive: {state}"
    );
    let (_, v) = send(&app, "GET", "/api/drives/0/objects/6510/34", None, None).await;
    assert_eq!(v["value"], json!("150000"), "measured, mV: {v}");
    let (_, v) = send(&app, "GET", "/api/drives/0/objects/1003/1", None, None).await;
    let newest: u64 = v["value"]
        .as_str()
        .and_then(|t| t.parse().ok())
        .unwrap_or(0);
    assert_eq!(
        newest & 0xFFFF,
        0x3220,
        "02-0 DC-link undervoltage in 1003h: {v}"
    );
    // Bad input, and a drive without a supply.
    let (status, e) = put("/api/drives/0/supply", json!({"volts": -5})).await;
    assert_eq!(status, StatusCode::BAD_REQUEST, "{e}");
    let (status, e) = put("/api/drives/1/supply", json!({"volts": 24})).await;
    assert_eq!(status, StatusCode::NOT_FOUND, "{e}");
    // Nominal again: the fault reset acknowledges it.
    let (status, _) = put("/api/drives/0/supply", json!({"volts": null})).await;
    assert_eq!(status, StatusCode::OK);
    let (status, d) = send(&app, "POST", "/api/drives/0/enable", None, None).await;
    assert_eq!(
        (status, &d["state"]),
        (StatusCode::OK, &json!("OPERATION ENABLED")),
        "{d}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn openapi_document_names_every_route() {
    let cell = cell();
    let app = app(&cell, None);
    let (status, doc) = send(&app, "GET", "/api/openapi.json", None, None).await;
    assert_eq!(status, StatusCode::OK);
    assert!(doc["openapi"].as_str().is_some_and(|v| v.starts_with("3.")));
    for path in [
        "/api/drives",
        "/api/drives/{drive}",
        "/api/drives/{drive}/enable",
        "/api/drives/{drive}/disable",
        "/api/drives/{drive}/objects",
        "/api/drives/{drive}/objects/{index}/{sub}",
        "/api/drives/{drive}/plant",
        "/api/drives/{drive}/inputs",
        "/api/drives/{drive}/load",
        "/api/drives/{drive}/supply",
        "/api/drives/{drive}/samples",
        "/api/ethercat/{chain}/line",
    ] {
        assert!(doc["paths"][path].is_object(), "{path} missing");
    }
    assert!(doc["components"]["schemas"]["ApiError"].is_object());
}

/// The line of a chain the cell does not have: 404, and a line action that is none: 400
/// (`tests/interop/test_ethercat_line.py` runs the line of a real chain).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ethercat_line_of_no_chain_is_not_found() {
    let cell = cell();
    let app = app(&cell, None);
    let (status, d) = send(&app, "GET", "/api/ethercat/0/line", None, None).await;
    assert_eq!(status, StatusCode::NOT_FOUND, "{d}");
    let (status, d) = send(
        &app,
        "POST",
        "/api/ethercat/0/line",
        Some(json!({"action": "pull-cable", "after": 1})),
        None,
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND, "{d}");
    let (status, d) = send(
        &app,
        "POST",
        "/api/ethercat/0/line",
        Some(json!({"action": "melt"})),
        None,
    )
    .await;
    assert!(status.is_client_error(), "{d}");
}

#[test]
fn default_address_gives_way_an_explicit_one_must_bind_and_beyond_loopback_a_token() {
    let cell = cell();
    // Whoever has the default port (this test or another process), a second console gives way.
    let _held = TcpListener::bind(web::DEFAULT_ADDR);
    let second = web::start(
        &HttpSetting::Default,
        cell.handle.clone(),
        drivetwin::vendors::VENDORS.web_pages,
    )
    .expect("no error");
    assert!(second.is_none());
    let taken = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = taken.local_addr().expect("addr").to_string();
    assert!(web::start(
        &HttpSetting::At(addr),
        cell.handle.clone(),
        drivetwin::vendors::VENDORS.web_pages
    )
    .is_err());
    assert_eq!(HttpSetting::parse(Some("off")), HttpSetting::Off);
    assert!(web::start(
        &HttpSetting::Off,
        cell.handle.clone(),
        drivetwin::vendors::VENDORS.web_pages
    )
    .expect("off")
    .is_none());
    let local = web::start(
        &HttpSetting::At("127.0.0.1:0".into()),
        cell.handle.clone(),
        drivetwin::vendors::VENDORS.web_pages,
    )
    .expect("binds")
    .expect("serves");
    assert!(local.token.is_none());
    let wide = web::start(
        &HttpSetting::At("0.0.0.0:0".into()),
        cell.handle.clone(),
        drivetwin::vendors::VENDORS.web_pages,
    )
    .expect("binds")
    .expect("serves");
    assert!(
        wide.token.as_deref().is_some_and(|t| t.len() == 32),
        "{wide:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn samples_arrive_over_the_websocket_in_batches() {
    use futures_util::StreamExt;
    use std::future::IntoFuture;
    let cell = cell();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .expect("bind");
    let addr = listener.local_addr().expect("addr");
    let server = tokio::spawn(axum::serve(listener, app(&cell, None)).into_future());
    let url = format!("ws://{addr}/api/drives/0/samples?rate_hz=200&batch_ms=50");
    let (mut ws, _) = tokio_tungstenite::connect_async(url)
        .await
        .expect("upgrade");
    let mut times = Vec::new();
    let mut messages = 0;
    while times.len() < 40 {
        let message = tokio::time::timeout(Duration::from_secs(3), ws.next())
            .await
            .expect("a batch within 3 s")
            .expect("open")
            .expect("message");
        let batch: Value = serde_json::from_str(message.to_text().expect("text")).expect("JSON");
        assert_eq!(batch["drive"], 0);
        let samples = batch["samples"].as_array().expect("samples");
        assert!(samples[0]["velocity"].is_number(), "{batch}");
        times.extend(samples.iter().filter_map(|s| s["t"].as_f64()));
        messages += 1;
    }
    assert!(times.windows(2).all(|w| w[1] > w[0]), "{times:?}");
    // 200 samples a second, sent 20 times a second: batches, not one message per sample.
    assert!(
        messages * 3 <= times.len(),
        "{messages} messages for {} samples",
        times.len()
    );
    // A drive that is not there: refused before the upgrade.
    let url = format!("ws://{addr}/api/drives/9/samples");
    assert!(tokio_tungstenite::connect_async(url).await.is_err());
    server.abort();
}
