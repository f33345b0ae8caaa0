//! The CMMO-ST's own web server, as its manual describes it (its extract kept beside the project,
//! `cmmo-st-fhpp.md` §2.2): the tabs "Control Interface", "FHPP Profile", "Network" and "Info";
//! "Device Control" must be activated before parameters can be saved; changes to the control
//! interface, the device profile, the interface parameters (TCP port, timeout) and the network take
//! effect only after the controller restarts, and the page marks them so.
//!
//! Decision: served by the console at `/cmmo-st/{drive}` (API under `/api/cmmo-st/{drive}/…`),
//! not on a port of its own as on the real device (`http://192.168.178.1/`, port 80): a cell
//! may hold several CMMO-STs, port 80 needs root, and one server keeps one token and one
//! thread. The page is the device's, the address is the console's.
//!
//! Settings the twin keeps as objects (PNU 128 "Enabled by") are written to the drive and
//! stored with PNU 127:2 "Save Data"; the others (interface, profile, network) exist only on
//! this page: they are kept here, pending until "Restart controller" (PNU 127:3 Reset Device).

use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::header::{CACHE_CONTROL, CONTENT_TYPE};
use axum::http::StatusCode;
use axum::response::IntoResponse;
use axum::routing::{get, post};
use axum::{Json, Router};
use drive::vendors::festo_cmmo_st::device::pnu_index;
use drive::vendors::festo_cmmo_st::fhpp::Authority;
use serde::{Deserialize, Serialize};
use utoipa::{OpenApi, ToSchema};

use super::fhpp_console::{fhpp, FhppRequest};
use crate::cell::control::{ControlHandle, Interface};
use crate::web::api::ApiError;
use crate::web::AppState;

const PAGE: &str = include_str!("web_server.html");

/// The settings of the four tabs that need a restart (§2.2 "Restart required").
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RestartSettings {
    /// "IO-Link", "I-Port" or "MODBUS".
    pub control_interface: String,
    /// "FHPP Channel" (8 bytes) or "FHPP + FPC Channel" (16 bytes).
    pub device_profile: String,
    /// Modbus TCP port (factory 502).
    #[schema(minimum = 1, maximum = 65535)]
    pub tcp_port: u16,
    /// Modbus timeout, ms (factory 100, not activated).
    #[schema(minimum = 0, maximum = 65535)]
    pub timeout_ms: u16,
    pub timeout_active: bool,
    /// "DHCP server active", "Obtain an IP address automatically" or "Use the following IP address".
    pub network: String,
    pub ip_address: String,
    pub subnet_mask: String,
    pub default_gateway: String,
}

impl Default for RestartSettings {
    /// The factory settings (§2.2); the interface is Modbus, the one the twin serves.
    fn default() -> Self {
        RestartSettings {
            control_interface: "MODBUS".into(),
            device_profile: "FHPP Channel".into(),
            tcp_port: 502,
            timeout_ms: 100,
            timeout_active: false,
            network: "DHCP server active".into(),
            ip_address: "192.168.178.1".into(),
            subnet_mask: "255.255.255.0".into(),
            default_gateway: "0.0.0.0".into(),
        }
    }
}

const INTERFACES: [&str; 3] = ["IO-Link", "I-Port", "MODBUS"];
const PROFILES: [&str; 2] = ["FHPP Channel", "FHPP + FPC Channel"];
const NETWORKS: [&str; 3] = [
    "DHCP server active",
    "Obtain an IP address automatically",
    "Use the following IP address",
];
/// PNU 128 values: 0 = fieldbus, 1 = digital input ENABLE and fieldbus (§3.1, Tab. B.19).
const ENABLED_BY: [&str; 2] = ["Fieldbus", "Digital Input 'Enable' and Fieldbus"];

