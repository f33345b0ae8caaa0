//! `drivetwin diff`: a recording's requests replayed against another node (or a second
//! recording read), and each answer that differs reported.

use std::path::Path;

use drivetwin::master::recorder::Recorder;
use drivetwin::master::recording::compare::{compare, Difference, StepDifferences};
use drivetwin::master::recording::{file, Recording};

use super::record::{at_line, target, write_recording};
use super::*;

fn read_recording(path: &Path) -> Result<Recording, CommandError> {
    let text = std::fs::read_to_string(path).map_err(io(path.display().to_string()))?;
    file::parse(&text).map_err(at_line(path))
}

fn kind(d: &Difference) -> &'static str {
    match d {
        Difference::Request { .. } => "request",
        Difference::NotReplayed => "not-replayed",
        Difference::NotRecorded => "not-recorded",
        Difference::Bytes { .. } => "bytes",
        Difference::Missing { .. } => "missing",
        Difference::Extra { .. } => "extra",
        Difference::Time { .. } => "time",
    }
}

fn where_of(s: &StepDifferences) -> String {
    if s.line > 0 {
        format!("step {} (line {}, {})", s.number, s.line, s.label)
    } else {
        format!("step {} ({})", s.number, s.label)
    }
}

pub(crate) async fn diff(args: DiffArgs) -> Result<(), CommandError> {
    if !(args.time_tolerance.is_finite() && args.time_tolerance >= 0.0) {
        return Err(CommandError::Usage(
            "--time-tolerance is milliseconds, 0 or more".into(),
        ));
    }
    let tolerance = Duration::from_secs_f64(args.time_tolerance / 1000.0);
    let recorded = read_recording(&args.recording)?;
    let replayed = match &args.with {
        Some(other) => read_recording(other)?,
        None => {
            let mut link = connect(&args.bus).await?;
            let mut recorder = Recorder::new(&mut link, recorded.ignore.clone());
            // Step by step, for the progress shown on a terminal.
            let bar = super::progress::bar(recorded.steps.len(), "replay");
            for step in &recorded.steps {
                let one = Recording {
                    ignore: Vec::new(),
                    steps: vec![step.clone()],
                };
                let replayed = recorder.replay(&one).await;
                bar.inc(1);
                if replayed.is_err() {
                    bar.finish_and_clear();
                }
                replayed?;
            }
            bar.finish_and_clear();
            recorder.finish()
        }
    };
    if let Some(out) = &args.output {
        let notes = [
            format!("replay of {}", args.recording.display()),
            target(&args.bus),
        ];
        write_recording(&replayed, &notes, Some(out))?;
    }
    let differing = compare(&recorded, &replayed, tolerance);
    let steps = recorded.steps.len().max(replayed.steps.len());
    if args.bus.json {
        let list: Vec<_> = differing
            .iter()
            .map(|s| {
                serde_json::json!({
                    "step": s.number, "line": s.line, "label": s.label,
                    "differences": s.differences.iter().map(|d| serde_json::json!({
                        "kind": kind(d), "text": d.to_string(),
                    })).collect::<Vec<_>>(),
                })
            })
            .collect();
        out!(
            "{}",
            serde_json::json!({
                "steps": steps, "equal": differing.is_empty(),
                "time_tolerance_ms": args.time_tolerance, "differing": list,
            })
        );
    } else {
        for s in &differing {
            for d in &s.differences {
                out!("{}: {d}", where_of(s));
            }
        }
        if differing.is_empty() {
            out!(
                "{steps} steps, every answer equal (time tolerance {} ms)",
                args.time_tolerance
            );
        }
    }
    if differing.is_empty() {
        Ok(())
    } else {
        Err(CommandError::Differs(format!(
            "{} of {steps} steps differ",
            differing.len()
        )))
    }
}
