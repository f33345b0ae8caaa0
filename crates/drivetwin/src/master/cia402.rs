//! CiA 402 master commands over SDO: read the state and actual values, walk the state
//! machine to OPERATION ENABLED, and start moves in profile position, velocity and torque.

use std::time::Duration;

use drive::controlword::Controlword;
use drive::device_control::State;
use drive::statusword::Statusword;
use od::AbortCode;

use super::sdo_client::{SdoClient, SdoError};

/// The state the statusword shows, by its CiA 402 name ("UNKNOWN" for bits no state has).
pub fn state_name(sw: u16) -> &'static str {
    Statusword(sw).state().map_or("UNKNOWN", State::name)
}

#[derive(Debug, thiserror::Error)]
pub enum Cia402Error {
    #[error(transparent)]
    Sdo(#[from] SdoError),
    #[error("the drive did not reach {want} within {timeout:?} (statusword {sw:04X}h, {state})")]
    Timeout {
        want: &'static str,
        timeout: Duration,
        sw: u16,
        state: &'static str,
    },
    #[error("the drive has no {what} ({index:04X}h:{sub:02X}h does not exist)")]
    Missing {
        what: &'static str,
        index: u16,
        sub: u8,
    },
    #[error("the drive does not support {0} (6502h = {1:08X}h)")]
    NoMode(&'static str, u32),
    #[error("the drive refused mode {mode} (6060h): {code}{hint}")]
    ModeRefused {
        mode: i8,
        code: AbortCode,
        hint: &'static str,
    },
    #[error("{value} is out of the range of {index:04X}h ({min} … {max})")]
    OutOfRange {
        index: u16,
        value: i64,
        min: i64,
        max: i64,
    },
}

/// State and actual values, as `drivetwin drive state` prints them. An actual value the
/// drive does not have (a Nanotec has neither 606Ch nor 6077h / 6078h) is `None`.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Snapshot {
    pub statusword: u16,
    pub state: &'static str,
    pub mode: i8,
    pub position: i32,
    pub velocity: Option<i32>,
    /// The object `velocity` was read from: 606Ch, or 6044h (VL velocity actual value, in
    /// the units of 604Ch) in velocity mode VL on a drive without 606Ch.
    pub velocity_object: Option<&'static str>,
    pub current_permille: Option<i16>,
    pub torque_permille: Option<i16>,
    pub target_reached: bool,
    pub following_error: bool,
}

fn int_of(d: &[u8]) -> i64 {
    match d {
        [a] => i64::from(*a as i8),
        [a, b] => i64::from(i16::from_le_bytes([*a, *b])),
        [a, b, cc, dd] => i64::from(i32::from_le_bytes([*a, *b, *cc, *dd])),
        _ => 0,
    }
}

async fn read_int(c: &mut SdoClient<'_>, index: u16, sub: u8) -> Result<i64, SdoError> {
    Ok(int_of(&c.upload(index, sub).await?))
}

/// Whether an abort says the object (or its sub-index) is not in the dictionary.
fn is_missing(e: &SdoError) -> bool {
    matches!(e, SdoError::Abort(code) if *code == AbortCode::NO_OBJECT || *code == AbortCode::NO_SUB_INDEX)
}

/// An object a drive may not have: `None` where the drive answers 0602 0000h or 0609 0011h.
pub async fn read_optional(
    c: &mut SdoClient<'_>,
    index: u16,
    sub: u8,
) -> Result<Option<i64>, SdoError> {
    match c.upload(index, sub).await {
        Ok(d) => Ok(Some(int_of(&d))),
        Err(e) if is_missing(&e) => Ok(None),
        Err(e) => Err(e),
    }
}

/// A download to an object the drive may not have: [`Cia402Error::Missing`] names it.
async fn write_object(
    c: &mut SdoClient<'_>,
    index: u16,
    sub: u8,
    data: &[u8],
    what: &'static str,
) -> Result<(), Cia402Error> {
    match c.download(index, sub, data).await {
        Err(e) if is_missing(&e) => Err(Cia402Error::Missing { what, index, sub }),
        r => Ok(r?),
    }
}

pub async fn statusword(c: &mut SdoClient<'_>) -> Result<u16, SdoError> {
    Ok(read_int(c, 0x6041, 0).await? as u16)
}

/// How long a drive may take to show a new velocity or torque target in its statusword
/// (a few of its cycles; the twins' cycle is 1 ms).
pub const SET_POINT_SETTLE: Duration = Duration::from_millis(30);

/// VL velocity mode (CiA 402 §10; Nanotec ch. 6).
const MODE_VL: i8 = 2;

pub async fn snapshot(c: &mut SdoClient<'_>) -> Result<Snapshot, SdoError> {
    let sw = statusword(c).await?;
    let mode = read_int(c, 0x6061, 0).await? as i8;
    let (velocity, velocity_object) = match read_optional(c, 0x606C, 0).await? {
        Some(v) => (Some(v as i32), Some("606Ch")),
        // Decision: a drive without 606Ch (Nanotec §3.4) has 6044h, the VL velocity actual
        // value; it is reported in VL only, as the manual names it for that mode.
        None if mode == MODE_VL => match read_optional(c, 0x6044, 0).await? {
            Some(v) => (Some(v as i32), Some("6044h")),
            None => (None, None),
        },
        None => (None, None),
    };
    Ok(Snapshot {
        statusword: sw,
        state: state_name(sw),
        mode,
        position: read_int(c, 0x6064, 0).await? as i32,
        velocity,
        velocity_object,
        current_permille: read_optional(c, 0x6078, 0).await?.map(|v| v as i16),
        torque_permille: read_optional(c, 0x6077, 0).await?.map(|v| v as i16),
        target_reached: Statusword(sw).contains(Statusword::TARGET_REACHED),
        following_error: Statusword(sw).contains(Statusword::FOLLOWING_ERROR),
    })
}

pub async fn controlword(c: &mut SdoClient<'_>, cw: Controlword) -> Result<(), SdoError> {
    c.download(0x6040, 0, &cw.bits().to_le_bytes()).await
}

/// Polls the statusword until `done` holds.
pub async fn wait_for(
    c: &mut SdoClient<'_>,
    want: &'static str,
    timeout: Duration,
    done: impl Fn(Statusword) -> bool,
) -> Result<u16, Cia402Error> {
    let deadline = tokio::time::Instant::now() + timeout;
    loop {
        let sw = statusword(c).await?;
        if done(Statusword(sw)) {
            return Ok(sw);
        }
        if tokio::time::Instant::now() > deadline {
            return Err(Cia402Error::Timeout {
                want,
                timeout,
                sw,
                state: state_name(sw),
            });
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// Whether the statusword shows `state`.
fn shows(state: State) -> impl Fn(Statusword) -> bool {
    move |sw| sw.state() == Some(state)
}

/// Fault reset if needed, then shutdown → switch on → enable operation, each confirmed.
pub async fn enable(c: &mut SdoClient<'_>, timeout: Duration) -> Result<(), Cia402Error> {
    let sw = Statusword(statusword(c).await?);
    if matches!(sw.state(), Some(State::Fault | State::FaultReactionActive)) {
        controlword(c, Controlword::EMPTY).await?;
        controlword(c, Controlword::FAULT_RESET).await?;
        wait_for(
            c,
            "SWITCH ON DISABLED",
            timeout,
            shows(State::SwitchOnDisabled),
        )
        .await?;
    }
    if Statusword(statusword(c).await?).state() == Some(State::OperationEnabled) {
        return Ok(());
    }
    controlword(c, Controlword::SHUTDOWN).await?;
    wait_for(
        c,
        "READY TO SWITCH ON",
        timeout,
        shows(State::ReadyToSwitchOn),
    )
    .await?;
    controlword(c, Controlword::SWITCH_ON_CMD).await?;
    wait_for(c, "SWITCHED ON", timeout, shows(State::SwitchedOn)).await?;
    controlword(c, Controlword::ENABLE_OPERATION_CMD).await?;
    wait_for(
        c,
        "OPERATION ENABLED",
        timeout,
        shows(State::OperationEnabled),
    )
    .await?;
    Ok(())
}

/// Shutdown (transition 8/6): READY TO SWITCH ON, output stage off.
pub async fn disable(c: &mut SdoClient<'_>, timeout: Duration) -> Result<(), Cia402Error> {
    controlword(c, Controlword::SHUTDOWN).await?;
    wait_for(
        c,
        "READY TO SWITCH ON",
        timeout,
        shows(State::ReadyToSwitchOn),
    )
    .await?;
    Ok(())
}

/// Hints for a mode a drive refused, by vendor-ID (1018h:01), mode and abort code.
const MODE_HINTS: [(u32, i8, AbortCode, &str); 1] = [(
    0x0000_026C,
    4,
    AbortCode::DEVICE_STATE,
    "; a Nanotec takes torque mode only with its closed loop on (200Ah = 1, set by 2001h; \
     Nanotec §5.5)",
)];

/// Writes 6060h and waits until 6061h shows the mode.
pub async fn set_mode(
    c: &mut SdoClient<'_>,
    mode: i8,
    timeout: Duration,
) -> Result<(), Cia402Error> {
    if let Err(e) = c.download(0x6060, 0, &[mode as u8]).await {
        let SdoError::Abort(code) = e else {
            return Err(e.into());
        };
        let vendor = read_optional(c, 0x1018, 1).await.ok().flatten();
        let hint = MODE_HINTS
            .iter()
            .find(|(v, m, a, _)| Some(i64::from(*v)) == vendor && *m == mode && *a == code)
            .map_or("", |h| h.3);
        return Err(Cia402Error::ModeRefused { mode, code, hint });
    }
    let deadline = tokio::time::Instant::now() + timeout;
    loop {
        if read_int(c, 0x6061, 0).await? as i8 == mode {
            return Ok(());
        }
        if tokio::time::Instant::now() > deadline {
            let sw = statusword(c).await?;
            return Err(Cia402Error::Timeout {
                want: "the new mode in 6061h",
                timeout,
                sw,
                state: state_name(sw),
            });
        }
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
}

/// 6502h, the supported drive modes; `None` on a drive without it.
async fn supported_modes(c: &mut SdoClient<'_>) -> Result<Option<u32>, SdoError> {
    Ok(read_optional(c, 0x6502, 0).await?.map(|v| v as u32))
}

/// A profile-position move with the set-point handshake (CiA 402 §12.2; CMMP-AS Fig. 7.4).
pub async fn move_to(
    c: &mut SdoClient<'_>,
    target: i32,
    relative: bool,
    profile: (Option<u32>, Option<u32>, Option<u32>),
    timeout: Duration,
) -> Result<(), Cia402Error> {
    set_mode(c, 1, timeout).await?;
    if let Some(v) = profile.0 {
        write_object(c, 0x6081, 0, &v.to_le_bytes(), "profile velocity").await?;
    }
    if let Some(a) = profile.1 {
        write_object(c, 0x6083, 0, &a.to_le_bytes(), "profile acceleration").await?;
    }
    if let Some(d) = profile.2 {
        write_object(c, 0x6084, 0, &d.to_le_bytes(), "profile deceleration").await?;
    }
    c.download(0x607A, 0, &target.to_le_bytes()).await?;
    let base = Controlword::ENABLE_OPERATION_CMD.with(Controlword::RELATIVE, relative);
    controlword(c, base).await?;
    controlword(c, base | Controlword::NEW_SET_POINT).await?;
    wait_for(c, "set-point acknowledge", timeout, |sw| {
        sw.contains(Statusword::SET_POINT_ACKNOWLEDGE)
    })
    .await?;
    controlword(c, base).await?;
    Ok(())
}

/// The mode a velocity command ran in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VelocityMode {
    /// Profile velocity PV (6060h = 3), the target in 60FFh.
    ProfileVelocity,
    /// Velocity mode VL (6060h = 2), the target in 6042h (s16, units of 604Ch).
    Vl,
}

/// 6502h bits (CiA 402 §6.3.6).
const SUPPORTS_VL: u32 = 1 << 1;
const SUPPORTS_PV: u32 = 1 << 2;
const SUPPORTS_TQ: u32 = 1 << 3;

/// Runs at `velocity`: in PV where 6502h lists it (or where the drive has no 6502h), else in
/// VL (a Nanotec: §3.4 lists no PV, and no 60FFh), where the value must fit 6042h's s16.
pub async fn run_at(
    c: &mut SdoClient<'_>,
    velocity: i32,
    timeout: Duration,
) -> Result<VelocityMode, Cia402Error> {
    let modes = supported_modes(c).await?;
    let mode = match modes {
        None => VelocityMode::ProfileVelocity,
        Some(m) if m & SUPPORTS_PV != 0 => VelocityMode::ProfileVelocity,
        Some(m) if m & SUPPORTS_VL != 0 => VelocityMode::Vl,
        Some(m) => {
            return Err(Cia402Error::NoMode(
                "profile velocity (bit 2) or velocity mode VL (bit 1)",
                m,
            ))
        }
    };
    match mode {
        VelocityMode::ProfileVelocity => {
            set_mode(c, 3, timeout).await?;
            write_object(c, 0x60FF, 0, &velocity.to_le_bytes(), "target velocity").await?;
        }
        VelocityMode::Vl => {
            let v = i16::try_from(velocity).map_err(|_| Cia402Error::OutOfRange {
                index: 0x6042,
                value: i64::from(velocity),
                min: i64::from(i16::MIN),
                max: i64::from(i16::MAX),
            })?;
            set_mode(c, MODE_VL, timeout).await?;
            write_object(c, 0x6042, 0, &v.to_le_bytes(), "VL target velocity").await?;
        }
    }
    Ok(mode)
}

/// Profile torque (6060h = 4) at `torque` ‰, with the slope 6087h if given (a drive
/// without 6087h, like a Nanotec, refuses a slope with [`Cia402Error::Missing`] before
/// anything changes).
pub async fn run_torque(
    c: &mut SdoClient<'_>,
    torque: i16,
    slope: Option<u32>,
    timeout: Duration,
) -> Result<(), Cia402Error> {
    if let Some(m) = supported_modes(c).await? {
        if m & SUPPORTS_TQ == 0 {
            return Err(Cia402Error::NoMode("profile torque (bit 3)", m));
        }
    }
    if let Some(s) = slope {
        write_object(c, 0x6087, 0, &s.to_le_bytes(), "torque slope").await?;
    }
    set_mode(c, 4, timeout).await?;
    c.download(0x6071, 0, &torque.to_le_bytes()).await?;
    Ok(())
}
