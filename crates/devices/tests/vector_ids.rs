//! Every vector of the catalogue of the manuals' worked examples (`spec/vectors.md`, kept beside
//! the repository in `../shared`) is named by its own ID in a test: a file under a `tests/` folder, or the part of
//! a source file from its first `#[cfg(test)]` on. A range or an abbreviation ("KINCO-DIAG-01…07",
//! "KINCO-SC-01/02", "KINCO-MB-01, -02") names only its first ID and is refused as well. The
//! count per device is printed.
//!
//! `DRIVETWIN_SHARED` names another shared folder. Without the catalogue the check says so and
//! passes, except under CI (`CI` set), where shared/ is always beside the repository.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

/// The four devices' ID prefixes, as the catalogue's sections have them.
const DEVICES: [&str; 4] = ["CMMP", "FHPP", "NT", "KINCO"];

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn catalogue() -> Option<String> {
    let shared = std::env::var_os("DRIVETWIN_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join("../shared"));
    fs::read_to_string(shared.join("spec/vectors.md")).ok()
}

/// Whether `b` may continue an ID (so "KINCO-DIP-01" is not found in "KINCO-DIP-010").
fn id_char(b: u8) -> bool {
    b.is_ascii_alphanumeric() || b == b'-' || b == b'_'
}

/// An ID as the catalogue writes one: a device prefix, a topic, a number, e.g. `NT-CW-07`,
/// `KINCO-232-01`, `CMMP-PDO-10`.
fn is_id(s: &str) -> bool {
    let mut parts = s.split('-');
    let prefix = parts.next().unwrap_or("");
    let rest: Vec<&str> = parts.collect();
    DEVICES.contains(&prefix)
        && rest.len() >= 2
        && rest
            .iter()
            .all(|p| !p.is_empty() && p.bytes().all(|b| b.is_ascii_alphanumeric()))
        && rest
            .last()
            .is_some_and(|n| n.bytes().next().is_some_and(|b| b.is_ascii_digit()))
}

/// The IDs of the catalogue's rows (the first cell of a table row), in order, once each.
fn catalogue_ids(text: &str) -> Vec<String> {
    let mut ids: Vec<String> = Vec::new();
    for line in text.lines() {
        let Some(cell) = line.strip_prefix('|').and_then(|l| l.split('|').next()) else {
            continue;
        };
        let cell = cell.trim();
        if is_id(cell) && !ids.iter().any(|i| i == cell) {
            ids.push(cell.to_owned());
        }
    }
    ids
}

/// The test text of the repository: test files whole, source files from `#[cfg(test)]` on.
fn test_texts(dir: &Path, out: &mut Vec<(PathBuf, String)>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if path.is_dir() {
            if !matches!(name.as_ref(), "target" | ".git" | "node_modules" | "corpus") {
                test_texts(&path, out);
            }
            continue;
        }
        let rust = name.ends_with(".rs");
        if !(rust || name.ends_with(".py")) {
            continue;
        }
        let Ok(text) = fs::read_to_string(&path) else {
            continue;
        };
        let in_tests = path.components().any(|c| c.as_os_str() == "tests");
        if in_tests {
            out.push((path, text));
        } else if let Some(at) = text.find("#[cfg(test)]").filter(|_| rust) {
            out.push((path, text[at..].to_owned()));
        }
    }
}

/// Whether `text` names `id` on its own (not as the start of a longer ID).
fn names(text: &str, id: &str) -> bool {
    text.match_indices(id).any(|(at, _)| {
        let before = at.checked_sub(1).and_then(|i| text.as_bytes().get(i));
        let after = text.as_bytes().get(at + id.len());
        !before.is_some_and(|b| id_char(*b)) && !after.is_some_and(|b| id_char(*b))
    })
}

