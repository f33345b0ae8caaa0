//! The faults of an EtherCAT line as asked for from outside (the control handle, the REST
//! API, the cell file, scenario steps): a cable pulled and plugged back, a slave switched off
//! and on, a slave's clock off nominal. The chain carries them out (`ecat::line`,
//! `ecat::chain`); these are the words for them.

use serde::{Deserialize, Serialize};

use crate::cell::wire_faults::TimeSpan;

/// One change to a chain's line.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(tag = "action", rename_all = "kebab-case", deny_unknown_fields)]
pub enum LineAction {
    /// The cable behind `after` slaves pulled (0: the master's own cable): frames return from
    /// slave `after`, the slaves behind it see none.
    PullCable { after: usize },
    /// The pulled cable plugged back.
    PlugCable,
    /// Slave `slave` (0 = first from the master) switched off: it and the slaves behind it
    /// drop off the line.
    PowerOff { slave: usize },
    /// Slave `slave` switched on: AL Init, registers at reset, the drive boots.
    PowerOn { slave: usize },
    /// Slave `slave`'s local clock off nominal from now on: `drift_ppm` (its rate error),
    /// `jitter_ns` (each reading off by up to ± that), `seed` (of the jitter's sequence).
    Clock {
        slave: usize,
        #[serde(default)]
        drift_ppm: f64,
        #[serde(default)]
        jitter_ns: u32,
        #[serde(default)]
        seed: u64,
    },
}

impl LineAction {
    /// The ESC's clock error of a [`LineAction::Clock`].
    pub fn clock_error(drift_ppm: f64, jitter_ns: u32, seed: u64) -> ethercat::ClockError {
        ethercat::ClockError {
            // ppm to ppb; a rate beyond ±1 s/s is no oscillator.
            drift_ppb: (drift_ppm * 1000.0).clamp(-1e9, 1e9).round() as i64,
            jitter_ns,
            seed,
        }
    }
}

/// One slave's clock, as set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, utoipa::ToSchema)]
pub struct SlaveClock {
    pub slave: usize,
    pub drift_ppm: f64,
    pub jitter_ns: u32,
}

/// A chain's line as it is.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct LineStatus {
    /// The chain (from 0, in the order of the cell's chains).
    pub chain: usize,
    /// Its network interface.
    pub interface: String,
    pub slaves: usize,
    /// How many slaves a frame passes before it returns (what a master counts).
    pub reached: usize,
    /// Where the cable is pulled, if it is.
    pub cable_pulled_after: Option<usize>,
    /// Slaves without power.
    pub powered_off: Vec<usize>,
    /// Clocks off nominal.
    pub clocks: Vec<SlaveClock>,
    /// Slave AL states (1 Init, 2 Pre-Op, 4 Safe-Op, 8 Op), in line order.
    pub al_states: Vec<u8>,
}

/// Why a line change is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LineControlError {
    #[error("the cell has no EtherCAT chain {0}")]
    NoChain(usize),
    #[error("{0}")]
    Refused(String),
    #[error("the cell loop has stopped")]
    Stopped,
}

/// A line change at a time after the start (the cell file's `[[ethercat_line]]`, carried out
/// by the cell loop on its clock; a scenario step).
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct TimedLineAction {
    /// The chain by its interface; none: the cell's first chain.
    pub interface: Option<String>,
    /// When, from the start ("2s", "150ms"); none: at once.
    pub at: Option<TimeSpan>,
    #[serde(flatten)]
    pub action: LineAction,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn actions_read_as_the_api_writes_them() {
        let a: LineAction = serde_json::from_str(r#"{"action":"pull-cable","after":32}"#).unwrap();
        assert_eq!(a, LineAction::PullCable { after: 32 });
        let a: LineAction =
            serde_json::from_str(r#"{"action":"clock","slave":1,"drift_ppm":50}"#).unwrap();
        assert_eq!(
            a,
            LineAction::Clock {
                slave: 1,
                drift_ppm: 50.0,
                jitter_ns: 0,
                seed: 0
            }
        );
        assert_eq!(LineAction::clock_error(50.0, 0, 0).drift_ppb, 50_000);
        assert!(serde_json::from_str::<LineAction>(r#"{"action":"melt"}"#).is_err());
    }

    #[test]
    fn a_cell_file_plans_line_faults() {
        let f: crate::cell::config::CellFile = toml::from_str(
            r#"
[[ethercat_line]]
at = "2s"
action = "pull-cable"
after = 32

[[ethercat_line]]
interface = "veth1"
action = "clock"
slave = 1
drift_ppm = -20.5
"#,
        )
        .unwrap();
        assert_eq!(f.ethercat_line.len(), 2);
        let a = &f.ethercat_line[0];
        assert_eq!(a.at, Some(TimeSpan(Duration::from_secs(2))));
        assert_eq!(a.action, LineAction::PullCable { after: 32 });
        assert_eq!(f.ethercat_line[1].interface.as_deref(), Some("veth1"));
    }
}
