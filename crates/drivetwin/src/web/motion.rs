//! Manual motion from the console: enable, disable, jog, move to a position and home, done
//! the way each manual tells a master to do it: through the control handle's object writes
//! for the CiA 402 drives (CMMP-AS, Nanotec, Kinco, a drive from its EDS), and for a drive
//! whose profile is its vendor's own (the CMMO-ST's FHPP) through the [`DeviceMotion`] its
//! vendor folder gives the console with its pages ([`super::DevicePages::motion`]).
//!
//! The CiA 402 sequences are plain functions over [`Objects`], so a test runs them against a
//! fake drive that records what was written; the REST endpoints at the end of the file call
//! them on the cell's [`ControlHandle`]. Where the drive refuses (an SDO abort, a state that
//! does not allow the step) the answer is a 409 that says why.

use std::time::Duration;

use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::routing::{get, post};
use axum::{Json, Router};
use serde::{Deserialize, Serialize};
use utoipa::{OpenApi, ToSchema};

use super::api::{console_state, ApiError};
use super::{error_text, AppState, DevicePages};
use crate::cell::control::{ControlError, ControlHandle, DriveInfo};
use drive::controlword::Controlword;
use drive::device_control::State as Cia402State;
use drive::drive::refusal::Request;
use drive::statusword::Statusword;

// ------------------------------------------------------------------------------- the access

/// What a CiA 402 sequence needs of a drive.
pub trait Objects {
    fn read(&self, index: u16, sub: u8) -> Result<Vec<u8>, ControlError>;
    fn write(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), ControlError>;
    /// Lets the drive run for `d` (its cycles go on in the cell loop).
    fn wait(&self, d: Duration);
}

/// One drive of a running cell, through its control handle.
pub struct Handle<'a> {
    pub handle: &'a ControlHandle,
    pub drive: usize,
}

