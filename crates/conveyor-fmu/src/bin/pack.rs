//! Packs the conveyor FMU (FMI 3.0 §2.5 "FMU Distribution"): `modelDescription.xml`, written
//! from the model's own declarations, and the shared library as
//! `binaries/x86_64-linux/conveyor.so`, into a ZIP archive. With `--fmi2`, the FMI 2.0 FMU of
//! the same library (FMI 2.0 §2.5: `binaries/linux64/conveyor.so`, [`conveyor::fmi2`]).
//!
//! `conveyor-fmu-pack [--fmi2] LIBRARY OUTPUT.fmu` (scripts/conveyor-fmu builds the library
//! first).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use conveyor::Conveyor;
use fmi::schema::fmi3::{Fmi3CoSimulation, Fmi3ModelDescription, Fmi3Unknown, VariableDependency};
use fmi::schema::traits::FmiModelDescription;
use fmi_export::fmi3::Model;

/// The model identifier: the library's name inside the archive (FMI 3.0 §2.5.1.1).
const MODEL_IDENTIFIER: &str = "conveyor";

fn model_description() -> Result<String, String> {
    let mut meta = Conveyor::build_toplevel_metadata();
    // Every output is also an initial unknown (FMI 3.0 §2.4.8: outputs are calculated in
    // Initialization Mode), listed after the outputs as the schema orders them.
    let initial: Vec<VariableDependency> = meta
        .model_structure
        .unknowns
        .iter()
        .filter_map(|u| match u {
            VariableDependency::Output(o) => {
                Some(VariableDependency::InitialUnknown(Fmi3Unknown {
                    value_reference: o.value_reference,
                    ..Default::default()
                }))
            }
            _ => None,
        })
        .collect();
    meta.model_structure.unknowns.extend(initial);
    let md = Fmi3ModelDescription {
        fmi_version: "3.0".into(),
        model_name: Conveyor::MODEL_NAME.into(),
        instantiation_token: Conveyor::INSTANTIATION_TOKEN.into(),
        description: Some(
            "A belt conveyor: a mass on an elastic belt with viscous and Coulomb friction, \
             driven by a motor shaft, with a light barrier"
                .into(),
        ),
        generation_tool: Some("drivetwin conveyor-fmu (fmi-export)".into()),
        co_simulation: Some(Fmi3CoSimulation {
            model_identifier: MODEL_IDENTIFIER.into(),
            can_handle_variable_communication_step_size: Some(true),
            ..Default::default()
        }),
        model_variables: meta.model_variables,
        model_structure: meta.model_structure,
        ..Default::default()
    };
    md.serialize()
        .map_err(|e| format!("model description: {e}"))
}

/// Which standard the archive follows.
#[derive(Clone, Copy, PartialEq)]
enum Version {
    Fmi3,
    Fmi2,
}

fn pack(library: &PathBuf, output: &PathBuf, version: Version) -> Result<(), String> {
    let (xml, platform) = match version {
        Version::Fmi3 => (model_description()?, "x86_64-linux"),
        Version::Fmi2 => (
            conveyor::fmi2::model_description(MODEL_IDENTIFIER),
            "linux64",
        ),
    };
    let lib = std::fs::read(library).map_err(|e| format!("{}: {e}", library.display()))?;
    // Written beside the output and renamed over it: a reader never sees half an archive.
    let partial = output.with_extension("fmu.partial");
    let file =
        std::fs::File::create(&partial).map_err(|e| format!("{}: {e}", partial.display()))?;
    let mut zip = zip::ZipWriter::new(file);
    let opts = zip::write::SimpleFileOptions::default();
    let w = |e: zip::result::ZipError| format!("{}: {e}", output.display());
    zip.start_file("modelDescription.xml", opts).map_err(w)?;
    zip.write_all(xml.as_bytes())
        .map_err(|e| format!("{}: {e}", output.display()))?;
    zip.start_file(format!("binaries/{platform}/{MODEL_IDENTIFIER}.so"), opts)
        .map_err(w)?;
    zip.write_all(&lib)
        .map_err(|e| format!("{}: {e}", output.display()))?;
    zip.finish().map_err(w)?;
    std::fs::rename(&partial, output).map_err(|e| format!("{}: {e}", output.display()))?;
    Ok(())
}

fn main() -> ExitCode {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let version = match args.iter().position(|a| a == "--fmi2") {
        Some(i) => {
            args.remove(i);
            Version::Fmi2
        }
        None => Version::Fmi3,
    };
    let [library, output] = args.as_slice() else {
        eprintln!("usage: conveyor-fmu-pack [--fmi2] LIBRARY OUTPUT.fmu");
        return ExitCode::from(2);
    };
    match pack(&PathBuf::from(library), &PathBuf::from(output), version) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("conveyor-fmu-pack: {e}");
            ExitCode::FAILURE
        }
    }
}
