//! Every datagram command, its working counter and its addressing (the ESC reference kept beside
//! the project, §1).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod common;

use common::*;
use ethercat::datagram::Command;
use ethercat::frame::{Address, FrameWriter};
use ethercat::{Esc, FrameOutcome, WireError};
use proptest::prelude::*;

#[test]
fn brd_counts_slaves_and_ors_data() {
    let mut bus = Bus::plain(3);
    let r = bus.brd(0x0000, 2);
    assert_eq!(r.wkc, 3);
    // type 0x04 | revision 0x01, ORed over three identical slaves.
    assert_eq!(r.data, vec![0x04, 0x01]);
    // Every slave increments ADP.
    assert_eq!(r.adp, 3);
    // OR with what the master sent.
    let r = bus.one(Command::Brd, phys(0, 0x0000), &[0x80, 0x10]);
    assert_eq!(r.data, vec![0x84, 0x11]);
    // Different values are ORed: give the slaves different station addresses.
    bus.assign_addresses();
    let r = bus.brd(0x0010, 2);
    assert_eq!(r.u16(), 0x1001 | 0x1002 | 0x1003);
}

#[test]
fn bwr_writes_every_slave() {
    let mut bus = Bus::plain(3);
    let r = bus.bwr(0x0F80, &[1, 2, 3]);
    assert_eq!(r.wkc, 3);
    assert_eq!(r.data, vec![1, 2, 3], "write data returned unchanged");
    for s in &bus.slaves {
        assert_eq!(&s.memory()[0xF80..0xF83], &[1, 2, 3]);
    }
}

#[test]
fn brw_ors_old_and_writes_new() {
    let mut bus = Bus::plain(2);
    bus.bwr(0x0F80, &[0x01]);
    let r = bus.one(Command::Brw, phys(0, 0x0F80), &[0x10]);
    // read +1, write +2 per slave.
    assert_eq!(r.wkc, 6);
    assert_eq!(r.data, vec![0x11]);
    // Each slave writes the data as it arrives there: the second one already sees the
    // first one's read ORed in (the frame is processed on the fly, slave after slave).
    assert_eq!(bus.slaves[0].memory()[0xF80], 0x10);
    assert_eq!(bus.slaves[1].memory()[0xF80], 0x11);
}

#[test]
fn auto_increment_addressing() {
    let mut bus = Bus::plain(3);
    // APRD position 0 hits the first slave only; ADP comes back incremented by 3.
    let r = bus.aprd(0, 0x0000, 1);
    assert_eq!(r.wkc, 1);
    assert_eq!(r.adp, 3);
    // Position -2 = 0xFFFE hits the third.
    let r = bus.apwr(0xFFFE, 0x0010, &[0x34, 0x12]);
    assert_eq!(r.wkc, 1);
    assert_eq!(r.adp, 1);
    assert_eq!(bus.slaves[2].station_address(), 0x1234);
    assert_eq!(bus.slaves[0].station_address(), 0);
    assert_eq!(bus.slaves[1].station_address(), 0);
    // Position beyond the chain: nobody.
    let r = bus.aprd(0xFFFC, 0x0000, 1);
    assert_eq!(r.wkc, 0);
    assert_eq!(r.data, vec![0]);
    assert_eq!(r.adp, 0xFFFF);
}

#[test]
fn aprw_reads_old_and_writes_new() {
    let mut bus = Bus::plain(2);
    bus.apwr(0xFFFF, 0x0F80, &[0xAA, 0xBB]);
    let r = bus.one(Command::Aprw, phys(0xFFFF, 0x0F80), &[0x01, 0x02]);
    assert_eq!(r.wkc, 3);
    assert_eq!(r.data, vec![0xAA, 0xBB]);
    assert_eq!(&bus.slaves[1].memory()[0xF80..0xF82], &[0x01, 0x02]);
    assert_eq!(&bus.slaves[0].memory()[0xF80..0xF82], &[0, 0]);
}

#[test]
fn configured_addressing_hit_and_miss() {
    let mut bus = Bus::plain(3);
    bus.assign_addresses();
    let r = bus.fprd(0x1002, 0x0010, 2);
    assert_eq!(r.wkc, 1);
    assert_eq!(r.u16(), 0x1002);
    assert_eq!(r.adp, 0x1002, "FPxx leave the address unchanged");
    let r = bus.fprd(0x2000, 0x0010, 2);
    assert_eq!(r.wkc, 0);
    assert_eq!(r.data, vec![0, 0]);
    let r = bus.fpwr(0x1003, 0x0F80, &[7]);
    assert_eq!(r.wkc, 1);
    assert_eq!(bus.slaves[2].memory()[0xF80], 7);
    assert_eq!(bus.slaves[1].memory()[0xF80], 0);
    // FPRW: +3.
    let r = bus.one(Command::Fprw, phys(0x1003, 0x0F80), &[9]);
    assert_eq!(r.wkc, 3);
    assert_eq!(r.data, vec![7]);
    assert_eq!(bus.slaves[2].memory()[0xF80], 9);
}

