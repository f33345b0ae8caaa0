//! How a master configures a chain of CMMP-AS for process data, as SOEM does from their SII:
//! the mailbox sync managers, then per slave SM2 / SM3 and two FMMUs that place every slave's
//! outputs, then its inputs, in one LRW. The benches that drive such a chain (in process and
//! over a veth pair) share it.

#![allow(dead_code)]

use ethercat::register::RegisterAddress;
use ethercat::{Fmmu, SyncManager};

/// SOEM's primary source MAC; the slave sets bit 0x02 of the first byte on the way back.
pub const MASTER_MAC: [u8; 6] = [0x01; 6];
/// The station address of the first slave; the k-th has `STATION + k`.
pub const STATION: u16 = 0x1001;
/// The CMMP-AS SII: mailbox out 1000h / in 1080h, 128 bytes each (SII word 18h), process
/// data SM2 at 1100h, SM3 at 1180h.
pub const MAILBOX_OUT: u16 = 0x1000;
pub const MAILBOX_IN: u16 = 0x1080;
pub const MAILBOX_LEN: u16 = 0x80;
pub const SM2: u16 = 0x1100;
pub const SM3: u16 = 0x1180;
/// Default mapping: 1600h = controlword, 1A00h = statusword.
pub const OUTPUT_BYTES: u16 = 2;
pub const INPUT_BYTES: u16 = 2;
/// LRW working counter per slave: outputs written (+2) and inputs read (+1).
pub const WKC_PER_SLAVE: u16 = 3;

/// The two mailbox sync managers (SM0 and SM1, written together from SM0's register on).
pub fn mailboxes() -> Vec<u8> {
    let mut bytes = SyncManager::new(MAILBOX_OUT, MAILBOX_LEN, 0x26, true)
        .to_bytes()
        .to_vec();
    bytes.extend_from_slice(&SyncManager::new(MAILBOX_IN, MAILBOX_LEN, 0x22, true).to_bytes());
    bytes
}

/// Slave `k` of a chain of `slaves` set up for process data: `fpwr(station, register, data)`
/// is called for SM2, SM3 and the output and input FMMUs. The LRW's image holds every
/// slave's outputs first, then every slave's inputs.
pub fn configure_process_data(k: u16, slaves: u16, mut fpwr: impl FnMut(u16, u16, &[u8])) {
    let station = STATION + k;
    fpwr(
        station,
        RegisterAddress::sync_manager(2),
        &SyncManager::new(SM2, OUTPUT_BYTES, 0x64, true).to_bytes(),
    );
    fpwr(
        station,
        RegisterAddress::sync_manager(3),
        &SyncManager::new(SM3, INPUT_BYTES, 0x20, true).to_bytes(),
    );
    let outputs = u32::from(slaves) * u32::from(OUTPUT_BYTES);
    let out_at = u32::from(k) * u32::from(OUTPUT_BYTES);
    let in_at = outputs + u32::from(k) * u32::from(INPUT_BYTES);
    fpwr(
        station,
        RegisterAddress::fmmu(0),
        &Fmmu::bytes(out_at, OUTPUT_BYTES, SM2, false, true).to_bytes(),
    );
    fpwr(
        station,
        RegisterAddress::fmmu(1),
        &Fmmu::bytes(in_at, INPUT_BYTES, SM3, true, false).to_bytes(),
    );
}
