//! Determinism: a cell with a CMMP-AS on CANopen, a CMMP-AS on EtherCAT and a CMMO-ST on Modbus
//! TCP, inputs on the three protocols, run twice on the virtual clock: the outputs are equal
//! bit for bit.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

#[path = "support/ecat_inputs.rs"]
mod ecat_inputs;
use ecat_inputs::{bwr, coe, coe_download, fprd, fpwr, mailbox_counters, mailbox_sms, set_station};

use std::time::Duration;

use canopen::CanFrame;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::station::Station;
use drivetwin::cell_loop::virtual_clock::{run_virtual_mixed, Input, Output};
use drivetwin::ecat::chain::{own_drive, SlaveChain, SlaveDrive};
use drivetwin::modbus_tcp::cell_drive::ModbusDrive;
use drivetwin::modbus_tcp::server::ModbusConfig;
use drivetwin::vendors::festo_cmmo_st::modbus_server::FhppModbus;
use ethercat::frame::{EthernetFrame, Frame};

fn ms(t: u64) -> Duration {
    Duration::from_millis(t)
}

fn can(id: u16, data: &[u8]) -> Input {
    Input::Can(CanFrame::new(id, data).expect("frame"))
}

/// Expedited SDO download to node 1 (CiA 301 §7.2.4.3.3: 23h/2Bh/2Fh for 4/2/1 bytes).
fn sdo_write(index: u16, sub: u8, value: &[u8]) -> Input {
    let cs = match value.len() {
        1 => 0x2F,
        2 => 0x2B,
        _ => 0x23,
    };
    let [lo, hi] = index.to_le_bytes();
    let mut data = [cs, lo, hi, sub, 0, 0, 0, 0];
    data[4..4 + value.len().min(4)].copy_from_slice(&value[..value.len().min(4)]);
    can(0x601, &data)
}

fn sdo_read(index: u16, sub: u8) -> Input {
    let [lo, hi] = index.to_le_bytes();
    can(0x601, &[0x40, lo, hi, sub, 0, 0, 0, 0])
}

/// FHPP FC 17h: write the 8 output bytes (CCON, CPOS, …), read the 8 input bytes.
fn fhpp_cycle(tid: u16, ccon: u8, cpos: u8) -> Input {
    let [t0, t1] = tid.to_be_bytes();
    Input::Modbus {
        drive: 0,
        bytes: vec![
            t0, t1, 0, 0, 0, 19, 1, 0x17, 0, 0, 0, 4, 0, 0, 0, 4, 8, ccon, cpos, 0, 0, 0, 0, 0, 0,
        ],
    }
}

/// The EtherCAT script, from `t0`: SOEM's start-up to Pre-Op with the mailbox, then CoE
/// writes that enable the drive in profile velocity, then 6064h uploads, each answer read
/// from SM1 one millisecond later.
fn ethercat_inputs(t0: u64) -> Vec<(Duration, Input)> {
    let mut script = vec![
        bwr(0x0120, &[0x11, 0]),
        set_station(),
        mailbox_sms(),
        fpwr(0x0120, &[0x02, 0x00]),
    ];
    let mut next = mailbox_counters();
    for (index, data) in [
        (0x6060u16, vec![3u8]),
        (0x60FF, 300_000i32.to_le_bytes().to_vec()),
        (0x6040, vec![0x06, 0]),
        (0x6040, vec![0x07, 0]),
        (0x6040, vec![0x0F, 0]),
    ] {
        script.push(coe_download(next(), index, 0, &data));
        script.push(fprd(0x1080, 0x80));
    }
    for _ in 0..20 {
        script.push(coe(next(), &[0x40, 0x64, 0x60, 0]));
        script.push(fprd(0x1080, 0x80));
    }
    script
        .into_iter()
        .enumerate()
        .map(|(i, input)| (ms(t0 + 10 * i as u64), input))
        .collect()
}