#[test]
fn station_alias_only_when_enabled() {
    let mut image = test_sii();
    image[8] = 0xCD; // word 4: alias 0xABCD
    image[9] = 0xAB;
    let image: &'static [u8] = Box::leak(image.into_boxed_slice());
    let mut bus = Bus::new(vec![Esc::with_sii(image)]);
    assert_eq!(bus.fprd(0xABCD, 0x0012, 2).wkc, 0);
    // DL control bit 24 (byte 0x0103 bit 0): alias enable.
    bus.bwr(0x0103, &[0x01]);
    let r = bus.fprd(0xABCD, 0x0012, 2);
    assert_eq!(r.wkc, 1);
    assert_eq!(r.u16(), 0xABCD);
    // The alias is read-only for ECAT.
    bus.bwr(0x0012, &[0, 0]);
    assert_eq!(bus.fprd(0xABCD, 0x0012, 2).u16(), 0xABCD);
}

#[test]
fn frmw_reads_at_reference_writes_at_others() {
    let mut bus = Bus::plain(3);
    bus.assign_addresses();
    bus.slaves[1].memory(); // no-op: slaves share the clock in this simulation
                            // Give the reference (slave 0) a distinct system time via its offset.
    bus.fpwr(0x1001, 0x0920, &1_000_000u64.to_le_bytes());
    let r = bus.one(Command::Frmw, phys(0x1001, 0x0910), &[0; 8]);
    assert_eq!(r.wkc, 3, "one read + two writes");
    let t_ref = r.u64();
    assert_eq!(t_ref, bus.now.as_nanos() + 1_000_000);
    // The others converged to the reference's time (instant convergence).
    for s in &bus.slaves[1..] {
        assert_eq!(s.system_time_at(bus.now), t_ref);
    }
    // ARMW: position 0 reads, the others write.
    let r = bus.one(Command::Armw, phys(0, 0x0910), &[0; 8]);
    assert_eq!(r.wkc, 3);
    assert_eq!(r.adp, 3);
}

#[test]
fn nop_and_unknown_commands_leave_datagrams_untouched() {
    let mut bus = Bus::plain(2);
    let mut f = build(&[
        req(Command::Nop, phys(0, 0x0000), &[0xEE, 0xEE]),
        req(Command::Unknown(0x20), phys(0, 0x0000), &[0x55, 0x55]),
        req(Command::Brd, phys(0, 0x0000), &[0, 0]),
    ]);
    let orig = f.clone();
    let o = bus.send_frame(&mut f);
    assert_eq!(o, FrameOutcome::Processed { datagrams: 3 });
    // The first two datagrams are byte for byte unchanged (header, data, WKC).
    assert_eq!(&f[14..16 + 2 * 14], &orig[14..16 + 2 * 14]);
    let r = parse(&f);
    assert_eq!(r[2].wkc, 2);
    for s in &bus.slaves {
        assert_eq!(s.errors().unknown_commands, 1);
    }
}

#[test]
fn several_datagrams_see_each_others_effects() {
    let mut bus = Bus::plain(1);
    let r = bus.send(&[
        req(Command::Apwr, phys(0, 0x0010), &[0x01, 0x10]),
        req(Command::Fprd, phys(0x1001, 0x0010), &[0, 0]),
    ]);
    assert_eq!(r[0].wkc, 1);
    assert_eq!(r[1].wkc, 1);
    assert_eq!(r[1].u16(), 0x1001);
}

#[test]
fn read_only_registers_refuse_writes_but_count() {
    let mut bus = Bus::plain(1);
    let before: Vec<u8> = bus.slaves[0].memory()[0..0x10].to_vec();
    let r = bus.bwr(0x0000, &[0xFF; 16]);
    assert_eq!(r.wkc, 1);
    assert_eq!(&bus.slaves[0].memory()[0..0x10], &before[..]);
    // DL status, AL status and status code are read-only.
    bus.bwr(0x0110, &[0, 0]);
    assert_eq!(bus.brd(0x0110, 2).u16(), 0x5613);
    bus.bwr(0x0130, &[0x08, 0x00, 0, 0, 0x34, 0x12]);
    assert_eq!(bus.brd(0x0130, 2).u16(), 0x0001);
    assert_eq!(bus.brd(0x0134, 2).u16(), 0x0000);
    // Reserved registers read 0.
    assert_eq!(bus.brd(0x0E00, 4).data, vec![0; 4]);
    // Addresses beyond the backed memory read 0, count, ignore writes.
    let r = bus.bwr(0xF000, &[1, 2]);
    assert_eq!(r.wkc, 1);
    let r = bus.brd(0xF000, 2);
    assert_eq!((r.wkc, r.data.clone()), (1, vec![0, 0]));
}

