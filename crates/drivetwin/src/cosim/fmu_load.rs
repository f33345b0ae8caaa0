//! A co-simulation FMU as a drive's load (FMI 3.0 §4 "Co-Simulation"): imported with the
//! `fmi` crate, instantiated once, and stepped by the drive's plant cycles on the cell's clock
//! ([`drive::drive::external_load`]).
//!
//! Each plant cycle of `dt` at cell time `t`: the mapped inputs are set from the shaft as it
//! is at `t` (`fmi3SetFloat64`), `fmi3DoStep(t, dt)` advances the FMU to `t + dt`, and the
//! load torque, the position and the switch outputs are read (`fmi3GetFloat64`,
//! `fmi3GetBoolean`). The communication points are the cell clock's nanoseconds as seconds,
//! so the FMU sees the same times, and gives the same values, on every run; the wall time a
//! step takes is measured only to report a slow FMU (a `doStep` longer than the virtual time
//! it advances, which a real-time cell cannot keep up with), never to skip a step.
//!
//! Refused when the cell is built: an archive that does not open, an FMU that is not FMI 3.0
//! co-simulation, a mapped variable the FMU lacks (named) or of the wrong type or causality.
//! An FMU call that returns an error stops the load: [`FmuLoad`] returns the error, and the
//! cell stops with it.

use std::path::Path;
use std::time::Instant as WallClock;

use drive::drive::external_load::{ExternalLoad, LoadReaction, Shaft, SWITCHES};
use drive::drive::named_switches::NamedSwitch;
use fmi::fmi3::import::Fmi3Import;
use fmi::fmi3::{CoSimulation, Common, Fmi3Model, GetSet};
use fmi::schema::fmi3::{Causality, VariableType};
use fmi::traits::FmiImport;
use od::Instant;

use super::mapping::LoadMapping;
use crate::sys::fmu_instance::FmuInstance;

/// Why a load FMU was refused or stopped.
#[derive(Debug, thiserror::Error)]
pub enum FmuLoadError {
    #[error("{fmu}: {message}")]
    Import { fmu: String, message: String },
    #[error("{fmu}: FMI {version} is not supported (an FMI 3.0 co-simulation FMU is)")]
    Version { fmu: String, version: String },
    #[error("{fmu}: no co-simulation interface (only FMI 3.0 co-simulation FMUs are loads)")]
    NotCoSimulation { fmu: String },
    #[error("{fmu}: no variable `{name}` (mapped as `{role}`)")]
    MissingVariable {
        fmu: String,
        role: String,
        name: String,
    },
    #[error("{fmu}: variable `{name}` (mapped as `{role}`) is {found}; `{role}` needs {needed}")]
    WrongVariable {
        fmu: String,
        role: String,
        name: String,
        found: String,
        needed: &'static str,
    },
    #[error("{fmu}: a load needs a drive with a motor (a CiA 402 drive)")]
    NoShaft { fmu: String },
    #[error("{fmu}: `{name}` is not a switch (home, limit_positive, limit_negative)")]
    UnknownSwitch { fmu: String, name: String },
    #[error("{fmu}: {call} at t = {time_s} s returned {status} (the FMU's log says why)")]
    Call {
        fmu: String,
        call: &'static str,
        time_s: f64,
        status: String,
    },
}

/// How the load has stepped so far: for the console, the diagnostics and the benches.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LoadReport {
    /// `doStep` calls made.
    pub steps: u64,
    /// Of them, those that took longer in wall time than the virtual time they advanced.
    pub slow_steps: u64,
    /// The longest `doStep` in wall time, ns.
    pub worst_step_ns: u64,
    /// The mapped position output after the last step.
    pub position: f64,
    /// The load torque after the last step, N·m.
    pub torque_nm: f64,
}

/// A load FMU, instantiated and mapped.
pub struct FmuLoad {
    /// The instance first: it is freed before the library and the unpacked archive it uses.
    instance: FmuInstance,
    _import: Fmi3Import,
    name: String,
    /// Value references of the inputs, in [`LoadMapping::inputs`]' order, with their role.
    inputs: Vec<(Input, u32)>,
    /// The load torque, then the position if mapped.
    outputs: Vec<u32>,
    /// The switch outputs: (index into [`SWITCHES`], value reference).
    switches: Vec<(usize, u32)>,
    /// The value references alone, as the FMI calls take them (made once: a plant step
    /// allocates nothing).
    input_vrs: Vec<u32>,
    switch_vrs: Vec<u32>,
    /// The parameters to set before initialisation: (value reference, value).
    parameters: Vec<(u32, f64)>,
    /// The switch levels last given to the drive.
    levels: [Option<bool>; 3],
    /// The cell time the FMU was initialised at (its first plant cycle).
    start: Option<Instant>,
    input_values: Vec<f64>,
    output_values: Vec<f64>,
    switch_values: Vec<bool>,
    report: LoadReport,
}

