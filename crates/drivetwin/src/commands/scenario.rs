//! `drivetwin scenario FILE…`: scenarios on the virtual clock, their reports, the exit code
//! (0 when every scenario passed).

use std::path::Path;

use drivetwin::scenario::report::Report;
use drivetwin::scenario::runner;
use drivetwin::scenario::samples::Sampled;
use drivetwin::scenario::virtual_rig::VirtualRig;
use drivetwin::scenario::Scenario;

use super::CommandError;
use crate::cli::ScenarioArgs;

pub(crate) fn scenario(args: ScenarioArgs) -> Result<(), CommandError> {
    if args.files.len() > 1 {
        if args.trace.is_some() {
            return Err(CommandError::Usage(
                "--trace: one scenario file at a time".to_owned(),
            ));
        }
        if args.samples.is_some() {
            return Err(CommandError::Usage(
                "--samples: one scenario file at a time".to_owned(),
            ));
        }
    }
    let bar = super::progress::bar(args.files.len(), "scenario");
    let mut reports = Vec::with_capacity(args.files.len());
    for file in &args.files {
        bar.set_message(format!("scenario {}", file.display()));
        let report = run_one(file, &args)?;
        if !args.json {
            bar.suspend(|| out_raw!(report.text()));
        }
        bar.inc(1);
        reports.push(report);
    }
    bar.finish_and_clear();
    if args.json {
        let text = match reports.as_slice() {
            [one] => serde_json::to_string_pretty(one),
            all => serde_json::to_string_pretty(all),
        }
        .map_err(|e| CommandError::Usage(e.to_string()))?;
        out!("{text}");
    }
    let failed: Vec<String> = reports
        .iter()
        .filter(|r| !r.passed)
        .map(|r| {
            let names: Vec<&str> = r
                .expectations
                .iter()
                .filter(|o| !o.passed)
                .map(|o| o.name.as_str())
                .collect();
            let mut why = names.join("; ");
            if !r.errors.is_empty() {
                why.push_str(&format!(" ({} refused actions)", r.errors.len()));
            }
            why
        })
        .collect();
    if failed.is_empty() {
        Ok(())
    } else {
        Err(CommandError::ScenarioFailed(format!(
            "scenario failed: {}",
            failed.join(" | ")
        )))
    }
}

/// One scenario file on a virtual rig of its own.
fn run_one(file: &Path, args: &ScenarioArgs) -> Result<Report, CommandError> {
    let s = Scenario::load(file).map_err(|e| CommandError::Usage(e.to_string()))?;
    let cell = s.cell.as_ref().ok_or_else(|| {
        CommandError::Usage(format!(
            "{}: no cell (`cell = \"cell.toml\"` or a [cell] table)",
            file.display()
        ))
    })?;
    let mut rig = VirtualRig::new(cell, drivetwin::vendors::VENDORS.runtime)
        .map_err(|e| CommandError::Usage(e.to_string()))?;
    if let Some(path) = &args.trace {
        rig.trace_to(path)
            .map_err(super::io(format!("trace {}", path.display())))?;
    }
    let report = match &args.samples {
        None => runner::run(&s, &mut rig),
        Some(path) => {
            if !(args.sample_ms.is_finite() && args.sample_ms > 0.0) {
                return Err(CommandError::Usage(
                    "--sample-ms must be a positive number".into(),
                ));
            }
            let every = std::time::Duration::from_secs_f64(args.sample_ms / 1000.0);
            let file = std::fs::File::create(path)
                .map_err(super::io(format!("samples {}", path.display())))?;
            let mut sampled = Sampled::new(&mut rig, every, std::io::BufWriter::new(file))
                .map_err(super::io(format!("samples {}", path.display())))?;
            let report = runner::run(&s, &mut sampled);
            sampled
                .finish()
                .map_err(super::io(format!("samples {}", path.display())))?;
            report
        }
    };
    rig.finish().map_err(super::io("trace"))?;
    Ok(report)
}