impl Objects for Handle<'_> {
    fn read(&self, index: u16, sub: u8) -> Result<Vec<u8>, ControlError> {
        self.handle.read(self.drive, index, sub)
    }
    fn write(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), ControlError> {
        self.handle.write(self.drive, index, sub, data)
    }
    fn wait(&self, d: Duration) {
        std::thread::sleep(d);
    }
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MotionError {
    #[error(transparent)]
    Control(#[from] ControlError),
    /// A write of the sequence was refused (the drive's answer in `error`).
    #[error("{index:04X}h:{sub:02X}: {error}")]
    Refused {
        index: u16,
        sub: u8,
        error: ControlError,
    },
    /// 6060h := `wanted` was refused.
    #[error("modes of operation 6060h := {wanted}: {error}")]
    ModeRefused { wanted: i8, error: ControlError },
    #[error("the drive is in {0}; enable it first (OPERATION ENABLED)")]
    NotEnabled(String),
    #[error("the drive did not reach {wanted}: it shows {shown}")]
    NotReached { wanted: String, shown: String },
    #[error("modes of operation 6061h shows {shown}, not {wanted}: the drive kept its mode")]
    ModeNotTaken { wanted: i8, shown: i8 },
    #[error("no set-point acknowledge (6041h bit 12) within {0} ms")]
    NoAcknowledge(u64),
}

/// How long a step may take before the drive counts as not following (its cycle is 1 ms,
/// the cell loop answers between two socket events).
pub const STEP_WAIT: Duration = Duration::from_millis(5);
/// How many steps a sequence waits for the drive to follow.
pub const TRIES: u32 = 60;

// ------------------------------------------------------------------------------- CiA 402

/// Modes of operation 6060h (CiA 402 §6.2; CMMP-AS §6.1.6 Tab. 6.9).
pub mod mode {
    pub const PROFILE_POSITION: i8 = 1;
    pub const VELOCITY: i8 = 2;
    pub const PROFILE_VELOCITY: i8 = 3;
    pub const HOMING: i8 = 6;
}

fn u16_of(b: &[u8]) -> u16 {
    u16::from_le_bytes([
        b.first().copied().unwrap_or(0),
        b.get(1).copied().unwrap_or(0),
    ])
}

fn statusword_of(io: &impl Objects) -> Result<u16, ControlError> {
    io.read(0x6041, 0).map(|b| u16_of(&b))
}

fn state_name(sw: u16) -> String {
    console_state(sw).map_or_else(|| format!("6041h = {sw:#06X}"), |s| s.name().to_owned())
}

/// A write of the sequence; a refusal names the object.
fn write(io: &impl Objects, index: u16, sub: u8, data: &[u8]) -> Result<(), MotionError> {
    io.write(index, sub, data)
        .map_err(|error| MotionError::Refused { index, sub, error })
}

fn controlword(io: &impl Objects, word: Controlword) -> Result<(), MotionError> {
    write(io, 0x6040, 0, &word.bits().to_le_bytes())?;
    io.wait(STEP_WAIT);
    Ok(())
}

/// Polls the statusword until `done` holds.
fn await_status(
    io: &impl Objects,
    done: impl Fn(u16) -> bool,
) -> Result<Result<u16, u16>, ControlError> {
    let mut sw = statusword_of(io)?;
    for _ in 0..TRIES {
        if done(sw) {
            return Ok(Ok(sw));
        }
        io.wait(STEP_WAIT);
        sw = statusword_of(io)?;
    }
    Ok(if done(sw) { Ok(sw) } else { Err(sw) })
}

fn enabled(sw: u16) -> bool {
    Statusword(sw).state() == Some(Cia402State::OperationEnabled)
}

/// To OPERATION ENABLED: a fault reset first when in FAULT (rising edge of bit 7), then
/// shutdown, switch on, enable operation (CMMP-AS §6.1.3 Tab. 6.4, CiA 402 Fig. 5).
pub fn enable(io: &impl Objects) -> Result<u16, MotionError> {
    let sw = statusword_of(io)?;
    if enabled(sw) {
        return Ok(sw);
    }
    if Statusword(sw).contains(Statusword::FAULT) {
        controlword(io, Controlword::EMPTY)?;
        controlword(io, Controlword::FAULT_RESET)?;
    }
    for word in [
        Controlword::SHUTDOWN,
        Controlword::SWITCH_ON_CMD,
        Controlword::ENABLE_OPERATION_CMD,
    ] {
        controlword(io, word)?;
    }
    await_status(io, enabled)?.map_err(|sw| MotionError::NotReached {
        wanted: "OPERATION ENABLED".into(),
        shown: state_name(sw),
    })
}

/// The power stage off: "shutdown" to READY TO SWITCH ON (Tab. 6.4, transition 8).
pub fn disable(io: &impl Objects) -> Result<u16, MotionError> {
    controlword(io, Controlword::SHUTDOWN)?;
    Ok(statusword_of(io)?)
}

fn require_enabled(io: &impl Objects) -> Result<(), MotionError> {
    let sw = statusword_of(io)?;
    if enabled(sw) {
        Ok(())
    } else {
        Err(MotionError::NotEnabled(state_name(sw)))
    }
}

/// 6060h := `wanted`, then waits for 6061h to show it (CiA 402 §6.2: the mode is in force
/// once 6061h shows it).
fn set_mode(io: &impl Objects, wanted: i8) -> Result<(), MotionError> {
    io.write(0x6060, 0, &wanted.to_le_bytes())
        .map_err(|error| MotionError::ModeRefused { wanted, error })?;
    let mut shown = 0;
    for _ in 0..TRIES {
        shown = io
            .read(0x6061, 0)?
            .first()
            .map_or(0, |b| i8::from_le_bytes([*b]));
        if shown == wanted {
            return Ok(());
        }
        io.wait(STEP_WAIT);
    }
    Err(MotionError::ModeNotTaken { wanted, shown })
}

/// Jog in profile velocity mode: 6060h = 3, target velocity 60FFh = `velocity` (the drive's
/// velocity units; negative: backwards, 0: stop), enable operation (CMMP-AS §6.4, CiA 402
/// §10). A drive whose supported drive modes (6502h) lack profile velocity but have velocity
/// mode (the Nanotec PD4-N, 6502h = 6Bh) jogs in velocity mode: 6060h = 2, vl target
/// velocity 6042h (INTEGER16, rpm; CiA 402 §9, Nanotec §6.3). The drive must be enabled.
pub fn jog(io: &impl Objects, velocity: i32) -> Result<u16, MotionError> {
    let sw = statusword_of(io)?;
    if velocity == 0 && !enabled(sw) {
        // Stopping a drive that cannot move (a fault stopped it) asks nothing of it.
        return Ok(sw);
    }
    require_enabled(io)?;
    let supported = io.read(0x6502, 0).ok().map(|b| {
        u32::from_le_bytes([
            b.first().copied().unwrap_or(0),
            b.get(1).copied().unwrap_or(0),
            b.get(2).copied().unwrap_or(0),
            b.get(3).copied().unwrap_or(0),
        ])
    });
    // 6502h bit 2: profile velocity; bit 1: velocity mode (CiA 402 §6.4.4).
    let vl_only = supported.is_some_and(|m| m & 0b100 == 0 && m & 0b010 != 0);
    if vl_only {
        set_mode(io, mode::VELOCITY)?;
        let rpm = velocity.clamp(i32::from(i16::MIN), i32::from(i16::MAX)) as i16;
        write(io, 0x6042, 0, &rpm.to_le_bytes())?;
    } else {
        set_mode(io, mode::PROFILE_VELOCITY)?;
        write(io, 0x60FF, 0, &velocity.to_le_bytes())?;
    }
    controlword(io, Controlword::ENABLE_OPERATION_CMD)?;
    Ok(statusword_of(io)?)
}

/// A move in profile position mode: 6060h = 1, target 607Ah, then the new-set-point handshake:
/// bit 4 rises (with bit 5 "change immediately" and bit 6 "relative"), the drive answers with
/// set-point acknowledge (6041h bit 12), bit 4 falls (CMMP-AS §6.3 Fig. 6.6, CiA 402 §12.2).
pub fn move_to(io: &impl Objects, target: i32, relative: bool) -> Result<u16, MotionError> {
    require_enabled(io)?;
    set_mode(io, mode::PROFILE_POSITION)?;
    write(io, 0x607A, 0, &target.to_le_bytes())?;
    let base = Controlword::ENABLE_OPERATION_CMD.with(Controlword::RELATIVE, relative);
    controlword(io, base)?;
    controlword(
        io,
        base | Controlword::NEW_SET_POINT | Controlword::CHANGE_SET_IMMEDIATELY,
    )?;
    let acked = await_status(io, |sw| {
        Statusword(sw).contains(Statusword::SET_POINT_ACKNOWLEDGE)
    })?;
    controlword(io, base)?;
    match acked {
        Ok(sw) => Ok(sw),
        Err(_) => Err(MotionError::NoAcknowledge(
            STEP_WAIT.as_millis() as u64 * u64::from(TRIES),
        )),
    }
}

/// Homing with the method in 6098h: 6060h = 6, then bit 4 "homing operation start" rises
/// and stays set while homing runs (CMMP-AS §6.2, CiA 402 §11: bit 4 falling interrupts).
pub fn home(io: &impl Objects) -> Result<u16, MotionError> {
    require_enabled(io)?;
    set_mode(io, mode::HOMING)?;
    controlword(io, Controlword::ENABLE_OPERATION_CMD)?;
    controlword(
        io,
        Controlword::ENABLE_OPERATION_CMD | Controlword::HOMING_START,
    )?;
    Ok(statusword_of(io)?)
}

// ---------------------------------------------------------------------------- REST: views

/// One bit of a status word or byte.
#[derive(Debug, Serialize, ToSchema)]
pub struct BitView {
    /// `6041h`, `SCON` or `SPOS`.
    pub word: String,
    pub bit: u8,
    pub name: String,
    pub set: bool,
}

/// An error, with its text.
#[derive(Debug, Serialize, ToSchema)]
pub struct ErrorView {
    /// CiA 301 error code (CiA 402 drives) or FHPP diagnostic number (CMMO-ST), hex.
    pub code: String,
    pub text: String,
    /// The CMMO-ST memory's event type (fault, warning, gone, switch-on) and time stamp.
    pub event: Option<String>,
    pub time_ms: Option<u32>,
}

/// What a drive's page shows above its parameters.
#[derive(Debug, Serialize, ToSchema)]
pub struct MotionView {
    pub drive: usize,
    /// `cia402` or `fhpp`.
    pub profile: String,
    /// CiA 402 state or FHPP state (from SCON).
    pub state: String,
    /// 6041h, or SCON and SPOS as one word (SCON low byte).
    pub word: u16,
    pub bits: Vec<BitView>,
    /// The active error, if any.
    pub active_error: Option<ErrorView>,
    /// 1003h (CiA 402, newest first) or the diagnostic memory (CMMO-ST, newest first).
    pub history: Vec<ErrorView>,
    /// CMMO-ST: who holds device control (`fieldbus`, `web server`, `FCT`).
    pub device_control: Option<String>,
    /// The drive's display; `null` for a drive without one.
    pub display: Option<String>,
}

fn cia402_view(
    h: &ControlHandle,
    drive: usize,
    table: &'static [od::Diagnostic],
) -> Result<MotionView, ApiError> {
    let sw = u16_of(&h.read(drive, 0x6041, 0)?);
    let bits = Statusword::BIT_NAMES
        .iter()
        .zip(0u8..)
        .map(|(name, bit)| BitView {
            word: "6041h".into(),
            bit,
            name: (*name).to_owned(),
            set: sw & (1 << bit) != 0,
        })
        .collect();
    let code = h.read(drive, 0x603F, 0).ok().map(|b| u16_of(&b));
    // 1003h: sub 0 the number of errors, sub 1 the newest (CiA 301 §7.5.2.5).
    let count = h
        .read(drive, 0x1003, 0)
        .ok()
        .and_then(|b| b.first().copied())
        .unwrap_or(0);
    let codes: Vec<u16> = (1..=count)
        .filter_map(|sub| h.read(drive, 0x1003, sub).ok())
        // Low 16 bits: the error code; high 16: manufacturer-specific information.
        .map(|b| u16_of(&b))
        .collect();
    // In FAULT: 603Fh, the code of the last error (CiA 402 §6.3.3); a drive that leaves it 0
    // names the fault by its newest 1003h entry.
    let active_error = Statusword(sw)
        .contains(Statusword::FAULT)
        .then(|| code.filter(|c| *c != 0).or_else(|| codes.first().copied()))
        .flatten()
        .map(|c| error_text::cia_error(table, c));
    let history = codes
        .into_iter()
        .map(|c| error_text::cia_error(table, c))
        .collect();
    Ok(MotionView {
        drive,
        profile: "cia402".into(),
        state: state_name(sw),
        word: sw,
        bits,
        active_error,
        history,
        device_control: None,
        display: display_of(h, drive),
    })
}

/// The drive's display as the motion page shows it.
pub fn display_of(h: &ControlHandle, drive: usize) -> Option<String> {
    h.plant(drive)
        .ok()
        .and_then(|s| s.display)
        .map(|d| super::api::display_text(&d))
}

/// The motion of a drive whose profile is its vendor's own (the CMMO-ST's FHPP): the
/// vendor folder gives it to the console with its pages ([`DevicePages::motion`]).
#[derive(Debug, Clone, Copy)]
pub struct DeviceMotion {
    /// Whether this motion moves `drive`.
    pub moves: fn(drive: &DriveInfo) -> bool,
    /// The page's view of the drive, its diagnostic table naming its numbers.
    pub view: fn(
        h: &ControlHandle,
        drive: usize,
        table: &'static [od::Diagnostic],
    ) -> Result<MotionView, ApiError>,
    /// Carries out `command` the way the drive's manual tells a master to.
    pub run: fn(h: &ControlHandle, drive: usize, command: MotionCommand) -> Result<(), ApiError>,
}

/// A command of the motion page, as its endpoints take it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionCommand {
    Enable,
    Disable,
    /// `direction` 1, -1 or 0 (stop); `velocity` in the drive's velocity units where it jogs
    /// at a given speed.
    Jog {
        direction: i8,
        velocity: u32,
    },
    /// `velocity_percent`: of the maximum, where the drive takes a velocity so.
    Move {
        target: i32,
        relative: bool,
        velocity_percent: u8,
    },
    Home,
}

