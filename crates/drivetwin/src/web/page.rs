//! The console page: one HTML file, its script and its style, and the scope's plotting
//! library (uPlot, from the npm registry through `web/package.json`), all compiled into the
//! binary (no CDN, nothing fetched at run time). `build.rs` puts the library in `OUT_DIR`, or
//! a stand-in that makes the scope say how to build it.

use axum::http::header::{CACHE_CONTROL, CONTENT_TYPE};
use axum::response::IntoResponse;
use axum::routing::get;
use axum::Router;

use super::AppState;

const INDEX: &str = include_str!("assets/index.html");
const SCRIPT: &str = include_str!("assets/console.js");
const STYLE: &str = include_str!("assets/console.css");
const SCOPE_SCRIPT: &str = include_str!("assets/scope.js");
const UPLOT_SCRIPT: &str = include_str!(concat!(env!("OUT_DIR"), "/uPlot.iife.min.js"));
const UPLOT_STYLE: &str = include_str!(concat!(env!("OUT_DIR"), "/uPlot.min.css"));

fn asset(kind: &'static str, body: &'static str) -> impl IntoResponse {
    ([(CONTENT_TYPE, kind), (CACHE_CONTROL, "no-cache")], body)
}

pub fn routes() -> Router<AppState> {
    Router::new()
        .route(
            "/",
            get(|| async { asset("text/html; charset=utf-8", INDEX) }),
        )
        .route(
            "/console.js",
            get(|| async { asset("text/javascript; charset=utf-8", SCRIPT) }),
        )
        .route(
            "/console.css",
            get(|| async { asset("text/css; charset=utf-8", STYLE) }),
        )
        .route(
            "/scope.js",
            get(|| async { asset("text/javascript; charset=utf-8", SCOPE_SCRIPT) }),
        )
        .route(
            "/uplot.js",
            get(|| async { asset("text/javascript; charset=utf-8", UPLOT_SCRIPT) }),
        )
        .route(
            "/uplot.css",
            get(|| async { asset("text/css; charset=utf-8", UPLOT_STYLE) }),
        )
}