/// The script: NMT start, CiA 402 enable and a profile-position move on CAN; FHPP enable and
/// cyclic telegrams on Modbus; position read back on both.
fn inputs() -> Vec<(Duration, Input)> {
    let mut v = vec![
        (ms(5), can(0x000, &[0x01, 0x01])),
        (ms(10), sdo_write(0x6060, 0, &[1])),
        (ms(20), sdo_write(0x6040, 0, &[0x06, 0])),
        (ms(30), sdo_write(0x6040, 0, &[0x07, 0])),
        (ms(40), sdo_write(0x6040, 0, &[0x0F, 0])),
        (ms(50), sdo_write(0x607A, 0, &10_000i32.to_le_bytes())),
        (ms(60), sdo_write(0x6040, 0, &[0x1F, 0])),
        (ms(70), sdo_write(0x6040, 0, &[0x0F, 0])),
    ];
    for i in 0..40u16 {
        let t = 100 + u64::from(i) * 25;
        v.push((ms(t), sdo_read(0x6064, 0)));
        // ENABLE + STOP, HALT released (CMMO-ST §5: CCON 03h, CPOS 01h).
        v.push((ms(t + 3), fhpp_cycle(i, 0x03, 0x01)));
    }
    v.extend(ethercat_inputs(7));
    v.sort_by_key(|(t, _)| *t);
    v
}

fn cmmo_st() -> ModbusDrive {
    let desc = devices::by_name("cmmo-st").expect("cmmo-st");
    let od = od::ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).expect("od");
    let dev = drive::vendors::festo_cmmo_st::device::FhppDevice::new(od, Default::default());
    ModbusDrive::without_listener(
        Box::new(FhppModbus::new(dev, None)),
        ModbusConfig::default(),
    )
}

/// One run: every output as (time, tag, bytes).
fn run() -> Vec<(Duration, u8, Vec<u8>)> {
    let desc = devices::by_name("cmmp-as").expect("cmmp-as");
    let drive =
        Station::with_settings(desc, 1, None, vec![], Some(Default::default())).expect("drive");
    let mut cell = CanCell::one_bus(vec![drive]);
    let mut modbus = vec![cmmo_st()];
    let mut chain = SlaveChain::empty();
    let spec = drivetwin::cell::config::CellFile::single("cmmp-as", 2)
        .drives(drivetwin::vendors::VENDORS.runtime)
        .expect("spec")
        .remove(0);
    chain
        .push(desc, own_drive(spec, None).expect("drive"))
        .expect("slave");
    let mut chains = vec![chain];
    let mut outputs = Vec::new();
    run_virtual_mixed(
        &mut cell,
        &mut modbus,
        &mut chains,
        &inputs(),
        Duration::from_millis(1200),
        &mut |t, o| match o {
            Output::Can(f) => {
                let mut b = u16::try_from(f.id)
                    .expect("standard id")
                    .to_le_bytes()
                    .to_vec();
                b.extend_from_slice(f.payload());
                outputs.push((t, 0, b));
            }
            Output::Modbus { drive, bytes } => {
                outputs.push((t, 1 + drive as u8, bytes.to_vec()));
            }
            Output::Ethercat { chain, frame } => {
                outputs.push((t, 10 + chain as u8, frame.to_vec()));
            }
            Output::Serial { line, bytes } => {
                outputs.push((t, 20 + line as u8, bytes.to_vec()));
            }
        },
    );
    outputs
}

/// Position actual values (6064h) from the SDO upload answers of node 1.
fn can_positions(outputs: &[(Duration, u8, Vec<u8>)]) -> Vec<i32> {
    outputs
        .iter()
        .filter(|(_, tag, b)| *tag == 0 && b.len() == 10 && b[..2] == 0x581u16.to_le_bytes())
        .filter(|(_, _, b)| b[2] == 0x43 && b[3..5] == [0x64, 0x60])
        .map(|(_, _, b)| i32::from_le_bytes([b[6], b[7], b[8], b[9]]))
        .collect()
}

