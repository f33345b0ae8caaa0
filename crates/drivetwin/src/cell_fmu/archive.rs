//! The cell FMU's archive (FMI 3.0 §2.5): `modelDescription.xml`, the binary as
//! `binaries/x86_64-linux/drivetwin_cell.so`, and in `resources/` the cell file and the
//! timeline the instance reads when it is instantiated (and the EtherCAT interface
//! `drivetwin fmu --ethercat` names); with CAN buses, the FMI-LS-BUS
//! terminals (`terminalsAndIcons/terminalsAndIcons.xml`) and the layered standard's manifest
//! (`extra/org.fmi-standard.fmi-ls-bus/fmi-ls-manifest.xml`).

use std::io::Write;
use std::path::Path;

use super::{
    can_terminal, CellFmuError, CELL_FILE, ETHERCAT_FILE, MODEL_IDENTIFIER, TIMELINE_FILE,
};

/// What goes into the archive.
pub struct Contents<'a> {
    pub model_description: &'a str,
    /// The binary (`libdrivetwin_cell.so` of `crates/cell-fmu`).
    pub library: &'a [u8],
    /// The cell file's text.
    pub cell: &'a str,
    /// The timeline's text (a scenario file), if any.
    pub timeline: Option<&'a str>,
    /// The interface of the chain of the EtherCAT slaves that name none, if given.
    pub ethercat: Option<&'a str>,
    /// The cell's CAN buses: each has an FMI-LS-BUS terminal, declared in
    /// `terminalsAndIcons/terminalsAndIcons.xml`, with the layered standard's manifest.
    pub buses: usize,
}

/// Writes the archive to `output`.
pub fn write(output: &Path, contents: &Contents<'_>) -> Result<(), CellFmuError> {
    let file = std::fs::File::create(output).map_err(|source| CellFmuError::Io {
        path: output.to_path_buf(),
        source,
    })?;
    let mut zip = zip::ZipWriter::new(file);
    let opts = zip::write::SimpleFileOptions::default();
    let mut entries: Vec<(String, &[u8])> = vec![
        (
            "modelDescription.xml".into(),
            contents.model_description.as_bytes(),
        ),
        (
            format!("binaries/x86_64-linux/{MODEL_IDENTIFIER}.so"),
            contents.library,
        ),
        (format!("resources/{CELL_FILE}"), contents.cell.as_bytes()),
    ];
    if let Some(t) = contents.timeline {
        entries.push((format!("resources/{TIMELINE_FILE}"), t.as_bytes()));
    }
    if let Some(interface) = contents.ethercat {
        entries.push((format!("resources/{ETHERCAT_FILE}"), interface.as_bytes()));
    }
    let terminals = can_terminal::terminals_and_icons(contents.buses);
    if contents.buses > 0 {
        entries.push((
            "terminalsAndIcons/terminalsAndIcons.xml".into(),
            terminals.as_bytes(),
        ));
        entries.push((
            can_terminal::MANIFEST_PATH.into(),
            can_terminal::MANIFEST.as_bytes(),
        ));
    }
    let err = |e: String| CellFmuError::Archive(format!("{}: {e}", output.display()));
    for (name, bytes) in entries {
        zip.start_file(name, opts).map_err(|e| err(e.to_string()))?;
        zip.write_all(bytes).map_err(|e| err(e.to_string()))?;
    }
    zip.finish().map_err(|e| err(e.to_string()))?;
    Ok(())
}
