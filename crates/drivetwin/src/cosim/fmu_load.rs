//! A co-simulation FMU as a drive's load (FMI 3.0 §4 "Co-Simulation", FMI 2.0 §4 "FMI for
//! Co-Simulation"): imported with the `fmi` crate, instantiated once, and stepped by the
//! drive's plant cycles on the cell's clock ([`drive::drive::external_load`]).
//!
//! Each plant cycle of `dt` at cell time `t`: the mapped inputs are set from the shaft as it
//! is at `t` (`fmi3SetFloat64`, `fmi2SetReal`), `fmi3DoStep(t, dt)` (`fmi2DoStep`) advances
//! the FMU to `t + dt`, and the load torque, the position and the switch outputs are read
//! (`fmi3GetFloat64` / `fmi2GetReal`, `fmi3GetBoolean` / `fmi2GetBoolean`). The communication points are the cell clock's nanoseconds as seconds,
//! so the FMU sees the same times, and gives the same values, on every run; the wall time a
//! step takes is measured only to report a slow FMU (a `doStep` longer than the virtual time
//! it advances, which a real-time cell cannot keep up with), never to skip a step.
//!
//! Refused when the cell is built: an archive that does not open, an FMU that is not FMI 2.0
//! or 3.0 co-simulation, a mapped variable the FMU lacks (named) or of the wrong type or causality.
//! An FMU call that returns an error stops the load: [`FmuLoad`] returns the error, and the
//! cell stops with it.

use std::path::Path;
use std::time::Instant as WallClock;

use drive::drive::external_load::{ExternalLoad, LoadReaction, Shaft, SWITCHES};
use drive::drive::named_switches::NamedSwitch;
use od::Instant;

use super::load_instance::{LoadInstance, OpenError, Role, Type};
use super::mapping::LoadMapping;

/// Why a load FMU was refused or stopped.
#[derive(Debug, Clone, thiserror::Error)]
pub enum FmuLoadError {
    #[error("{fmu}: {message}")]
    Import { fmu: String, message: String },
    #[error("{fmu}: FMI {version} is not supported (an FMI 2.0 or 3.0 co-simulation FMU is)")]
    Version { fmu: String, version: String },
    #[error("{fmu}: no co-simulation interface (only co-simulation FMUs are loads)")]
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
    #[error("{fmu}: the {device} has no `{switch}` input (its one switch input is `home`)")]
    NoInput {
        fmu: String,
        device: &'static str,
        switch: &'static str,
    },
    #[error("{fmu}: `{name}` is not a switch (home, limit_positive, limit_negative)")]
    UnknownSwitch { fmu: String, name: String },
    #[error("{fmu}: {call} at t = {time_s} s returned {status}{}", said(log.as_deref()))]
    Call {
        fmu: String,
        call: &'static str,
        time_s: f64,
        status: String,
        /// What the FMU said through its logger in the call ([`super::fmu_log`]).
        log: Option<String>,
    },
}

/// The FMU's own message after a failed call's status, when it said one.
fn said(log: Option<&str>) -> String {
    match log {
        Some(m) => format!(": {m}"),
        None => " (the FMU's log says why)".into(),
    }
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

/// The value of a mapped variable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LoadValue {
    Float64(f64),
    Boolean(bool),
}

