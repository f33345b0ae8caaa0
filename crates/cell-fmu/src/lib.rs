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
//! The only `unsafe` is in `sys`: the FMI C functions (raw pointers from the importer,
//! `#[unsafe(export_name)]`), which pass their calls on to `fmi-export`. A panic inside
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
    /// The parameters the importer set (value reference, value), in the order set.
    parameters: Vec<(u32, f64)>,
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
        // A load FMU's own message joins the error that stops the cell (a logger set by the
        // importer's process already wins; then the error says only the status).
        drivetwin::cosim::fmu_log::install();
        let resources = context.resource_path().clone();
        let set = &self.parameters;
        match guarded(|| {
            CellInstance::from_resources_with(&resources, drivetwin::vendors::VENDORS.runtime, set)
        }) {
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

    /// The values of the get call whose first value reference is `vr` (`sys::with_call`:
    /// all of the call's, read by `read` under one lock of the cell and one panic guard),
    /// or of `vr` alone; how many were read.
    fn get_many<T>(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [T],
        context: &dyn Context<CellModel>,
        read: impl FnOnce(&CellInstance, &[u32], &mut [T]) -> Result<(), CellFmuError>,
    ) -> Result<usize, Fmi3Error> {
        let Some(cell) = &self.cell else {
            log_error(context, "get: the cell is not built");
            return Err(Fmi3Error::Error);
        };
        // `fmi-export` numbers the model's variables from 0 after `time`.
        let read = sys::with_call(vr + 1, |vrs| {
            guarded(|| read(cell, vrs, values)).map(|()| vrs.len())
        });
        read.map_err(|e| {
            log_error(context, &e);
            Fmi3Error::Error
        })
    }

    /// A parameter (FMI 3.0 §2.4.7.4: `fixed`, set before the FMU is initialised): kept, and
    /// the cell built with it; a cell already built (a set in Initialization Mode) is built
    /// anew, its clock still at its start.
    fn set_parameter(
        &mut self,
        vr: binding::fmi3ValueReference,
        values: &[f64],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        let Some(value) = values.first() else {
            return Err(Fmi3Error::Error);
        };
        let vr = vr + 1;
        match self.parameters.iter_mut().find(|(r, _)| *r == vr) {
            Some(slot) => slot.1 = *value,
            None => self.parameters.push((vr, *value)),
        }
        if self.cell.take().is_some() {
            self.ensure(context)?;
        }
        Ok(1)
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
        self.get_many(vr, values, context, CellInstance::get_float64s)
    }

    fn set_float64(
        &mut self,
        vr: binding::fmi3ValueReference,
        values: &[f64],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        if drivetwin::cell_fmu::parameters::is_parameter(vr + 1) {
            return self.set_parameter(vr, values, context);
        }
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

    fn get_uint8(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [u8],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        self.get_many(vr, values, context, CellInstance::get_uint8s)
    }

    fn get_uint16(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [u16],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        self.get_many(vr, values, context, CellInstance::get_uint16s)
    }

    /// Reached only through `fmi-export`'s own `fmi3GetString`, which `sys` replaces
    /// ([`CellModel::get_uint64`] gives it the display's own bytes).
    fn get_string(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [std::ffi::CString],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        self.get(vr, values, context, |cell, vr| {
            cell.display(vr).map(std::ffi::CStr::to_owned)
        })
    }

    /// Only inside `sys::fmi3_get_string` (the cell has no UInt64 variable): the address of
    /// the display's text the instance holds, which `fmi3GetString` hands out as it is
    /// (FMI 3.0 §2.2.6.2), after `fmi-export`'s state checks of a get.
    fn get_uint64(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [u64],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        if !sys::in_string_get() {
            log_error(context, "fmi3GetUInt64: the FMU has no UInt64 variable");
            return Err(Fmi3Error::Error);
        }
        self.get(vr, values, context, |cell, vr| {
            let address = cell.display(vr)?.as_ptr().expose_provenance();
            Ok(address as u64)
        })
    }

    fn get_int32(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [i32],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        self.get_many(vr, values, context, CellInstance::get_int32s)
    }

    /// An LS-BUS terminal's `Rx_Data` or `Tx_Data`: `values` is `sys::fmi3_get_binary`'s
    /// place, into which the value's address and length go (see [`binary_place`]).
    fn get_binary(
        &self,
        vr: binding::fmi3ValueReference,
        values: &mut [&mut [u8]],
        context: &dyn Context<CellModel>,
    ) -> Result<Vec<usize>, Fmi3Error> {
        let (Some(cell), Some(place)) = (&self.cell, values.first_mut()) else {
            log_error(context, "get: the cell is not built");
            return Err(Fmi3Error::Error);
        };
        match guarded(|| {
            cell.get_binary(vr + 1)
                .map(|b| binary_place::write(place, b))
        }) {
            Ok(true) => Ok(vec![place.len()]),
            Ok(false) => {
                log_error(context, "fmi3GetBinary: no place for the value");
                Err(Fmi3Error::Error)
            }
            Err(e) => {
                log_error(context, &e);
                Err(Fmi3Error::Error)
            }
        }
    }

    fn set_binary(
        &mut self,
        vr: binding::fmi3ValueReference,
        values: &[&[u8]],
        context: &dyn Context<CellModel>,
    ) -> Result<usize, Fmi3Error> {
        self.set(vr, values, context, |c, vr, v| c.set_binary(vr, v))
    }

    fn get_clock(
        &mut self,
        vr: binding::fmi3ValueReference,
        value: &mut binding::fmi3Clock,
        context: &dyn Context<CellModel>,
    ) -> Result<(), Fmi3Error> {
        self.ensure(context)?;
        let Some(cell) = &mut self.cell else {
            return Err(Fmi3Error::Error);
        };
        match guarded(|| cell.get_clock(vr + 1)) {
            Ok(tick) => {
                *value = tick;
                Ok(())
            }
            Err(e) => {
                log_error(context, &e);
                Err(Fmi3Error::Error)
            }
        }
    }

    fn set_clock(
        &mut self,
        vr: binding::fmi3ValueReference,
        value: &binding::fmi3Clock,
        context: &dyn Context<CellModel>,
    ) -> Result<(), Fmi3Error> {
        self.set(vr, std::slice::from_ref(value), context, |c, vr, v| {
            c.set_clock(vr, v)
        })
        .map(drop)
    }
}

/// How `sys::fmi3_get_binary` learns where a binary value is: `fmi-export` hands
/// [`ModelGetSet::get_binary`] only buffers to copy into, so the model writes the address and
/// the length of the bytes it holds into a buffer of `sys::BINARY_PLACE` bytes, and
/// `fmi3GetBinary` gives the importer that address, as FMI 3.0 has it.
pub mod binary_place {
    const WORD: usize = std::mem::size_of::<usize>();

    /// `bytes`' address and length into `place` (false: `place` is not the place).
    pub fn write(place: &mut [u8], bytes: &[u8]) -> bool {
        let Some((address, length)) = place.split_at_mut_checked(WORD) else {
            return false;
        };
        if length.len() != WORD {
            return false;
        }
        address.copy_from_slice(&bytes.as_ptr().expose_provenance().to_le_bytes());
        length.copy_from_slice(&bytes.len().to_le_bytes());
        true
    }

    /// The address and the length [`write()`] put into `place`.
    pub fn read(place: &[u8]) -> Option<(usize, usize)> {
        let address = place
            .get(..WORD)?
            .try_into()
            .ok()
            .map(usize::from_le_bytes)?;
        let length = place
            .get(WORD..)?
            .try_into()
            .ok()
            .map(usize::from_le_bytes)?;
        Some((address, length))
    }
}

impl UserModel for CellModel {
    type LoggingCategory = DefaultLoggingCategory;

    /// `fmi3UpdateDiscreteStates`: the LS-BUS terminals take what their `Rx_Clock` brought.
    fn event_update(
        &mut self,
        context: &dyn Context<Self>,
        event_flags: &mut fmi::EventFlags,
    ) -> Result<Fmi3Res, Fmi3Error> {
        self.ensure(context)?;
        if let Some(cell) = &mut self.cell {
            if let Err(e) = guarded(|| {
                cell.update_discrete_states();
                Ok(())
            }) {
                log_error(context, &e);
                return Err(Fmi3Error::Error);
            }
        }
        event_flags.reset();
        Ok(Fmi3Res::OK)
    }

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
                let mut result = CSDoStepResult::completed(end);
                // A Tx_Clock ticked: the importer enters Event Mode to read it.
                result.event_handling_needed = cell.event_needed();
                Ok(result)
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

#[cfg(test)]
mod tests {
    use super::binary_place;

    #[test]
    fn a_binary_values_place_reads_back_as_its_address_and_length() {
        let value = [0x10u8, 0, 0, 0, 24, 0, 0, 0];
        let mut place = [0u8; 2 * std::mem::size_of::<usize>()];
        assert!(binary_place::write(&mut place, &value));
        assert_eq!(
            binary_place::read(&place),
            Some((value.as_ptr().expose_provenance(), value.len()))
        );
        // Any other buffer is not the place.
        assert!(!binary_place::write(&mut [0u8; 8], &value));
        assert!(!binary_place::write(&mut [0u8; 24], &value));
    }
}
