//! Generates one static `od::DeviceDescription` per `devices/*.toml`.

use std::{env, fs, path::PathBuf};

fn main() {
    let dir = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"))
        .join("../../devices");
    println!("cargo:rerun-if-changed={}", dir.display());
    let mut files: Vec<PathBuf> = fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    let mut out = String::new();
    let mut names = Vec::new();
    for f in &files {
        println!("cargo:rerun-if-changed={}", f.display());
        let device = match devdesc::load_file(f) {
            Ok(d) => d,
            Err(e) => panic!("device description error: {e}"),
        };
        out.push_str(&devdesc::codegen::generate(&device));
        out.push_str(&devdesc::codegen::generate_addresses(&device));
        names.push(devdesc::codegen::static_name(&device.name));
    }
    out.push_str("/// Every personality, in file-name order.\npub static ALL: &[&od::DeviceDescription] = &[");
    for n in &names {
        out.push_str(&format!("&{n}, "));
    }
    out.push_str("];\n");
    out.push_str("/// The panel addresses and Modbus registers of every personality, in file-name order.\npub static ALL_ADDRESSES: &[&Addresses] = &[");
    for n in &names {
        out.push_str(&format!("&{n}_ADDRESSES, "));
    }
    out.push_str("];\n");
    let dest = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("devices.rs");
    fs::write(&dest, out).unwrap_or_else(|e| panic!("{}: {e}", dest.display()));
}
