//! A drive's load FMU through the control handle (docs/cosimulation.md): what is coupled (the
//! FMU, its mapping table, the mapped variables' values as last exchanged, how it has
//! stepped), and coupling one, or uncoupling it, while the cell runs.
//!
//! The FMU is opened (unpacked, loaded, its variables checked) on the caller's thread, so the
//! cell's loop never waits for an archive; the loop only swaps it in between two plant cycles.
//! It starts at the drive's next plant cycle (its time 0 there), as one of the cell file does at
//! the first.

use std::sync::mpsc::SyncSender;

use super::control::{Command, ControlError, ControlHandle};
use super::device_model::Model;
use super::modbus_device::ModbusDevice;
use crate::cosim::{FmuLoad, FmuLoadError, LoadMapping, LoadReport, LoadValue};

/// The load of one drive.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LoadState {
    /// The coupled FMU, if any.
    pub coupled: Option<CoupledLoad>,
    /// Why the load stopped the drive, once it has.
    pub failure: Option<String>,
}

/// A coupled load FMU.
#[derive(Debug, Clone, PartialEq)]
pub struct CoupledLoad {
    /// Its path.
    pub fmu: String,
    /// "2.0" or "3.0".
    pub fmi_version: &'static str,
    pub mapping: LoadMapping,
    /// (role, variable, value) of each mapped variable.
    pub values: Vec<(String, String, LoadValue)>,
    pub report: LoadReport,
}

/// What to do with a drive's load.
pub enum LoadChange {
    /// Nothing: read only.
    None,
    /// Couple this FMU, in place of any other.
    Couple(Box<FmuLoad>),
    /// Uncouple the FMU.
    Uncouple,
}

/// Why a load request failed.
#[derive(Debug, thiserror::Error)]
pub enum LoadControlError {
    #[error(transparent)]
    Control(#[from] ControlError),
    /// The FMU was refused (it does not open, lacks a variable, …), or the drive has no shaft.
    #[error("load: {0}")]
    Load(#[from] FmuLoadError),
}

/// A load request to the loop (appended to [`Command`] through [`Command::Load`]).
pub(crate) struct LoadRequest {
    pub drive: usize,
    pub change: LoadChange,
    pub reply: SyncSender<Result<LoadState, LoadControlError>>,
}

impl ControlHandle {
    fn load_request(
        &self,
        drive: usize,
        change: LoadChange,
    ) -> Result<LoadState, LoadControlError> {
        self.ask(|reply| {
            Command::Load(LoadRequest {
                drive,
                change,
                reply,
            })
        })?
    }

    /// Drive `drive`'s load.
    pub fn load(&self, drive: usize) -> Result<LoadState, LoadControlError> {
        self.load_request(drive, LoadChange::None)
    }

    /// Couples the FMU `mapping` names (a relative path: to the working directory) to drive
    /// `drive`'s shaft, in place of any other; refused as the cell file's `[drive.load]` is.
    pub fn couple_load(
        &self,
        drive: usize,
        mapping: &LoadMapping,
    ) -> Result<LoadState, LoadControlError> {
        let load = FmuLoad::open(mapping, None, &format!("load{drive}"))?;
        self.load_request(drive, LoadChange::Couple(Box::new(load)))
    }

    /// Uncouples drive `drive`'s load FMU (none coupled: nothing changes).
    pub fn uncouple_load(&self, drive: usize) -> Result<LoadState, LoadControlError> {
        self.load_request(drive, LoadChange::Uncouple)
    }
}

/// Carries out `change` on a drive's model; its load after it. A model without a shaft (a
/// device without a simulated motor) has no load and takes none.
pub fn apply(model: &mut Model, change: LoadChange) -> Result<LoadState, LoadControlError> {
    let Some(d) = model.drive_mut() else {
        return match change {
            LoadChange::Couple(load) => Err(FmuLoadError::NoShaft {
                fmu: load.name().to_owned(),
            }
            .into()),
            LoadChange::None | LoadChange::Uncouple => Ok(LoadState::default()),
        };
    };
    match change {
        LoadChange::None => {}
        LoadChange::Couple(load) => d.set_load(*load),
        LoadChange::Uncouple => d.uncouple(),
    }
    Ok(state(d.load(), d.load_failure()))
}

/// Carries out `change` on a drive served with its own register image (the CMMO-ST): its
/// load steps with the device's cycle; refused (and nothing changes) when the FMU drives a
/// switch the device has no input for.
pub fn apply_to_modbus_device(
    device: &mut dyn ModbusDevice,
    change: LoadChange,
) -> Result<LoadState, LoadControlError> {
    match change {
        LoadChange::None => {}
        LoadChange::Couple(load) => device.couple_load(Some(*load))?,
        LoadChange::Uncouple => device.couple_load(None)?,
    }
    Ok(state(device.load(), device.load_failure()))
}

/// What a drive's load is: its FMU, if one is coupled, and why it stopped the drive.
fn state(load: Option<&FmuLoad>, failure: Option<&FmuLoadError>) -> LoadState {
    LoadState {
        coupled: load.map(|l| CoupledLoad {
            fmu: l.name().to_owned(),
            fmi_version: l.fmi_version(),
            mapping: l.mapping().clone(),
            values: l.values(),
            report: l.report(),
        }),
        failure: failure.map(|e| e.to_string()),
    }
}