enum Kind {
    /// With the drive's diagnostic table, which names its error codes.
    Cia402(&'static [od::Diagnostic]),
    /// A vendor's own motion, with the drive's diagnostic table.
    Device(DeviceMotion, &'static [od::Diagnostic]),
}

fn kind(h: &ControlHandle, pages: &[DevicePages], drive: &str) -> Result<(usize, Kind), ApiError> {
    let info = super::api::find_drive(h, drive)?;
    let index = info.index;
    let desc = crate::cell::eds_drive::by_name(info.device);
    let own = pages
        .iter()
        .filter_map(|p| p.motion)
        .find(|m| (m.moves)(&info));
    if let Some(m) = own {
        Ok((index, Kind::Device(m, desc.map_or(&[], |d| d.diagnostics))))
    } else if let Some(d) = desc.filter(|d| d.entry(0x6040, 0).is_some()) {
        Ok((index, Kind::Cia402(d.diagnostics)))
    } else {
        Err(ApiError::new(
            StatusCode::CONFLICT,
            format!(
                "drive {index} ({}) has neither a CiA 402 controlword nor FHPP",
                info.device
            ),
        ))
    }
}

fn view(h: &ControlHandle, drive: usize, k: &Kind) -> Result<MotionView, ApiError> {
    match k {
        Kind::Cia402(table) => cia402_view(h, drive, table),
        Kind::Device(m, table) => (m.view)(h, drive, table),
    }
}

impl From<MotionError> for ApiError {
    fn from(e: MotionError) -> ApiError {
        match e {
            MotionError::Control(c) => ApiError::from(c),
            MotionError::Refused { error, .. } | MotionError::ModeRefused { error, .. } => {
                ApiError::from(error)
            }
            other => ApiError::new(StatusCode::CONFLICT, other.to_string()),
        }
    }
}

/// What the drive was asked when `e` stopped a sequence.
fn request_of(e: &MotionError) -> Option<Request> {
    match e {
        MotionError::Refused { index, sub, .. } => Some(Request::Write {
            index: *index,
            sub: *sub,
        }),
        MotionError::ModeRefused { wanted, .. } | MotionError::ModeNotTaken { wanted, .. } => {
            Some(Request::Mode(*wanted))
        }
        MotionError::NotEnabled(_) | MotionError::NotReached { .. } => Some(Request::Enable),
        _ => None,
    }
}

/// The answer to a sequence that `e` stopped: its error with the drive's reason where the
/// drive names one, so a click on a control is never a silent no-op.
pub(super) fn refusal(h: &ControlHandle, drive: usize, e: MotionError) -> ApiError {
    let request = request_of(&e);
    let error = ApiError::from(e);
    match request {
        Some(r) => error.asking(h, drive, r),
        None => error,
    }
}

/// Carries out `command` (none: only the view) on drive `drive` and answers its view.
async fn run(
    s: &AppState,
    drive: String,
    command: Option<MotionCommand>,
) -> Result<Json<MotionView>, ApiError> {
    let handle = s.handle.clone();
    let pages = s.pages;
    tokio::task::spawn_blocking(move || {
        let (index, k) = kind(&handle, pages, &drive)?;
        if let Some(command) = command {
            act(&handle, index, &k, command)?;
        }
        view(&handle, index, &k)
    })
    .await
    .map_err(|_| ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "the request was lost"))?
    .map(Json)
}

fn act(h: &ControlHandle, drive: usize, k: &Kind, command: MotionCommand) -> Result<(), ApiError> {
    match k {
        Kind::Device(m, _) => (m.run)(h, drive, command),
        Kind::Cia402(_) => {
            let io = Handle { handle: h, drive };
            match command {
                MotionCommand::Enable => enable(&io).map(drop),
                MotionCommand::Disable => disable(&io).map(drop),
                MotionCommand::Jog {
                    direction,
                    velocity,
                } => jog(&io, i32::from(direction) * velocity as i32).map(drop),
                MotionCommand::Move {
                    target, relative, ..
                } => move_to(&io, target, relative).map(drop),
                MotionCommand::Home => home(&io).map(drop),
            }
            .map_err(|e| refusal(h, drive, e))
        }
    }
}

// ------------------------------------------------------------------------- REST: endpoints

/// The drive's status word (or FHPP SCON / SPOS) bit by bit, its active error and error
/// history with their texts, the display.
#[utoipa::path(get, path = "/api/drives/{drive}/motion", tag = "motion",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = MotionView), (status = 400, body = ApiError),
        (status = 404, body = ApiError), (status = 409, body = ApiError)))]
