//! The CiA 402 engine names no vendor: outside `src/vendors/` no code line names a vendor
//! (Kinco, Nanotec, the Festo CMMP-AS, the CMMO-ST and its FHPP) or a `Vendor::` variant, and
//! no engine module imports a vendor module (vendors import the engine, never the reverse).
//! Comments may cite a manual, and a file's unit tests may name the drive their vectors come
//! from; a vendor's behaviour is a [`drive::personality::Vendor`] hook or personality data.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("a source folder") {
        let path = entry.expect("an entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The code of `line`: without a trailing `//` comment, empty for a comment line.
fn code(line: &str) -> &str {
    let trimmed = line.trim_start();
    if trimmed.starts_with("//") {
        return "";
    }
    match line.find("//") {
        Some(at) if !line[..at].contains('"') => &line[..at],
        _ => line,
    }
}

fn names_vendor(code: &str) -> bool {
    let lower = code.to_lowercase();
    ["kinco", "nanotec", "cmmp", "cmmo", "fhpp", "festo"]
        .iter()
        .any(|v| lower.contains(v))
        || code.contains("Vendor::")
}

#[test]
fn engine_code_names_no_vendor() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut found = Vec::new();
    for path in files {
        let rel = path
            .strip_prefix(&src)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let top = rel.split('/').next().unwrap_or_default();
        if top == "vendors" {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        // A file's unit tests (its `#[cfg(test)]` module, at its end) may name the drive
        // whose manual gave their vectors.
        let text = text.split("#[cfg(test)]").next().unwrap_or_default();
        let lines: Vec<(usize, &str)> = text
            .lines()
            .enumerate()
            .filter(|(_, l)| names_vendor(code(l)))
            .collect();
        for (n, l) in lines {
            found.push(format!("src/{rel}:{}: {}", n + 1, l.trim()));
        }
        for (n, l) in text.lines().enumerate() {
            if code(l).contains("crate::vendors") {
                found.push(format!(
                    "src/{rel}:{}: imports a vendor: {}",
                    n + 1,
                    l.trim()
                ));
            }
        }
    }
    assert!(
        found.is_empty(),
        "the engine names a vendor (move it into src/vendors/<vendor>/ as a hook or data):\n{}",
        found.join("\n")
    );
}

#[test]
fn vendors_serve_their_device_files_only() {
    // Each vendor folder's personality names the device files it serves; the generic drive
    // names none (it serves any other CiA 402 file).
    assert!(drive::vendors::cia402::CIA402.devices.is_empty());
    for p in [
        &drive::vendors::festo_cmmp_as::CMMP_AS,
        &drive::vendors::nanotec::NANOTEC,
        &drive::vendors::kinco::KINCO,
    ] {
        assert!(!p.devices.is_empty());
    }
}
