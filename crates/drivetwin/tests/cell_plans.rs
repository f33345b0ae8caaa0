//! `[[drive.diagnostic]]`, `[[drive.plant]]` and `[drive.thermal]` of the drives outside the
//! CAN cells (a CMMO-ST on Modbus TCP; EtherCAT-only drives are found the same way): the cell
//! file's plans carried out through the running cell loop's control handle
//! (`drivetwin::cell::planned`).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod web_rig;

use std::time::{Duration, Instant};

use drivetwin::cell::config::CellFile;
use drivetwin::cell::planned::{self, Locator};

const FILE: &str = r#"
[[drive]]
device = "cmmp-as"
node = 1

[[drive]]
device = "cmmo-st"
node = 1
[drive.thermal]
ambient_c = 30.0
[[drive.diagnostic]]
at_ms = 50
number = "2Fh"
[[drive.plant]]
at_ms = 100
encoder = "disconnected"
"#;

#[test]
fn a_cmmo_st_gets_its_planned_message_and_plant_change() {
    let file: CellFile = toml::from_str(FILE).expect("cell file");
    let specs = file
        .drives(drivetwin::vendors::VENDORS.runtime)
        .expect("specs");
    let plans = planned::outside_plans(&specs, true);
    assert_eq!(
        plans.len(),
        1,
        "only the CMMO-ST: the CMMP-AS plans in its cell"
    );
    assert_eq!(plans[0].drive, Locator::Modbus(0));
    assert_eq!(
        plans[0].plans.len(),
        4,
        "thermal figures, ambient, 2Fh, the encoder"
    );
    // Drive 1 of the rig is a CMMO-ST on Modbus TCP, as drive 1 of the file.
    let cell = web_rig::cmmp_and_cmmo_st();
    let t0 = Instant::now();
    let thread = planned::start(cell.handle.clone(), plans)
        .expect("thread")
        .expect("plans to carry out");
    thread.join().expect("done");
    assert!(t0.elapsed() >= Duration::from_millis(100), "at their times");
    let active = |number: &str| {
        cell.handle
            .diagnostics(1)
            .expect("table")
            .iter()
            .any(|d| d.row.number == number && d.active)
    };
    assert!(active("2Fh"), "the planned message");
    let p = cell.handle.physics(1, Default::default()).expect("physics");
    assert_eq!(p.ambient_c, 30.0);
    assert_eq!(p.encoder, drive::encoder_fault::EncoderFault::Disconnected);
    std::thread::sleep(Duration::from_millis(20));
    assert!(
        active("06h"),
        "the CMMO-ST's supervision finds the pulled cable"
    );
}
