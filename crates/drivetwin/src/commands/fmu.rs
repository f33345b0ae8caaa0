//! `drivetwin fmu --config cell.toml --output cell.fmu`: a cell as an FMI 3.0 co-simulation
//! FMU (docs/cosimulation.md). The description comes from the cell's drives, the binary is
//! crates/cell-fmu's library (`--library`, default beside this binary, where `cargo build`
//! puts both), the cell file and the timeline go into `resources/`.

use std::path::PathBuf;

use drivetwin::cell::config::CellFile;
use drivetwin::cell_fmu::instance::CellInstance;
use drivetwin::cell_fmu::{archive, model_description, MODEL_IDENTIFIER};
use drivetwin::scenario::Scenario;

use super::CommandError;
use crate::cli::FmuArgs;

/// The library's file name as cargo writes it.
fn library_file() -> String {
    format!("lib{MODEL_IDENTIFIER}.so")
}

pub(crate) fn fmu(args: FmuArgs) -> Result<(), CommandError> {
    let usage = |e: String| CommandError::Usage(e);
    let read = |path: &PathBuf| {
        std::fs::read_to_string(path).map_err(super::io(format!("{}", path.display())))
    };
    let cell_text = read(&args.config)?;
    let cell = CellFile::load(&args.config)?;
    let timeline_text = args.scenario.as_ref().map(read).transpose()?;
    let timeline = match (&timeline_text, &args.scenario) {
        (Some(text), Some(path)) => Some(
            Scenario::parse(text, &path.display().to_string(), None)
                .map_err(|e| usage(e.to_string()))?,
        ),
        _ => None,
    };
    // The cell as the FMU builds it: its drives are the variables, and a cell the FMU could
    // not build is refused here rather than in the importer.
    let instance = CellInstance::with_ethercat(
        &cell,
        timeline.as_ref(),
        drivetwin::vendors::VENDORS.runtime,
        args.ethercat.as_deref(),
    )
    .map_err(|e| usage(e.to_string()))?;
    let name = args
        .config
        .file_stem()
        .map_or_else(|| "cell".to_string(), |s| s.to_string_lossy().into_owned());
    let xml = model_description::model_description_with(
        &name,
        instance.variables(),
        instance.buses(),
        instance.parameters(),
    );
    let library = match &args.library {
        Some(p) => p.clone(),
        None => std::env::current_exe()
            .map_err(super::io("the drivetwin binary's path"))?
            .with_file_name(library_file()),
    };
    let lib = std::fs::read(&library).map_err(|e| {
        usage(format!(
            "{}: {e} (the FMU's binary: scripts/cell-fmu builds it; --library names it)",
            library.display()
        ))
    })?;
    archive::write(
        &args.output,
        &archive::Contents {
            model_description: &xml,
            library: &lib,
            cell: &cell_text,
            timeline: timeline_text.as_deref(),
            ethercat: args.ethercat.as_deref(),
            buses: instance.buses(),
        },
    )
    .map_err(|e| usage(e.to_string()))?;
    out!(
        "{}: {} drive(s), {} variables, {} parameters",
        args.output.display(),
        instance.variables().names.len(),
        instance.variables().all().count() + 1,
        instance.parameters().list.len()
    );
    for (interface, slaves) in instance.ethercat_chains() {
        out!("EtherCAT on {interface}: {slaves} slave(s), served while the FMU runs");
    }
    Ok(())
}