async fn status(
    State(s): State<AppState>,
    Path(drive): Path<String>,
) -> Result<Json<MotionView>, ApiError> {
    run(&s, drive, None).await
}

/// Enables the drive (CiA 402: to OPERATION ENABLED, a fault reset first; FHPP: CCON.ENABLE
/// and STOP, a RESET edge first).
#[utoipa::path(post, path = "/api/drives/{drive}/motion/enable", tag = "motion",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = MotionView), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError), (status = 409, body = ApiError)))]
async fn post_enable(
    State(s): State<AppState>,
    Path(drive): Path<String>,
) -> Result<Json<MotionView>, ApiError> {
    run(&s, drive, Some(MotionCommand::Enable)).await
}

/// Disables the drive (CiA 402: shutdown; FHPP: CCON.ENABLE = 0).
#[utoipa::path(post, path = "/api/drives/{drive}/motion/disable", tag = "motion",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = MotionView), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError), (status = 409, body = ApiError)))]
async fn post_disable(
    State(s): State<AppState>,
    Path(drive): Path<String>,
) -> Result<Json<MotionView>, ApiError> {
    run(&s, drive, Some(MotionCommand::Disable)).await
}

/// A jog command.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct JogBody {
    /// 1: forwards, -1: backwards, 0: stop.
    #[schema(minimum = -1, maximum = 1)]
    pub direction: i8,
    /// CiA 402: the speed, in the drive's velocity units (60FFh); default 300. The CMMO-ST
    /// jogs with its own jog parameters (PNU 530…).
    #[schema(minimum = 0, maximum = 100000)]
    pub velocity: Option<u32>,
}

