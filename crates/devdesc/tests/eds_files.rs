//! The test EDS files of `tests/interop/data/eds/` (written after other vendors' public
//! object lists) read as CiA 306 says, and a broken copy refused at its line.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::path::{Path, PathBuf};

use devdesc::eds::{self, EdsError};
use od::{Access, DataType, ObjectKind};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/interop/data/eds")
        .join(name)
}

fn entry(d: &devdesc::Device, index: u16, sub: u8) -> &devdesc::model::Ent {
    d.objects
        .iter()
        .find(|o| o.index == index)
        .and_then(|o| o.entries.iter().find(|e| e.sub == sub))
        .unwrap_or_else(|| panic!("{index:04X}:{sub}"))
}

/// After the maxon EPOS4 Firmware Specification's object list.
#[test]
fn epos4_like() {
    let e = eds::load_file(&data("epos4_like.eds")).unwrap();
    e.require_cia402().unwrap();
    let d = &e.device;
    assert_eq!(d.name, "epos4-like");
    assert_eq!(d.vendor_id, 0xFB);
    assert_eq!(d.baud_rates, [50, 125, 250, 500, 800, 1000]);
    assert!(!d.cia301.lss_unsupported);
    // An EDS says nothing of its bus-fault reactions: CiA 301's usage.
    assert_eq!(d.bus_faults, devdesc::model::BusFaults::default());
    assert_eq!(
        devdesc::runtime::leak(d).bus_faults,
        od::BusFaultReactions::CIA_301
    );
    let modes = entry(d, 0x6502, 0);
    assert_eq!(
        modes.default,
        0x3A5u32.to_le_bytes(),
        "PPM, PVM, HMM, CSP, CSV, CST"
    );
    let tpdo1 = entry(d, 0x1800, 1);
    assert!(tpdo1.default_plus_node_id);
    assert_eq!(tpdo1.default, 0x4000_0180u32.to_le_bytes());
    assert_eq!(entry(d, 0x1A00, 1).default, 0x6041_0010u32.to_le_bytes());
    let map = d.objects.iter().find(|o| o.index == 0x1600).unwrap();
    assert_eq!(map.entries.len(), 9, "8 mapping entries");
    let method = entry(d, 0x6098, 0);
    assert_eq!(
        (method.data_type, method.access),
        (DataType::Integer8, Access::ReadWrite)
    );
    assert_eq!(method.min, Some(od::Limit::Signed(-4)));
    assert_eq!(entry(d, 0x1008, 0).default, b"EPOS4-like");
}

/// After the Schneider Lexium 32 fieldbus manual's object list.
#[test]
fn lexium32_like() {
    let e = eds::load_file(&data("lexium32_like.eds")).unwrap();
    e.require_cia402().unwrap();
    let d = &e.device;
    assert_eq!(d.vendor_id, 0x0800_005A);
    assert!(d.cia301.lss_unsupported);
    // 1016h written with CompactSubObj=3, named in [1016Name].
    let hb = d.objects.iter().find(|o| o.index == 0x1016).unwrap();
    assert_eq!(hb.kind, ObjectKind::Array);
    assert_eq!(hb.entries.len(), 4);
    assert_eq!(hb.entries[2].name, "Consumer heartbeat time 2");
    assert_eq!(hb.entries[3].access, Access::ReadWrite);
    // 60E3h: the homing methods, INTEGER8 each.
    let methods = d.objects.iter().find(|o| o.index == 0x60E3).unwrap();
    assert_eq!(methods.entries.len(), 32);
    assert_eq!(methods.entries.last().unwrap().default, [35]);
    // TPDOs without an event timer: sub 0 … 3.
    let tpdo = d.objects.iter().find(|o| o.index == 0x1801).unwrap();
    assert_eq!(
        tpdo.entries.iter().map(|e| e.sub).collect::<Vec<_>>(),
        [0, 1, 2, 3]
    );
}

/// A damaged copy is refused with the file, the line, the section and the key.
#[test]
fn a_broken_copy_names_its_line() {
    let path = data("epos4_like.eds");
    let text = std::fs::read_to_string(&path).unwrap();
    let at = text.find("[6081]").unwrap();
    let key = at + text[at..].find("DataType=0x0007").unwrap();
    let line = text[..key].lines().count() + 1;
    let broken = format!("{}DataType=0x0042{}", &text[..key], &text[key + 15..]);
    let err = eds::parse(&broken, "broken.eds").unwrap_err();
    assert!(matches!(err, EdsError::Invalid { .. }));
    assert_eq!(
        err.to_string(),
        format!("broken.eds:{line}: [6081] DataType: 0x0042 is no CiA 301 data type")
    );
    let loc = err.location().unwrap();
    assert_eq!(
        (loc.section.as_str(), loc.key.as_str(), loc.line),
        ("6081", "DataType", line)
    );
}
