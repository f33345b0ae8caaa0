//! The report of a run: every expectation with its name, met or not and why, and the actions
//! the cell refused. The text is the same bit for bit for the same run (times in whole
//! microseconds, no floats).

use std::fmt::Write as _;
use std::time::Duration;

use serde::Serialize;

/// One expectation's outcome.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, utoipa::ToSchema)]
pub struct Outcome {
    pub name: String,
    pub passed: bool,
    /// What was looked for and what was seen.
    pub detail: String,
}

#[derive(Debug, Clone, PartialEq, Eq, Serialize, utoipa::ToSchema)]
pub struct Report {
    pub scenario: String,
    pub passed: bool,
    pub expectations: Vec<Outcome>,
    /// Actions the cell refused (each fails the scenario).
    pub errors: Vec<String>,
    /// Frames seen on the bus during the run.
    pub frames: u64,
}

/// `t` as seconds with six decimals.
pub fn seconds(t: Duration) -> String {
    format!("{}.{:06}s", t.as_secs(), t.subsec_micros())
}

impl Report {
    pub fn text(&self) -> String {
        let met = self.expectations.iter().filter(|o| o.passed).count();
        let mut s = String::new();
        let _ = writeln!(
            s,
            "scenario {}: {} ({met} of {} expectations met, {} frames)",
            self.scenario,
            if self.passed { "PASS" } else { "FAIL" },
            self.expectations.len(),
            self.frames
        );
        for o in &self.expectations {
            let _ = writeln!(
                s,
                "  {}  {}: {}",
                if o.passed { "PASS" } else { "FAIL" },
                o.name,
                o.detail
            );
        }
        for e in &self.errors {
            let _ = writeln!(s, "  ERROR {e}");
        }
        s
    }
}
