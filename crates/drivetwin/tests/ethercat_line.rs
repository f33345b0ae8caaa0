//! The faults of a real line on a chain of three CMMP-AS, on the virtual clock, with the
//! datagrams SOEM sends: a cable pulled behind the first slave (the frame returns from it, the
//! master counts one slave, the others' process-data watchdogs expire and their drives raise
//! 62-5), plugged back (all three found again); a slave powered off (it and those behind it
//! vanish) and on (AL Init, registers at reset); the master's own cable pulled (no frame
//! returns).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

#[path = "support/ecat_inputs.rs"]
mod ecat_inputs;
use ecat_inputs::{phys, sm};

use std::time::Duration;

use drivetwin::cell::config::CellFile;
use drivetwin::ecat::chain::SlaveChain;
use ethercat::datagram::Command;
use ethercat::frame::{Address, EthernetFrame, Frame, FrameWriter};
use ethercat::{AlState, AlStatusCode, Fmmu, FrameOutcome};
use od::{Instant, ObjectAccess};

const SLAVES: u16 = 3;
const SM2: u16 = 0x1100;
const SM3: u16 = 0x1180;

struct Master {
    cell: SlaveChain,
    now: Instant,
}

struct Reply {
    wkc: u16,
    data: Vec<u8>,
}

impl Master {
    fn send(&mut self, c: Command, a: Address, d: &[u8]) -> Option<Reply> {
        let mut buf = vec![0u8; 1514];
        let mut w = FrameWriter::ethernet(&mut buf, [0x01; 6]).unwrap();
        w.push(c, 0, a, d).unwrap();
        let n = w.finish();
        buf.truncate(n);
        if !self.cell.on_frame(self.now, &mut buf).forward() {
            return None;
        }
        let eth = EthernetFrame::new_checked(&buf[..]).unwrap();
        let f = Frame::new_checked(eth.payload()).unwrap();
        let d = f.datagrams().next().unwrap().unwrap();
        Some(Reply {
            wkc: d.wkc(),
            data: d.data().to_vec(),
        })
    }
    /// DL status 0x0110 of `station`, read over the wire.
    fn dl_status(&mut self, station: u16) -> u16 {
        let r = self
            .send(Command::Fprd, phys(station, 0x0110), &[0, 0])
            .unwrap();
        assert_eq!(r.wkc, 1, "station {station:#x} answers");
        u16::from_le_bytes([r.data[0], r.data[1]])
    }
    fn wkc(&mut self, c: Command, a: Address, d: &[u8]) -> u16 {
        self.send(c, a, d).unwrap().wkc
    }
    fn fpwr(&mut self, station: u16, ado: u16, d: &[u8]) {
        assert_eq!(
            self.wkc(Command::Fpwr, phys(station, ado), d),
            1,
            "{ado:#x}"
        );
    }
    fn al_state(&self, i: usize) -> AlState {
        self.cell.esc(i).unwrap().al_state()
    }
    /// One cycle of the process data: 2 output and 2 input bytes per slave.
    fn lrw(&mut self) -> u16 {
        self.now = self.now + Duration::from_millis(1);
        self.cell.poll(self.now);
        let data = vec![0u8; 4 * usize::from(SLAVES)];
        self.send(Command::Lrw, Address::Logical(0), &data)
            .map_or(0, |r| r.wkc)
    }
    fn slaves_found(&mut self) -> u16 {
        self.send(Command::Brd, phys(0, 0), &[0, 0])
            .map_or(0, |r| r.wkc)
    }
}

fn read_u16(dev: &dyn ObjectAccess, index: u16) -> u16 {
    let mut b = [0u8; 2];
    let _ = dev.read(index, 0, &mut b).unwrap();
    u16::from_le_bytes(b)
}

