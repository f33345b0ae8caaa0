//! Embeds the web console's plotting library (uPlot, from the npm registry through
//! `web/package.json` and its lock file) in the binary: its script and style are copied from
//! `web/node_modules` into `OUT_DIR`, where `web::page` takes them with `include_str!`.
//!
//! Decision: the build installs the library itself (`npm ci` in `web/`, from the lock file)
//! when `web/node_modules` is missing and npm is on the PATH; `DRIVETWIN_NPM=0` forbids that
//! (offline or vendored builds). A build without the library still succeeds: the console then
//! serves a script that says on the scope "scope library not built: run npm ci in web/ and
//! rebuild", and everything else of the console works. Nothing of the library is committed,
//! and nothing is fetched at run time (no CDN).

use std::path::{Path, PathBuf};
use std::process::Command;

const SCRIPT: &str = "uPlot.iife.min.js";
const STYLE: &str = "uPlot.min.css";

/// What the console serves in place of the library when it was not built.
const MISSING_SCRIPT: &str = "// uPlot was not built into this binary.\n\
window.uPlotMissing = \"scope library not built: run npm ci in web/ and rebuild\";\n";
const MISSING_STYLE: &str = "/* uPlot was not built into this binary. */\n";

fn main() {
    let manifest = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let out = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default());
    let web = manifest.join("../../web");
    let dist = web.join("node_modules/uplot/dist");
    println!(
        "cargo:rerun-if-changed={}",
        web.join("package-lock.json").display()
    );
    println!("cargo:rerun-if-changed={}", dist.join(SCRIPT).display());
    println!("cargo:rerun-if-changed={}", dist.join(STYLE).display());
    println!("cargo:rerun-if-env-changed=DRIVETWIN_NPM");

    if !dist.join(SCRIPT).exists() && web.join("package-lock.json").exists() && npm_allowed() {
        install(&web);
        date_as_lock(&web, &[dist.join(SCRIPT), dist.join(STYLE)]);
    }
    let embedded = copy(&dist.join(SCRIPT), &out.join(SCRIPT), MISSING_SCRIPT)
        & copy(&dist.join(STYLE), &out.join(STYLE), MISSING_STYLE);
    if !embedded {
        println!(
            "cargo:warning=the console's scope library (uPlot) is not built in: run `npm ci --prefix web` and rebuild"
        );
    }
}

fn npm_allowed() -> bool {
    std::env::var("DRIVETWIN_NPM").map_or(true, |v| v != "0")
}

/// `npm ci` in `web/`: the lock file's versions, nothing else.
fn install(web: &Path) {
    let status = Command::new("npm")
        .args(["ci", "--no-audit", "--no-fund", "--silent"])
        .current_dir(web)
        .status();
    if !matches!(status, Ok(s) if s.success()) {
        println!("cargo:warning=`npm ci` in web/ failed; the console's scope is built without its library");
    }
}

/// Dates the files `npm ci` just wrote as the lock file they come from. Written while this
/// script runs, they would be newer than its run, and cargo would take them for a change made
/// after the build: the next build would run the script and compile the crate again.
fn date_as_lock(web: &Path, files: &[PathBuf]) {
    let Ok(lock) = std::fs::metadata(web.join("package-lock.json")).and_then(|m| m.modified())
    else {
        return;
    };
    for f in files {
        if let Err(e) = std::fs::File::options()
            .write(true)
            .open(f)
            .and_then(|file| file.set_modified(lock))
        {
            println!("cargo:warning=cannot date {}: {e}", f.display());
        }
    }
}

/// Copies `from` to `to`, or writes `missing` there; true when the file was copied.
fn copy(from: &Path, to: &Path, missing: &str) -> bool {
    if std::fs::copy(from, to).is_ok() {
        return true;
    }
    if let Err(e) = std::fs::write(to, missing) {
        println!("cargo:warning=cannot write {}: {e}", to.display());
    }
    false
}
