//! A cell FMU's `doStep` allocates nothing once its working lists have grown
//! (docs/performance.md, "The cell as an FMU"): the ten-drive cell of the speed benchmark and
//! the example cell with its timeline (a drive made operational and enabled, its PDOs on the
//! bus) stepped 1 ms at a time, every output read after each step as an importer that
//! records them does. Counted with a global allocator on the test's own thread.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::path::Path;

use drivetwin::cell::config::CellFile;
use drivetwin::cell_fmu::instance::CellInstance;
use drivetwin::cell_fmu::variables::Role;
use drivetwin::scenario::Scenario;
use platform::alloc::Counting;

#[global_allocator]
static ALLOCATOR: Counting = Counting;

const STEP: f64 = 1e-3;

fn example(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/cell_fmu")
        .join(name)
}

/// The cell of `cell`, with the timeline `start` when given.
fn instance(cell: &str, start: Option<&str>) -> CellInstance {
    let file = CellFile::load(&example(cell)).unwrap();
    let timeline = start.map(|s| {
        let text = std::fs::read_to_string(example(s)).unwrap();
        Scenario::parse(&text, s, None).unwrap()
    });
    CellInstance::new(
        &file,
        timeline.as_ref(),
        drivetwin::vendors::VENDORS.runtime,
    )
    .unwrap()
}

/// Every output an importer reads, by its getter.
fn read_outputs(cell: &CellInstance, outputs: &[(u32, Role)]) -> f64 {
    let mut sum = 0.0;
    for (vr, role) in outputs {
        sum += match role {
            Role::Position | Role::Velocity | Role::Current => cell.get_float64(*vr).unwrap(),
            Role::Statusword => f64::from(cell.get_uint16(*vr).unwrap()),
            Role::PositionActual => f64::from(cell.get_int32(*vr).unwrap()),
            Role::Scon | Role::Spos => f64::from(cell.get_uint8(*vr).unwrap()),
            Role::Display => cell.display(*vr).unwrap().to_bytes().len() as f64,
            _ => 0.0,
        };
    }
    sum
}

/// The value references of the outputs of each getter, with room for their values: what an
/// importer passes to one `fmi3Get…` call per type.
#[derive(Default)]
struct Calls {
    float64: (Vec<u32>, Vec<f64>),
    uint8: (Vec<u32>, Vec<u8>),
    uint16: (Vec<u32>, Vec<u16>),
    int32: (Vec<u32>, Vec<i32>),
}

impl Calls {
    fn of(outputs: &[(u32, Role)]) -> Calls {
        let mut calls = Calls::default();
        for (vr, role) in outputs {
            match role {
                Role::Position | Role::Velocity | Role::Current => calls.float64.0.push(*vr),
                Role::Scon | Role::Spos => calls.uint8.0.push(*vr),
                Role::Statusword => calls.uint16.0.push(*vr),
                Role::PositionActual => calls.int32.0.push(*vr),
                _ => {}
            }
        }
        calls.float64.1 = vec![0.0; calls.float64.0.len()];
        calls.uint8.1 = vec![0; calls.uint8.0.len()];
        calls.uint16.1 = vec![0; calls.uint16.0.len()];
        calls.int32.1 = vec![0; calls.int32.0.len()];
        calls
    }

    /// One get call per type, as `fmi3GetFloat64` … passes them to the cell.
    fn read(&mut self, cell: &CellInstance) -> f64 {
        cell.get_float64s(&self.float64.0, &mut self.float64.1)
            .unwrap();
        cell.get_uint8s(&self.uint8.0, &mut self.uint8.1).unwrap();
        cell.get_uint16s(&self.uint16.0, &mut self.uint16.1)
            .unwrap();
        cell.get_int32s(&self.int32.0, &mut self.int32.1).unwrap();
        self.float64.1.iter().sum::<f64>()
            + self.uint8.1.iter().map(|v| f64::from(*v)).sum::<f64>()
            + self.uint16.1.iter().map(|v| f64::from(*v)).sum::<f64>()
            + self.int32.1.iter().map(|v| f64::from(*v)).sum::<f64>()
    }
}

/// Heap allocations of `steps` steps of 1 ms with every output read after each, after
/// `warm_up` steps that let the lists grow and the timeline act: value by value, or (`calls`)
/// one get call per type.
fn allocations(cell: CellInstance, warm_up: u32, steps: u32) -> u64 {
    allocations_reading(cell, warm_up, steps, false)
}

