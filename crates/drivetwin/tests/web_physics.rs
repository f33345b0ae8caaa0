//! The plant's physics through the REST API against a running cell loop (a CMMP-AS on CAN, a
//! CMMO-ST on Modbus TCP): ambient and thermal figures, the encoder, the switches by name;
//! the drives' own supervision raises their manuals' messages from them; the Nanotec's home
//! switch is its input 6.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod web_rig;

use std::time::Duration;

use axum::http::StatusCode;
use serde_json::{json, Value};
use web_rig::{app, send, Running};

fn cell() -> Running {
    web_rig::cmmp_and_cmmo_st()
}

/// Whether message `number` of drive `drive` is active.
async fn active(app: &axum::Router, drive: usize, number: &str) -> bool {
    let (_, table) = send(
        app,
        "GET",
        &format!("/api/drives/{drive}/diagnostics"),
        None,
        None,
    )
    .await;
    table
        .as_array()
        .and_then(|rows| rows.iter().find(|r| r["number"] == number))
        .is_some_and(|r| r["active"] == true)
}

async fn wait_active(app: &axum::Router, drive: usize, number: &str) {
    for _ in 0..250 {
        if active(app, drive, number).await {
            return;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    panic!("drive {drive}: {number} not active within 5 s");
}

/// A hot cabinet heats the CMMP-AS's motor past 6510h:2F: 03-0 (and its EMCY code in 1003h),
/// 6510h:2E shows the temperature; the CMMO-ST's output stage past PNU 1068:2: 15h.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hot_cabinet_raises_the_temperature_messages() {
    let cell = cell();
    let app = app(&cell, None);
    let (status, p) = send(&app, "GET", "/api/drives/0/physics", None, None).await;
    assert_eq!(status, StatusCode::OK, "{p}");
    assert_eq!(p["ambient_c"], 25.0);
    assert_eq!(p["encoder"], "connected");
    for drive in [0, 1] {
        let (status, p) = send(
            &app,
            "PUT",
            &format!("/api/drives/{drive}/thermal"),
            Some(json!({"motor_time_constant_s": 0.2, "stage_time_constant_s": 0.2})),
            None,
        )
        .await;
        assert_eq!(status, StatusCode::OK, "{p}");
        let (status, p) = send(
            &app,
            "PUT",
            &format!("/api/drives/{drive}/ambient"),
            Some(json!({"celsius": 120.0})),
            None,
        )
        .await;
        assert_eq!(status, StatusCode::OK, "{p}");
        assert_eq!(p["ambient_c"], 120.0);
    }
    wait_active(&app, 0, "03-0").await;
    wait_active(&app, 1, "15h").await;
    let (_, p) = send(&app, "GET", "/api/drives/0/physics", None, None).await;
    assert!(
        p["motor_temperature_c"].as_f64().is_some_and(|t| t > 100.0),
        "{p}"
    );
    let (_, v) = send(&app, "GET", "/api/drives/0/objects/6510/2E", None, None).await;
    let shown: i64 = v["value"]
        .as_str()
        .and_then(|t| t.parse().ok())
        .unwrap_or(0);
    assert!(shown >= 100, "6510h:2E: {v}");
    let (_, v) = send(&app, "GET", "/api/drives/0/objects/1003/1", None, None).await;
    let newest: u64 = v["value"]
        .as_str()
        .and_then(|t| t.parse().ok())
        .unwrap_or(0);
    assert!(
        [0x4310, 0x4210].contains(&(newest & 0xFFFF)),
        "03-0 / 04-0 in 1003h: {v}"
    );
    // Bad input.
    let (status, e) = send(
        &app,
        "PUT",
        "/api/drives/0/ambient",
        Some(json!({"celsius": 5000})),
        None,
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST, "{e}");
    let (status, e) = send(
        &app,
        "PUT",
        "/api/drives/0/thermal",
        Some(json!({"motor_rise_k": -1})),
        None,
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST, "{e}");
}

/// A pulled encoder cable: CMMP-AS 08-0, CMMO-ST 06h; repaired, the cause goes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pulled_encoder_cable_raises_the_encoder_messages() {
    let cell = cell();
    let app = app(&cell, None);
    for (drive, number) in [(0, "08-0"), (1, "06h")] {
        let path = format!("/api/drives/{drive}/encoder");
        let (status, p) = send(
            &app,
            "PUT",
            &path,
            Some(json!({"fault": "disconnected"})),
            None,
        )
        .await;
        assert_eq!(status, StatusCode::OK, "{p}");
        assert_eq!(p["encoder"], "disconnected");
        wait_active(&app, drive, number).await;
        let (status, p) = send(
            &app,
            "PUT",
            &path,
            Some(json!({"fault": "noisy", "noise_increments": 10})),
            None,
        )
        .await;
        assert_eq!(status, StatusCode::OK, "{p}");
        assert_eq!(
            (p["encoder"].clone(), p["noise_increments"].clone()),
            (json!("noisy"), json!(10))
        );
    }
    let (status, e) = send(
        &app,
        "PUT",
        "/api/drives/0/encoder",
        Some(json!({"fault": "melted"})),
        None,
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST, "{e}");
}