#[derive(Debug, Clone, Copy)]
enum Input {
    Torque,
    Speed,
    Angle,
}

impl std::fmt::Debug for FmuLoad {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FmuLoad")
            .field("fmu", &self.name)
            .field("report", &self.report)
            .finish_non_exhaustive()
    }
}

/// The variable `name` of the FMU: its value reference, checked for `role`'s type and causality.
fn variable(
    import: &Fmi3Import,
    fmu: &str,
    role: &str,
    name: &str,
    ty: VariableType,
    causality: Causality,
) -> Result<u32, FmuLoadError> {
    let vars = &import.model_description().model_variables;
    let Some(v) = vars.iter_abstract().find(|v| v.name() == name) else {
        return Err(FmuLoadError::MissingVariable {
            fmu: fmu.into(),
            role: role.into(),
            name: name.into(),
        });
    };
    let needed = match (ty, causality) {
        (VariableType::FmiFloat64, Causality::Input) => "a Float64 input",
        (VariableType::FmiFloat64, Causality::Parameter) => "a Float64 parameter",
        (VariableType::FmiFloat64, _) => "a Float64 output",
        (_, _) => "a Boolean output",
    };
    if v.data_type() != ty || v.causality() != causality {
        return Err(FmuLoadError::WrongVariable {
            fmu: fmu.into(),
            role: role.into(),
            name: name.into(),
            found: format!("a {:?} {:?}", v.data_type(), v.causality()),
            needed,
        });
    }
    Ok(v.value_reference())
}

impl FmuLoad {
    /// Opens the FMU of `mapping` (a relative path relative to `base`), checks every mapped
    /// variable and instantiates it for co-simulation, named `instance`.
    pub fn open(
        mapping: &LoadMapping,
        base: Option<&Path>,
        instance: &str,
    ) -> Result<Self, FmuLoadError> {
        let path = match base {
            Some(b) if mapping.fmu.is_relative() => b.join(&mapping.fmu),
            _ => mapping.fmu.clone(),
        };
        let fmu = path.display().to_string();
        let import_error = |e: fmi::Error| FmuLoadError::Import {
            fmu: fmu.clone(),
            message: e.to_string(),
        };
        let version = fmi::import::peek_descr_path(&path)
            .map_err(import_error)?
            .fmi_version;
        if !version.starts_with("3.") {
            return Err(FmuLoadError::Version { fmu, version });
        }
        let import: Fmi3Import = fmi::import::from_path(&path).map_err(import_error)?;
        if import.model_description().co_simulation.is_none() {
            return Err(FmuLoadError::NotCoSimulation { fmu });
        }
        let mut inputs = Vec::new();
        for (role, name) in mapping.inputs() {
            let vr = variable(
                &import,
                &fmu,
                role,
                name,
                VariableType::FmiFloat64,
                Causality::Input,
            )?;
            let input = match role {
                "torque" => Input::Torque,
                "speed" => Input::Speed,
                _ => Input::Angle,
            };
            inputs.push((input, vr));
        }
        let mut outputs = vec![variable(
            &import,
            &fmu,
            "load_torque",
            &mapping.load_torque,
            VariableType::FmiFloat64,
            Causality::Output,
        )?];
        if let Some(p) = &mapping.position {
            outputs.push(variable(
                &import,
                &fmu,
                "position",
                p,
                VariableType::FmiFloat64,
                Causality::Output,
            )?);
        }
        let mut switches = Vec::new();
        for (switch, name) in &mapping.switches {
            let index = NamedSwitch::parse(switch)
                .and_then(|s| SWITCHES.iter().position(|&k| k == s))
                .ok_or_else(|| FmuLoadError::UnknownSwitch {
                    fmu: fmu.clone(),
                    name: switch.clone(),
                })?;
            let vr = variable(
                &import,
                &fmu,
                switch,
                name,
                VariableType::FmiBoolean,
                Causality::Output,
            )?;
            switches.push((index, vr));
        }
        let mut parameters = Vec::new();
        for (name, value) in &mapping.parameters {
            let vr = variable(
                &import,
                &fmu,
                "parameter",
                name,
                VariableType::FmiFloat64,
                Causality::Parameter,
            )?;
            parameters.push((vr, *value));
        }
        let instance_cs = import
            .instantiate_cs(instance, false, true, false, false, &[])
            .map_err(import_error)?;
        Ok(FmuLoad {
            instance: FmuInstance::new(instance_cs),
            _import: import,
            name: fmu,
            input_values: vec![0.0; inputs.len()],
            output_values: vec![0.0; outputs.len()],
            switch_values: vec![false; switches.len()],
            input_vrs: inputs.iter().map(|&(_, vr)| vr).collect(),
            switch_vrs: switches.iter().map(|&(_, vr)| vr).collect(),
            inputs,
            outputs,
            switches,
            parameters,
            levels: [None; 3],
            start: None,
            report: LoadReport::default(),
        })
    }