impl RestartSettings {
    fn check(&self) -> Result<(), String> {
        let one_of = |what: &str, v: &str, list: &[&str]| {
            if list.contains(&v) {
                Ok(())
            } else {
                Err(format!("{what} {v:?}: one of {list:?}"))
            }
        };
        one_of("control_interface", &self.control_interface, &INTERFACES)?;
        one_of("device_profile", &self.device_profile, &PROFILES)?;
        one_of("network", &self.network, &NETWORKS)?;
        for (what, v) in [
            ("ip_address", &self.ip_address),
            ("subnet_mask", &self.subnet_mask),
            ("default_gateway", &self.default_gateway),
        ] {
            v.parse::<std::net::Ipv4Addr>()
                .map_err(|_| format!("{what} {v:?}: an IPv4 address"))?;
        }
        if self.tcp_port == 0 {
            return Err("tcp_port 1…65535".into());
        }
        Ok(())
    }
}

/// Per drive: the settings in force and those saved for the next restart.
#[derive(Debug, Clone, Default)]
struct Kept {
    active: RestartSettings,
    pending: Option<RestartSettings>,
}

fn kept() -> &'static Mutex<HashMap<usize, Kept>> {
    static KEPT: OnceLock<Mutex<HashMap<usize, Kept>>> = OnceLock::new();
    KEPT.get_or_init(|| Mutex::new(HashMap::new()))
}

fn with_kept<T>(drive: usize, f: impl FnOnce(&mut Kept) -> T) -> T {
    let mut map = kept().lock().unwrap_or_else(|p| p.into_inner());
    f(map.entry(drive).or_default())
}

/// What the page shows.
#[derive(Debug, Serialize, ToSchema)]
pub struct WebServerView {
    pub drive: usize,
    /// "Device Control" is active: the web server holds device control (PNU 125 = 0).
    pub device_control: bool,
    /// Who holds device control: `fieldbus`, `web server` or `FCT`.
    pub control_held_by: String,
    /// Settings in force.
    pub active: RestartSettings,
    /// Saved, in force after the next restart.
    pub pending: Option<RestartSettings>,
    /// PNU 128, in force at once: "Fieldbus" or "Digital Input 'Enable' and Fieldbus".
    pub enabled_by: String,
    /// The Info tab.
    pub info: InfoView,
    /// The names of the settings that need a restart.
    pub restart_required: Vec<String>,
}

#[derive(Debug, Serialize, ToSchema)]
pub struct InfoView {
    pub product: String,
    pub firmware_version: String,
    pub mac_id: String,
    pub serial_number: String,
    pub vendor: String,
}

/// The settings a save sends.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SaveBody {
    pub settings: RestartSettings,
    /// PNU 128: "Fieldbus" or "Digital Input 'Enable' and Fieldbus".
    pub enabled_by: String,
}

impl SaveBody {
    /// The settings checked; PNU 128's value (the index of `enabled_by` in its list).
    /// Shared with the fuzz target `http_body`.
    pub fn enabled_by(&self) -> Result<usize, ApiError> {
        self.settings
            .check()
            .map_err(|m| ApiError::new(StatusCode::BAD_REQUEST, m))?;
        ENABLED_BY
            .iter()
            .position(|e| *e == self.enabled_by)
            .ok_or_else(|| {
                ApiError::new(
                    StatusCode::BAD_REQUEST,
                    format!("enabled_by {:?}: one of {ENABLED_BY:?}", self.enabled_by),
                )
            })
    }
}

#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct DeviceControlBody {
    pub active: bool,
}

fn cmmo_st(h: &ControlHandle, drive: &str) -> Result<usize, ApiError> {
    let info = crate::web::api::find_drive(h, drive)?;
    let index = info.index;
    if info.device != "cmmo-st" || info.interface != Interface::ModbusTcp {
        return Err(ApiError::new(
            StatusCode::NOT_FOUND,
            format!(
                "drive {index} is a {}, not a CMMO-ST: it has no web server",
                info.device
            ),
        ));
    }
    Ok(index)
}

fn read_u32(h: &ControlHandle, drive: usize, index: u16, sub: u8) -> Option<u32> {
    let b = h.read(drive, index, sub).ok()?;
    let mut a = [0u8; 4];
    for (d, s) in a.iter_mut().zip(b.iter()) {
        *d = *s;
    }
    Some(u32::from_le_bytes(a))
}