#[test]
fn identity_registers() {
    let mut bus = Bus::plain(1);
    let r = bus.aprd(0, 0x0000, 10);
    assert_eq!(r.data[0], 0x04); // type
    assert_eq!(r.data[4], 8); // FMMUs
    assert_eq!(r.data[5], 8); // SMs
    assert_eq!(r.data[6], 8); // RAM KiB
    assert_eq!(r.data[7], 0x0F); // port descriptor
    assert_eq!(u16::from_le_bytes([r.data[8], r.data[9]]), 0x010C); // features
    assert_eq!(bus.aprd(0, 0x0100, 4).u32(), 0x0007_C001);
    assert_eq!(bus.aprd(0, 0x0120, 2).u16(), 0x0001);
    assert_eq!(bus.aprd(0, 0x0400, 2).u16(), 0x09C2);
    assert_eq!(bus.aprd(0, 0x0410, 2).u16(), 0x03E8);
    assert_eq!(bus.aprd(0, 0x0420, 2).u16(), 0x03E8);
    assert_eq!(bus.aprd(0, 0x0140, 2).u16(), 0x0005);
    // Watchdog registers are writable.
    bus.bwr(0x0400, &[0x10, 0x00]);
    assert_eq!(bus.aprd(0, 0x0400, 2).u16(), 0x0010);
}

#[test]
fn error_counters_clear_on_write() {
    let mut bus = Bus::plain(1);
    // A truncated frame bumps the invalid-frame counter 0x0300.
    let mut f = build(&[req(Command::Brd, phys(0, 0), &[0; 4])]);
    f.truncate(f.len() - 3);
    bus.send_frame(&mut f);
    assert_eq!(bus.brd(0x0300, 1).data, vec![1]);
    bus.bwr(0x0300, &[0xAA; 8]);
    assert_eq!(bus.brd(0x0300, 1).data, vec![0]);
}

#[test]
fn truncated_datagram_stops_processing_and_leaves_rest_untouched() {
    let mut bus = Bus::plain(1);
    let mut f = build(&[
        req(Command::Bwr, phys(0, 0x0F80), &[1]),
        req(Command::Bwr, phys(0, 0x0F81), &[2, 2, 2, 2]),
    ]);
    // Cut the second datagram's WKC and last data byte (EtherCAT length still claims them).
    f.truncate(f.len() - 3);
    let orig = f.clone();
    let o = bus.send_frame(&mut f);
    assert_eq!(
        o,
        FrameOutcome::Malformed {
            datagrams: 1,
            error: WireError::Truncated
        }
    );
    assert!(o.forward());
    assert_eq!(bus.slaves[0].memory()[0xF80], 1);
    assert_eq!(
        bus.slaves[0].memory()[0xF81],
        0,
        "second datagram not executed"
    );
    // First datagram got its WKC; the rest of the frame is as it came.
    let first_end = 14 + 2 + 10 + 1 + 2;
    assert_eq!(&f[first_end..], &orig[first_end..]);
    assert_eq!(u16::from_le_bytes([f[first_end - 2], f[first_end - 1]]), 1);
    assert_eq!(bus.slaves[0].errors().truncated_frames, 1);
}

#[test]
fn datagram_longer_than_ethercat_length_is_refused() {
    let mut bus = Bus::plain(1);
    let mut f = build(&[req(Command::Bwr, phys(0, 0x0F80), &[1, 2, 3, 4])]);
    // EtherCAT length 10: the datagram (16 bytes) runs past it; padding after.
    f[14] = 10;
    f[15] = 0x10;
    f.extend_from_slice(&[0; 20]);
    let orig = f.clone();
    let o = bus.send_frame(&mut f);
    assert_eq!(
        o,
        FrameOutcome::Malformed {
            datagrams: 0,
            error: WireError::Truncated
        }
    );
    assert_eq!(&f[12..], &orig[12..]);
    assert_eq!(bus.slaves[0].memory()[0xF80], 0);
    assert_eq!(bus.slaves[0].errors().truncated_datagrams, 1);
    // "more" bit set but nothing follows.
    let mut f = build(&[req(Command::Brd, phys(0, 0), &[0, 0])]);
    f[14 + 2 + 7] |= 0x80;
    let o = bus.send_frame(&mut f);
    assert_eq!(
        o,
        FrameOutcome::Malformed {
            datagrams: 1,
            error: WireError::Truncated
        }
    );
    assert_eq!(parse_first_wkc(&f), 1);
}

