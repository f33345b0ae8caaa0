//! One instance of the cell FMU: the cell file's CANopen drives on the virtual clock
//! ([`VirtualRig`]), stepped by the importer.
//!
//! A `doStep(t, h)` does, in this order: the inputs set since the last step act at `t` (a load
//! torque as a scenario's `load`, a digital input as its `din`), the timeline's actions due
//! in `[t, t + h)` each at its time, then the cell runs to `t + h` from deadline to deadline
//! as `drivetwin scenario` runs it. Times are the clock's nanoseconds (`t` rounded to the
//! nanosecond), so the same inputs at the same times give the same outputs bit for bit, and
//! the same as the scenario with those inputs as its steps.

use std::path::Path;
use std::time::Duration;

use crate::cell::config::CellFile;
use crate::cell::Vendors;
use crate::scenario::file::{Action, StepKind};
use crate::scenario::runner::Rig;
use crate::scenario::virtual_rig::{Probe, VirtualRig};
use crate::scenario::Scenario;

use super::variables::{Role, Variables, DIGITAL_INPUTS};
use super::{CellFmuError, CELL_FILE, TIMELINE_FILE};

/// What the importer set for a drive, and what has acted of it.
#[derive(Debug, Clone, Default)]
struct Inputs {
    load_torque: f64,
    /// The load torque that acted last (none before the first step).
    load_applied: Option<f64>,
    din: [Option<bool>; DIGITAL_INPUTS as usize],
    din_applied: [Option<bool>; DIGITAL_INPUTS as usize],
}

/// A cell stepped by an FMI importer.
pub struct CellInstance {
    rig: VirtualRig,
    variables: Variables,
    /// The timeline's actions in time order, and how many have been done.
    timeline: Vec<(Duration, Action)>,
    done: usize,
    inputs: Vec<Inputs>,
    outputs: Vec<Probe>,
    /// The virtual clock, ns.
    now: u64,
}

impl CellInstance {
    /// The cell of `resources/cell.toml`, with the actions of `resources/timeline.toml` when
    /// there is one, booted at 0.
    pub fn from_resources(
        resources: &Path,
        vendors: Vendors,
    ) -> Result<CellInstance, CellFmuError> {
        let cell_path = resources.join(CELL_FILE);
        let cell = CellFile::load(&cell_path).map_err(|e| CellFmuError::Cell(e.to_string()))?;
        let timeline_path = resources.join(TIMELINE_FILE);
        let timeline = if timeline_path.exists() {
            let text =
                std::fs::read_to_string(&timeline_path).map_err(|source| CellFmuError::Io {
                    path: timeline_path.clone(),
                    source,
                })?;
            Some(
                Scenario::parse(&text, TIMELINE_FILE, None)
                    .map_err(|e| CellFmuError::Timeline(e.to_string()))?,
            )
        } else {
            None
        };
        CellInstance::new(&cell, timeline.as_ref(), vendors)
    }

    /// `cell`, with `timeline`'s actions (its expectations are not checked here).
    pub fn new(
        cell: &CellFile,
        timeline: Option<&Scenario>,
        vendors: Vendors,
    ) -> Result<CellInstance, CellFmuError> {
        let rig = VirtualRig::new(cell, vendors).map_err(|e| CellFmuError::Cell(e.to_string()))?;
        let variables = Variables::new(rig.nodes())?;
        let timeline = timeline
            .map(|s| {
                s.steps
                    .iter()
                    .filter_map(|(at, k)| match k {
                        StepKind::Act(a) => Some((*at, a.clone())),
                        StepKind::Expect { .. } => None,
                    })
                    .collect()
            })
            .unwrap_or_default();
        let n = variables.nodes.len();
        let mut instance = CellInstance {
            rig,
            variables,
            timeline,
            done: 0,
            inputs: vec![Inputs::default(); n],
            outputs: vec![Probe::default(); n],
            now: 0,
        };
        instance.refresh();
        Ok(instance)
    }

    /// The FMU's variables.
    pub fn variables(&self) -> &Variables {
        &self.variables
    }

    /// The virtual clock, s.
    pub fn time(&self) -> f64 {
        Duration::from_nanos(self.now).as_secs_f64()
    }

    fn refresh(&mut self) {
        for (out, node) in self.outputs.iter_mut().zip(&self.variables.nodes) {
            if let Ok(p) = self.rig.probe(*node) {
                *out = p;
            }
        }
    }

    fn find(&self, vr: u32) -> Result<(usize, Role), CellFmuError> {
        self.variables
            .find(vr)
            .ok_or(CellFmuError::UnknownVariable(vr))
    }