fn chars(h: &ControlHandle, drive: usize, pnu: u16) -> String {
    // Char arrays: one character per subindex 1…30 (devices/cmmo-st.toml mapping rule).
    (1..=30u8)
        .filter_map(|sub| read_u32(h, drive, pnu_index(pnu), sub))
        .map(|c| c as u8)
        .take_while(|c| *c != 0)
        .map(char::from)
        .collect()
}

fn view(h: &ControlHandle, drive: usize) -> Result<WebServerView, ApiError> {
    let s = fhpp(h, drive, FhppRequest::Status)?;
    let (active, pending) = with_kept(drive, |k| (k.active.clone(), k.pending.clone()));
    let pnu128 = read_u32(h, drive, pnu_index(128), 1).unwrap_or(0);
    let fw: Vec<String> = (1..=4u8)
        .map(|sub| {
            read_u32(h, drive, pnu_index(101), sub)
                .unwrap_or(0)
                .to_string()
        })
        .collect();
    let serial = read_u32(h, drive, 0x1018, 4).unwrap_or(0);
    Ok(WebServerView {
        drive,
        device_control: s.authority == Authority::WebServer,
        control_held_by: match s.authority {
            Authority::Fieldbus => "fieldbus",
            Authority::WebServer => "web server",
            Authority::Fct => "FCT",
        }
        .into(),
        active,
        pending,
        enabled_by: ENABLED_BY
            .get(pnu128 as usize)
            .copied()
            .unwrap_or("unknown")
            .into(),
        info: InfoView {
            product: chars(h, drive, 120),
            firmware_version: format!("V{}", fw.join(".")),
            // Decision: the manual shows a MAC-ID on the Info tab but gives none; 00:0E:F0 is
            // Festo's OUI as remembered (NOT verified), the rest is the drive's place.
            mac_id: format!("00:0E:F0:00:00:{:02X}", drive & 0xFF),
            serial_number: format!("{serial:08X}"),
            vendor: chars(h, drive, 122),
        },
        restart_required: [
            "control_interface",
            "device_profile",
            "tcp_port",
            "timeout_ms",
            "timeout_active",
            "network",
            "ip_address",
            "subnet_mask",
            "default_gateway",
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .collect(),
    })
}

async fn call<T: Send + 'static>(
    s: &AppState,
    f: impl FnOnce(&ControlHandle) -> Result<T, ApiError> + Send + 'static,
) -> Result<Json<T>, ApiError> {
    let handle = s.handle.clone();
    tokio::task::spawn_blocking(move || f(&handle))
        .await
        .map_err(|_| ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "the request was lost"))?
        .map(Json)
}

/// The web server's tabs: settings in force and pending, Device Control, Info.
#[utoipa::path(get, path = "/api/cmmo-st/{drive}", tag = "cmmo-st web server",
    params(("drive" = u32, Path, description = "the CMMO-ST's index in the cell")),
    responses((status = 200, body = WebServerView), (status = 400, body = ApiError), (status = 404, body = ApiError)))]
async fn get_view(
    State(s): State<AppState>,
    Path(drive): Path<String>,
) -> Result<Json<WebServerView>, ApiError> {
    call(&s, move |h| view(h, cmmo_st(h, &drive)?)).await
}

/// "Device Control": the web server takes device control (or gives it back to the fieldbus).
/// Refused while the PLC sets CCON.LOCK (Tab. 5.14) or FCT holds it.
#[utoipa::path(post, path = "/api/cmmo-st/{drive}/device-control", tag = "cmmo-st web server",
    params(("drive" = u32, Path, description = "the CMMO-ST's index in the cell")),
    request_body = DeviceControlBody,
    responses((status = 200, body = WebServerView), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError), (status = 409, body = ApiError), (status = 415, body = ApiError)))]
async fn device_control(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<DeviceControlBody>, JsonRejection>,
) -> Result<Json<WebServerView>, ApiError> {
    let Json(body) = body?;
    call(&s, move |h| {
        let d = cmmo_st(h, &drive)?;
        let st = fhpp(h, d, FhppRequest::DeviceControl(body.active))?;
        if body.active && st.authority != Authority::WebServer {
            let why = match (st.refused, st.authority) {
                (Some(0x0B), _) => "the PLC locks it (CCON.LOCK = 1)",
                (_, Authority::Fct) => "FCT holds device control",
                _ => "the drive refused",
            };
            return Err(ApiError::new(
                StatusCode::CONFLICT,
                format!("Device Control not activated: {why}"),
            ));
        }
        view(h, d)
    })
    .await
}

