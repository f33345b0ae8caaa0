//! `drivetwin record`: a script run against a node, every request and answer written with its
//! time (`master::recording::file`).

use std::path::Path;

use drivetwin::master::recorder::Recorder;
use drivetwin::master::recording::script::{self, CandumpOptions};
use drivetwin::master::recording::{file, LineError, Recording};

use super::*;

/// A mistake in `path`, with its line.
pub(crate) fn at_line(path: &Path) -> impl Fn(LineError) -> CommandError + '_ {
    move |e| CommandError::Script {
        path: path.to_path_buf(),
        line: e.line,
        what: e.what,
    }
}

/// Where the frames went, for the recording's head.
pub(crate) fn target(bus: &BusArgs) -> String {
    match &bus.can {
        Some(ifname) => format!("target: SocketCAN {ifname}"),
        None => format!("target: socketcand {} {}", bus.socketcand, bus.channel),
    }
}

/// Writes `recording` with `notes` to `path`, or to standard output.
pub(crate) fn write_recording(
    recording: &Recording,
    notes: &[String],
    path: Option<&Path>,
) -> Result<(), CommandError> {
    let text = file::emit_noted(recording, notes);
    match path {
        Some(p) => std::fs::write(p, text).map_err(io(p.display().to_string())),
        None => {
            out_raw!(text);
            Ok(())
        }
    }
}

pub(crate) async fn record(args: RecordArgs) -> Result<(), CommandError> {
    let path = args.script.as_path();
    let text = std::fs::read_to_string(path).map_err(io(path.display().to_string()))?;
    let parsed = if path.extension().is_some_and(|e| e == "toml") {
        script::parse_toml(&text)
    } else {
        script::parse_candump(
            &text,
            CandumpOptions {
                sdo_timeout: Duration::from_millis(args.sdo_timeout_ms),
                quiet: Duration::from_millis(args.quiet_ms),
            },
        )
    }
    .map_err(at_line(path))?;
    let mut link = connect(&args.bus).await?;
    let mut recorder = Recorder::new(&mut link, parsed.ignore.clone());
    // A link lost halfway still leaves the steps run so far on file. Action by action, for
    // the progress shown on a terminal.
    let bar = super::progress::bar(parsed.actions.len(), "record");
    let mut run = Ok(());
    for action in parsed.actions {
        let one = script::Script {
            ignore: Vec::new(),
            actions: vec![action],
        };
        run = recorder.run_script(one).await;
        bar.inc(1);
        if run.is_err() {
            break;
        }
    }
    bar.finish_and_clear();
    let recording = recorder.finish();
    let mut notes = vec![format!("script: {}", path.display()), target(&args.bus)];
    if let Err(e) = &run {
        notes.push(format!("cut short: {e}"));
    }
    write_recording(&recording, &notes, args.output.as_deref())?;
    run?;
    let unanswered = recording.steps.iter().filter(|s| !s.awaited_came()).count();
    let answers: usize = recording.steps.iter().map(|s| s.answers.len()).sum();
    tracing::info!(
        steps = recording.steps.len(),
        answers,
        unanswered,
        "recorded"
    );
    Ok(())
}
