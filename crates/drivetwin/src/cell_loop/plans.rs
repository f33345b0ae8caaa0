//! What the cell file plans for the loop to carry out on its clock: the drives' changes
//! (`[[drive.diagnostic]]`, `[[drive.plant]]`, `[drive.thermal]`) on the cell's one timeline
//! ([`crate::cell::planned`], `CanCell::plan`), and the faults of the EtherCAT lines
//! (`[[ethercat_line]]`, [`crate::cell::ethercat_line`]), which are the loop's chains' links.
//! Both are timers of the loop like a drive's step, carried out at their time before the
//! drives due at that turn step.
//!
//! The drives outside the CAN buses join the cell as the loop starts (an EtherCAT chain's own
//! drives when it joins the cell, the Modbus drives as their front ends join it):
//! [`plan_outside`] puts their plans on the cell's timeline by the station id each then has.

use crate::cell::can_cell::CanCell;
use crate::cell::ethercat_line::{LineAction, TimedLineAction};
use crate::cell::planned::{Locator, OutsidePlans, Timeline};
use crate::modbus_tcp::cell_drive::ModbusDrive;

use super::{CellLoop, ChainState};

/// Plans `plans` on `cell`'s timeline, each drive found among the loop's `chains` (joined to
/// the cell's list) and its `modbus` drives (joined too); a drive not in the cell is left out with a
/// warning.
pub(super) fn plan_outside(
    cell: &mut CanCell,
    plans: Vec<OutsidePlans>,
    chains: &[ChainState],
    modbus: &[ModbusDrive],
) {
    for p in plans {
        let planee = match p.drive {
            Locator::Modbus(k) => modbus.get(k).and_then(ModbusDrive::station),
            Locator::Ethercat { chain, k } => chains.get(chain).and_then(|c| {
                (0..c.chain.len())
                    .filter_map(|i| c.chain.own_station(i))
                    .nth(k)
            }),
        };
        let Some(planee) = planee else {
            tracing::warn!(drive = ?p.drive, "planned changes: the drive is not in the cell");
            continue;
        };
        for (ms, what) in p.plans {
            cell.plan(od::Instant::from_millis(ms), planee, what);
        }
    }
}

/// The timeline of `line_plans`, each line by its chain's interface (chain index, action); a
/// chain not in the cell is left out with a warning.
pub(super) fn line_timeline(
    line_plans: Vec<TimedLineAction>,
    chains: &[ChainState],
) -> Timeline<(usize, LineAction)> {
    let mut timeline = Timeline::default();
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
        timeline.plan(at, (chain, a.action));
    }
    timeline
}

impl CellLoop {
    /// The time of the first plan still to come, the drives' or the lines'.
    pub(super) fn plans_deadline(&self) -> Option<od::Instant> {
        od::time::earliest(self.cell.plans_deadline(), self.line_plans.deadline())
    }

    /// Carries out the plans due by `now`: the drives', then the lines'.
    pub(super) fn carry_out_plans(&mut self, now: std::time::Instant) {
        let t = self.now(now);
        self.cell.carry_out_plans(t);
        while let Some((chain, action)) = self.line_plans.take_due(t) {
            if let Err(e) = self.ethercat_line(chain, Some(action), now) {
                tracing::warn!(chain, ?action, "[[ethercat_line]]: {e}");
            }
        }
    }
}
