//! The FHPP half of the console's motion page: enable, disable, jog, move to a position and
//! home a CMMO-ST the way its manual tells a master to, through the FHPP output telegram
//! ([`super::fhpp_console`]), and the page's view of SCON, SPOS and the diagnostic memory.
//! The motion page reaches it through [`MOTION`] (`web::DevicePages::motion`).
//!
//! The sequences are plain functions over [`FhppIo`], so a test runs them against a fake
//! device that records the telegrams written.

use std::time::Duration;

use axum::http::StatusCode;
use drive::vendors::festo_cmmo_st::fhpp::{
    Authority, Ccon, Cdir, Cpos, OperatingMode, OutputData, Scon, Spos,
};

use super::fhpp_console::{fhpp, FhppRequest, FhppState};
use crate::cell::control::{ControlError, ControlHandle, DriveInfo, Interface};
use crate::web::api::{ApiError, ReasonView};
use crate::web::error_text;
use crate::web::motion::{
    self, BitView, DeviceMotion, ErrorView, Handle, MotionCommand, MotionView, STEP_WAIT, TRIES,
};

/// The CMMO-ST's motion on the console's motion page.
pub const MOTION: DeviceMotion = DeviceMotion { moves, view, run };

/// What an FHPP sequence needs of a CMMO-ST.
pub trait FhppIo {
    fn fhpp(&self, request: FhppRequest) -> Result<FhppState, ControlError>;
    fn wait(&self, d: Duration);
}

impl FhppIo for Handle<'_> {
    fn fhpp(&self, request: FhppRequest) -> Result<FhppState, ControlError> {
        fhpp(self.handle, self.drive, request)
    }
    fn wait(&self, d: Duration) {
        std::thread::sleep(d);
    }
}

/// Why an FHPP sequence stopped.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FhppMotionError {
    #[error(transparent)]
    Control(#[from] ControlError),
    #[error("the drive did not reach {wanted}: it shows {shown}")]
    NotReached { wanted: String, shown: String },
    #[error("the web server holds Device Control: the drive ignores the FHPP control bytes (PNU 125); give Device Control back first")]
    WebServerHasControl,
    #[error("FCT holds device control (SCON.FCT/MMI)")]
    FctHasControl,
    #[error("the CMMO-ST is not enabled (SCON {scon}); enable it first")]
    FhppNotEnabled { scon: String },
    #[error("the CMMO-ST did not acknowledge the start (SPOS.ACK) within {0} ms")]
    FhppNoAck(u64),
}

/// The CMMO-ST takes the console's telegram only while the fieldbus holds device control
/// (§5.1 Tab. 5.2 T2: "the PLC has control authority").
///
/// Decision: the console acts as the fieldbus master (it writes the output telegram a Modbus
/// master would write, CMMO-ST §5.3.2); a Modbus master connected at the same time
/// overwrites it at its next write, as a second master on the real device would.
fn fhpp_status(io: &impl FhppIo) -> Result<FhppState, FhppMotionError> {
    let s = io.fhpp(FhppRequest::Status)?;
    match s.authority {
        Authority::Fieldbus => Ok(s),
        Authority::WebServer => Err(FhppMotionError::WebServerHasControl),
        Authority::Fct => Err(FhppMotionError::FctHasControl),
    }
}

fn scon(s: &FhppState) -> Scon {
    Scon(s.inputs[0])
}

fn spos(s: &FhppState) -> Spos {
    Spos(s.inputs[1])
}

fn bits_text(value: u8, names: &[(u8, &str)]) -> String {
    let set: Vec<&str> = names
        .iter()
        .filter(|(bit, _)| value & bit != 0)
        .map(|(_, n)| *n)
        .collect();
    format!("{value:#04X} [{}]", set.join(" "))
}

fn scon_text(s: &FhppState) -> String {
    let names: Vec<(u8, &str)> = Scon::NAMES.iter().map(|(b, n)| (b.0, *n)).collect();
    bits_text(s.inputs[0], &names)
}

fn put(io: &impl FhppIo, out: OutputData) -> Result<FhppState, FhppMotionError> {
    let s = io.fhpp(FhppRequest::SetOutputs(out.to_bytes()))?;
    // Two drive cycles: the telegram is taken at the next one.
    io.wait(STEP_WAIT);
    Ok(s)
}

fn await_fhpp(
    io: &impl FhppIo,
    done: impl Fn(&FhppState) -> bool,
) -> Result<Result<FhppState, FhppState>, FhppMotionError> {
    let mut s = io.fhpp(FhppRequest::Status)?;
    for _ in 0..TRIES {
        if done(&s) {
            return Ok(Ok(s));
        }
        io.wait(STEP_WAIT);
        s = io.fhpp(FhppRequest::Status)?;
    }
    Ok(if done(&s) { Ok(s) } else { Err(s) })
}

