//! The example conveyor FMUs (FMI 3.0 and 2.0), built from source by `scripts/conveyor-fmu`.

use std::path::PathBuf;

/// Builds the example conveyor FMUs and returns the folder that holds them (`target/fmu`).
pub fn conveyor_fmus() -> PathBuf {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let built = std::process::Command::new(root.join("scripts/conveyor-fmu"))
        .current_dir(&root)
        .status()
        .is_ok_and(|s| s.success());
    assert!(built, "scripts/conveyor-fmu");
    root.join("target/fmu")
}
