//! A drivetwin cell as an FMI 3.0 co-simulation FMU (FMI 3.0 §4 "Co-Simulation"): the
//! library whose C functions an importer (fmpy, a simulation tool) calls.
//!
//! `fmi-export` writes the FMI C functions (`export_fmu!`); it dispatches every get and set by
//! value reference to the model's `ModelGetSet`, which this crate implements by hand: the
//! variables are not fields of a struct but a table built from the cell file when the FMU is
//! instantiated (`drivetwin::cell_fmu::variables`), so their number follows the cell's drives.
//! The model is [`CellModel`]: an empty shell until the first call that needs the cell, which
//! reads `resources/cell.toml` (and `resources/timeline.toml`) and builds it
//! (`drivetwin::cell_fmu::instance::CellInstance`).
//!
//! The only `unsafe` is in `sys`: the C functions `export_fmu!` generates (raw pointers from
//! the importer, `#[unsafe(export_name)]`). A panic inside
//! the cell must not cross the C boundary: every call into the cell runs under
//! `catch_unwind` and becomes `fmi3Error` with a log message.
#![deny(unsafe_code)]

use std::panic::{catch_unwind, AssertUnwindSafe};

use drivetwin::cell_fmu::instance::CellInstance;
use drivetwin::cell_fmu::{CellFmuError, INSTANTIATION_TOKEN};
use fmi::fmi3::{binding, Fmi3Error, Fmi3Res, Fmi3Status};
use fmi_export::fmi3::{
    CSDoStepResult, Context, DefaultLoggingCategory, Model, ModelGetSet, ModelGetSetStates,
    UserModel,
};

/// The cell, once built.
#[derive(Default)]
pub struct CellModel {
    cell: Option<CellInstance>,
}

/// What a call into the cell gives: its value, or the error it ended with.
fn guarded<T>(f: impl FnOnce() -> Result<T, CellFmuError>) -> Result<T, String> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(e.to_string()),
        Err(_) => Err("the cell panicked".to_string()),
    }
}

fn log_error(context: &dyn Context<CellModel>, what: &str) {
    context.log(
        Fmi3Status::from(Fmi3Error::Error),
        DefaultLoggingCategory::LogAll,
        format_args!("{what}"),
    );
}

impl CellModel {
    /// Builds the cell from the FMU's resources if it is not built yet.
    fn ensure(&mut self, context: &dyn Context<CellModel>) -> Result<(), Fmi3Error> {
        if self.cell.is_some() {
            return Ok(());
        }
        let resources = context.resource_path().clone();
        match guarded(|| CellInstance::from_resources(&resources, drivetwin::vendors::VENDORS)) {
            Ok(cell) => {
                self.cell = Some(cell);
                Ok(())
            }
            Err(e) => {
                log_error(context, &format!("{}: {e}", resources.display()));
                Err(Fmi3Error::Error)
            }
        }
    }

    /// One value of the built cell by value reference (`vr` as the C API numbers it).
    fn get<T>(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [T],
        context: &dyn Context<CellModel>,
        read: impl FnOnce(&CellInstance, u32) -> Result<T, CellFmuError>,
    ) -> Result<usize, Fmi3Error> {
        let (Some(cell), Some(slot)) = (&self.cell, values.first_mut()) else {
            log_error(context, "get: the cell is not built");
            return Err(Fmi3Error::Error);
        };
        // `fmi-export` numbers the model's variables from 0 after `time`.
        match guarded(|| read(cell, vr + 1)) {
            Ok(v) => {
                *slot = v;
                Ok(1)
            }
            Err(e) => {
                log_error(context, &e);
                Err(Fmi3Error::Error)
            }
        }
    }

    fn set<T: Copy>(
        &mut self,
        vr: binding::fmi3ValueReference,
        values: &[T],
        context: &dyn Context<CellModel>,
        write: impl FnOnce(&mut CellInstance, u32, T) -> Result<(), CellFmuError>,
    ) -> Result<usize, Fmi3Error> {
        self.ensure(context)?;
        let (Some(cell), Some(v)) = (&mut self.cell, values.first()) else {
            return Err(Fmi3Error::Error);
        };
        match guarded(|| write(cell, vr + 1, *v)) {
            Ok(()) => Ok(1),
            Err(e) => {
                log_error(context, &e);
                Err(Fmi3Error::Error)
            }
        }
    }
}

