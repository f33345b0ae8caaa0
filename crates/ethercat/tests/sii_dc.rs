//! SII EEPROM interface (0x0500–0x050F) and distributed clocks (0x0900–0x09FF)
//! (the ESC reference kept beside the project, §2.4, §2.7, §8).

mod common;

use common::*;
use ethercat::datagram::Command;
use ethercat::{Eeprom, Esc, EscConfig};

const ST: u16 = 0x1001;

#[test]
fn sii_reads_through_0x0502() {
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    // Bit 6: 8-byte reads offered.
    assert_eq!(bus.fprd(ST, 0x0502, 2).u16() & 0x0040, 0x0040);
    assert_eq!(bus.sii_read(ST, 0x08, 4), vec![0x1D, 0, 0, 0]);
    assert_eq!(
        bus.sii_read(ST, 0x0A, 8),
        vec![0x78, 0x56, 0x34, 0x12, 2, 0, 0, 0]
    );
    assert_eq!(bus.sii_read(ST, 0x18, 4), vec![0x00, 0x10, 0x80, 0x00]);
    assert_eq!(bus.sii_read(ST, 0x1A, 4), vec![0x80, 0x10, 0x80, 0x00]);
    // Beyond the image: erased words.
    assert_eq!(bus.sii_read(ST, 0x7FFE, 8), vec![0xFF; 8]);
    // Every word, as ethercrab's dump would fetch it.
    let image = test_sii();
    for w in (0..image.len() / 2).step_by(4) {
        let got = bus.sii_read(ST, w as u32, 8);
        for (k, b) in got.iter().enumerate() {
            assert_eq!(*b, *image.get(2 * w + k).unwrap_or(&0xFF), "word {w}");
        }
    }
    // The data stays until the next command, whatever else is read meanwhile.
    bus.fpwr(ST, 0x0502, &[0x00, 0x01, 0x1C, 0x00, 0x00, 0x00]);
    bus.fprd(ST, 0x0008, 2);
    bus.fprd(ST, 0x0110, 2);
    assert_eq!(bus.fprd(ST, 0x0508, 4).data, vec![0x04, 0x00, 0x00, 0x00]);
    // Power-on values from the SII: PDI control 0x05.
    assert_eq!(bus.fprd(ST, 0x0140, 1).data, vec![0x05]);
}

#[test]
fn sii_read_by_bwr_to_all_slaves() {
    // KickCAT issues the read command with BWR and expects WKC = slave count.
    let mut bus = Bus::with_sii(3);
    bus.assign_addresses();
    assert_eq!(
        bus.bwr(0x0502, &[0x00, 0x01, 0x08, 0x00, 0x00, 0x00]).wkc,
        3
    );
    for i in 0..3 {
        assert_eq!(bus.fprd(0x1001 + i, 0x0508, 4).data, vec![0x1D, 0, 0, 0]);
    }
}

#[test]
fn sii_errors_writes_and_ownership() {
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    // Invalid command (SOEM 1.4 "reload" 0x0300): command error bit 13.
    bus.fpwr(ST, 0x0502, &[0x00, 0x03]);
    assert_eq!(bus.fprd(ST, 0x0502, 2).u16() & 0x2000, 0x2000);
    // NOP clears it.
    bus.fpwr(ST, 0x0502, &[0x00, 0x00]);
    assert_eq!(bus.fprd(ST, 0x0502, 2).u16(), 0x0040);
    // Write without write enable: bit 14.
    bus.fpwr(ST, 0x0508, &[0x34, 0x12]);
    bus.fpwr(ST, 0x0502, &[0x00, 0x02, 0x04, 0x00, 0x00, 0x00]);
    assert_eq!(bus.fprd(ST, 0x0502, 2).u16() & 0x4000, 0x4000);
    // Write with enable to a read-only image: refused (bit 13), image unchanged.
    bus.fpwr(ST, 0x0502, &[0x01, 0x02, 0x04, 0x00, 0x00, 0x00]);
    assert_eq!(bus.fprd(ST, 0x0502, 2).u16() & 0x6000, 0x2000);
    assert_eq!(bus.sii_read(ST, 0x04, 4), vec![0, 0, 0, 0]);
    // Ownership register: bit 0 reads back, 0x0501 stays 0.
    bus.fpwr(ST, 0x0500, &[0x02, 0xFF]);
    bus.fpwr(ST, 0x0500, &[0x01, 0x00]);
    assert_eq!(bus.fprd(ST, 0x0500, 2).data, vec![0x01, 0x00]);
}

