//! What the cell file plans for the loop to carry out: the changes of the drives outside the
//! CAN buses (a CMMO-ST on Modbus TCP, an EtherCAT-only drive; [`crate::cell::planned`]) and
//! the faults of the EtherCAT lines (`[[ethercat_line]]`, [`crate::cell::ethercat_line`]). A
//! timer of the loop like a drive's step, carried out at its time on the loop's clock before
//! the drives due at that turn step. A CAN bus carries out its stations' plans itself, in the
//! same way, when the loop polls it.

use crate::cell::diagnostics::Planned;
use crate::cell::ethercat_line::{LineAction, TimedLineAction};
use crate::cell::planned::{self, Locator, OutsidePlans, Timeline};
use crate::cell::stations::StationId;

use super::{CellLoop, ChainState};

/// The drive a plan of the loop is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Planee {
    /// A station of the cell's list (an EtherCAT chain's own drive).
    Station(StationId),
    /// A Modbus drive, by its index in the loop's list.
    Modbus(usize),
}

/// A change the loop carries out.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum LoopPlan {
    /// A drive's change.
    Drive(Planee, Planned),
    /// A fault of chain `chain`'s line.
    Line(usize, LineAction),
}

/// The timeline of `plans` and `line_plans`, each drive found among the loop's `chains`
/// (joined to the cell's list) and its `modbus_drives`, each line by its chain's interface;
/// a drive or chain not in the cell is left out with a warning.
pub(super) fn timeline(
    plans: Vec<OutsidePlans>,
    line_plans: Vec<TimedLineAction>,
    chains: &[ChainState],
    modbus_drives: usize,
) -> Timeline<LoopPlan> {
    let mut timeline = Timeline::default();
    for p in plans {
        let planee = match p.drive {
            Locator::Modbus(k) => (k < modbus_drives).then_some(Planee::Modbus(k)),
            Locator::Ethercat { chain, k } => chains.get(chain).and_then(|c| {
                (0..c.chain.len())
                    .filter_map(|i| c.chain.own_station(i))
                    .nth(k)
                    .map(Planee::Station)
            }),
        };
        let Some(planee) = planee else {
            tracing::warn!(drive = ?p.drive, "planned changes: the drive is not in the cell");
            continue;
        };
        for (ms, what) in p.plans {
            timeline.plan(od::Instant::from_millis(ms), LoopPlan::Drive(planee, what));
        }
    }
    for a in line_plans {
        // The chain on `interface`; none: the first.
        let chain = chains.iter().position(|c| {
            a.interface
                .as_deref()
                .is_none_or(|name| c.interface() == name)
        });
        let Some(chain) = chain else {
            tracing::warn!(interface = ?a.interface, "[[ethercat_line]]: no such chain");
            continue;
        };
        let at = a.at.map_or(std::time::Duration::ZERO, |t| t.0);
        let at = od::Instant::from_nanos(u64::try_from(at.as_nanos()).unwrap_or(u64::MAX));
        timeline.plan(at, LoopPlan::Line(chain, a.action));
    }
    timeline
}

impl CellLoop {
    /// Carries out the plans due by `now`.
    pub(super) fn carry_out_plans(&mut self, now: std::time::Instant) {
        let t = self.now(now);
        while let Some(plan) = self.plans.take_due(t) {
            let (planee, what) = match plan {
                LoopPlan::Drive(planee, what) => (planee, what),
                LoopPlan::Line(chain, action) => {
                    if let Err(e) = self.ethercat_line(chain, Some(action), now) {
                        tracing::warn!(chain, ?action, "[[ethercat_line]]: {e}");
                    }
                    continue;
                }
            };
            let done = match planee {
                Planee::Station(id) => match self.cell.stations.station_mut(id) {
                    Some(s) => planned::on_model(&mut s.model, &what),
                    None => Err(planned::PlanError::NoDrive),
                },
                Planee::Modbus(k) => match self.modbus.get_mut(k) {
                    Some(m) => planned::on_modbus(m.device_mut(), &what),
                    None => Err(planned::PlanError::NoDrive),
                },
            };
            if let Err(e) = done {
                tracing::warn!(?planee, ?what, "planned change: {e}");
            }
        }
    }
}