fn three_in_op() -> Master {
    let mut file = CellFile::single("cmmp-as", 1);
    for node in 2..=SLAVES {
        let mut d = file.drive[0].clone();
        d.node = node as u8;
        file.drive.push(d);
    }
    let mut m = Master {
        cell: SlaveChain::from_cell_file(&file, drivetwin::vendors::VENDORS.runtime).unwrap(),
        now: Instant::from_millis(1),
    };
    m.cell.boot(m.now);
    assert_eq!(m.slaves_found(), SLAVES);
    for i in 0..SLAVES {
        let r = m.wkc(
            Command::Apwr,
            phys(i.wrapping_neg(), 0x0010),
            &(0x1001 + i).to_le_bytes(),
        );
        assert_eq!(r, 1);
    }
    for i in 0..SLAVES {
        let st = 0x1001 + i;
        let mut mbx = sm(0x1000, 0x80, 0x26);
        mbx.extend_from_slice(&sm(0x1080, 0x80, 0x22));
        m.fpwr(st, 0x0800, &mbx);
        m.fpwr(st, 0x0120, &[0x02, 0]);
        // SM2 watchdog-triggered (control bit 6), as SOEM takes it from the SII.
        m.fpwr(st, 0x0810, &sm(SM2, 2, 0x64));
        m.fpwr(st, 0x0818, &sm(SM3, 2, 0x20));
        let base = 4 * u32::from(i);
        m.fpwr(
            st,
            0x0600,
            &Fmmu::bytes(base, 2, SM2, false, true).to_bytes(),
        );
        m.fpwr(
            st,
            0x0610,
            &Fmmu::bytes(base + 2, 2, SM3, true, false).to_bytes(),
        );
        m.fpwr(st, 0x0120, &[0x04, 0]);
        m.fpwr(st, 0x0120, &[0x08, 0]);
        assert_eq!(m.al_state(usize::from(i)), AlState::Op, "slave {i}");
    }
    assert_eq!(m.lrw(), 3 * SLAVES);
    m
}

#[test]
fn a_pulled_cable_cuts_off_the_slaves_behind_it_until_plugged_back() {
    let mut m = three_in_op();
    m.cell.pull_cable(1).unwrap();
    assert_eq!(
        m.slaves_found(),
        1,
        "the frame returns from the first slave"
    );
    assert_eq!(m.lrw(), 3, "the working counter of one slave");
    // The watchdog (0x0420 × (0x0400 + 2) × 40 ns = 100 ms at reset values) expires behind
    // the cut; the first slave, still served, stays in Op.
    for _ in 0..120 {
        assert_eq!(m.lrw(), 3);
    }
    assert_eq!(m.al_state(0), AlState::Op);
    for i in 1..usize::from(SLAVES) {
        let esc = m.cell.esc(i).unwrap();
        assert_eq!(esc.al_state(), AlState::SafeOp, "slave {i}");
        assert_eq!(esc.al_status_code(), AlStatusCode::SYNC_MANAGER_WATCHDOG);
        assert_eq!(m.cell.device(i).unwrap().watchdog_expiries, 1);
        // The drive raised 62-5 "EtherCAT: faulty cyclic data transfer" with its reaction
        // (configurable, by default the quick-stop ramp): Fault.
        let model = m.cell.model(i).unwrap();
        assert_eq!(read_u16(model, 0x6041) & 0x4F, 0x08, "slave {i}: fault");
    }
    assert_eq!(m.cell.device(0).unwrap().watchdog_expiries, 0);

    m.cell.plug_cable();
    assert_eq!(m.slaves_found(), SLAVES, "found again");
    // Safe-Op + error: the master acknowledges and asks for Op again.
    for i in 1..SLAVES {
        m.fpwr(0x1001 + i, 0x0120, &[0x18, 0]);
        assert_eq!(m.al_state(usize::from(i)), AlState::Op);
    }
    assert_eq!(m.lrw(), 3 * SLAVES);
}

/// DL status 0x0110 (ETG.1000.4): inside the line ports 0 and 1 have a link with their loops
/// open, the last slave's port 1 none with its loop closed; the cable pulled behind the first
/// slave takes its port 1 link and closes that loop (the frame turns round there) and takes
/// the second slave's port 0 link; plugged back, the links are there again.
#[test]
fn the_dl_status_shows_a_pulled_cable_and_its_return() {
    let mut m = three_in_op();
    assert_eq!(m.dl_status(0x1001), 0x5A33);
    assert_eq!(m.dl_status(0x1002), 0x5A33);
    assert_eq!(m.dl_status(0x1003), 0x5613, "the last slave: line end");

    m.cell.pull_cable(1).unwrap();
    let first = m.dl_status(0x1001);
    assert_eq!(first & 0x0020, 0, "port 1: no link");
    assert_eq!(
        first & 0x0C00,
        0x0400,
        "port 1: loop closed, no communication"
    );
    assert_eq!(first, 0x5613);
    // No frame reaches the second slave: its ESC shows it.
    let second = m.cell.esc(1).unwrap().read_u16(0x0110);
    assert_eq!(second & 0x0310, 0x0100, "port 0: no link, loop closed");

    m.cell.plug_cable();
    assert_eq!(m.dl_status(0x1001), 0x5A33, "port 1: link again");
    assert_eq!(m.dl_status(0x1002), 0x5A33);
    assert_eq!(m.dl_status(0x1003), 0x5613);
}