#[test]
fn sii_write_to_writable_image() {
    let image: &'static mut [u8] = Box::leak(test_sii().into_boxed_slice());
    let cfg = EscConfig::from_sii(image);
    let mut bus = Bus::new(vec![Esc::new(cfg, Eeprom::Writable(image))]);
    bus.assign_addresses();
    bus.fpwr(ST, 0x0508, &[0xCD, 0xAB]);
    bus.fpwr(ST, 0x0502, &[0x01, 0x02, 0x04, 0x00, 0x00, 0x00]);
    assert_eq!(bus.fprd(ST, 0x0502, 2).u16() & 0xF800, 0);
    assert_eq!(bus.sii_read(ST, 0x04, 4), vec![0xCD, 0xAB, 0, 0]);
    // Write enable is self-clearing.
    assert_eq!(bus.fprd(ST, 0x0502, 2).u16() & 0x0001, 0);
}

#[test]
fn dc_latch_system_time_offset_and_delay() {
    let mut bus = Bus::plain(2);
    bus.assign_addresses();
    bus.now = od::Instant::from_nanos(5_000_000);
    // BWR 0x0900 latches receive times at every DC slave (ethercrab needs WKC = 2 here).
    assert_eq!(bus.bwr(0x0900, &[0xEE; 4]).wkc, 2);
    let r = bus.fprd(ST, 0x0900, 16);
    for p in 0..4 {
        assert_eq!(
            u32::from_le_bytes(r.data[4 * p..4 * p + 4].try_into().unwrap()),
            5_000_000
        );
    }
    assert_eq!(bus.fprd(ST, 0x0918, 8).u64(), 5_000_000);
    // Offset: system time = local + offset, advancing with now.
    let master = 1_000_000_000_000u64;
    bus.fpwr(ST, 0x0920, &(master - 5_000_000).to_le_bytes());
    assert_eq!(bus.fprd(ST, 0x0910, 8).u64(), master);
    bus.now = od::Instant::from_nanos(6_000_000);
    assert_eq!(bus.fprd(ST, 0x0910, 8).u64(), master + 1_000_000);
    assert_eq!(bus.fprd(ST, 0x0920, 8).u64(), master - 5_000_000);
    // Delay stored; a write to 0x0910 sets system time = written + delay.
    bus.fpwr(0x1002, 0x0928, &[100, 0, 0, 0]);
    assert_eq!(bus.fprd(0x1002, 0x0928, 4).u32(), 100);
    let r = bus.one(Command::Frmw, phys(ST, 0x0910), &[0; 8]);
    assert_eq!(r.wkc, 2);
    assert_eq!(r.u64(), master + 1_000_000);
    assert_eq!(bus.fprd(0x1002, 0x0910, 8).u64(), master + 1_000_000 + 100);
    // 0x092C holds the difference seen: received > local copy → sign bit 0.
    let diff = bus.fprd(0x1002, 0x092C, 4).u32();
    assert_eq!(diff & 0x8000_0000, 0);
    assert_eq!(diff, 0x7FFF_FFFF, "saturated magnitude");
    // A second FRMW finds them in sync.
    bus.one(Command::Frmw, phys(ST, 0x0910), &[0; 8]);
    assert_eq!(
        bus.fprd(0x1002, 0x092C, 4).u32(),
        0x8000_0000,
        "difference 0"
    );
}

#[test]
fn dc_sync0_configuration() {
    let mut bus = Bus::plain(1);
    bus.assign_addresses();
    bus.now = od::Instant::from_nanos(10_000_000);
    // ecx_dcsync0: 0x0981 = 0, 0x0980 = 0, read 0x0910, start, cycle, 0x0981 = 3.
    bus.fpwr(ST, 0x0981, &[0]);
    bus.fpwr(ST, 0x0980, &[0]);
    let t = bus.fprd(ST, 0x0910, 8).u64();
    let cycle = 1_000_000u32;
    let start = t + 100_000_000;
    bus.fpwr(ST, 0x0990, &start.to_le_bytes());
    bus.fpwr(ST, 0x09A0, &cycle.to_le_bytes());
    bus.fpwr(ST, 0x0981, &[0x03]);
    assert_eq!(bus.slaves[0].sync0_cycle_ns(), Some(cycle));
    assert_eq!(
        bus.fprd(ST, 0x0990, 8).u64(),
        start,
        "next SYNC0 = start while in the future"
    );
    bus.now = od::Instant::from_nanos(10_000_000 + 100_000_000 + 2_500_000);
    assert_eq!(bus.fprd(ST, 0x0990, 8).u64(), start + 3 * u64::from(cycle));
    assert_eq!(
        bus.slaves[0].next_sync0_at(bus.now),
        Some(start + 3_000_000)
    );
    assert_eq!(bus.fprd(ST, 0x09A0, 4).u32(), cycle);
    // Deactivate: plain storage again.
    bus.fpwr(ST, 0x0981, &[0]);
    assert_eq!(bus.slaves[0].sync0_cycle_ns(), None);
    // Speed counter start and filter depths are stored.
    bus.bwr(0x0930, &[0x00, 0x10]);
    bus.bwr(0x0934, &[0x00, 0x0C]);
    assert_eq!(bus.fprd(ST, 0x0930, 2).u16(), 0x1000);
    assert_eq!(bus.fprd(ST, 0x0934, 2).u16(), 0x0C00);
}

