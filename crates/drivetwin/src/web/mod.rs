//! The web console: an HTTP server beside the cell loop (axum) with a REST API, its OpenAPI
//! document, live plant samples over a WebSocket and a page served from the binary.
//!
//! The server runs on a thread of its own with its own tokio runtime and reaches the cell
//! only through its [`ControlHandle`]: a request costs the cell loop one command between two
//! socket events, never a lock on the drives (`DESIGN.md`, "The runtime owns the clock and
//! every socket"). Its requests ride on the loop's next turn ([`RIDE`]) instead of waking
//! it, so that browsers polling the console add no wake-up to the loop.
//!
//! Loopback only by default. Bound to any other address the console is reachable from the
//! network, so it prints a token at start and refuses every write without it
//! ([`auth::TOKEN_HEADER`]).
//!
//! - [`api`]: the REST handlers and the OpenAPI document;
//! - [`live`]: samples over a WebSocket, decimated for the browser;
//! - [`page`]: the console page and its script;
//! - [`parameters`]: the parameter table, and the parameter set as a DCF (export, import);
//! - [`auth`]: the write token;
//! - [`wire`]: wire faults and traces; [`scenarios`]: scenarios on the live cell;
//! - [`DevicePages`]: a device's own pages, served beside these; the console names no device,
//!   its caller hands it the pages (`drivetwin::vendors::VENDORS.web_pages`).

pub mod api;
pub mod auth;
pub mod diagnostics;
pub mod error_text;
pub mod ethercat_line;
pub mod live;
pub mod load_fmu;
pub mod motion;
pub mod page;
pub mod parameters;
pub mod physics;
pub mod scenarios;
pub mod wire;

use std::net::{SocketAddr, TcpListener};
use std::sync::Arc;

use axum::Router;

use crate::cell::control::ControlHandle;

/// Where `drivetwin run` serves the console unless told otherwise.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8080";

/// How long a console request waits at most for a turn the cell loop makes anyway (its
/// drives step each millisecond) before it wakes the loop ([`ControlHandle::riding`]): a
/// browser does not see 2 ms, the loop sees no wake-up per object the page reads.
pub const RIDE: std::time::Duration = std::time::Duration::from_millis(2);

/// `--http`: where the console listens.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HttpSetting {
    /// No `--http`: [`DEFAULT_ADDR`] when that port is free, else no console (a warning).
    Default,
    /// `--http ADDR`: this address, or an error when it cannot be bound.
    At(String),
    /// `--http off`.
    Off,
}

impl HttpSetting {
    pub fn parse(arg: Option<&str>) -> HttpSetting {
        match arg {
            None => HttpSetting::Default,
            Some(a) if a.eq_ignore_ascii_case("off") => HttpSetting::Off,
            Some(a) => HttpSetting::At(a.to_owned()),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum WebError {
    #[error("web console: cannot listen on {addr}: {source}")]
    Bind {
        addr: String,
        source: std::io::Error,
    },
    #[error("web console: {0}")]
    Io(#[from] std::io::Error),
}

/// What the handlers share: the cell's handle, the write token (none on loopback) and the
/// devices' own pages (their OpenAPI documents join the console's).
#[derive(Clone)]
pub struct AppState {
    pub handle: ControlHandle,
    pub token: Option<Arc<str>>,
    pub pages: &'static [DevicePages],
}

/// A device's own pages and API beside the console's, as the device's vendor folder defines
/// them: the console serves them without naming the device, so that adding a device's pages
/// touches its folder and the table that lists it (`drivetwin::vendors::VENDORS.web_pages`).
#[derive(Debug, Clone, Copy)]
pub struct DevicePages {
    /// The routes, under a path of the device's own (`/cmmo-st/{drive}`, `/api/…/panel`).
    pub routes: fn() -> Router<AppState>,
    /// Their part of `/api/openapi.json`.
    pub openapi: fn() -> utoipa::openapi::OpenApi,
    /// The motion page's way to move a drive whose profile is the device's own (the
    /// CMMO-ST's FHPP); `None`: the device's drives move as CiA 402 drives, if at all.
    pub motion: Option<motion::DeviceMotion>,
}

/// The whole console: API, OpenAPI document, WebSocket and page, and the devices' pages
/// of `state.pages`.
pub fn router(state: AppState) -> Router {
    let devices = state
        .pages
        .iter()
        .fold(Router::new(), |r, pages| r.merge((pages.routes)()));
    Router::new()
        .merge(api::routes())
        .merge(live::routes())
        .merge(diagnostics::routes())
        .merge(page::routes())
        .merge(wire::routes())
        .merge(ethercat_line::routes())
        .merge(motion::routes())
        .merge(physics::routes())
        .merge(load_fmu::routes())
        .merge(parameters::routes())
        .merge(devices)
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            auth::require_token_for_writes,
        ))
        .with_state(state)
}

/// A console that is serving.
#[derive(Debug)]
pub struct WebConsole {
    pub addr: SocketAddr,
    /// The write token, when the console is not on loopback.
    pub token: Option<String>,
    _thread: std::thread::JoinHandle<()>,
}

/// Binds the console's listener as `setting` says (`Ok(None)`: no console) and serves it on a
/// thread of its own until the process ends, with the devices' own `pages`.
pub fn start(
    setting: &HttpSetting,
    handle: ControlHandle,
    pages: &'static [DevicePages],
) -> Result<Option<WebConsole>, WebError> {
    let listener = match setting {
        HttpSetting::Off => return Ok(None),
        // Decision: the default console gives way to another instance (parallel test runs,
        // a second cell) instead of failing the run; an explicit --http ADDR must bind.
        HttpSetting::Default => match TcpListener::bind(DEFAULT_ADDR) {
            Ok(l) => l,
            Err(e) => {
                tracing::warn!(
                    addr = DEFAULT_ADDR,
                    error = %e,
                    "web console off: its default address is taken (--http ADDR chooses another)"
                );
                return Ok(None);
            }
        },
        HttpSetting::At(addr) => TcpListener::bind(addr).map_err(|source| WebError::Bind {
            addr: addr.clone(),
            source,
        })?,
    };
    let addr = listener.local_addr()?;
    let token = if addr.ip().is_loopback() {
        None
    } else {
        Some(auth::new_token()?)
    };
    listener.set_nonblocking(true)?;
    let state = AppState {
        handle: handle.riding(RIDE),
        token: token.as_deref().map(Arc::from),
        pages,
    };
    let thread = std::thread::Builder::new()
        .name("web".into())
        .spawn(move || serve(listener, state))?;
    Ok(Some(WebConsole {
        addr,
        token,
        _thread: thread,
    }))
}

/// The console's own runtime: two workers, so a slow browser never holds up the API. Its
/// threads run `SCHED_BATCH` ([`crate::sys::sched::set_batch`]): the samples and pages they
/// serve to the browsers' tabs wake them often, and those wake-ups must not take the CPU from
/// the cell loop; where the policy cannot be set they run as they are.
fn serve(listener: TcpListener, state: AppState) {
    let _ = crate::sys::sched::set_batch();
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("web-worker")
        .on_thread_start(|| {
            let _ = crate::sys::sched::set_batch();
        })
        .enable_all()
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            tracing::error!(error = %e, "web console: no runtime");
            return;
        }
    };
    runtime.block_on(async move {
        let listener = match tokio::net::TcpListener::from_std(listener) {
            Ok(l) => l,
            Err(e) => {
                tracing::error!(error = %e, "web console: listener");
                return;
            }
        };
        if let Err(e) = axum::serve(listener, router(state)).await {
            tracing::error!(error = %e, "web console stopped");
        }
    });
}
