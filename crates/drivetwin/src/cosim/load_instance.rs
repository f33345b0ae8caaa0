//! A load FMU's instance, FMI 2.0 or FMI 3.0 co-simulation: the few calls a load makes
//! (set Float64 inputs, step, get Float64 and Boolean outputs, initialise with parameters),
//! each in the version's own functions, and its variables as its model description declares
//! them.
//!
//! The two versions differ where a load sees them: FMI 2.0 calls Float64 `Real` and returns a
//! Boolean as an `int` (FMI 2.0 §2.1.2); it fixes the start time with `fmi2SetupExperiment`
//! before `fmi2EnterInitializationMode` (§2.1.6), where FMI 3.0 gives it to
//! `fmi3EnterInitializationMode` (§2.3.2); and its `fmi2DoStep` returns no early-return or
//! terminate flags (§4.2.2).

use std::path::Path;

use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::{CoSimulation as _, Common as _};
use fmi::fmi3::import::Fmi3Import;
use fmi::fmi3::{CoSimulation as _, Common as _, Fmi3Model as _, GetSet as _};
use fmi::schema::fmi2::{Causality as Causality2, ScalarVariableElement};
use fmi::schema::fmi3::{Causality as Causality3, VariableType};
use fmi::traits::FmiImport;

use crate::sys::fmu_instance::FmuInstance;

/// A variable's type, as far as a load tells them apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Type {
    Float64,
    Boolean,
    Other,
}

/// A variable's causality, as far as a load tells them apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    Input,
    Output,
    Parameter,
    Other,
}

/// A variable as the model description declares it.
#[derive(Debug, Clone, PartialEq)]
pub struct Declared {
    pub value_reference: u32,
    pub ty: Type,
    pub causality: Role,
    /// Type and causality in the model description's words, for a refusal.
    pub found: String,
}

/// Why an FMU could not be opened.
#[derive(Debug)]
pub enum OpenError {
    /// The archive, its description or its library.
    Import(String),
    /// An FMI version other than 2.0 and 3.0.
    Version(String),
    /// No co-simulation interface.
    NotCoSimulation,
}