impl Model for CellModel {
    const MODEL_NAME: &'static str = "drivetwin cell";
    const INSTANTIATION_TOKEN: &'static str = INSTANTIATION_TOKEN;
    const MAX_EVENT_INDICATORS: usize = 0;
    const SUPPORTS_MODEL_EXCHANGE: bool = false;
    const SUPPORTS_CO_SIMULATION: bool = true;
    const SUPPORTS_SCHEDULED_EXECUTION: bool = false;

    /// The variables depend on the cell file: `drivetwin fmu` writes the description
    /// (`drivetwin::cell_fmu::model_description`), not this library.
    fn build_metadata(
        _variables: &mut fmi::schema::fmi3::ModelVariables,
        _model_structure: &mut fmi::schema::fmi3::ModelStructure,
        _vr_offset: u32,
        _prefix: Option<&str>,
    ) -> u32 {
        0
    }

    fn set_start_values(&mut self) {}
}

impl ModelGetSetStates for CellModel {
    const NUM_STATES: usize = 0;

    fn get_continuous_states(&self, _states: &mut [f64]) -> Result<(), Fmi3Error> {
        Ok(())
    }

    fn set_continuous_states(&mut self, _states: &[f64]) -> Result<(), Fmi3Error> {
        Ok(())
    }

    fn get_continuous_state_derivatives(
        &mut self,
        _derivatives: &mut [f64],
    ) -> Result<(), Fmi3Error> {
        Ok(())
    }
}

impl ModelGetSet<CellModel> for CellModel {
    const FIELD_COUNT: usize = 0;

    fn get_float64(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [f64],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        self.get(vr, values, context, CellInstance::get_float64)
    }

    fn set_float64(
        &mut self,
        vr: binding::fmi3ValueReference,
        values: &[f64],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        self.set(vr, values, context, CellInstance::set_float64)
    }

    fn get_boolean(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [bool],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        self.get(vr, values, context, CellInstance::get_boolean)
    }

    fn set_boolean(
        &mut self,
        vr: binding::fmi3ValueReference,
        values: &[bool],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        self.set(vr, values, context, CellInstance::set_boolean)
    }

    fn get_uint16(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [u16],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        self.get(vr, values, context, CellInstance::get_uint16)
    }

    fn get_int32(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [i32],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        self.get(vr, values, context, CellInstance::get_int32)
    }
}

impl UserModel for CellModel {
    type LoggingCategory = DefaultLoggingCategory;

    /// Called before any get after a change: builds the cell the first time.
    fn calculate_values(&mut self, context: &dyn Context<Self>) -> Result<Fmi3Res, Fmi3Error> {
        self.ensure(context)?;
        Ok(Fmi3Res::OK)
    }

    fn configurate(&mut self, context: &dyn Context<Self>) -> Result<(), Fmi3Error> {
        self.ensure(context)
    }

    fn do_step(
        &mut self,
        context: &mut dyn Context<Self>,
        current_communication_point: f64,
        communication_step_size: f64,
        _no_set_fmu_state_prior_to_current_point: bool,
    ) -> Result<CSDoStepResult, Fmi3Error> {
        self.ensure(&*context)?;
        let Some(cell) = &mut self.cell else {
            return Err(Fmi3Error::Error);
        };
        match guarded(|| cell.do_step(current_communication_point, communication_step_size)) {
            Ok(()) => {
                let end = current_communication_point + communication_step_size;
                context.set_time(end);
                Ok(CSDoStepResult::completed(end))
            }
            Err(e) => {
                log_error(&*context, &format!("fmi3DoStep: {e}"));
                Err(Fmi3Error::Error)
            }
        }
    }
}

#[allow(unsafe_code)]
mod sys;