/// Saves the tabs' settings. Needs Device Control (§2.2); PNU 128 is in force at once and
/// stored with PNU 127:2, the rest after the next restart.
#[utoipa::path(put, path = "/api/cmmo-st/{drive}/settings", tag = "cmmo-st web server",
    params(("drive" = u32, Path, description = "the CMMO-ST's index in the cell")),
    request_body = SaveBody,
    responses((status = 200, body = WebServerView), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError), (status = 409, body = ApiError), (status = 415, body = ApiError)))]
async fn save(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<SaveBody>, JsonRejection>,
) -> Result<Json<WebServerView>, ApiError> {
    let Json(body) = body?;
    let enabled_by = body.enabled_by()?;
    call(&s, move |h| {
        let d = cmmo_st(h, &drive)?;
        if fhpp(h, d, FhppRequest::Status)?.authority != Authority::WebServer {
            return Err(ApiError::new(
                StatusCode::CONFLICT,
                "activate Device Control before saving parameters (CMMO-ST §2.2)",
            ));
        }
        h.write(d, pnu_index(128), 1, &[enabled_by as u8])?;
        // PNU 127:2 = 01h: the user settings to EEPROM (§3.1.2).
        h.write(d, pnu_index(127), 2, &[0x01])?;
        with_kept(d, |k| {
            k.pending = (k.active != body.settings).then(|| body.settings.clone());
        });
        view(h, d)
    })
    .await
}

/// "Restart controller": PNU 127:3 = 10h Reset Device (§3.1.2); the saved settings come into
/// force, device control returns to the fieldbus (PNU 125 preset after every restart).
#[utoipa::path(post, path = "/api/cmmo-st/{drive}/restart", tag = "cmmo-st web server",
    params(("drive" = u32, Path, description = "the CMMO-ST's index in the cell")),
    responses((status = 200, body = WebServerView), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError), (status = 409, body = ApiError)))]
async fn restart(
    State(s): State<AppState>,
    Path(drive): Path<String>,
) -> Result<Json<WebServerView>, ApiError> {
    call(&s, move |h| {
        let d = cmmo_st(h, &drive)?;
        h.write(d, pnu_index(127), 3, &[0x10])?;
        fhpp(h, d, FhppRequest::DeviceControl(false))?;
        with_kept(d, |k| {
            if let Some(p) = k.pending.take() {
                k.active = p;
            }
        });
        view(h, d)
    })
    .await
}

#[derive(OpenApi)]
#[openapi(
    paths(get_view, device_control, save, restart),
    components(schemas(WebServerView, InfoView, RestartSettings, SaveBody, DeviceControlBody))
)]
pub struct CmmoStDoc;

pub fn routes() -> Router<AppState> {
    Router::new()
        .route(
            "/cmmo-st/{drive}",
            get(|| async {
                (
                    [
                        (CONTENT_TYPE, "text/html; charset=utf-8"),
                        (CACHE_CONTROL, "no-cache"),
                    ],
                    PAGE,
                )
                    .into_response()
            }),
        )
        .route("/api/cmmo-st/{drive}", get(get_view))
        .route("/api/cmmo-st/{drive}/device-control", post(device_control))
        .route("/api/cmmo-st/{drive}/settings", axum::routing::put(save))
        .route("/api/cmmo-st/{drive}/restart", post(restart))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factory_settings_are_the_manuals_and_valid() {
        let f = RestartSettings::default();
        assert_eq!(
            (f.tcp_port, f.timeout_ms, f.timeout_active),
            (502, 100, false)
        );
        assert_eq!(f.network, "DHCP server active");
        assert_eq!(f.check(), Ok(()));
        let bad = RestartSettings {
            device_profile: "FHPP 32".into(),
            ..f.clone()
        };
        assert!(bad.check().is_err_and(|m| m.contains("device_profile")));
        let bad = RestartSettings {
            ip_address: "999.1.1.1".into(),
            ..f
        };
        assert!(bad.check().is_err());
    }
}