/// CCON.ENABLE and STOP with CPOS.HALT (T2, T3, §5.1 Tab. 5.2); a pending fault is
/// acknowledged first by a rising edge of CCON.RESET (T8).
pub fn fhpp_enable(io: &impl FhppIo) -> Result<FhppState, FhppMotionError> {
    let s = fhpp_status(io)?;
    let mut out = OutputData::from_bytes(s.outputs);
    if scon(&s).contains(Scon::FAULT) {
        out.ccon = Ccon(out.ccon.0 & !Ccon::RESET.0);
        put(io, out)?;
        out.ccon = out.ccon.union(Ccon::RESET);
        put(io, out)?;
    }
    out.ccon = Ccon(out.ccon.0 & !Ccon::RESET.0).union(Ccon::ENABLE.union(Ccon::STOP));
    out.cpos = Cpos::HALT;
    put(io, out)?;
    await_fhpp(io, |s| {
        scon(s).contains(Scon::ENABLED) && spos(s).contains(Spos::HALT)
    })?
    .map_err(|s| FhppMotionError::NotReached {
        wanted: "operation enabled (SCON.ENABLED, SPOS.HALT)".into(),
        shown: format!("SCON {}", scon_text(&s)),
    })
}

/// CCON.ENABLE = 0: the drive is disabled, a running task stops (Tab. 5.14).
pub fn fhpp_disable(io: &impl FhppIo) -> Result<FhppState, FhppMotionError> {
    let s = fhpp_status(io)?;
    let mut out = OutputData::from_bytes(s.outputs);
    out.ccon = Ccon(out.ccon.0 & !(Ccon::ENABLE.0 | Ccon::RESET.0));
    out.cpos = Cpos::HALT;
    put(io, out)?;
    Ok(io.fhpp(FhppRequest::Status)?)
}

fn fhpp_require_enabled(io: &impl FhppIo) -> Result<FhppState, FhppMotionError> {
    let s = fhpp_status(io)?;
    if scon(&s).contains(Scon::ENABLED) {
        Ok(s)
    } else {
        Err(FhppMotionError::FhppNotEnabled {
            scon: scon_text(&s),
        })
    }
}

/// Jog while CPOS.JOGP (positive) or JOGN (negative) is set; `direction` 0 clears both
/// (CMMO-ST §6.6 "Jog mode", Tab. 5.15).
pub fn fhpp_jog(io: &impl FhppIo, direction: i8) -> Result<FhppState, FhppMotionError> {
    if direction == 0 {
        let s = fhpp_status(io)?;
        if !scon(&s).contains(Scon::ENABLED) {
            return Ok(s);
        }
    }
    let s = fhpp_require_enabled(io)?;
    let mut out = OutputData::from_bytes(s.outputs);
    let jog = match direction.signum() {
        1 => Cpos::JOGP.0,
        -1 => Cpos::JOGN.0,
        _ => 0,
    };
    out.cpos = Cpos(Cpos::HALT.0 | jog);
    put(io, out)?;
    Ok(io.fhpp(FhppRequest::Status)?)
}

/// Homing: a rising edge of CPOS.HOM with HALT = 1 (SA1 → SA4, §5.1.2).
pub fn fhpp_home(io: &impl FhppIo) -> Result<FhppState, FhppMotionError> {
    let s = fhpp_require_enabled(io)?;
    let mut out = OutputData::from_bytes(s.outputs);
    out.cpos = Cpos::HALT;
    put(io, out)?;
    out.cpos = Cpos(Cpos::HALT.0 | Cpos::HOM.0);
    put(io, out)?;
    Ok(io.fhpp(FhppRequest::Status)?)
}