/// The switches by name: the CMMP-AS's positive limit switch on DIN7 (60FDh bit 1), the home
/// switch on DIN9 (bit 2); released again with `null`. The CMMO-ST has no such inputs (404),
/// an unknown name is 404.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn switches_by_name() {
    let cell = cell();
    let app = app(&cell, None);
    let din = |app: axum::Router| async move {
        let (_, v) = send(&app, "GET", "/api/drives/0/objects/60FD/0", None, None).await;
        v["value"]
            .as_str()
            .and_then(|t| t.parse::<u64>().ok())
            .unwrap_or(0)
    };
    let put = |name: &str, body: Value| {
        let app = app.clone();
        let path = format!("/api/drives/0/switches/{name}");
        async move { send(&app, "PUT", &path, Some(body), None).await }
    };
    let (status, p) = put("limit_positive", json!({"actuated": true})).await;
    assert_eq!(status, StatusCode::OK, "{p}");
    let (status, _) = put("home", json!({"actuated": true})).await;
    assert_eq!(status, StatusCode::OK);
    tokio::time::sleep(Duration::from_millis(20)).await;
    assert_eq!(
        din(app.clone()).await & 0b111,
        0b110,
        "60FDh: positive limit and home"
    );
    put("limit_positive", json!({"actuated": null})).await;
    put("home", json!({"actuated": null})).await;
    tokio::time::sleep(Duration::from_millis(20)).await;
    assert_eq!(din(app.clone()).await & 0b111, 0);
    let (status, e) = put("sideways", json!({"actuated": true})).await;
    assert_eq!(status, StatusCode::NOT_FOUND, "{e}");
    // The CMMO-ST's one switch input is its reference switch (`home`); its ends of travel
    // are fixed stops, no inputs to force.
    let (status, e) = send(
        &app,
        "PUT",
        "/api/drives/1/switches/home",
        Some(json!({"actuated": true})),
        None,
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{e}");
    let (status, e) = send(
        &app,
        "PUT",
        "/api/drives/1/switches/limit_positive",
        Some(json!({"actuated": true})),
        None,
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND, "{e}");
    let (_, doc) = send(&app, "GET", "/api/openapi.json", None, None).await;
    for path in [
        "/api/drives/{drive}/physics",
        "/api/drives/{drive}/ambient",
        "/api/drives/{drive}/thermal",
        "/api/drives/{drive}/encoder",
        "/api/drives/{drive}/switches/{name}",
    ] {
        assert!(doc["paths"][path].is_object(), "{path} missing");
    }
}

/// The Nanotec's `home` is its input 6, the reference switch (§9.1): forced through the REST
/// API it shows in 60FDh bits 2 and 21 (its input 6 twice) once the cell loop has stepped the
/// drive; it has no limit-switch input, so `limit_positive` and `limit_negative` are 404s.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_nanotec_home_switch_is_its_input_6() {
    let cell = web_rig::nanotec();
    let app = app(&cell, None);
    // 60FDh once it reads `want`, within 5 s of the loop's real time.
    let din_becomes = |want: u64| {
        let app = app.clone();
        async move {
            let mut last = None;
            for _ in 0..250 {
                let (_, v) = send(&app, "GET", "/api/drives/0/objects/60FD/0", None, None).await;
                last = v["value"].as_str().and_then(|t| t.parse::<u64>().ok());
                if last == Some(want) {
                    return;
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
            panic!("60FDh {last:?}, not {want:#x}");
        }
    };
    let put = |name: &str, body: Value| {
        let app = app.clone();
        let path = format!("/api/drives/0/switches/{name}");
        async move { send(&app, "PUT", &path, Some(body), None).await }
    };
    din_becomes(0).await;
    for limit in ["limit_positive", "limit_negative"] {
        let (status, e) = put(limit, json!({"actuated": true})).await;
        assert_eq!(status, StatusCode::NOT_FOUND, "{limit}: {e}");
    }
    let (status, p) = put("home", json!({"actuated": true})).await;
    assert_eq!(status, StatusCode::OK, "{p}");
    din_becomes((1 << 21) | (1 << 2)).await;
    let (status, p) = put("home", json!({"actuated": null})).await;
    assert_eq!(status, StatusCode::OK, "{p}");
    din_becomes(0).await;
}