/// A failed call: its name and the status it returned.
pub type CallError = (&'static str, String);

/// An FMU instantiated for co-simulation, with the import it runs from.
// One per coupled drive, made once: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
pub enum LoadInstance {
    /// The instance before the import: it is freed before the library and the unpacked
    /// archive it uses.
    Fmi3 {
        instance: FmuInstance<fmi::fmi3::instance::InstanceCS>,
        import: Fmi3Import,
    },
    Fmi2 {
        instance: FmuInstance<fmi::fmi2::instance::InstanceCS>,
        import: Fmi2Import,
        /// The Boolean outputs as FMI 2.0 returns them (`fmi2Boolean`), sized once.
        booleans: Vec<i32>,
    },
}

impl LoadInstance {
    /// Opens the FMU at `path` (FMI 2.0 or 3.0, co-simulation) and instantiates it as
    /// `name`, logging on (its messages go to the cell's log).
    pub fn open(path: &Path, name: &str) -> Result<Self, OpenError> {
        let import_error = |e: fmi::Error| OpenError::Import(e.to_string());
        let version = fmi::import::peek_descr_path(path)
            .map_err(import_error)?
            .fmi_version;
        if version.starts_with("3.") {
            let import: Fmi3Import = fmi::import::from_path(path).map_err(import_error)?;
            if import.model_description().co_simulation.is_none() {
                return Err(OpenError::NotCoSimulation);
            }
            let instance = import
                .instantiate_cs(name, false, true, false, false, &[])
                .map_err(import_error)?;
            Ok(LoadInstance::Fmi3 {
                instance: FmuInstance::new(instance),
                import,
            })
        } else if version.starts_with("2.") {
            let import: Fmi2Import = fmi::import::from_path(path).map_err(import_error)?;
            if import.model_description().co_simulation.is_none() {
                return Err(OpenError::NotCoSimulation);
            }
            let instance = import
                .instantiate_cs(name, false, true)
                .map_err(import_error)?;
            Ok(LoadInstance::Fmi2 {
                instance: FmuInstance::new(instance),
                import,
                booleans: Vec::new(),
            })
        } else {
            Err(OpenError::Version(version))
        }
    }

    /// "2.0" or "3.0".
    pub fn fmi_version(&self) -> &'static str {
        match self {
            LoadInstance::Fmi3 { .. } => "3.0",
            LoadInstance::Fmi2 { .. } => "2.0",
        }
    }

    /// The variable `name`, as the model description declares it.
    pub fn variable(&self, name: &str) -> Option<Declared> {
        match self {
            LoadInstance::Fmi3 { import, .. } => {
                let vars = &import.model_description().model_variables;
                let v = vars.iter_abstract().find(|v| v.name() == name)?;
                Some(Declared {
                    value_reference: v.value_reference(),
                    ty: match v.data_type() {
                        VariableType::FmiFloat64 => Type::Float64,
                        VariableType::FmiBoolean => Type::Boolean,
                        _ => Type::Other,
                    },
                    causality: match v.causality() {
                        Causality3::Input => Role::Input,
                        Causality3::Output => Role::Output,
                        Causality3::Parameter => Role::Parameter,
                        _ => Role::Other,
                    },
                    found: format!("a {:?} {:?}", v.data_type(), v.causality()),
                })
            }
            LoadInstance::Fmi2 { import, .. } => {
                let md = import.model_description();
                let v = md
                    .model_variables
                    .variables
                    .iter()
                    .find(|v| v.name == name)?;
                let (ty, ty_name) = match v.elem {
                    ScalarVariableElement::Real(_) => (Type::Float64, "Real"),
                    ScalarVariableElement::Boolean(_) => (Type::Boolean, "Boolean"),
                    ScalarVariableElement::Integer(_) => (Type::Other, "Integer"),
                    ScalarVariableElement::String => (Type::Other, "String"),
                    ScalarVariableElement::Enumeration => (Type::Other, "Enumeration"),
                };
                Some(Declared {
                    value_reference: v.value_reference,
                    ty,
                    causality: match v.causality {
                        Causality2::Input => Role::Input,
                        Causality2::Output => Role::Output,
                        Causality2::Parameter => Role::Parameter,
                        _ => Role::Other,
                    },
                    found: format!("a {ty_name} {:?}", v.causality),
                })
            }
        }
    }

    /// Room for `n` Boolean outputs, so that reading them allocates nothing.
    pub fn reserve_booleans(&mut self, n: usize) {
        if let LoadInstance::Fmi2 { booleans, .. } = self {
            booleans.resize(n, 0);
        }
    }

    /// Parameters (in Instantiated mode), then initialisation at `start_s` (FMI 3.0 §2.3.2,
    /// FMI 2.0 §2.1.6), then step mode.
    pub fn initialise(
        &mut self,
        parameters: &[u32],
        values: &[f64],
        start_s: f64,
    ) -> Result<(), CallError> {
        match self {
            LoadInstance::Fmi3 { instance, .. } => {
                if !parameters.is_empty() {
                    instance
                        .set_float64(parameters, values)
                        .map_err(|e| ("fmi3SetFloat64", format!("{e:?}")))?;
                }
                instance
                    .enter_initialization_mode(None, start_s, None)
                    .map_err(|e| ("fmi3EnterInitializationMode", format!("{e:?}")))?;
                instance
                    .exit_initialization_mode()
                    .map_err(|e| ("fmi3ExitInitializationMode", format!("{e:?}")))?;
            }
            LoadInstance::Fmi2 { instance, .. } => {
                if !parameters.is_empty() {
                    instance
                        .set_real(parameters, values)
                        .map_err(|e| ("fmi2SetReal", format!("{e:?}")))?;
                }
                instance
                    .setup_experiment(None, start_s, None)
                    .map_err(|e| ("fmi2SetupExperiment", format!("{e:?}")))?;
                instance
                    .enter_initialization_mode()
                    .map_err(|e| ("fmi2EnterInitializationMode", format!("{e:?}")))?;
                instance
                    .exit_initialization_mode()
                    .map_err(|e| ("fmi2ExitInitializationMode", format!("{e:?}")))?;
            }
        }
        Ok(())
    }

    pub fn set_float64(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), CallError> {
        match self {
            LoadInstance::Fmi3 { instance, .. } => instance
                .set_float64(vrs, values)
                .map(drop)
                .map_err(|e| ("fmi3SetFloat64", format!("{e:?}"))),
            LoadInstance::Fmi2 { instance, .. } => instance
                .set_real(vrs, values)
                .map(drop)
                .map_err(|e| ("fmi2SetReal", format!("{e:?}"))),
        }
    }

    /// One communication step from `t` of `dt` s.
    pub fn do_step(&mut self, t: f64, dt: f64) -> Result<(), CallError> {
        match self {
            LoadInstance::Fmi3 { instance, .. } => {
                let (mut event, mut terminate, mut early, mut last) = (false, false, false, 0.0);
                instance
                    .do_step(
                        t,
                        dt,
                        true,
                        &mut event,
                        &mut terminate,
                        &mut early,
                        &mut last,
                    )
                    .map_err(|e| ("fmi3DoStep", format!("{e:?}")))?;
                if terminate {
                    return Err(("fmi3DoStep", "terminateSimulation".into()));
                }
                Ok(())
            }
            LoadInstance::Fmi2 { instance, .. } => instance
                .do_step(t, dt, true)
                .map(drop)
                .map_err(|e| ("fmi2DoStep", format!("{e:?}"))),
        }
    }

    pub fn get_float64(&mut self, vrs: &[u32], values: &mut [f64]) -> Result<(), CallError> {
        match self {
            LoadInstance::Fmi3 { instance, .. } => instance
                .get_float64(vrs, values)
                .map(drop)
                .map_err(|e| ("fmi3GetFloat64", format!("{e:?}"))),
            LoadInstance::Fmi2 { instance, .. } => instance
                .get_real(vrs, values)
                .map(drop)
                .map_err(|e| ("fmi2GetReal", format!("{e:?}"))),
        }
    }

    /// The Boolean outputs `vrs` into `values` (after [`LoadInstance::reserve_booleans`] of
    /// as many).
    pub fn get_boolean(&mut self, vrs: &[u32], values: &mut [bool]) -> Result<(), CallError> {
        match self {
            LoadInstance::Fmi3 { instance, .. } => instance
                .get_boolean(vrs, values)
                .map(drop)
                .map_err(|e| ("fmi3GetBoolean", format!("{e:?}"))),
            LoadInstance::Fmi2 {
                instance, booleans, ..
            } => {
                let Some(raw) = booleans.get_mut(..vrs.len()) else {
                    return Err(("fmi2GetBoolean", "more outputs than reserved".into()));
                };
                instance
                    .get_boolean(vrs, raw)
                    .map_err(|e| ("fmi2GetBoolean", format!("{e:?}")))?;
                for (v, r) in values.iter_mut().zip(raw.iter()) {
                    *v = *r != 0;
                }
                Ok(())
            }
        }
    }
}
