//! CiA 402 master commands over SDO: read the state and actual values, walk the state
//! machine to OPERATION ENABLED, and start moves in profile position, velocity and torque.

use std::time::Duration;

use super::sdo_client::{SdoClient, SdoError};

/// CiA 402 state names from the statusword (masks of CiA 402 Tab. 30, CMMP-AS Tab. 6.6).
pub fn state_name(sw: u16) -> &'static str {
    match (sw & 0x4F, sw & 0x6F) {
        (0x00, _) => "NOT READY TO SWITCH ON",
        (0x40, _) => "SWITCH ON DISABLED",
        (_, 0x21) => "READY TO SWITCH ON",
        (_, 0x23) => "SWITCHED ON",
        (_, 0x27) => "OPERATION ENABLED",
        (_, 0x07) => "QUICK STOP ACTIVE",
        (0x0F, _) => "FAULT REACTION ACTIVE",
        (0x08, _) => "FAULT",
        _ => "UNKNOWN",
    }
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
}

/// State and actual values, as `drivetwin drive state` prints them.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Snapshot {
    pub statusword: u16,
    pub state: &'static str,
    pub mode: i8,
    pub position: i32,
    pub velocity: i32,
    pub current_permille: i16,
    pub torque_permille: i16,
    pub target_reached: bool,
    pub following_error: bool,
}

async fn read_int(c: &mut SdoClient<'_>, index: u16, sub: u8) -> Result<i64, SdoError> {
    let d = c.upload(index, sub).await?;
    Ok(match d.as_slice() {
        [a] => i64::from(*a as i8),
        [a, b] => i64::from(i16::from_le_bytes([*a, *b])),
        [a, b, cc, dd] => i64::from(i32::from_le_bytes([*a, *b, *cc, *dd])),
        _ => 0,
    })
}

pub async fn statusword(c: &mut SdoClient<'_>) -> Result<u16, SdoError> {
    Ok(read_int(c, 0x6041, 0).await? as u16)
}

pub async fn snapshot(c: &mut SdoClient<'_>) -> Result<Snapshot, SdoError> {
    let sw = statusword(c).await?;
    Ok(Snapshot {
        statusword: sw,
        state: state_name(sw),
        mode: read_int(c, 0x6061, 0).await? as i8,
        position: read_int(c, 0x6064, 0).await? as i32,
        velocity: read_int(c, 0x606C, 0).await? as i32,
        current_permille: read_int(c, 0x6078, 0).await? as i16,
        torque_permille: read_int(c, 0x6077, 0).await? as i16,
        target_reached: sw & 0x0400 != 0,
        following_error: sw & 0x2000 != 0,
    })
}

pub async fn controlword(c: &mut SdoClient<'_>, cw: u16) -> Result<(), SdoError> {
    c.download(0x6040, 0, &cw.to_le_bytes()).await
}

/// Polls the statusword until `done` holds.
pub async fn wait_for(
    c: &mut SdoClient<'_>,
    want: &'static str,
    timeout: Duration,
    done: impl Fn(u16) -> bool,
) -> Result<u16, Cia402Error> {
    let deadline = tokio::time::Instant::now() + timeout;
    loop {
        let sw = statusword(c).await?;
        if done(sw) {
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

/// Fault reset if needed, then shutdown → switch on → enable operation, each confirmed.
pub async fn enable(c: &mut SdoClient<'_>, timeout: Duration) -> Result<(), Cia402Error> {
    let sw = statusword(c).await?;
    if matches!(state_name(sw), "FAULT" | "FAULT REACTION ACTIVE") {
        controlword(c, 0x0000).await?;
        controlword(c, 0x0080).await?;
        wait_for(c, "SWITCH ON DISABLED", timeout, |sw| sw & 0x4F == 0x40).await?;
    }
    if state_name(statusword(c).await?) == "OPERATION ENABLED" {
        return Ok(());
    }
    controlword(c, 0x0006).await?;
    wait_for(c, "READY TO SWITCH ON", timeout, |sw| sw & 0x6F == 0x21).await?;
    controlword(c, 0x0007).await?;
    wait_for(c, "SWITCHED ON", timeout, |sw| sw & 0x6F == 0x23).await?;
    controlword(c, 0x000F).await?;
    wait_for(c, "OPERATION ENABLED", timeout, |sw| sw & 0x6F == 0x27).await?;
    Ok(())
}

/// Shutdown (transition 8/6): READY TO SWITCH ON, output stage off.
pub async fn disable(c: &mut SdoClient<'_>, timeout: Duration) -> Result<(), Cia402Error> {
    controlword(c, 0x0006).await?;
    wait_for(c, "READY TO SWITCH ON", timeout, |sw| sw & 0x6F == 0x21).await?;
    Ok(())
}

/// Writes 6060h and waits until 6061h shows the mode.
pub async fn set_mode(
    c: &mut SdoClient<'_>,
    mode: i8,
    timeout: Duration,
) -> Result<(), Cia402Error> {
    c.download(0x6060, 0, &[mode as u8]).await?;
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
        c.download(0x6081, 0, &v.to_le_bytes()).await?;
    }
    if let Some(a) = profile.1 {
        c.download(0x6083, 0, &a.to_le_bytes()).await?;
    }
    if let Some(d) = profile.2 {
        c.download(0x6084, 0, &d.to_le_bytes()).await?;
    }
    c.download(0x607A, 0, &target.to_le_bytes()).await?;
    let base = if relative { 0x004F } else { 0x000F };
    controlword(c, base).await?;
    controlword(c, base | 0x0010).await?;
    wait_for(c, "set-point acknowledge", timeout, |sw| sw & 0x1000 != 0).await?;
    controlword(c, base).await?;
    Ok(())
}
