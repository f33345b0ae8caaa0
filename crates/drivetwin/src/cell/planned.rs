//! What a cell file plans for the drives outside the CAN cells — a CMMO-ST on Modbus TCP, an
//! EtherCAT-only drive — (`[[drive.diagnostic]]`, `[[drive.plant]]`, `[drive.thermal]`):
//! carried out through the cell loop's control handle at their times, on a thread of their
//! own, as a console would. The CAN drives' plans run inside their [`super::can_segment::CanSegment`]
//! (`CanSegment::plan_diagnostic`, `CanSegment::plan_physics`), on the virtual clock too.
//!
//! Decision: these drives run on the real clock only (the cell loop refuses the virtual one
//! for them), so a time here is wall time since the loop started, to the thread's sleep
//! resolution (~1 ms).

use std::time::{Duration, Instant};

use super::config::DriveSpec;
use super::control::{ControlHandle, Interface};
use super::diagnostics::{Action, Planned};

/// How the control handle's list finds the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Locator {
    /// The k-th CMMO-ST on Modbus TCP.
    Modbus(usize),
    /// The k-th own drive of EtherCAT chain `chain` (chains in the order the file names
    /// them).
    Ethercat { chain: usize, k: usize },
}

/// The plans of one drive outside the CAN cells.
#[derive(Debug, Clone)]
pub struct OutsidePlans {
    pub drive: Locator,
    /// (ms, what), any order.
    pub plans: Vec<(u64, Planned)>,
}

/// The plans of the specs that are not CANopen nodes, with their locators (call before the
/// specs are spent on the cells). `in_loop`: the CMMO-STs run in the cell loop.
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

/// The index in [`ControlHandle::drives`] of `locator`.
fn index_of(handle: &ControlHandle, locator: Locator) -> Option<usize> {
    let drives = handle.drives().ok()?;
    match locator {
        Locator::Modbus(k) => drives
            .iter()
            .filter(|d| d.interface == Interface::ModbusTcp)
            .nth(k)
            .map(|d| d.index),
        Locator::Ethercat { chain, k } => drives
            .iter()
            .filter(|d| matches!(d.interface, Interface::Ethercat { chain: c, .. } if c == chain))
            .nth(k)
            .map(|d| d.index),
    }
}

/// Carries out `plans` through `handle` at their times from now, on a thread of its own (none
/// for no plans).
pub fn start(
    handle: ControlHandle,
    plans: Vec<OutsidePlans>,
) -> std::io::Result<Option<std::thread::JoinHandle<()>>> {
    if plans.is_empty() {
        return Ok(None);
    }
    let start = Instant::now();
    std::thread::Builder::new()
        .name("cell-plans".into())
        .spawn(move || run(&handle, plans, start))
        .map(Some)
}

fn run(handle: &ControlHandle, plans: Vec<OutsidePlans>, start: Instant) {
    let mut timeline: Vec<(u64, Locator, Planned)> = plans
        .into_iter()
        .flat_map(|p| p.plans.into_iter().map(move |(t, what)| (t, p.drive, what)))
        .collect();
    timeline.sort_by_key(|(t, _, _)| *t);
    for (t, locator, what) in timeline {
        let due = start + Duration::from_millis(t);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        let Some(drive) = index_of(handle, locator) else {
            tracing::warn!(?locator, "planned change: the drive is not in the cell");
            continue;
        };
        let done = match &what {
            Planned::Diagnostic(p) => match p.action {
                Action::Raise => handle.raise_diagnostic(drive, &p.number).map(|_| ()),
                Action::Clear => handle.clear_diagnostic(drive, &p.number).map(|_| ()),
            },
            Planned::Physics(c) => handle.physics(drive, *c).map(|_| ()),
        };
        match done {
            Ok(()) => {}
            // The cell has stopped: nothing more to do.
            Err(super::control::ControlError::Stopped) => return,
            Err(e) => tracing::warn!(drive, ?what, "planned change: {e}"),
        }
    }
}