/// Position actual values (6064h) of the CoE upload answers read from the EtherCAT slave's SM1.
fn ethercat_positions(outputs: &[(Duration, u8, Vec<u8>)]) -> Vec<i32> {
    let mut positions = Vec::new();
    for (_, _, b) in outputs.iter().filter(|(_, tag, _)| *tag == 10) {
        let eth = EthernetFrame::new_checked(&b[..]).expect("ethernet");
        let frame = Frame::new_checked(eth.payload()).expect("frame");
        for d in frame.datagrams().flatten() {
            let data = d.data();
            let upload = data.len() == 0x80 && data[8] == 0x43 && data[9..11] == [0x64, 0x60];
            if d.ado() == 0x1080 && d.wkc() == 1 && upload {
                positions.push(i32::from_le_bytes([data[12], data[13], data[14], data[15]]));
            }
        }
    }
    positions
}

#[test]
fn can_ethercat_and_modbus_inputs_give_the_same_outputs_bit_for_bit() {
    let first = run();
    let second = run();
    assert_eq!(first, second);
    // Not a quiet cell: the CMMP-AS moved and the CMMO-ST answered every telegram.
    let ecat = ethercat_positions(&first);
    assert_eq!(ecat.len(), 20, "every CoE 6064h upload answered");
    assert!(
        ecat.windows(2).all(|w| w[1] > w[0]),
        "the EtherCAT CMMP-AS turns (profile velocity): {ecat:?}"
    );
    let positions = can_positions(&first);
    assert_eq!(positions.len(), 40, "every 6064h upload answered");
    assert!(
        positions.first() != positions.last(),
        "the CMMP-AS moves: {positions:?}"
    );
    let answers: Vec<_> = first.iter().filter(|(_, tag, _)| *tag == 1).collect();
    assert_eq!(answers.len(), 40);
    // FC 17h answer: MBAP (7) + FC + byte count + 8 input bytes; SCON is the first of them.
    assert!(answers
        .iter()
        .all(|(_, _, b)| b.len() == 17 && b[7] == 0x17));
    let scons: Vec<u8> = answers.iter().map(|(_, _, b)| b[9]).collect();
    assert!(
        scons.iter().any(|s| s & 0x01 != 0),
        "the CMMO-ST is enabled (SCON.ENABLED): {scons:02X?}"
    );
}

/// A slave whose drive is a CANopen node of the cell's second bus (`allow_unreal_interfaces`)
/// reaches that very station on the virtual clock: the chain joins the cell's list and names
/// it by id, as in the cell loop. A profile velocity written over CoE is the one the CAN
/// side's dictionary holds.
#[test]
fn a_slave_reaches_its_drive_on_the_second_bus() {
    let desc = devices::by_name("cmmp-as").expect("cmmp-as");
    let station = |node| {
        Station::with_settings(desc, node, None, vec![], Some(Default::default())).expect("drive")
    };
    let mut cell = CanCell::one_bus(vec![station(1)]);
    cell.add_bus(vec![station(2)]);
    let mut chain = SlaveChain::empty();
    let id = cell.buses[1].members()[0];
    chain
        .push(desc, SlaveDrive::Station { id, bus: Some(1) })
        .expect("slave");
    let mut chains = vec![chain];
    run_virtual_mixed(
        &mut cell,
        &mut [],
        &mut chains,
        &ethercat_inputs(7),
        Duration::from_millis(400),
        &mut |_, _| {},
    );
    assert!(matches!(
        chains[0].drive(0),
        Some(SlaveDrive::Station { bus: Some(1), .. })
    ));
    let on_bus = |bus: usize| {
        let d = cell.station(cell.buses[bus].members()[0]).expect("station");
        let mut v = [0u8; 4];
        od::ObjectAccess::read(&d.model, 0x60FF, 0, &mut v).expect("60FFh");
        i32::from_le_bytes(v)
    };
    assert_eq!(on_bus(1), 300_000, "written over CoE");
    assert_eq!(on_bus(0), 0, "the first bus's drive is another");
}