/// Jogs the drive (CiA 402: profile velocity 60FFh; FHPP: CPOS.JOGP / JOGN).
#[utoipa::path(post, path = "/api/drives/{drive}/motion/jog", tag = "motion",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    request_body = JogBody,
    responses((status = 200, body = MotionView), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError), (status = 409, body = ApiError), (status = 415, body = ApiError)))]
async fn post_jog(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<JogBody>, JsonRejection>,
) -> Result<Json<MotionView>, ApiError> {
    let Json(body) = body?;
    let speed = body.velocity.unwrap_or(300);
    if !(-1..=1).contains(&body.direction) || speed > 100_000 {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            "direction -1, 0 or 1; velocity 0…100000",
        ));
    }
    let command = MotionCommand::Jog {
        direction: body.direction,
        velocity: speed,
    };
    run(&s, drive, Some(command)).await
}

/// A move to a position.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct MoveBody {
    /// The target (CiA 402: 607Ah in position units; CMMO-ST: set-point 2 in its SI unit).
    pub target: i32,
    /// Relative to the last target (default: absolute).
    #[serde(default)]
    pub relative: bool,
    /// CMMO-ST only: velocity, % of the maximum (1…100, default 100).
    #[schema(minimum = 1, maximum = 100)]
    pub velocity_percent: Option<u8>,
}

