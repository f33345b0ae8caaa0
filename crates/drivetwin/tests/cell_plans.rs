//! `[[drive.diagnostic]]`, `[[drive.plant]]` and `[drive.thermal]` of the drives outside the
//! CAN buses (a CMMO-ST on Modbus TCP, an EtherCAT-only drive): the cell file's plans handed
//! to the cell loop (`FrontEnds::plans`, found by `drivetwin::cell::planned::outside_plans`)
//! and carried out by the loop itself at their times on its clock, as are the faults planned
//! for an EtherCAT line (`[[ethercat_line]]`, `FrontEnds::line_plans`).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

#[path = "support/ecat_veth.rs"]
mod ecat_veth;
mod web_rig;

use std::time::{Duration, Instant};

use drivetwin::cell::config::CellFile;
use drivetwin::cell::control::ControlHandle;
use drivetwin::cell::planned::{self, Locator};
use drivetwin::cell_loop::{EthercatChain, FrontEnds};
use drivetwin::ecat::chain::SlaveChain;
use drivetwin::ecat::link::SlaveSocket;

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

/// How long a planned change may take to show on a loaded machine.
const PATIENCE: Duration = Duration::from_secs(5);

/// Waits until `done` holds (the loop carries the plans out on its own thread).
fn until(what: &str, mut done: impl FnMut() -> bool) {
    let end = Instant::now() + PATIENCE;
    while !done() {
        assert!(Instant::now() < end, "{what}: not within {PATIENCE:?}");
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Whether message `number` of drive `drive` is active.
fn active(handle: &ControlHandle, drive: usize, number: &str) -> bool {
    handle
        .diagnostics(drive)
        .expect("table")
        .iter()
        .any(|d| d.row.number == number && d.active)
}

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
        "only the CMMO-ST: the CMMP-AS plans in its bus"
    );
    assert_eq!(plans[0].drive, Locator::Modbus(0));
    assert_eq!(
        plans[0].plans.len(),
        4,
        "thermal figures, ambient, 2Fh, the encoder"
    );
    // Drive 0 a CMMP-AS on CAN, drive 1 the CMMO-ST on Modbus TCP, as in the file.
    let t0 = Instant::now();
    let cell = web_rig::cmmp_and_cmmo_st_with(FrontEnds {
        plans,
        ..FrontEnds::default()
    });
    until("the planned message", || active(&cell.handle, 1, "2Fh"));
    assert!(
        t0.elapsed() >= Duration::from_millis(50),
        "at its time on the loop's clock, not before"
    );
    until("the planned encoder fault", || {
        let p = cell.handle.physics(1, Default::default()).expect("physics");
        p.encoder == drive::encoder_fault::EncoderFault::Disconnected
    });
    assert!(t0.elapsed() >= Duration::from_millis(100), "at its time");
    let p = cell.handle.physics(1, Default::default()).expect("physics");
    assert_eq!(p.ambient_c, 30.0, "the thermal section's ambient, at 0 ms");
    until("the CMMO-ST's supervision finds the pulled cable", || {
        active(&cell.handle, 1, "06h")
    });
    assert!(
        !active(&cell.handle, 0, "2Fh"),
        "the CMMP-AS on the bus has plans of its own, none here"
    );
}

const ECAT_FILE: &str = r#"
[[drive]]
device = "cmmp-as"
node = 1
ethercat = "ecat0"
[drive.thermal]
ambient_c = 35.0
[[drive.diagnostic]]
at_ms = 60
number = "43-0"

[[ethercat_line]]
at = "80ms"
action = "pull-cable"
after = 0
"#;

/// An EtherCAT-only drive (no CANopen node): its plans reach the chain's own station, on
/// the loop's clock, with no master sending frames; the cell file's `[[ethercat_line]]` is
/// carried out by the loop on the same clock.
#[test]
fn an_ethercat_only_drive_gets_its_planned_message() {
    let file: CellFile = toml::from_str(ECAT_FILE).expect("cell file");
    let runtime = drivetwin::vendors::VENDORS.runtime;
    let specs = file.drives(runtime).expect("specs");
    let plans = planned::outside_plans(&specs, true);
    assert_eq!(plans.len(), 1, "{plans:?}");
    assert_eq!(plans[0].drive, Locator::Ethercat { chain: 0, k: 0 });
    let pair = match ecat_veth::VethPair::create() {
        Ok(p) => p,
        Err(why) => {
            eprintln!("skipped: {why}");
            return;
        }
    };
    let socket = SlaveSocket::open(&pair.twin_if).expect("raw socket");
    let chain = SlaveChain::from_cell_file(&CellFile::single("cmmp-as", 1), runtime)
        .expect("a chain of one CMMP-AS");
    let t0 = Instant::now();
    let cell = web_rig::start(
        drivetwin::cell::can_cell::CanCell::new(),
        FrontEnds {
            ethercat: vec![EthercatChain {
                chain,
                socket,
                trace: None,
            }],
            plans,
            line_plans: file.ethercat_line.clone(),
            ..FrontEnds::default()
        },
        None,
    );
    let drives = cell.handle.drives().expect("drives");
    assert_eq!(drives.len(), 1, "the chain's own drive: {drives:?}");
    until("the planned message", || active(&cell.handle, 0, "43-0"));
    assert!(
        t0.elapsed() >= Duration::from_millis(60),
        "at its time on the loop's clock, not before"
    );
    let p = cell.handle.physics(0, Default::default()).expect("physics");
    assert_eq!(p.ambient_c, 35.0, "the thermal section's ambient, at 0 ms");
    // The line's planned fault, by the loop on the same clock.
    until("the planned pulled cable", || {
        let line = cell.handle.ethercat_line(0, None).expect("line");
        line.cable_pulled_after == Some(0)
    });
    assert!(t0.elapsed() >= Duration::from_millis(80), "at its time");
    drop(cell);
    drop(pair);
}
