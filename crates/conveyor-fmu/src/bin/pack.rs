//! Packs the conveyor FMU (FMI 3.0 §2.5 "FMU Distribution"): `modelDescription.xml`, written
//! from the model's own declarations ([`conveyor::description`]), and the shared library
//! (`libconveyor_fmu.so`, this crate's cdylib) as `binaries/x86_64-linux/conveyor.so`, into a
//! ZIP archive. With `--fmi2`, the FMI 2.0 FMU of the same library (FMI 2.0 §2.5:
//! `binaries/linux64/conveyor.so`, its functions in `src/fmi2.rs`).
//!
//! `conveyor-fmu-pack [--fmi2] LIBRARY OUTPUT.fmu` (scripts/conveyor-fmu builds the library
//! first).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use conveyor::description;

/// The model identifier: the library's name inside the archive (FMI 3.0 §2.5.1.1).
const MODEL_IDENTIFIER: &str = "conveyor";

/// Which standard the archive follows.
#[derive(Clone, Copy, PartialEq)]
enum Version {
    Fmi3,
    Fmi2,
}

fn pack(library: &PathBuf, output: &PathBuf, version: Version) -> Result<(), String> {
    let (xml, platform) = match version {
        Version::Fmi3 => (description::fmi3(MODEL_IDENTIFIER)?, "x86_64-linux"),
        Version::Fmi2 => (description::fmi2(MODEL_IDENTIFIER), "linux64"),
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