/// Moves the drive to a position (CiA 402: profile position with the new-set-point handshake;
/// FHPP: a direct-mode positioning task).
#[utoipa::path(post, path = "/api/drives/{drive}/motion/move", tag = "motion",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    request_body = MoveBody,
    responses((status = 200, body = MotionView), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError), (status = 409, body = ApiError), (status = 415, body = ApiError)))]
async fn post_move(
    State(s): State<AppState>,
    Path(drive): Path<String>,
    body: Result<Json<MoveBody>, JsonRejection>,
) -> Result<Json<MotionView>, ApiError> {
    let Json(body) = body?;
    let percent = body.velocity_percent.unwrap_or(100);
    if !(1..=100).contains(&percent) {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            "velocity_percent 1…100",
        ));
    }
    let command = MotionCommand::Move {
        target: body.target,
        relative: body.relative,
        velocity_percent: percent,
    };
    run(&s, drive, Some(command)).await
}

/// Starts homing (CiA 402: homing mode, bit 4; FHPP: CPOS.HOM).
#[utoipa::path(post, path = "/api/drives/{drive}/motion/home", tag = "motion",
    params(("drive" = u32, Path, description = "the drive's index in the cell")),
    responses((status = 200, body = MotionView), (status = 400, body = ApiError), (status = 401, body = ApiError),
        (status = 404, body = ApiError), (status = 409, body = ApiError)))]