    /// The FMU's path, as the cell file names it.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// How it has stepped so far.
    pub fn report(&self) -> LoadReport {
        self.report
    }

    fn call_error(&self, call: &'static str, time_s: f64, status: String) -> FmuLoadError {
        FmuLoadError::Call {
            fmu: self.name.clone(),
            call,
            time_s,
            status,
        }
    }

    /// Initialisation at the first plant cycle (FMI 3.0 §4.2.1): the parameters, start time
    /// `time_s`, then step mode.
    fn initialise(&mut self, time_s: f64) -> Result<(), FmuLoadError> {
        // Parameters are set in Instantiated mode, before initialisation (FMI 3.0 §2.3.2).
        if !self.parameters.is_empty() {
            let (vrs, values): (Vec<u32>, Vec<f64>) = self.parameters.iter().copied().unzip();
            self.instance
                .set_float64(&vrs, &values)
                .map_err(|e| self.call_error("fmi3SetFloat64", time_s, format!("{e:?}")))?;
        }
        self.instance
            .enter_initialization_mode(None, time_s, None)
            .map_err(|e| {
                self.call_error("fmi3EnterInitializationMode", time_s, format!("{e:?}"))
            })?;
        self.instance
            .exit_initialization_mode()
            .map_err(|e| self.call_error("fmi3ExitInitializationMode", time_s, format!("{e:?}")))?;
        Ok(())
    }
}

impl ExternalLoad for FmuLoad {
    type Error = FmuLoadError;

    fn plant_step(
        &mut self,
        now: Instant,
        dt_s: f64,
        shaft: Shaft,
    ) -> Result<LoadReaction, FmuLoadError> {
        let start = *self.start.get_or_insert(now);
        let t = now.as_nanos().saturating_sub(start.as_nanos()) as f64 * 1e-9;
        if self.report.steps == 0 {
            self.initialise(t)?;
        }
        for ((input, _), value) in self.inputs.iter().zip(self.input_values.iter_mut()) {
            *value = match input {
                Input::Torque => shaft.motor_torque_nm,
                Input::Speed => shaft.velocity_rad_s,
                Input::Angle => shaft.angle_rad,
            };
        }
        if !self.input_vrs.is_empty() {
            let set = self
                .instance
                .set_float64(&self.input_vrs, &self.input_values);
            set.map_err(|e| self.call_error("fmi3SetFloat64", t, format!("{e:?}")))?;
        }
        let (mut event, mut terminate, mut early, mut last) = (false, false, false, 0.0);
        let wall = WallClock::now();
        let stepped = self.instance.do_step(
            t,
            dt_s,
            true,
            &mut event,
            &mut terminate,
            &mut early,
            &mut last,
        );
        let took = u64::try_from(wall.elapsed().as_nanos()).unwrap_or(u64::MAX);
        stepped.map_err(|e| self.call_error("fmi3DoStep", t, format!("{e:?}")))?;
        if terminate {
            return Err(self.call_error("fmi3DoStep", t, "terminateSimulation".into()));
        }
        self.report.steps += 1;
        self.report.worst_step_ns = self.report.worst_step_ns.max(took);
        if took as f64 > dt_s * 1e9 {
            self.report.slow_steps += 1;
            // The first and then every power of two: reported, never skipped.
            if self.report.slow_steps.is_power_of_two() {
                tracing::warn!(
                    fmu = %self.name,
                    took_us = took / 1000,
                    step_us = dt_s * 1e6,
                    slow_steps = self.report.slow_steps,
                    steps = self.report.steps,
                    "load FMU: a doStep took longer than the virtual time it advanced"
                );
            }
        }
        let read = self
            .instance
            .get_float64(&self.outputs, &mut self.output_values);
        read.map_err(|e| self.call_error("fmi3GetFloat64", t + dt_s, format!("{e:?}")))?;
        let torque_nm = self.output_values.first().copied().unwrap_or(0.0);
        self.report.torque_nm = torque_nm;
        if let Some(p) = self.output_values.get(1) {
            self.report.position = *p;
        }
        let mut reaction = LoadReaction {
            torque_nm,
            switches: [None; 3],
        };
        if !self.switches.is_empty() {
            let read = self
                .instance
                .get_boolean(&self.switch_vrs, &mut self.switch_values);
            read.map_err(|e| self.call_error("fmi3GetBoolean", t + dt_s, format!("{e:?}")))?;
            for ((index, _), level) in self.switches.iter().zip(&self.switch_values) {
                if let (Some(last), Some(out)) = (
                    self.levels.get_mut(*index),
                    reaction.switches.get_mut(*index),
                ) {
                    if *last != Some(*level) {
                        *last = Some(*level);
                        *out = Some(*level);
                    }
                }
            }
        }
        Ok(reaction)
    }
}