/// A slave without power takes the link of the ports facing it; powered on, its ESC starts
/// from reset and shows the links it has.
#[test]
fn the_dl_status_shows_a_slave_without_power() {
    let mut m = three_in_op();
    m.cell.power_off(1).unwrap();
    assert_eq!(
        m.dl_status(0x1001),
        0x5613,
        "port 1 towards the dark slave: no link"
    );
    m.cell
        .power_on(1, m.now, &mut drivetwin::ecat::chain::NoBuses)
        .unwrap();
    assert_eq!(m.dl_status(0x1001), 0x5A33);
    assert_eq!(m.cell.esc(1).unwrap().read_u16(0x0110), 0x5A33);
}

#[test]
fn a_slave_powered_off_breaks_the_line_and_comes_back_in_init() {
    let mut m = three_in_op();
    m.cell.power_off(1).unwrap();
    assert_eq!(m.slaves_found(), 1, "slave 1 and the one behind it vanish");
    assert_eq!(m.lrw(), 3);
    m.cell
        .power_on(1, m.now, &mut drivetwin::ecat::chain::NoBuses)
        .unwrap();
    assert_eq!(m.slaves_found(), SLAVES);
    let esc = m.cell.esc(1).unwrap();
    assert_eq!(esc.al_state(), AlState::Init);
    assert_eq!(esc.station_address(), 0, "registers at their reset values");
    assert_eq!(esc.fmmu(0).map(|f| f.enable), Some(false));
    // The slave behind kept its power and its state.
    assert_eq!(m.cell.esc(2).unwrap().station_address(), 0x1003);
    // Slave 0 and 2 still exchange (2 + 1 each); slave 1 has no FMMU.
    assert_eq!(m.lrw(), 6);
    // The master finds it by position and configures it again.
    let r = m.wkc(Command::Aprd, phys(1u16.wrapping_neg(), 0x0010), &[0, 0]);
    assert_eq!(r, 1);
}

#[test]
fn the_masters_own_cable_pulled_returns_nothing() {
    let mut m = three_in_op();
    m.cell.pull_cable(0).unwrap();
    let mut buf = vec![0u8; 64];
    let mut w = FrameWriter::ethernet(&mut buf, [0x01; 6]).unwrap();
    w.push(Command::Brd, 0, phys(0, 0), &[0, 0]).unwrap();
    let n = w.finish();
    buf.truncate(n);
    assert_eq!(m.cell.on_frame(m.now, &mut buf), FrameOutcome::Unreturned);
    assert!(
        m.cell.pull_cable(3).is_err(),
        "no cable behind the last slave"
    );
}

/// `examples/ethercat-64.toml`: 64 CMMP-AS on one chain; a broadcast read counts them all,
/// with the cable pulled after slave 32 it counts 32.
#[test]
fn the_64_drive_example_is_one_chain_of_64() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/ethercat-64.toml"
    );
    let file = CellFile::load(std::path::Path::new(path)).unwrap();
    let mut m = Master {
        cell: SlaveChain::from_cell_file(&file, drivetwin::vendors::VENDORS.runtime).unwrap(),
        now: Instant::from_millis(1),
    };
    m.cell.boot(m.now);
    assert_eq!(m.cell.len(), 64);
    assert_eq!(m.slaves_found(), 64);
    m.cell.pull_cable(32).unwrap();
    assert_eq!(m.slaves_found(), 32);
    m.cell.plug_cable();
    assert_eq!(m.slaves_found(), 64);
}