    pub fn get_float64(&self, vr: u32) -> Result<f64, CellFmuError> {
        let (drive, role) = self.find(vr)?;
        let out = self.outputs.get(drive).copied().unwrap_or_default();
        match role {
            Role::LoadTorque => Ok(self.inputs.get(drive).map_or(0.0, |i| i.load_torque)),
            Role::Position => Ok(out.position_rad),
            Role::Velocity => Ok(out.velocity_rad_s),
            Role::Current => Ok(out.current_a),
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn set_float64(&mut self, vr: u32, value: f64) -> Result<(), CellFmuError> {
        match self.find(vr)? {
            (drive, Role::LoadTorque) => {
                if let Some(i) = self.inputs.get_mut(drive) {
                    i.load_torque = value;
                }
                Ok(())
            }
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn get_boolean(&self, vr: u32) -> Result<bool, CellFmuError> {
        match self.find(vr)? {
            (drive, Role::DigitalInput(k)) => Ok(self
                .inputs
                .get(drive)
                .and_then(|i| i.din.get(usize::from(k)).copied().flatten())
                .unwrap_or(false)),
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn set_boolean(&mut self, vr: u32, value: bool) -> Result<(), CellFmuError> {
        match self.find(vr)? {
            (drive, Role::DigitalInput(k)) => {
                if let Some(slot) = self
                    .inputs
                    .get_mut(drive)
                    .and_then(|i| i.din.get_mut(usize::from(k)))
                {
                    *slot = Some(value);
                }
                Ok(())
            }
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn get_uint16(&self, vr: u32) -> Result<u16, CellFmuError> {
        match self.find(vr)? {
            (drive, Role::Statusword) => Ok(self.outputs.get(drive).map_or(0, |o| o.statusword)),
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn get_int32(&self, vr: u32) -> Result<i32, CellFmuError> {
        match self.find(vr)? {
            (drive, Role::PositionActual) => {
                Ok(self.outputs.get(drive).map_or(0, |o| o.position_actual))
            }
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    /// `fmi3DoStep(t, h)`: the inputs act at `t`, the timeline's actions in `[t, t + h)`, the
    /// cell runs to `t + h`.
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), CellFmuError> {
        let start = nanos(t)?;
        let end = nanos(t + h)?;
        if start != self.now {
            return Err(CellFmuError::NotAtTime {
                given: t,
                at: self.time(),
            });
        }
        let mut ignore = |_: usize, _: Duration, _: &canopen::CanFrame| {};
        self.apply_inputs(&mut ignore)?;
        while let Some((at, action)) = self.timeline.get(self.done) {
            let at_ns = u64::try_from(at.as_nanos()).unwrap_or(u64::MAX);
            if at_ns >= end {
                break;
            }
            if at_ns > self.now {
                self.rig.run_until(*at, &mut ignore);
            }
            // A refused action is the timeline's mistake, as in a scenario's report: logged.
            if let Err(e) = self.rig.act(action, &mut ignore) {
                tracing::warn!(at = ?at, "timeline action refused: {e}");
            }
            self.done += 1;
        }
        self.rig.run_until(Duration::from_nanos(end), &mut ignore);
        self.now = end;
        self.refresh();
        match self.rig.stopped() {
            Some(why) => Err(CellFmuError::Stopped {
                at: self.time(),
                why,
            }),
            None => Ok(()),
        }
    }

    fn apply_inputs(
        &mut self,
        seen: &mut dyn FnMut(usize, Duration, &canopen::CanFrame),
    ) -> Result<(), CellFmuError> {
        for (drive, node) in self.variables.nodes.iter().enumerate() {
            let Some(i) = self.inputs.get_mut(drive) else {
                continue;
            };
            if i.load_applied != Some(i.load_torque) {
                let torque_nm = i.load_torque;
                self.rig
                    .act(
                        &Action::Load {
                            node: Some(*node),
                            torque_nm,
                        },
                        seen,
                    )
                    .map_err(|e| CellFmuError::Cell(format!("node {node}: load torque: {e}")))?;
                i.load_applied = Some(torque_nm);
            }
            for (k, (want, applied)) in i.din.iter().zip(i.din_applied.iter_mut()).enumerate() {
                let (Some(level), false) = (*want, *want == *applied) else {
                    continue;
                };
                let din = u8::try_from(k).unwrap_or(0);
                self.rig
                    .act(
                        &Action::Input {
                            node: Some(*node),
                            din,
                            level,
                        },
                        seen,
                    )
                    .map_err(|e| CellFmuError::Cell(format!("node {node}: din{din}: {e}")))?;
                *applied = Some(level);
            }
        }
        Ok(())
    }
}

/// Seconds as the clock's nanoseconds.
fn nanos(seconds: f64) -> Result<u64, CellFmuError> {
    let ns = (seconds * 1e9).round();
    if !ns.is_finite() || ns < 0.0 || ns > u64::MAX as f64 {
        return Err(CellFmuError::BadTime(seconds));
    }
    Ok(ns as u64)
}
