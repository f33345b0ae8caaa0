//! The faults of an EtherCAT line carried out on the loop ([`crate::cell::ethercat_line`]):
//! the chain changes between two frames, so every frame sees a line either whole or cut.

use std::time::Instant;

use super::{CellLoop, ChainState};
use crate::cell::ethercat_line::{LineAction, LineControlError, LineStatus, SlaveClock};

impl CellLoop {
    /// Applies `action` (if any) to chain `chain` and returns its line's state.
    pub(super) fn ethercat_line(
        &mut self,
        chain: usize,
        action: Option<LineAction>,
        now: Instant,
    ) -> Result<LineStatus, LineControlError> {
        let t = self.now(now);
        let state = self
            .chains
            .get_mut(chain)
            .ok_or(LineControlError::NoChain(chain))?;
        let refused = |e: &dyn std::fmt::Display| LineControlError::Refused(e.to_string());
        let c = &mut state.chain;
        match action {
            None => {}
            Some(LineAction::PullCable { after }) => {
                c.pull_cable(after).map_err(|e| refused(&e))?
            }
            Some(LineAction::PlugCable) => c.plug_cable(),
            Some(LineAction::PowerOff { slave }) => c.power_off(slave).map_err(|e| refused(&e))?,
            Some(LineAction::PowerOn { slave }) => c
                .power_on(slave, t, &mut self.cell)
                .map_err(|e| refused(&e))?,
            Some(LineAction::Clock {
                slave,
                drift_ppm,
                jitter_ns,
                seed,
            }) => c
                .set_clock_error(
                    slave,
                    t,
                    LineAction::clock_error(drift_ppm, jitter_ns, seed),
                )
                .map_err(|e| refused(&e))?,
        }
        if let Some(a) = action {
            tracing::info!(chain, action = ?a, "EtherCAT line");
        }
        Ok(line_status(chain, state))
    }
}

/// What the API shows of a chain's line.
fn line_status(index: usize, state: &ChainState) -> LineStatus {
    let c = &state.chain;
    let line = c.line();
    let clocks = (0..c.len())
        .filter_map(|i| {
            let e = c.esc(i)?.clock_error();
            (!e.is_none()).then_some(SlaveClock {
                slave: i,
                drift_ppm: e.drift_ppb as f64 / 1000.0,
                jitter_ns: e.jitter_ns,
            })
        })
        .collect();
    LineStatus {
        chain: index,
        interface: state.interface().to_owned(),
        slaves: c.len(),
        reached: line.reach(c.len()),
        cable_pulled_after: line.cable_pulled_after(),
        powered_off: line.powered_off().collect(),
        clocks,
        al_states: (0..c.len())
            .filter_map(|i| c.esc(i).map(|e| e.al_state() as u8))
            .collect(),
    }
}
