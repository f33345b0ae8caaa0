//! Scenarios: a TOML timeline of actions and expectations run against a cell, on the virtual
//! clock for CI (`drivetwin scenario FILE`: the same file gives the same report and trace bit
//! for bit) or on a live cell through its control handle (`POST /api/scenarios`).
//!
//! - [`file`](mod@file): the file format and what each step means;
//! - [`runner`]: the timeline against a [`runner::Rig`];
//! - [`virtual_rig`]: the rig of the virtual clock (the CANopen drives of the cell's buses);
//! - [`live`]: the rig of a running cell;
//! - [`samples`]: a virtual rig sampled at a fixed period (`--samples`);
//! - [`report`]: the pass / fail report.

pub mod file;
pub mod live;
pub mod report;
pub mod runner;
pub mod samples;
pub mod virtual_rig;

pub use file::{Scenario, ScenarioError};
pub use report::Report;
