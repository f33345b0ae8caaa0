//! What a cell file plans for its drives (`[[drive.diagnostic]]`, `[[drive.plant]]`,
//! `[drive.thermal]`): one [`Timeline`] of the cell ([`super::can_cell::CanCell::plan`]),
//! each change keyed by the station of the drive it is for (its [`StationId`](super::stations::StationId): a drive on a
//! CAN bus, an EtherCAT chain's own, a CMMO-ST on Modbus TCP), carried out on the cell's clock by
//! whatever steps the cell (the cell loop, the virtual clock, the scenario rig, the cell FMU
//! through the rig), as a timer of the cell like a drive's step
//! ([`super::can_cell::CanCell::carry_out_plans`]). A change is carried out with [`on_model`]
//! (a register-image device's through [`on_modbus`]), the functions the control handle's
//! requests use as well.
//!
//! The drives outside the CAN buses join the cell after it is built (an EtherCAT chain's own
//! drives when the chain joins it, the Modbus drives when their front ends join it): their
//! plans are found by [`outside_plans`] with a [`Locator`], which whoever joins them turns
//! into a [`StationId`](super::stations::StationId).

use std::collections::VecDeque;

use drive::drive::diagnostics::DiagnosticError;
use od::Instant;

use super::config::DriveSpec;
use super::device_model::Model;
use super::diagnostics::{set_model, Planned};
use super::modbus_device::ModbusDevice;

/// How the cell finds a drive outside the CAN buses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Locator {
    /// The k-th CMMO-ST on Modbus TCP.
    Modbus(usize),
    /// The k-th own drive of EtherCAT chain `chain` (chains in the order the file names
    /// them).
    Ethercat { chain: usize, k: usize },
}

/// The plans of one drive outside the CAN buses.
#[derive(Debug, Clone)]
pub struct OutsidePlans {
    pub drive: Locator,
    /// (ms on the cell's clock, what), any order.
    pub plans: Vec<(u64, Planned)>,
}

/// The plans of the specs that are not CANopen nodes, with their locators (call before the
/// specs are spent on the buses). `in_loop`: the CMMO-STs run in the cell loop.
pub fn outside_plans(specs: &[DriveSpec], in_loop: bool) -> Vec<OutsidePlans> {
    let mut out = Vec::new();
    let mut modbus = 0;
    let mut chains: Vec<Option<String>> = Vec::new();
    let mut per_chain: Vec<usize> = Vec::new();
    for s in specs {
        // Chains in the order any drive (own or shared) names them, as the cell builds them.
        let chain_at =
            s.ethercat
                .as_ref()
                .map(|chain| match chains.iter().position(|c| c == chain) {
                    Some(at) => at,
                    None => {
                        chains.push(chain.clone());
                        per_chain.push(0);
                        chains.len() - 1
                    }
                });
        let locator = if s.fhpp.is_some() {
            modbus += 1;
            if !in_loop {
                continue;
            }
            Locator::Modbus(modbus - 1)
        } else if let (false, Some(at)) = (s.canopen, chain_at) {
            let Some(k) = per_chain.get_mut(at) else {
                continue;
            };
            *k += 1;
            Locator::Ethercat {
                chain: at,
                k: *k - 1,
            }
        } else {
            continue;
        };
        let plans: Vec<(u64, Planned)> = s
            .diagnostics
            .iter()
            .map(|p| (p.at_ms, Planned::Diagnostic(p.clone())))
            .chain(s.physics.iter().map(|(t, c)| (*t, Planned::Physics(*c))))
            .collect();
        if !plans.is_empty() {
            out.push(OutsidePlans {
                drive: locator,
                plans,
            });
        }
    }
    out
}

/// Changes planned on the cell's clock (`T`: what, and for which drive), in time order
/// (those of one time in the order they were planned).
#[derive(Debug)]
pub struct Timeline<T> {
    plans: VecDeque<(Instant, T)>,
}

impl<T> Default for Timeline<T> {
    fn default() -> Self {
        Timeline {
            plans: VecDeque::new(),
        }
    }
}

impl<T> Timeline<T> {
    /// Plans `what` at `at`.
    pub fn plan(&mut self, at: Instant, what: T) {
        let after = self.plans.partition_point(|(t, _)| *t <= at);
        self.plans.insert(after, (at, what));
    }

    /// The time of the first change still to come.
    pub fn deadline(&self) -> Option<Instant> {
        self.plans.front().map(|(t, _)| *t)
    }

