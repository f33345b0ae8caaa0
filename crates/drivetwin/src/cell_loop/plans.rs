//! The plans of the drives outside the CAN buses (a CMMO-ST on Modbus TCP, an EtherCAT-only
//! drive): a timer of the loop like a drive's step, carried out at its time on the loop's
//! clock before the drives due at that turn step ([`crate::cell::planned`]). A CAN bus
//! carries out its stations' plans itself, in the same way, when the loop polls it.

use crate::cell::diagnostics::Planned;
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

/// The timeline of `plans`, each drive found among the loop's `chains` (joined to the cell's
/// list) and its `modbus_drives`; a drive not in the cell is left out with a warning.
pub(super) fn timeline(
    plans: Vec<OutsidePlans>,
    chains: &[ChainState],
    modbus_drives: usize,
) -> Timeline<(Planee, Planned)> {
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
            timeline.plan(od::Instant::from_millis(ms), (planee, what));
        }
    }
    timeline
}

impl CellLoop {
    /// Carries out the plans due by `t` (the cell's clock).
    pub(super) fn carry_out_plans(&mut self, t: od::Instant) {
        while let Some((planee, what)) = self.plans.take_due(t) {
            let done = match planee {
                Planee::Station(id) => match self.stations.station_mut(id) {
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
