//! Diagnostic messages raised and cleared from outside the drive, by the number its manual
//! prints ("08-2", "2Fh", "0800h", "Error_State.9"): from the cell (a scenario, the cell file's
//! `[[drive.diagnostic]]`), the control handle and the REST API. The drive then reacts as if
//! its own supervision had raised the message (`drive::drive::diagnostics`).

use drive::drive::diagnostics::{emcy_code, DiagnosticError};
use od::Diagnostic;
use serde::Deserialize;

use super::control::ControlError;
use super::device_model::Model;
use super::stations::StationId;

/// One message of a drive's table and whether it is active now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DiagnosticState {
    pub row: &'static Diagnostic,
    /// The EMCY code it is reported with (CiA 402 drives; 1000h where the manual gives none).
    pub emcy: Option<u16>,
    pub active: bool,
}

/// Raise or clear.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Action {
    Raise,
    Clear,
}

/// `[[drive.diagnostic]]` of a cell file: at `at_ms` on the cell's clock, raise (or clear)
/// message `number` of the drive.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlannedDiagnostic {
    pub at_ms: u64,
    pub number: String,
    #[serde(default = "raise")]
    pub action: Action,
}

fn raise() -> Action {
    Action::Raise
}

/// `[[drive.plant]]` of a cell file: at `at_ms` (default 0) on the cell's clock, the plant's
/// physics change: `ambient_c`, `encoder` (with `noise`), `switch` (with `actuated`, default
/// true; `release = true`: back to the travel). `[drive.thermal]` gives the figures.
#[derive(Debug, Clone, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct PlannedPhysics {
    #[serde(default)]
    pub at_ms: u64,
    pub ambient_c: Option<f64>,
    pub encoder: Option<String>,
    pub noise: Option<u32>,
    pub switch: Option<String>,
    pub actuated: Option<bool>,
    pub release: Option<bool>,
}

impl PlannedPhysics {
    /// What it changes; an error says which keys do not fit.
    pub fn change(&self) -> Result<super::control::PhysicsChange, String> {
        use super::control::PhysicsChange;
        let given = [
            self.ambient_c.is_some(),
            self.encoder.is_some(),
            self.switch.is_some(),
        ];
        if given.iter().filter(|g| **g).count() != 1 {
            return Err("one of ambient_c, encoder, switch".into());
        }
        if let Some(c) = self.ambient_c {
            if !(c.is_finite() && (-50.0..=200.0).contains(&c)) {
                return Err(format!("ambient_c {c}: °C within −50 … 200"));
            }
            return Ok(PhysicsChange::Ambient(c));
        }
        if let Some(name) = &self.encoder {
            return drive::drive::plant_supervision::encoder_fault(name, self.noise.unwrap_or(100))
                .map(PhysicsChange::Encoder)
                .ok_or_else(|| format!("encoder {name:?}: connected, disconnected or noisy"));
        }
        let name = self.switch.as_deref().unwrap_or("");
        let switch = drive::drive::named_switches::NamedSwitch::parse(name)
            .ok_or_else(|| format!("switch {name:?}: limit_positive, limit_negative or home"))?;
        let state = if self.release == Some(true) {
            None
        } else {
            Some(self.actuated.unwrap_or(true))
        };
        Ok(PhysicsChange::Switch(switch, state))
    }
}

/// Something the cell file plans for a drive at a time of the cell's clock.
#[derive(Debug, Clone, PartialEq)]
pub enum Planned {
    Diagnostic(PlannedDiagnostic),
    Physics(super::control::PhysicsChange),
}

fn refused(e: DiagnosticError) -> ControlError {
    ControlError::Diagnostic(e)
}

/// Raises (or clears) message `number` of a CiA 402 drive model.
pub fn set_model(
    model: &mut Model,
    number: &str,
    action: Action,
) -> Result<&'static Diagnostic, DiagnosticError> {
    if let Some(image) = model.register_image_mut() {
        return image.device_mut().set_diagnostic(number, action);
    }
    let d = model.drive_mut().ok_or(DiagnosticError::Unknown)?;
    match action {
        Action::Raise => d.raise_diagnostic(number),
        Action::Clear => d.clear_diagnostic(number),
    }
}

/// The table of a drive model with what is active (empty for a plain device); a
/// register-image device's is its own.
pub fn list_model(model: &Model) -> Vec<DiagnosticState> {
    if let Some(image) = model.register_image() {
        return image.device().diagnostics();
    }
    let Some(d) = model.drive() else {
        return Vec::new();
    };
    d.diagnostic_table()
        .iter()
        .map(|row| DiagnosticState {
            row,
            emcy: Some(emcy_code(row)),
            active: d.diagnostic_active(row),
        })
        .collect()
}

impl super::can_cell::CanCell {
    /// Raises diagnostic message `number` ("08-2", as the drive's manual prints it) of
    /// station `id`: the drive reacts as if it had detected it (reaction, EMCY, 1003h,
    /// statusword, display) and keeps it until [`Self::clear_diagnostic`]. The frames go out
    /// at its bus's next poll.
    pub fn raise_diagnostic(
        &mut self,
        id: StationId,
        number: &str,
    ) -> Result<&'static Diagnostic, ControlError> {
        self.act_on_diagnostic(id, number, Action::Raise)
    }

    /// Clears message `number` raised by [`Self::raise_diagnostic`].
    pub fn clear_diagnostic(
        &mut self,
        id: StationId,
        number: &str,
    ) -> Result<&'static Diagnostic, ControlError> {
        self.act_on_diagnostic(id, number, Action::Clear)
    }

    /// The diagnostic table of station `id`, with what is active.
    pub fn diagnostics(&self, id: StationId) -> Result<Vec<DiagnosticState>, ControlError> {
        let d = self.station(id).ok_or(ControlError::NoDrive(id.index()))?;
        Ok(list_model(&d.model))
    }

    fn act_on_diagnostic(
        &mut self,
        id: StationId,
        number: &str,
        action: Action,
    ) -> Result<&'static Diagnostic, ControlError> {
        let d = self
            .station_mut(id)
            .ok_or(ControlError::NoDrive(id.index()))?;
        set_model(&mut d.model, number, action).map_err(refused)
    }
}