fn allocations_reading(mut cell: CellInstance, warm_up: u32, steps: u32, calls: bool) -> u64 {
    let outputs: Vec<(u32, Role)> = cell
        .variables()
        .all()
        .filter(|v| {
            !matches!(
                v.role,
                Role::LoadTorque | Role::DigitalInput(_) | Role::ReferenceSwitch
            )
        })
        .map(|v| (v.value_reference, v.role))
        .collect();
    let mut by_type = Calls::of(&outputs);
    let mut k = 0u32;
    let mut step = |cell: &mut CellInstance| {
        cell.do_step(f64::from(k) * STEP, STEP).unwrap();
        k += 1;
        if calls {
            by_type.read(cell)
        } else {
            read_outputs(cell, &outputs)
        }
    };
    for _ in 0..warm_up {
        step(&mut cell);
    }
    let mut seen = 0.0;
    let count = Counting::count(|| {
        for _ in 0..steps {
            seen += step(&mut cell);
        }
    });
    assert!(seen.is_finite());
    count
}

#[test]
fn ten_drives_at_power_on_step_without_allocating() {
    let cell = instance("ten_drives.toml", None);
    assert_eq!(cell.variables().names.len(), 10);
    assert_eq!(allocations(cell, 100, 1000), 0);
}

#[test]
fn ten_drives_read_by_one_get_call_per_type_step_without_allocating() {
    let cell = instance("ten_drives.toml", None);
    assert_eq!(allocations_reading(cell, 100, 1000, true), 0);
}

#[test]
fn an_enabled_drive_with_its_pdos_on_the_bus_steps_without_allocating() {
    let mut probe = instance("cell.toml", Some("start.toml"));
    // The timeline has made the drive operation enabled (statusword 0x0027 in bits 0..6).
    let sw = probe
        .variables()
        .all()
        .find(|v| v.role == Role::Statusword)
        .unwrap()
        .value_reference;
    for k in 0..200 {
        probe.do_step(f64::from(k) * STEP, STEP).unwrap();
    }
    assert_eq!(probe.get_uint16(sw).unwrap() & 0x6F, 0x27);
    let cell = instance("cell.toml", Some("start.toml"));
    assert_eq!(allocations(cell, 200, 1000), 0);
    let cell = instance("cell.toml", Some("start.toml"));
    assert_eq!(allocations_reading(cell, 200, 1000, true), 0);
}

#[test]
fn a_masters_sdo_requests_through_the_ls_bus_terminal_and_their_answers_allocate_nothing() {
    use drivetwin::cell_fmu::can_terminal::{value_reference, Member};
    use drivetwin::cell_fmu::ls_bus::Operation;
    let mut cell = instance("cell.toml", Some("start.toml"));
    // SDO upload of 6041h:00, the statusword (CiA 301 §7.2.4.3.6), as an LS-BUS CAN Transmit.
    let mut request = Vec::new();
    Operation::CanTransmit {
        id: 0x601,
        ide: false,
        rtr: false,
        data: &[0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0],
    }
    .emit(&mut request)
    .unwrap();
    let (rx_data, rx_clock, tx_data, tx_clock) = (
        value_reference(0, Member::RxData),
        value_reference(0, Member::RxClock),
        value_reference(0, Member::TxData),
        value_reference(0, Member::TxClock),
    );
    // A request every 5 ms on the 125 kbit/s bus (its frame and the answer take about 2 ms),
    // the terminal's Tx_Data read after every step that ticked.
    let step = |cell: &mut CellInstance, k: u32| -> usize {
        if k.is_multiple_of(5) {
            cell.set_binary(rx_data, &request).unwrap();
            cell.set_clock(rx_clock, true).unwrap();
            cell.update_discrete_states();
        }
        cell.do_step(f64::from(k) * STEP, STEP).unwrap();
        if cell.get_clock(tx_clock).unwrap() {
            cell.get_binary(tx_data).unwrap().len()
        } else {
            0
        }
    };
    for k in 0..200 {
        step(&mut cell, k);
    }
    let mut tx_bytes = 0;
    let count = Counting::count(|| {
        for k in 200..1200 {
            tx_bytes += step(&mut cell, k);
        }
    });
    // 200 requests, each confirmed on Tx and answered by the drive (0x581 …).
    assert!(tx_bytes > 200 * 2 * 8, "{tx_bytes} bytes on Tx");
    assert_eq!(count, 0);
}