async fn post_home(
    State(s): State<AppState>,
    Path(drive): Path<String>,
) -> Result<Json<MotionView>, ApiError> {
    run(&s, drive, Some(MotionCommand::Home)).await
}

#[derive(OpenApi)]
#[openapi(
    paths(status, post_enable, post_disable, post_jog, post_move, post_home),
    components(schemas(MotionView, BitView, ErrorView, JogBody, MoveBody))
)]
pub struct MotionDoc;

pub fn routes() -> Router<AppState> {
    Router::new()
        .route("/api/drives/{drive}/motion", get(status))
        .route("/api/drives/{drive}/motion/enable", post(post_enable))
        .route("/api/drives/{drive}/motion/disable", post(post_disable))
        .route("/api/drives/{drive}/motion/jog", post(post_jog))
        .route("/api/drives/{drive}/motion/move", post(post_move))
        .route("/api/drives/{drive}/motion/home", post(post_home))
}

// ----------------------------------------------------------------------------------- tests

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;
    use std::collections::BTreeMap;

    /// A CiA 402 drive reduced to what the sequences look at: its state machine follows the
    /// controlword, 6061h follows 6060h (unless `refuse_mode`), set-point acknowledge follows
    /// bit 4 in profile position.
    #[derive(Default)]
    struct FakeDrive {
        objects: RefCell<BTreeMap<(u16, u8), Vec<u8>>>,
        writes: RefCell<Vec<(u16, u8, Vec<u8>)>>,
        refuse_mode: Option<i8>,
    }

    impl FakeDrive {
        fn new(sw: u16) -> Self {
            let d = FakeDrive::default();
            d.set(0x6041, sw.to_le_bytes().to_vec());
            d.set(0x6061, vec![0]);
            d
        }
        fn set(&self, index: u16, v: Vec<u8>) {
            self.objects.borrow_mut().insert((index, 0), v);
        }
        fn sw(&self) -> u16 {
            u16_of(&self.objects.borrow()[&(0x6041, 0)])
        }
        fn controlwords(&self) -> Vec<u16> {
            self.writes
                .borrow()
                .iter()
                .filter(|(i, _, _)| *i == 0x6040)
                .map(|(_, _, d)| u16_of(d))
                .collect()
        }
    }

    impl Objects for FakeDrive {
        fn read(&self, index: u16, sub: u8) -> Result<Vec<u8>, ControlError> {
            self.objects
                .borrow()
                .get(&(index, sub))
                .cloned()
                .ok_or(ControlError::Abort(od::AbortCode::NO_OBJECT))
        }
        fn write(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), ControlError> {
            self.writes.borrow_mut().push((index, sub, data.to_vec()));
            if index == 0x6060 {
                let m = data.first().map_or(0, |b| *b as i8);
                if self.refuse_mode == Some(m) {
                    return Err(ControlError::Abort(od::AbortCode(0x0609_0030)));
                }
                self.set(0x6061, data.to_vec());
            }
            if index == 0x6040 {
                let c = u16_of(data);
                let sw = self.sw();
                let mode = self.objects.borrow()[&(0x6061, 0)][0] as i8;
                let next = if sw & 0x08 != 0 {
                    if c & 0x80 != 0 {
                        0x0240
                    } else {
                        sw
                    }
                } else {
                    match c & 0x0F {
                        0x06 => 0x0221,
                        0x07 => 0x0223,
                        0x0F => 0x0227,
                        _ => 0x0240,
                    }
                };
                let ack = mode == mode::PROFILE_POSITION && c & 0x10 != 0 && next & 0x6F == 0x27;
                self.set(
                    0x6041,
                    (next | if ack { 0x1000 } else { 0 }).to_le_bytes().to_vec(),
                );
            }
            self.set(index, data.to_vec());
            Ok(())
        }
        fn wait(&self, _d: Duration) {}
    }

    #[test]
    fn enable_walks_shutdown_switch_on_enable_operation() {
        let d = FakeDrive::new(0x0240);
        assert_eq!(enable(&d).map(|sw| sw & 0x6F), Ok(0x27));
        assert_eq!(d.controlwords(), vec![0x06, 0x07, 0x0F]);
    }

    #[test]
    fn enable_from_fault_resets_on_a_rising_bit_7_first() {
        let d = FakeDrive::new(0x0218);
        assert!(enable(&d).is_ok());
        assert_eq!(d.controlwords(), vec![0x00, 0x80, 0x06, 0x07, 0x0F]);
    }

    #[test]
    fn jog_sets_profile_velocity_and_60ff() {
        let d = FakeDrive::new(0x0240);
        assert_eq!(
            jog(&d, 300),
            Err(MotionError::NotEnabled("SWITCH ON DISABLED".into())),
            "a drive not enabled is refused, nothing written"
        );
        assert!(d.writes.borrow().is_empty());
        assert_eq!(
            jog(&d, 0),
            Ok(0x0240),
            "a stop asks nothing of a drive that stands"
        );
        assert!(d.writes.borrow().is_empty());
        enable(&d).unwrap_or_default();
        assert!(jog(&d, -300).is_ok());
        assert_eq!(d.read(0x6061, 0), Ok(vec![3]));
        assert_eq!(d.read(0x60FF, 0), Ok((-300i32).to_le_bytes().to_vec()));
    }

    #[test]
    fn a_drive_without_profile_velocity_jogs_in_velocity_mode() {
        // Nanotec PD4-N 6502h = 6Bh: PP, VL, TQ, HM, IP, no PV.
        let d = FakeDrive::new(0x0227);
        d.set(0x6502, 0x6Bu32.to_le_bytes().to_vec());
        assert!(jog(&d, -120).is_ok());
        assert_eq!(d.read(0x6061, 0), Ok(vec![2]));
        assert_eq!(d.read(0x6042, 0), Ok((-120i16).to_le_bytes().to_vec()));
        assert!(d.read(0x60FF, 0).is_err(), "60FFh untouched");
    }

    #[test]
    fn move_does_the_new_set_point_handshake() {
        let d = FakeDrive::new(0x0227);
        let sw = move_to(&d, 10_000, true);
        assert!(
            sw.is_ok_and(|sw| sw & 0x1000 != 0),
            "set-point acknowledged"
        );
        assert_eq!(d.read(0x607A, 0), Ok(10_000i32.to_le_bytes().to_vec()));
        // Relative bit 6 throughout; bit 4 (with 5) rises once and falls again.
        assert_eq!(d.controlwords(), vec![0x4F, 0x7F, 0x4F]);
    }

    #[test]
    fn a_mode_the_drive_refuses_is_an_sdo_abort() {
        let d = FakeDrive {
            refuse_mode: Some(mode::HOMING),
            ..FakeDrive::new(0x0227)
        };
        assert_eq!(
            home(&d),
            Err(MotionError::ModeRefused {
                wanted: mode::HOMING,
                error: ControlError::Abort(od::AbortCode(0x0609_0030))
            })
        );
        assert_eq!(
            request_of(&MotionError::ModeRefused {
                wanted: mode::HOMING,
                error: ControlError::Abort(od::AbortCode(0x0609_0030))
            }),
            Some(Request::Mode(mode::HOMING)),
            "the drive is asked why it refused that mode"
        );
    }

    #[test]
    fn home_sets_mode_6_and_raises_bit_4() {
        let d = FakeDrive::new(0x0227);
        assert!(home(&d).is_ok());
        assert_eq!(d.read(0x6061, 0), Ok(vec![6]));
        assert_eq!(d.controlwords(), vec![0x0F, 0x1F]);
    }
}
