//! `drivetwin scenario FILE`: a scenario on the virtual clock, its report, its exit code.

use drivetwin::scenario::runner;
use drivetwin::scenario::virtual_rig::VirtualRig;
use drivetwin::scenario::Scenario;

use super::CommandError;
use crate::cli::ScenarioArgs;

pub(crate) fn scenario(args: ScenarioArgs) -> Result<(), CommandError> {
    let s = Scenario::load(&args.file).map_err(|e| CommandError::Usage(e.to_string()))?;
    let cell = s.cell.as_ref().ok_or_else(|| {
        CommandError::Usage(format!(
            "{}: no cell (`cell = \"cell.toml\"` or a [cell] table)",
            args.file.display()
        ))
    })?;
    let mut rig = VirtualRig::new(cell, drivetwin::vendors::CELL_SECTIONS)
        .map_err(|e| CommandError::Usage(e.to_string()))?;
    if let Some(path) = &args.trace {
        rig.trace_to(path)
            .map_err(super::io(format!("trace {}", path.display())))?;
    }
    let report = runner::run(&s, &mut rig);
    rig.finish().map_err(super::io("trace"))?;
    if args.json {
        let text = serde_json::to_string_pretty(&report)
            .map_err(|e| CommandError::Usage(e.to_string()))?;
        out!("{text}");
    } else {
        out_raw!(report.text());
    }
    if report.passed {
        Ok(())
    } else {
        let failed: Vec<&str> = report
            .expectations
            .iter()
            .filter(|o| !o.passed)
            .map(|o| o.name.as_str())
            .collect();
        let mut why = format!("scenario failed: {}", failed.join("; "));
        if !report.errors.is_empty() {
            why.push_str(&format!(" ({} refused actions)", report.errors.len()));
        }
        Err(CommandError::ScenarioFailed(why))
    }
}