    /// The first change due by `now`, taken off the timeline.
    pub fn take_due(&mut self, now: Instant) -> Option<T> {
        if self.deadline()? > now {
            return None;
        }
        self.plans.pop_front().map(|(_, what)| what)
    }

    /// The first change due by `now` for which `mine` holds, taken off the timeline (the
    /// others stay, in their order).
    pub fn take_due_if(&mut self, now: Instant, mine: impl Fn(&T) -> bool) -> Option<T> {
        let at = self
            .plans
            .iter()
            .take_while(|(t, _)| *t <= now)
            .position(|(_, what)| mine(what))?;
        self.plans.remove(at).map(|(_, what)| what)
    }

    pub fn is_empty(&self) -> bool {
        self.plans.is_empty()
    }
}

/// Why a planned change could not be carried out (the run goes on; the cell logs it).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PlanError {
    #[error("diagnostic message: {0:?}")]
    Diagnostic(DiagnosticError),
    #[error("the drive is not in the cell")]
    NoDrive,
    #[error("no simulated plant")]
    NoPlant,
    #[error("no input for switch {0}")]
    NoSwitch(&'static str),
}

/// Carries out `what` on a drive model of the cell (a CiA 402 drive's engine and plant).
pub fn on_model(model: &mut Model, what: &Planned) -> Result<(), PlanError> {
    if let Some(image) = model.register_image_mut() {
        return on_modbus(image.device_mut(), what);
    }
    match what {
        Planned::Diagnostic(p) => set_model(model, &p.number, p.action)
            .map(|_| ())
            .map_err(PlanError::Diagnostic),
        Planned::Physics(change) => {
            let d = model.drive_mut().ok_or(PlanError::NoPlant)?;
            super::control::apply_physics(d, *change)
                .map(|_| ())
                .map_err(PlanError::NoSwitch)
        }
    }
}

/// Carries out `what` on a drive served over Modbus TCP (the CMMO-ST).
pub fn on_modbus(device: &mut dyn ModbusDevice, what: &Planned) -> Result<(), PlanError> {
    match what {
        Planned::Diagnostic(p) => device
            .set_diagnostic(&p.number, p.action)
            .map(|_| ())
            .map_err(PlanError::Diagnostic),
        Planned::Physics(change) => device
            .physics(*change)
            .map(|_| ())
            .map_err(PlanError::NoSwitch),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell::control::PhysicsChange;

    fn ambient(c: f64) -> Planned {
        Planned::Physics(PhysicsChange::Ambient(c))
    }

    #[test]
    fn changes_come_in_time_order_and_planned_order_within_a_time() {
        let mut t = Timeline::default();
        t.plan(Instant::from_millis(50), (1, ambient(1.0)));
        t.plan(Instant::from_millis(20), (2, ambient(2.0)));
        t.plan(Instant::from_millis(50), (3, ambient(3.0)));
        assert_eq!(t.deadline(), Some(Instant::from_millis(20)));
        assert_eq!(t.take_due(Instant::from_millis(19)), None);
        assert_eq!(
            t.take_due(Instant::from_millis(20)),
            Some((2, ambient(2.0)))
        );
        assert_eq!(t.take_due(Instant::from_millis(49)), None);
        let now = Instant::from_millis(60);
        assert_eq!(t.take_due(now), Some((1, ambient(1.0))));
        assert_eq!(t.take_due(now), Some((3, ambient(3.0))));
        assert_eq!(t.take_due(now), None);
        assert!(t.is_empty());
    }

    #[test]
    fn a_change_taken_by_its_drive_leaves_the_others_in_order() {
        let mut t = Timeline::default();
        t.plan(Instant::from_millis(10), (1, ambient(1.0)));
        t.plan(Instant::from_millis(10), (2, ambient(2.0)));
        t.plan(Instant::from_millis(10), (1, ambient(3.0)));
        t.plan(Instant::from_millis(30), (2, ambient(4.0)));
        let now = Instant::from_millis(20);
        assert_eq!(
            t.take_due_if(now, |(d, _)| *d == 2),
            Some((2, ambient(2.0)))
        );
        assert_eq!(t.take_due_if(now, |(d, _)| *d == 2), None, "4.0 is not due");
        assert_eq!(t.take_due(now), Some((1, ambient(1.0))));
        assert_eq!(t.take_due(now), Some((1, ambient(3.0))));
        assert_eq!(t.deadline(), Some(Instant::from_millis(30)));
    }
}