/// ethercrab's DC reset (spec §8.1): BWR zeros to 0x0910 feeds the time-control loop a
/// difference, BWR 0x0930 (speed counter start) then resets its filters, so the reference
/// clock, which only ever answers FRMW reads afterwards, reads difference 0 (ethercrab's
/// examples/dc.rs waits for 0x092C to settle).
#[test]
fn speed_counter_start_resets_the_system_time_difference() {
    let mut bus = Bus::plain(1);
    bus.assign_addresses();
    bus.now = od::Instant::from_nanos(31_000_000);
    bus.bwr(0x0910, &[0; 8]);
    assert_eq!(
        bus.fprd(ST, 0x092C, 4).u32(),
        0x8000_0000 | 31_000_000,
        "local copy ahead of the zero written"
    );
    bus.bwr(0x0934, &[0x00, 0x0C]);
    bus.bwr(0x0930, &[0x00, 0x10]);
    assert_eq!(bus.fprd(ST, 0x092C, 4).u32(), 0, "filters reset");
    assert_eq!(bus.fprd(ST, 0x0932, 2).u16(), 0);
    assert_eq!(bus.fprd(ST, 0x0930, 2).u16(), 0x1000, "stored");
    // Offset written, then only FRMW reads at the reference: the difference stays 0.
    bus.fpwr(ST, 0x0920, &1_000_000_000u64.to_le_bytes());
    for k in 0..10u64 {
        bus.now = od::Instant::from_nanos(32_000_000 + k * 1_000_000);
        bus.one(Command::Frmw, phys(ST, 0x0910), &[0; 8]);
    }
    assert_eq!(bus.fprd(ST, 0x092C, 4).u32(), 0);
}

#[test]
fn frmw_system_time_increases() {
    let mut bus = Bus::plain(1);
    bus.assign_addresses();
    let mut last = 0;
    for k in 1..100u64 {
        bus.now = od::Instant::from_nanos(k * 1_000_000);
        let r = bus.one(Command::Frmw, phys(ST, 0x0910), &[0; 8]);
        assert_eq!(r.wkc, 1);
        assert!(r.u64() > last);
        last = r.u64();
    }
}

/// A slave whose oscillator runs 50 ppm fast: the master's cyclic FRMW of the reference's
/// system time (SOEM's DC sync, spec §8.1) finds it 50 ns ahead after each 1 ms cycle, stores
/// that in 0x092C (sign bit: the local copy was ahead) and brings its system time back onto
/// the reference's; the reference itself drifts not.
#[test]
fn a_drifting_clock_is_corrected_by_each_system_time_write() {
    let mut bus = Bus::plain(2);
    bus.assign_addresses();
    bus.now = od::Instant::from_nanos(1_000_000);
    bus.slaves[1].set_clock_error(
        bus.now,
        ethercat::ClockError {
            drift_ppb: 50_000,
            ..ethercat::ClockError::NONE
        },
    );
    bus.one(Command::Frmw, phys(ST, 0x0910), &[0; 8]);
    for cycle in 1..=5u64 {
        bus.now = od::Instant::from_nanos(1_000_000 + cycle * 1_000_000);
        assert_eq!(
            bus.fprd(0x1002, 0x0910, 8).u64() - bus.fprd(ST, 0x0910, 8).u64(),
            50,
            "50 ppm of 1 ms ahead before the correction"
        );
        let r = bus.one(Command::Frmw, phys(ST, 0x0910), &[0; 8]);
        assert_eq!(r.wkc, 2);
        assert_eq!(bus.fprd(0x1002, 0x092C, 4).u32(), 0x8000_0000 | 50);
        assert_eq!(
            bus.fprd(0x1002, 0x0910, 8).u64(),
            bus.fprd(ST, 0x0910, 8).u64(),
            "corrected"
        );
    }
    // The offset register carries the corrections: 5 × 50 ns.
    assert_eq!(
        bus.fprd(0x1002, 0x0920, 8).u64().wrapping_neg(),
        250,
        "offset follows the corrections"
    );
}