fn parse_first_wkc(f: &[u8]) -> u16 {
    let len = usize::from(u16::from_le_bytes([f[14 + 2 + 6], f[14 + 2 + 7]]) & 0x7FF);
    let at = 14 + 2 + 10 + len;
    u16::from_le_bytes([f[at], f[at + 1]])
}

#[test]
fn padding_after_datagrams_is_left_alone() {
    let mut bus = Bus::plain(1);
    let mut f = build(&[req(Command::Brd, phys(0, 0), &[0])]);
    assert_eq!(f.len(), 29, "unpadded 1-byte BRD is 29 bytes");
    f.resize(60, 0xA5);
    let o = bus.send_frame(&mut f);
    assert_eq!(o, FrameOutcome::Processed { datagrams: 1 });
    assert_eq!(f.len(), 60);
    assert!(f[29..].iter().all(|&b| b == 0xA5));
}

#[test]
fn non_ethercat_and_other_types() {
    let mut bus = Bus::plain(1);
    let mut f = build(&[req(Command::Brd, phys(0, 0), &[0])]);
    f[12] = 0x86;
    f[13] = 0xDD;
    let orig = f.clone();
    assert_eq!(bus.send_frame(&mut f), FrameOutcome::NotEtherCat);
    assert_eq!(f, orig);
    let mut short = vec![0u8; 10];
    assert_eq!(bus.send_frame(&mut short), FrameOutcome::NotEtherCat);
    // EtherCAT type 4 (network variables): forwarded, untouched but for the MAC bit.
    let mut f = build(&[req(Command::Brd, phys(0, 0), &[0])]);
    f[15] = (f[15] & 0x0F) | 0x40;
    let orig = f.clone();
    assert_eq!(bus.send_frame(&mut f), FrameOutcome::Ignored);
    assert_eq!(&f[12..], &orig[12..]);
    // Frame with only a partial EtherCAT header.
    let mut f = build(&[req(Command::Brd, phys(0, 0), &[0])]);
    f.truncate(15);
    assert!(matches!(
        bus.send_frame(&mut f),
        FrameOutcome::Malformed { .. }
    ));
    assert_eq!(bus.slaves[0].errors().not_ethercat, 2);
    assert_eq!(bus.slaves[0].errors().unsupported_type, 1);
}

#[test]
fn raw_ethercat_frame_without_ethernet_header() {
    let mut esc = Esc::new(Default::default(), ethercat::Eeprom::None);
    let mut buf = [0u8; 64];
    let mut w = FrameWriter::raw(&mut buf).unwrap();
    w.push(
        Command::Brd,
        7,
        Address::Physical { adp: 0, ado: 0 },
        &[0, 0],
    )
    .unwrap();
    let n = w.finish();
    let o = esc.process_ecat(od::Instant::ZERO, &mut buf[..n]);
    assert_eq!(o, FrameOutcome::Processed { datagrams: 1 });
    let f = ethercat::Frame::new_checked(&buf[..n]).unwrap();
    let d = f.datagrams().next().unwrap().unwrap();
    assert_eq!((d.index(), d.wkc(), d.data()), (7, 1, &[0x04, 0x01][..]));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2048, ..ProptestConfig::default() })]

    /// Any frame bytes, half of them with a valid-looking EtherCAT header (EtherType 88A4h,
    /// type 1), through a chain of two slaves: no panic, and the slaves go on being polled.
    #[test]
    fn garbage_never_panics(
        frames in prop::collection::vec(
            (prop::collection::vec(any::<u8>(), 0..200), any::<bool>()),
            1..20,
        )
    ) {
        let mut bus = Bus::with_sii(2);
        for (mut f, ethercat_header) in frames {
            if ethercat_header && f.len() >= 16 {
                f[12] = 0x88;
                f[13] = 0xA4;
                f[15] = (f[15] & 0x07) | 0x10;
            }
            let _ = bus.send_frame(&mut f);
            let _ = bus.slaves[0].poll(bus.now);
        }
    }
}

#[test]
fn irq_field_carries_al_status_event_when_masked() {
    let mut bus = Bus::plain(1);
    bus.bwr(0x0200, &[0x08, 0x00]); // ECAT event mask: AL status change
    bus.bwr(0x0120, &[0x05, 0x00]); // unknown state: AL status changes (error)
    let r = bus.brd(0x0000, 1);
    assert_eq!(r.irq & 0x0008, 0x0008);
    // Reading AL status clears the event.
    bus.brd(0x0130, 2);
    let r = bus.brd(0x0000, 1);
    assert_eq!(r.irq & 0x0008, 0);
}