/// A load FMU, instantiated and mapped.
pub struct FmuLoad {
    instance: LoadInstance,
    name: String,
    /// The table it was coupled with.
    mapping: LoadMapping,
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
    /// The parameters to set before initialisation: value references and values.
    parameter_vrs: Vec<u32>,
    parameter_values: Vec<f64>,
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
    instance: &LoadInstance,
    fmu: &str,
    role: &str,
    name: &str,
    ty: Type,
    causality: Role,
) -> Result<u32, FmuLoadError> {
    let Some(v) = instance.variable(name) else {
        return Err(FmuLoadError::MissingVariable {
            fmu: fmu.into(),
            role: role.into(),
            name: name.into(),
        });
    };
    let needed = match (ty, causality) {
        (Type::Float64, Role::Input) => "a Float64 input",
        (Type::Float64, Role::Parameter) => "a Float64 parameter",
        (Type::Float64, _) => "a Float64 output",
        (_, _) => "a Boolean output",
    };
    if v.ty != ty || v.causality != causality {
        return Err(FmuLoadError::WrongVariable {
            fmu: fmu.into(),
            role: role.into(),
            name: name.into(),
            found: v.found,
            needed,
        });
    }
    Ok(v.value_reference)
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
        // Only a regular file is an archive (a device or a pipe would be read without end).
        if !path.is_file() {
            return Err(FmuLoadError::Import {
                fmu,
                message: "no such file (an .fmu archive)".into(),
            });
        }
        let mut instance = LoadInstance::open(&path, instance).map_err(|e| match e {
            OpenError::Import(message) => FmuLoadError::Import {
                fmu: fmu.clone(),
                message,
            },
            OpenError::Version(version) => FmuLoadError::Version {
                fmu: fmu.clone(),
                version,
            },
            OpenError::NotCoSimulation => FmuLoadError::NotCoSimulation { fmu: fmu.clone() },
        })?;
        let mut inputs = Vec::new();
        for (role, name) in mapping.inputs() {
            let vr = variable(&instance, &fmu, role, name, Type::Float64, Role::Input)?;
            let input = match role {
                "torque" => Input::Torque,
                "speed" => Input::Speed,
                _ => Input::Angle,
            };
            inputs.push((input, vr));
        }
        let mut outputs = vec![variable(
            &instance,
            &fmu,
            "load_torque",
            &mapping.load_torque,
            Type::Float64,
            Role::Output,
        )?];
        if let Some(p) = &mapping.position {
            outputs.push(variable(
                &instance,
                &fmu,
                "position",
                p,
                Type::Float64,
                Role::Output,
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
            let vr = variable(&instance, &fmu, switch, name, Type::Boolean, Role::Output)?;
            switches.push((index, vr));
        }
        let mut parameters = Vec::new();
        for (name, value) in &mapping.parameters {
            let vr = variable(
                &instance,
                &fmu,
                "parameter",
                name,
                Type::Float64,
                Role::Parameter,
            )?;
            parameters.push((vr, *value));
        }
        instance.reserve_booleans(switches.len());
        Ok(FmuLoad {
            instance,
            name: fmu,
            mapping: mapping.clone(),
            input_values: vec![0.0; inputs.len()],
            output_values: vec![0.0; outputs.len()],
            switch_values: vec![false; switches.len()],
            input_vrs: inputs.iter().map(|&(_, vr)| vr).collect(),
            switch_vrs: switches.iter().map(|&(_, vr)| vr).collect(),
            inputs,
            outputs,
            switches,
            parameter_vrs: parameters.iter().map(|&(vr, _)| vr).collect(),
            parameter_values: parameters.iter().map(|&(_, v)| v).collect(),
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
            log: super::fmu_log::take(),
        }
    }

    /// "2.0" or "3.0".
    pub fn fmi_version(&self) -> &'static str {
        self.instance.fmi_version()
    }

    /// The table it was coupled with.
    pub fn mapping(&self) -> &LoadMapping {
        &self.mapping
    }

    /// The switches it drives.
    pub fn switches(&self) -> impl Iterator<Item = NamedSwitch> + '_ {
        self.switches
            .iter()
            .filter_map(|&(index, _)| SWITCHES.get(index).copied())
    }

    /// Each mapped variable with its value as last exchanged (the inputs as set, the outputs
    /// as read after the last step; zero and false before the first): (role, variable, value).
    pub fn values(&self) -> Vec<(String, String, LoadValue)> {
        let m = &self.mapping;
        let mut out: Vec<(String, String, LoadValue)> = m
            .inputs()
            .zip(&self.input_values)
            .map(|((role, name), v)| (role.to_owned(), name.to_owned(), LoadValue::Float64(*v)))
            .collect();
        let outputs = std::iter::once(("load_torque", Some(&m.load_torque)))
            .chain(std::iter::once(("position", m.position.as_ref())))
            .filter_map(|(role, name)| Some((role, name?)));
        for ((role, name), v) in outputs.zip(&self.output_values) {
            out.push((role.to_owned(), name.clone(), LoadValue::Float64(*v)));
        }
        // In the table's order, as `open` mapped them.
        for ((switch, name), v) in m.switches.iter().zip(&self.switch_values) {
            out.push((switch.clone(), name.clone(), LoadValue::Boolean(*v)));
        }
        out
    }

    /// Initialisation at the first plant cycle (FMI 3.0 §4.2.1, FMI 2.0 §4.2.4): the
    /// parameters (in Instantiated mode, FMI 3.0 §2.3.2), start time `time_s`, then step mode.
    fn initialise(&mut self, time_s: f64) -> Result<(), FmuLoadError> {
        let init = self
            .instance
            .initialise(&self.parameter_vrs, &self.parameter_values, time_s);
        init.map_err(|(call, status)| self.call_error(call, time_s, status))
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
        // A failure below says what the FMU said in it, not before.
        super::fmu_log::clear();
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
            set.map_err(|(call, status)| self.call_error(call, t, status))?;
        }
        let wall = WallClock::now();
        let stepped = self.instance.do_step(t, dt_s);
        let took = u64::try_from(wall.elapsed().as_nanos()).unwrap_or(u64::MAX);
        stepped.map_err(|(call, status)| self.call_error(call, t, status))?;
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
        read.map_err(|(call, status)| self.call_error(call, t + dt_s, status))?;
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
            read.map_err(|(call, status)| self.call_error(call, t + dt_s, status))?;
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