/// The cell's one timeline on the virtual clock: a message planned for an EtherCAT chain's
/// own drive (a station that joins the cell with its chain, after the CAN bus's) and one for
/// a CMMO-ST on Modbus TCP are carried out at their time, with no master sending a frame.
#[test]
fn planned_messages_reach_a_chains_own_drive_and_a_cmmo_st() {
    use drivetwin::cell::diagnostics::{Action, Planned, PlannedDiagnostic};
    use drivetwin::cell::stations::StationId;
    let message = |number: &str| {
        Planned::Diagnostic(PlannedDiagnostic {
            at_ms: 30,
            number: number.into(),
            action: Action::Raise,
        })
    };
    // Run until `until` ms: whether the slave's 43-0 and the CMMO-ST's 2Fh are active.
    let run = |until: u64| {
        let desc = devices::by_name("cmmp-as").expect("cmmp-as");
        let drive =
            Station::with_settings(desc, 1, None, vec![], Some(Default::default())).expect("drive");
        let mut cell = CanCell::one_bus(vec![drive]);
        let mut modbus = vec![cmmo_st()];
        let spec = drivetwin::cell::config::CellFile::single("cmmp-as", 2)
            .drives(drivetwin::vendors::VENDORS.runtime)
            .expect("spec")
            .remove(0);
        let mut chain = SlaveChain::empty();
        chain
            .push(desc, own_drive(spec, None).expect("drive"))
            .expect("slave");
        // The CMMO-ST is a station of its own once its front end joins the cell; the
        // chain's own drive joins the list after it.
        let cmmo = modbus[0]
            .join(&mut cell.stations)
            .expect("the CMMO-ST's station");
        let slave = StationId::from_index(cell.stations.len());
        let at = od::Instant::from_millis(30);
        cell.plan(at, slave, message("43-0"));
        cell.plan(at, cmmo, message("2Fh"));
        run_virtual_mixed(
            &mut cell,
            &mut modbus,
            &mut [chain],
            &[],
            ms(until),
            &mut |_, _| {},
        );
        let on_slave = cell
            .diagnostics(slave)
            .expect("the slave's station")
            .iter()
            .any(|d| d.active && d.row.number == "43-0");
        let on_cmmo_st = cell
            .diagnostics(cmmo)
            .expect("the CMMO-ST's station")
            .iter()
            .any(|d| d.active && d.row.number == "2Fh");
        (on_slave, on_cmmo_st)
    };
    assert_eq!(run(29), (false, false), "not before 30 ms");
    assert_eq!(run(31), (true, true), "both at 30 ms");
}

/// A CMMO-ST's Modbus TCP front end holds its drive until it joins the cell; then the drive
/// is a station of the list (no CANopen node, its register image as its model), joined once,
/// and the front end answers from that station: a read of the input telegram (registers
/// 0…3) gives the power-on status (SCON 10h in the high byte of register 0, SPOS 04h in its
/// low byte).
#[test]
fn a_cmmo_st_joins_the_cell_as_a_station_and_is_served_from_it() {
    let desc = devices::by_name("cmmp-as").expect("cmmp-as");
    let drive =
        Station::with_settings(desc, 1, None, vec![], Some(Default::default())).expect("drive");
    let mut cell = CanCell::one_bus(vec![drive]);
    let mut m = cmmo_st();
    assert_eq!(m.station(), None, "not in the cell before it joins");
    let id = m.join(&mut cell.stations).expect("joined");
    assert_eq!(id.index(), 1, "after the bus's station");
    assert_eq!(m.join(&mut cell.stations), Some(id), "joins once");
    assert_eq!(cell.stations.len(), 2);
    let station = cell.station(id).expect("the CMMO-ST's station");
    assert!(station.canopen.is_none());
    assert!(station.model.register_image().is_some());
    assert_eq!(station.od().description().name, "cmmo-st");
    assert_eq!(cell.bus_of(id), None, "on no CAN bus");
    m.open_connection(od::Instant::ZERO, &mut cell.stations);
    // Function 03h, registers 0…3, transaction 7, unit 1.
    let request = [0, 7, 0, 0, 0, 6, 1, 3, 0, 0, 0, 4];
    let mut answer = Vec::new();
    m.answer(&request, od::Instant::ZERO, &mut answer, &mut cell.stations)
        .expect("answered");
    assert_eq!(answer.len(), 17, "{answer:?}");
    assert_eq!(answer[..11], [0, 7, 0, 0, 0, 11, 1, 3, 8, 0x10, 0x04]);
}