/// A positioning task in direct mode (§5.4.1 Tab. 5.16–5.18): OPM = direct (changes only in
/// SA1 "ready"), CDIR.ABS (1 = relative), COM = position; set-point 1 the velocity in % of
/// the maximum, set-point 2 the position; START rises, the drive acknowledges with SPOS.ACK,
/// START falls (§5.4.2 Fig. 5.5).
pub fn fhpp_move(
    io: &impl FhppIo,
    target: i32,
    relative: bool,
    velocity_percent: u8,
) -> Result<FhppState, FhppMotionError> {
    let s = fhpp_require_enabled(io)?;
    let ccon = Ccon(s.outputs[0] & !Ccon::RESET.0).with_operating_mode(OperatingMode::Direct);
    let cdir = if relative { Cdir::ABS } else { Cdir(0) };
    let set = |cpos: Cpos| OutputData::direct(ccon, cpos, cdir, velocity_percent, target);
    put(io, set(Cpos::HALT))?;
    await_fhpp(io, |s| Scon(s.inputs[0]).intersects(Scon::OPM1))?.map_err(|s| {
        FhppMotionError::NotReached {
            wanted: "direct mode (SCON.OPM1)".into(),
            shown: format!("SCON {}", scon_text(&s)),
        }
    })?;
    put(io, set(Cpos(Cpos::HALT.0 | Cpos::START.0)))?;
    let acked = await_fhpp(io, |s| spos(s).contains(Spos::ACK))?;
    put(io, set(Cpos::HALT))?;
    acked.map_err(|_| FhppMotionError::FhppNoAck(STEP_WAIT.as_millis() as u64 * u64::from(TRIES)))
}

// ------------------------------------------------------------------------- the motion page

/// The drives the CMMO-ST's motion serves: those on Modbus TCP.
fn moves(drive: &DriveInfo) -> bool {
    drive.interface == Interface::ModbusTcp
}

fn view(
    h: &ControlHandle,
    drive: usize,
    table: &'static [od::Diagnostic],
) -> Result<MotionView, ApiError> {
    Ok(fhpp_view(
        h,
        drive,
        table,
        &fhpp(h, drive, FhppRequest::Status)?,
    ))
}

fn run(h: &ControlHandle, drive: usize, command: MotionCommand) -> Result<(), ApiError> {
    let io = Handle { handle: h, drive };
    match command {
        MotionCommand::Enable => fhpp_enable(&io).map(drop),
        MotionCommand::Disable => fhpp_disable(&io).map(drop),
        MotionCommand::Jog { direction, .. } => fhpp_jog(&io, direction).map(drop),
        MotionCommand::Move {
            target,
            relative,
            velocity_percent,
        } => fhpp_move(&io, target, relative, velocity_percent).map(drop),
        MotionCommand::Home => fhpp_home(&io).map(drop),
    }
    .map_err(ApiError::from)
}

impl From<FhppMotionError> for ApiError {
    fn from(e: FhppMotionError) -> ApiError {
        match e {
            FhppMotionError::Control(c) => ApiError::from(c),
            FhppMotionError::WebServerHasControl => device_control(e.to_string(), "the web server"),
            FhppMotionError::FctHasControl => device_control(e.to_string(), "FCT"),
            other => ApiError::new(StatusCode::CONFLICT, other.to_string()),
        }
    }
}

/// CMMO-ST §5.1 Tab. 5.2 T2: the control bytes act only while the fieldbus (the PLC) has
/// control authority.
fn device_control(text: String, holder: &str) -> ApiError {
    ApiError::new(StatusCode::CONFLICT, "").with_reason(ReasonView {
        kind: "device_control".into(),
        text,
        rule: format!(
            "CMMO-ST §5.1 Tab. 5.2 T2: the drive follows the FHPP control bytes only while the \
             PLC has control authority; {holder} holds it (PNU 125)"
        ),
    })
}

/// The FHPP state a person reads from SCON (§5.1 Tab. 5.1).
fn fhpp_state(s: &FhppState) -> String {
    let scon = scon(s);
    let mode = match scon.0 >> 6 {
        0 => "record selection",
        1 => "direct mode",
        _ => "reserved mode",
    };
    if scon.contains(Scon::FAULT) {
        format!("FAULT ({mode})")
    } else if scon.contains(Scon::ENABLED) {
        format!("OPERATION ENABLED ({mode})")
    } else {
        format!("DISABLED ({mode})")
    }
}

fn authority_name(a: Authority) -> &'static str {
    match a {
        Authority::Fieldbus => "fieldbus",
        Authority::WebServer => "web server",
        Authority::Fct => "FCT",
    }
}

