//! The cell FMU's display strings are the instance's own bytes (docs/cosimulation.md, "A cell
//! as an FMU"): `fmi3GetString` hands out pointers to them, so a read allocates nothing, and
//! the text stays at its address until a step changes it. Counted with a global allocator on
//! the test's own thread.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drivetwin::cell::config::CellFile;
use drivetwin::cell_fmu::instance::CellInstance;
use platform::alloc::Counting;

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// A CANopen CMMP-AS (7-segment display), a CMMO-ST and a CMMP-AS on EtherCAT.
const CELL: &str = "[[bus]]\nsocketcand = \"\"\n\
    [[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n\
    [[drive]]\ndevice = \"cmmo-st\"\n\
    [[drive]]\ndevice = \"cmmp-as\"\nnode = 2\nethercat = \"dtnone0\"\n";

fn displays(cell: &CellInstance) -> Vec<u32> {
    cell.variables()
        .all()
        .filter(|v| v.name().ends_with(".display"))
        .map(|v| v.value_reference)
        .collect()
}

#[test]
fn a_display_read_allocates_nothing_and_keeps_its_address_while_it_does_not_change() {
    let file: CellFile = toml::from_str(CELL).unwrap();
    let mut cell = CellInstance::new(&file, None, drivetwin::vendors::VENDORS.runtime).unwrap();
    let vrs = displays(&cell);
    assert_eq!(vrs.len(), 3, "one display per drive");
    for k in 0..10 {
        cell.do_step(f64::from(k) * 1e-3, 1e-3).unwrap();
    }
    let before: Vec<(usize, String)> = vrs
        .iter()
        .map(|vr| {
            let text = cell.display(*vr).unwrap();
            (text.as_ptr().addr(), text.to_string_lossy().into_owned())
        })
        .collect();
    // The CMMP-AS shows something at power-on (its 7-segment display is never blank).
    assert!(!before[0].1.is_empty(), "{before:?}");
    let mut lengths = 0usize;
    let reads = Counting::count(|| {
        for _ in 0..1000 {
            for vr in &vrs {
                lengths += cell.display(*vr).unwrap().to_bytes().len();
            }
        }
    });
    assert_eq!(reads, 0, "allocations in 3000 display reads");
    assert!(lengths > 0);
    // A step that leaves the displays as they are leaves their bytes where they are.
    cell.do_step(0.01, 1e-3).unwrap();
    for (vr, (address, text)) in vrs.iter().zip(&before) {
        let now = cell.display(*vr).unwrap();
        assert_eq!(now.to_string_lossy(), *text);
        assert_eq!(now.as_ptr().addr(), *address);
    }
}