/// Ranges and abbreviations after an ID: "…07", "...07", "/02", " / -02", ", -02".
fn ranges(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    for prefix in DEVICES {
        for (at, _) in text.match_indices(&format!("{prefix}-")) {
            let tail = &text[at..];
            let id_len = tail.bytes().take_while(|b| id_char(*b)).count();
            if !is_id(&tail[..id_len]) {
                continue;
            }
            let after = tail[id_len..].trim_start_matches(' ');
            let joined = ["…", "...", "/", "–"]
                .iter()
                .find_map(|sep| after.strip_prefix(sep))
                .map(|r| r.trim_start_matches([' ', '-']))
                .or_else(|| after.strip_prefix(", -"));
            if joined.is_some_and(|r| r.bytes().next().is_some_and(|b| b.is_ascii_digit())) {
                let end = tail.len().min(id_len + 6);
                let end = (end..=tail.len())
                    .find(|i| tail.is_char_boundary(*i))
                    .unwrap_or(tail.len());
                found.push(tail[..end].to_owned());
            }
        }
    }
    found
}

#[test]
fn every_vector_is_named_by_its_id_in_a_test() {
    let Some(text) = catalogue() else {
        assert!(
            std::env::var_os("CI").is_none(),
            "no ../shared/spec/vectors.md beside the repository (DRIVETWIN_SHARED names another)"
        );
        eprintln!("no ../shared/spec/vectors.md: the vector check is skipped outside CI");
        return;
    };
    let ids = catalogue_ids(&text);
    assert!(ids.len() >= 300, "the catalogue read: {} IDs", ids.len());
    let mut texts = Vec::new();
    test_texts(&repo_root(), &mut texts);
    // This file's own examples of what is refused are not tests of vectors.
    texts.retain(|(path, _)| !path.ends_with(file!().rsplit('/').next().unwrap_or(file!())));
    let mut per_device: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    let mut missing = Vec::new();
    for id in &ids {
        let device = DEVICES
            .iter()
            .find(|d| id.starts_with(&format!("{d}-")))
            .copied()
            .unwrap_or("?");
        let count = per_device.entry(device).or_default();
        count.1 += 1;
        if texts.iter().any(|(_, t)| names(t, id)) {
            count.0 += 1;
        } else {
            missing.push(id.as_str());
        }
    }
    for (device, (named, all)) in &per_device {
        println!("{device}: {named} of {all} vectors named in a test");
    }
    let root = repo_root();
    let abbreviated: Vec<String> = texts
        .iter()
        .flat_map(|(path, t)| {
            let file = path
                .strip_prefix(&root)
                .unwrap_or(path)
                .display()
                .to_string();
            ranges(t).into_iter().map(move |r| format!("{file}: {r}"))
        })
        .collect();
    assert!(
        missing.is_empty(),
        "{} vectors named in no test: {missing:?}",
        missing.len()
    );
    assert!(
        abbreviated.is_empty(),
        "IDs named by a range or an abbreviation (name each one): {abbreviated:#?}"
    );
}

#[test]
fn the_check_reads_ids_ranges_and_words() {
    let ids = catalogue_ids(
        "| KINCO-DIP-01 | a |\n| Device | x |\n| NT-CW-07 | b |\n| KINCO-DIP-01 | c |",
    );
    assert_eq!(ids, ["KINCO-DIP-01", "NT-CW-07"]);
    assert!(names("see KINCO-DIP-01.", "KINCO-DIP-01"));
    assert!(!names("KINCO-DIP-010", "KINCO-DIP-01"));
    assert!(!names("XKINCO-DIP-01", "KINCO-DIP-01"));
    for range in [
        "KINCO-DIAG-01…07",
        "NT-CW-01...04",
        "KINCO-SC-01/02",
        "KINCO-SC-01 / -02",
        "KINCO-MB-01, -02",
    ] {
        assert_eq!(ranges(range).len(), 1, "{range}");
    }
    for fine in [
        "KINCO-SC-01 and KINCO-SC-02",
        "NT-CW-07: 6085h",
        "CMMP-PDO-10, CMMP-PDO-11",
    ] {
        assert!(ranges(fine).is_empty(), "{fine}");
    }
}
