//! The console says why a drive refuses a command: a factory Kinco FD3 (drive 0: DIN1 Enable,
//! DIN3 Operation Mode Sel) and a CMMP-AS (drive 1) on one CAN bus of a running cell loop,
//! through the router. A refused Enable, jog or write answers 409 with the drive's reason and
//! the manual's rule, never 200 with the drive where it was; the OpenAPI document names the
//! reason's schema.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod web_rig;

use axum::http::StatusCode;
use serde_json::{json, Value};
use web_rig::{app, put, send, Running};

/// Drive 0 a Kinco FD3 (node 2) at factory defaults, drive 1 a CMMP-AS (node 1), on one bus.
fn cell() -> Running {
    web_rig::kinco_and_cmmp()
}

fn text(v: &Value) -> &str {
    v.as_str().unwrap_or_default()
}

/// The reason of a 409: kind, text, rule.
fn reason(e: &Value) -> (&str, &str, &str) {
    let r = &e["reason"];
    (text(&r["kind"]), text(&r["text"]), text(&r["rule"]))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn enable_on_a_factory_kinco_answers_409_naming_din1_and_the_rule() {
    let cell = cell();
    let app = app(&cell, None);
    let (_, v) = send(&app, "GET", "/api/drives/0/motion", None, None).await;
    assert_eq!(v["state"], "READY TO SWITCH ON", "DIN1 inactive: 06h");

    for path in ["/api/drives/0/motion/enable", "/api/drives/0/enable"] {
        let (status, e) = send(&app, "POST", path, None, None).await;
        assert_eq!(status, StatusCode::CONFLICT, "{path}: {e}");
        let (kind, why, rule) = reason(&e);
        assert_eq!(kind, "input_owns_object", "{e}");
        assert!(
            why.starts_with("DIN1 has the function Enable (2010h:03)") && why.contains("6040h"),
            "{why}"
        );
        assert!(rule.contains("L1287") && rule.contains("highest"), "{rule}");
        assert!(
            text(&e["error"]).starts_with(why) && text(&e["error"]).contains("SDO abort"),
            "the message is the reason, then the drive's answer: {e}"
        );
        assert_eq!(
            e["abort_code"], "0x08000021",
            "the drive's own answer stays beside it (local control)"
        );
    }
    let (_, v) = send(&app, "GET", "/api/drives/0/motion", None, None).await;
    assert_eq!(v["state"], "READY TO SWITCH ON");

    // Jog needs the enable: the same reason.
    let (status, e) = send(
        &app,
        "POST",
        "/api/drives/0/motion/jog",
        Some(json!({"direction": 1})),
        None,
    )
    .await;
    assert_eq!(status, StatusCode::CONFLICT, "{e}");
    assert!(reason(&e).1.starts_with("DIN1"), "{e}");

    // The controlword and the mode written in the parameter table: the owner is named.
    let (status, e) = put(&app, "/api/drives/0/objects/6060/0", json!({"value": 3})).await;
    assert_eq!(status, StatusCode::CONFLICT, "{e}");
    assert!(
        reason(&e)
            .1
            .starts_with("DIN3 has the function Operation Mode Sel (2010h:05)"),
        "{e}"
    );

    // Din1_Function and Din3_Function := 0, as a bus master does: Enable goes through.
    for sub in ["3", "5"] {
        let (status, o) = put(
            &app,
            &format!("/api/drives/0/objects/2010/{sub}"),
            json!({"value": 0}),
        )
        .await;
        assert_eq!(status, StatusCode::OK, "{o}");
    }
    let (status, v) = send(&app, "POST", "/api/drives/0/motion/enable", None, None).await;
    assert_eq!(status, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "OPERATION ENABLED");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cmmp_as_without_din4_says_its_hardware_enable_is_missing() {
    let cell = cell();
    let app = app(&cell, None);
    // DIN4 (output-stage enable) forced low.
    let (status, _) = put(
        &app,
        "/api/drives/1/inputs",
        json!({"mask": 0x10, "levels": 0}),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    let (status, e) = send(&app, "POST", "/api/drives/1/motion/enable", None, None).await;
    assert_eq!(status, StatusCode::CONFLICT, "{e}");
    let (kind, why, rule) = reason(&e);
    assert_eq!(kind, "hardware_enable_missing");
    assert!(why.contains("DIN4 output-stage enable"), "{why}");
    assert!(rule.contains("Tab. 6.4 transition 2"), "{rule}");
    // Given back: enabled.
    put(
        &app,
        "/api/drives/1/inputs",
        json!({"mask": 0, "levels": 0}),
    )
    .await;
    let (status, v) = send(&app, "POST", "/api/drives/1/motion/enable", None, None).await;
    assert_eq!(
        (status, &v["state"]),
        (StatusCode::OK, &json!("OPERATION ENABLED"))
    );
    // A mode the CMMP-AS does not have: the reason and CiA 402's rule.
    let (status, e) = put(&app, "/api/drives/1/objects/6060/0", json!({"value": 2})).await;
    assert_eq!(status, StatusCode::CONFLICT, "{e}");
    assert_eq!(e["abort_code"], "0x06090030");
    assert_eq!(reason(&e).0, "mode_not_supported", "{e}");
    assert!(reason(&e).2.contains("6502h"), "{e}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_openapi_document_has_the_reason() {
    let cell = cell();
    let app = app(&cell, None);
    let (status, doc) = send(&app, "GET", "/api/openapi.json", None, None).await;
    assert_eq!(status, StatusCode::OK);
    let schemas = &doc["components"]["schemas"];
    assert_eq!(
        schemas["ApiError"]["properties"]["reason"]["$ref"]
            .as_str()
            .or_else(|| {
                schemas["ApiError"]["properties"]["reason"]["oneOf"][1]["$ref"].as_str()
            }),
        Some("#/components/schemas/ReasonView"),
        "{}",
        schemas["ApiError"]
    );
    for field in ["kind", "text", "rule"] {
        assert!(
            schemas["ReasonView"]["properties"][field].is_object(),
            "{field}"
        );
    }
}
