//! The EtherCAT master's side of the virtual-clock tests and the chain's tests: frames of
//! datagrams addressed to the first slave (station 1001h) or to every slave, sync manager
//! registers and CoE SDO requests in its mailbox, as cell inputs.
#![allow(dead_code)]

use drivetwin::cell_loop::virtual_clock::Input;
use ethercat::datagram::Command;
use ethercat::frame::{Address, FrameWriter};

/// One EtherCAT frame of the master with the datagrams `reqs`.
pub fn ecat(reqs: &[(Command, Address, Vec<u8>)]) -> Input {
    let mut buf = vec![0u8; 1514];
    let mut w = FrameWriter::ethernet(&mut buf, [0x01; 6]).expect("writer");
    for (i, (c, a, d)) in reqs.iter().enumerate() {
        w.push(*c, i as u8, *a, d).expect("datagram");
    }
    let n = w.finish();
    buf.truncate(n);
    Input::Ethercat {
        chain: 0,
        frame: buf,
    }
}

pub const STATION: u16 = 0x1001;

/// The register `ado` of the slave at station address `adp`.
pub fn phys(adp: u16, ado: u16) -> Address {
    Address::Physical { adp, ado }
}

/// A broadcast write of `d` at register `ado` of every slave.
pub fn bwr(ado: u16, d: &[u8]) -> Input {
    ecat(&[(Command::Bwr, phys(0, ado), d.to_vec())])
}

/// A broadcast read of `len` bytes at register `ado` of every slave.
pub fn brd(ado: u16, len: usize) -> Input {
    ecat(&[(Command::Brd, phys(0, ado), vec![0; len])])
}

/// The first slave (position 0) gets the station address [`STATION`] (APWR of register
/// 0010h), as a master's configuration does.
pub fn set_station() -> Input {
    ecat(&[(
        Command::Apwr,
        phys(0, 0x0010),
        STATION.to_le_bytes().to_vec(),
    )])
}

/// SM0 and SM1 as the CMMP-AS's mailbox: out at 1000h, in at 1080h, 128 bytes each.
pub fn mailbox_sms() -> Input {
    fpwr(
        0x0800,
        &[sm(0x1000, 0x80, 0x26), sm(0x1080, 0x80, 0x22)].concat(),
    )
}

/// The mailbox counters of successive requests: 1 to 7 and round again (the mailbox header's
/// 3-bit Cnt, ETG.1000.4: 0 is its start value, 1 follows 7).
pub fn mailbox_counters() -> impl FnMut() -> u8 {
    let mut counter = 0u8;
    move || {
        counter = counter % 7 + 1;
        counter
    }
}

pub fn fpwr(ado: u16, d: &[u8]) -> Input {
    ecat(&[(Command::Fpwr, phys(STATION, ado), d.to_vec())])
}

pub fn fprd(ado: u16, len: usize) -> Input {
    ecat(&[(Command::Fprd, phys(STATION, ado), vec![0; len])])
}

/// A sync manager's 8 register bytes.
pub fn sm(start: u16, len: u16, control: u8) -> Vec<u8> {
    let mut v = start.to_le_bytes().to_vec();
    v.extend_from_slice(&len.to_le_bytes());
    v.extend_from_slice(&[control, 0, 0x01, 0]);
    v
}

/// A CoE SDO request (ETG.1000.6 §5.6.2) in the mailbox (SM0 at 1000h), counter `counter`.
pub fn coe(counter: u8, sdo: &[u8]) -> Input {
    let mut req = vec![0u8; 0x80];
    req[..8].copy_from_slice(&[10, 0, 0, 0, 0, 0x03 | counter << 4, 0x00, 0x20]);
    req[8..8 + sdo.len()].copy_from_slice(sdo);
    fpwr(0x1000, &req)
}

pub fn coe_download(counter: u8, index: u16, sub: u8, data: &[u8]) -> Input {
    let [i0, i1] = index.to_le_bytes();
    let mut sdo = vec![0x23 | ((4 - data.len() as u8) << 2), i0, i1, sub];
    sdo.extend_from_slice(data);
    coe(counter, &sdo)
}