fn fhpp_view(
    h: &ControlHandle,
    drive: usize,
    table: &[od::Diagnostic],
    s: &FhppState,
) -> MotionView {
    let mut bits = Vec::with_capacity(16);
    for (word, byte, names) in [
        (
            "SCON",
            s.inputs[0],
            Scon::NAMES
                .iter()
                .map(|(b, n)| (b.0, *n))
                .collect::<Vec<_>>(),
        ),
        (
            "SPOS",
            s.inputs[1],
            Spos::NAMES.iter().map(|(b, n)| (b.0, *n)).collect(),
        ),
    ] {
        for (mask, name) in names {
            bits.push(BitView {
                word: word.into(),
                bit: mask.trailing_zeros() as u8,
                name: name.to_owned(),
                set: byte & mask != 0,
            });
        }
    }
    MotionView {
        drive,
        profile: "fhpp".into(),
        state: fhpp_state(s),
        word: u16::from_le_bytes([s.inputs[0], s.inputs[1]]),
        bits,
        active_error: (s.fault != 0)
            .then(|| error_text::fhpp_diagnostic(table, u16::from(s.fault))),
        history: s
            .memory
            .iter()
            .map(|(event, number, time_ms)| ErrorView {
                event: Some(error_text::fhpp_event(*event).to_owned()),
                time_ms: Some(*time_ms),
                ..error_text::fhpp_diagnostic(table, *number)
            })
            .collect(),
        device_control: Some(authority_name(s.authority).to_owned()),
        display: motion::display_of(h, drive),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    /// An FHPP device reduced to SCON / SPOS following CCON / CPOS.
    struct FakeFhpp {
        state: RefCell<FhppState>,
        telegrams: RefCell<Vec<[u8; 8]>>,
    }

    impl FakeFhpp {
        fn new(authority: Authority, scon: u8) -> Self {
            FakeFhpp {
                state: RefCell::new(FhppState {
                    inputs: [scon, 0, 0, 0, 0, 0, 0, 0],
                    outputs: [0; 8],
                    authority,
                    fault: 0,
                    memory: Vec::new(),
                    refused: None,
                }),
                telegrams: RefCell::new(Vec::new()),
            }
        }
    }

    impl FhppIo for FakeFhpp {
        fn fhpp(&self, request: FhppRequest) -> Result<FhppState, ControlError> {
            let mut s = self.state.borrow_mut();
            if let FhppRequest::SetOutputs(o) = request {
                self.telegrams.borrow_mut().push(o);
                s.outputs = o;
                let ccon = Ccon(o[0]);
                let mut scon = Scon::VLOAD;
                if ccon.contains(Ccon::ENABLE) {
                    scon = scon.union(Scon::ENABLED);
                }
                s.inputs[0] = scon.0 | (ccon.0 & 0xC0);
                let cpos = Cpos(o[1]);
                s.inputs[1] = (o[1] & Spos::HALT.0)
                    | if cpos.contains(Cpos::START) {
                        Spos::ACK.0
                    } else {
                        0
                    };
            }
            Ok(s.clone())
        }
        fn wait(&self, _d: Duration) {}
    }

    #[test]
    fn fhpp_enable_sets_ccon_enable_stop_and_cpos_halt() {
        let d = FakeFhpp::new(Authority::Fieldbus, Scon::VLOAD.0);
        assert!(fhpp_enable(&d).is_ok());
        assert_eq!(
            d.telegrams.borrow().last().map(|t| (t[0], t[1])),
            Some((0x03, 0x01))
        );
    }

    #[test]
    fn fhpp_move_in_direct_mode_with_start_handshake() {
        let d = FakeFhpp::new(Authority::Fieldbus, Scon::VLOAD.0);
        fhpp_enable(&d).unwrap_or_else(|e| panic!("{e}"));
        assert!(fhpp_move(&d, 5000, false, 50).is_ok());
        let t = d.telegrams.borrow();
        let n = t.len();
        // OPM direct (0x40) with ENABLE and STOP; START rises once and falls.
        assert_eq!(t[n - 3][..4], [0x43, 0x01, 0x00, 50]);
        assert_eq!(t[n - 2][1], 0x03);
        assert_eq!(t[n - 1][1], 0x01);
        assert_eq!(t[n - 2][4..], 5000i32.to_be_bytes());
    }

    #[test]
    fn fhpp_refuses_while_the_web_server_holds_device_control() {
        let d = FakeFhpp::new(Authority::WebServer, Scon::VLOAD.0);
        assert_eq!(fhpp_enable(&d), Err(FhppMotionError::WebServerHasControl));
        assert!(d.telegrams.borrow().is_empty());
        let d = FakeFhpp::new(Authority::Fieldbus, Scon::VLOAD.0);
        assert!(matches!(
            fhpp_jog(&d, 1),
            Err(FhppMotionError::FhppNotEnabled { .. })
        ));
    }

    #[test]
    fn fhpp_jog_sets_and_clears_jogp_jogn() {
        let d = FakeFhpp::new(Authority::Fieldbus, Scon::VLOAD.0);
        fhpp_enable(&d).unwrap_or_else(|e| panic!("{e}"));
        fhpp_jog(&d, -1).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(d.telegrams.borrow().last().map(|t| t[1]), Some(0x11));
        fhpp_jog(&d, 0).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(d.telegrams.borrow().last().map(|t| t[1]), Some(0x01));
    }
}
