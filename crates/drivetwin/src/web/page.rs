//! The console page: one HTML file, its scripts (the console, the overview, the parameter
//! table, the scope) and its style, and the scope's plotting
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
const OVERVIEW_SCRIPT: &str = include_str!("assets/overview.js");
const PARAMETERS_SCRIPT: &str = include_str!("assets/parameters.js");
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
            "/overview.js",
            get(|| async { asset("text/javascript; charset=utf-8", OVERVIEW_SCRIPT) }),
        )
        .route(
            "/parameters.js",
            get(|| async { asset("text/javascript; charset=utf-8", PARAMETERS_SCRIPT) }),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_loads_the_library_then_the_scope_then_the_console() {
        let at = |s: &str| INDEX.find(s).unwrap_or(usize::MAX);
        assert!(at("/uplot.css") < at("/console.css"));
        assert!(at("/uplot.js") < at("/scope.js"));
        assert!(at("/scope.js") < at("/console.js") && at("/console.js") < INDEX.len());
        assert!(at("/overview.js") < at("/console.js") && at("/parameters.js") < at("/console.js"));
    }

    #[test]
    fn the_scope_library_or_a_stand_in_that_says_how_to_build_it_is_embedded() {
        // With web/node_modules: uPlot's own script; without: the stand-in the scope shows.
        assert!(
            UPLOT_SCRIPT.contains("uPlot")
                && (UPLOT_SCRIPT.len() > 10_000 || UPLOT_SCRIPT.contains("run npm ci in web/")),
            "{}",
            UPLOT_SCRIPT.get(..200).unwrap_or(UPLOT_SCRIPT)
        );
        assert!(SCOPE_SCRIPT.contains("window.uPlotMissing"));
    }
}
