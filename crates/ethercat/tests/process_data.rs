//! FMMUs and buffered sync managers: LRD/LWR/LRW through one and two slaves
//! (the ESC reference kept beside the project, §2.5, §7.3–§7.5).

mod common;

use common::*;
use ethercat::datagram::Command;
use ethercat::fmmu::Fmmu;
use ethercat::frame::Address;
use ethercat::PdiError;

/// Configure slave at `st` as SOEM does: SM2 `o` bytes, SM3 `i` bytes, FMMU0 outputs at
/// logical `lo`, FMMU1 inputs at logical `li`; then Pre-Op → Safe-Op → Op.
fn configure(bus: &mut Bus, st: u16, o: u16, i: u16, lo: u32, li: u32) {
    bus.write_mailbox_sms(st);
    bus.request_state(st, 0x0002);
    let mut sm2 = SM2_START.to_le_bytes().to_vec();
    sm2.extend_from_slice(&o.to_le_bytes());
    sm2.extend_from_slice(&[0x64, 0, 1, 0]);
    bus.fpwr(st, 0x0810, &sm2);
    let mut sm3 = SM3_START.to_le_bytes().to_vec();
    sm3.extend_from_slice(&i.to_le_bytes());
    sm3.extend_from_slice(&[0x20, 0, 1, 0]);
    bus.fpwr(st, 0x0818, &sm3);
    // ethercrab reads the FMMU back first: zero after reset.
    assert_eq!(bus.fprd(st, 0x0600, 16).data, vec![0; 16]);
    bus.fpwr(st, 0x0600, &fmmu_bytes(lo, o, SM2_START, false, true));
    bus.fpwr(st, 0x0610, &fmmu_bytes(li, i, SM3_START, true, false));
    assert_eq!(
        bus.fprd(st, 0x0600, 16).data,
        fmmu_bytes(lo, o, SM2_START, false, true).to_vec()
    );
    bus.request_state(st, 0x0004);
    bus.request_state(st, 0x0008);
    assert_eq!(bus.al(st), (0x0008, 0));
}

#[test]
fn lrw_two_slaves_inputs_read_outputs_written() {
    let mut bus = Bus::with_sii(2);
    bus.assign_addresses();
    // SOEM layout: [out0 (2) | out1 (2) | in0 (4) | in1 (4)].
    configure(&mut bus, 0x1001, 2, 4, 0, 4);
    configure(&mut bus, 0x1002, 2, 4, 2, 8);
    bus.slaves[0].set_inputs(&[0xA0, 0xA1, 0xA2, 0xA3]).unwrap();
    bus.slaves[1].set_inputs(&[0xB0, 0xB1, 0xB2, 0xB3]).unwrap();
    let r = bus.lrw(0, &[0x11, 0x12, 0x21, 0x22, 0, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(r.wkc, 6, "3 per slave");
    assert_eq!(
        r.data,
        vec![0x11, 0x12, 0x21, 0x22, 0xA0, 0xA1, 0xA2, 0xA3, 0xB0, 0xB1, 0xB2, 0xB3]
    );
    assert_eq!(bus.slaves[0].process_outputs(), Some(&[0x11, 0x12][..]));
    assert_eq!(bus.slaves[1].process_outputs(), Some(&[0x21, 0x22][..]));
    assert_eq!(bus.slaves[0].process_outputs(), None, "taken");
    assert_eq!(bus.slaves[0].outputs(), &[0x11, 0x12]);
    // LRD: +1 per slave, no outputs touched; LWR: +1 per slave.
    let r = bus.one(Command::Lrd, Address::Logical(0), &[0; 12]);
    assert_eq!(r.wkc, 2);
    assert_eq!(&r.data[4..6], &[0xA0, 0xA1]);
    assert_eq!(&r.data[0..4], &[0; 4], "no read FMMU over the outputs");
    let r = bus.one(
        Command::Lwr,
        Address::Logical(0),
        &[5, 6, 7, 8, 9, 9, 9, 9, 9, 9, 9, 9],
    );
    assert_eq!(r.wkc, 2);
    assert_eq!(
        r.data,
        vec![5, 6, 7, 8, 9, 9, 9, 9, 9, 9, 9, 9],
        "LWR data unchanged"
    );
    assert_eq!(bus.slaves[1].process_outputs(), Some(&[7, 8][..]));
    // A logical range that hits nobody.
    let r = bus.one(Command::Lrw, Address::Logical(0x1000), &[1; 4]);
    assert_eq!((r.wkc, r.data.clone()), (0, vec![1; 4]));
    // A datagram covering only part of slave 1's inputs: partial read still counts.
    let r = bus.one(Command::Lrd, Address::Logical(10), &[0; 2]);
    assert_eq!((r.wkc, r.data.clone()), (1, vec![0xB2, 0xB3]));
}

#[test]
fn overlap_map_outputs_and_inputs_share_logical_bytes() {
    // SOEM config_overlap_map: outputs and inputs both at logical 0.
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    configure(&mut bus, 0x1001, 2, 2, 0, 0);
    bus.slaves[0].set_inputs(&[0x41, 0x06]).unwrap();
    let r = bus.lrw(0, &[0x0F, 0x00]);
    assert_eq!(r.wkc, 3);
    assert_eq!(r.data, vec![0x41, 0x06]);
    assert_eq!(bus.slaves[0].process_outputs(), Some(&[0x0F, 0x00][..]));
}

#[test]
fn partial_output_write_is_not_a_complete_buffer() {
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    configure(&mut bus, 0x1001, 4, 2, 0, 4);
    // Write only the first two output bytes.
    let r = bus.one(Command::Lwr, Address::Logical(0), &[1, 2]);
    assert_eq!(r.wkc, 1);
    assert_eq!(bus.slaves[0].process_outputs(), None);
    // Complete it: the buffer counts from the write that covers the last byte.
    bus.one(Command::Lwr, Address::Logical(2), &[3, 4]);
    assert_eq!(bus.slaves[0].process_outputs(), Some(&[1, 2, 3, 4][..]));
    // SM2 status: buffer written (bit 0 cleared again by the PDI read), last buffer index.
    let st = bus.fprd(0x1001, 0x0815, 1).data[0];
    assert_eq!(
        st & 0x31,
        0x00,
        "buffer 0 written last, write event taken ({st:#04x})"
    );
}

#[test]
fn three_buffer_semantics() {
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    configure(&mut bus, 0x1001, 2, 2, 0, 2);
    // Inputs: the master always reads the latest complete buffer the device wrote.
    bus.slaves[0].set_inputs(&[1, 1]).unwrap();
    bus.slaves[0].set_inputs(&[2, 2]).unwrap();
    assert_eq!(bus.fprd(0x1001, SM3_START, 2).data, vec![2, 2]);
    assert_eq!(
        bus.fprd(0x1001, SM3_START, 2).data,
        vec![2, 2],
        "reads never block"
    );
    // The master cannot write into an input SM, nor read an output SM.
    assert_eq!(bus.fpwr(0x1001, SM3_START, &[9, 9]).wkc, 0);
    assert_eq!(bus.fprd(0x1001, SM2_START, 2).wkc, 0);
    // Outputs: writes never block; the device sees the newest complete one.
    assert_eq!(bus.fpwr(0x1001, SM2_START, &[3, 3]).wkc, 1);
    assert_eq!(bus.fpwr(0x1001, SM2_START, &[4, 4]).wkc, 1);
    assert_eq!(bus.slaves[0].process_outputs(), Some(&[4, 4][..]));
    assert_eq!(bus.slaves[0].set_inputs(&[1, 2, 3]), Err(PdiError::TooLong));
    // SM3 status shows a buffer written.
    let st = bus.fprd(0x1001, 0x081D, 1).data[0];
    assert_ne!(st & 0x30, 0x30);
}

#[test]
fn bit_granular_fmmu_maps_mailbox_status_bit() {
    // KickCAT: one bit of 0x080D (SM1 "mailbox full", bit 3) to logical bit 5 of byte 0x20.
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    bus.write_mailbox_sms(0x1001);
    bus.request_state(0x1001, 2);
    let f = Fmmu {
        logical_start: 0x20,
        length: 1,
        logical_start_bit: 5,
        logical_stop_bit: 5,
        physical_start: 0x080D,
        physical_start_bit: 3,
        read_enable: true,
        write_enable: false,
        enable: true,
    };
    assert_eq!(f.bit_count(), 1);
    bus.fpwr(0x1001, 0x0620, &f.to_bytes());
    let r = bus.one(Command::Lrd, Address::Logical(0x20), &[0xFF]);
    assert_eq!(
        (r.wkc, r.data[0]),
        (1, 0xDF),
        "bit 5 cleared: SM1 empty, other bits kept"
    );
    bus.slaves[0].mailbox_write(&[6, 0, 0, 0, 0, 0x03]).unwrap();
    let r = bus.one(Command::Lrd, Address::Logical(0x20), &[0x00]);
    assert_eq!(r.data[0], 0x20);
    // Reading the status register through an FMMU has no side effect: still full.
    assert_eq!(bus.fprd(0x1001, 0x080D, 1).data[0] & 0x08, 0x08);
}

#[test]
fn bit_granular_write_mapping() {
    // Logical bits 4..=11 (byte 0 bit 4 to byte 1 bit 3) → physical 0x0F80 bit 0.
    let mut bus = Bus::plain(1);
    let f = Fmmu {
        logical_start: 0x100,
        length: 2,
        logical_start_bit: 4,
        logical_stop_bit: 3,
        physical_start: 0x0F80,
        physical_start_bit: 0,
        read_enable: true,
        write_enable: true,
        enable: true,
    };
    assert_eq!(f.bit_count(), 8);
    bus.bwr(0x0600, &f.to_bytes());
    let r = bus.one(Command::Lwr, Address::Logical(0x100), &[0xA0, 0x0B]);
    assert_eq!(r.wkc, 1);
    assert_eq!(bus.slaves[0].memory()[0xF80], 0xBA);
    let r = bus.one(Command::Lrd, Address::Logical(0x100), &[0x05, 0x70]);
    assert_eq!(r.data, vec![0xA5, 0x7B]);
    let r = bus.lrw(0x100, &[0x00, 0x00]);
    assert_eq!(r.wkc, 3);
    assert_eq!(bus.slaves[0].memory()[0xF80], 0x00);
}

#[test]
fn several_fmmus_count_once_per_direction() {
    let mut bus = Bus::plain(1);
    // Three byte-aligned read FMMUs and two write FMMUs into user RAM.
    let mut all = vec![];
    all.extend_from_slice(&fmmu_bytes(0, 1, 0x0F80, true, false));
    all.extend_from_slice(&fmmu_bytes(1, 1, 0x0F81, true, false));
    all.extend_from_slice(&fmmu_bytes(2, 1, 0x0F82, true, false));
    all.extend_from_slice(&fmmu_bytes(3, 1, 0x0F90, false, true));
    all.extend_from_slice(&fmmu_bytes(4, 1, 0x0F91, false, true));
    bus.bwr(0x0600, &all);
    bus.bwr(0x0F80, &[7, 8, 9]);
    let r = bus.lrw(0, &[0, 0, 0, 0x33, 0x44]);
    assert_eq!(r.wkc, 3);
    assert_eq!(r.data, vec![7, 8, 9, 0x33, 0x44]);
    assert_eq!(&bus.slaves[0].memory()[0xF90..0xF92], &[0x33, 0x44]);
    // Inactive FMMU (activate 0): ignored.
    bus.bwr(0x060C, &[0]);
    let r = bus.one(Command::Lrd, Address::Logical(0), &[0]);
    assert_eq!(r.wkc, 0);
    // BWR zeros (master reset): no FMMU left.
    bus.bwr(0x0600, &[0; 256]);
    assert_eq!(bus.lrw(0, &[0; 5]).wkc, 0);
}

#[test]
fn fmmu_to_mailbox_respects_sm_rules() {
    // An FMMU into the SM1 window: reading while empty is refused (no WKC).
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    bus.write_mailbox_sms(0x1001);
    bus.request_state(0x1001, 2);
    bus.fpwr(0x1001, 0x0600, &fmmu_bytes(0, 0x80, 0x1080, true, false));
    assert_eq!(
        bus.one(Command::Lrd, Address::Logical(0), &[0; 0x80]).wkc,
        0
    );
    bus.slaves[0].mailbox_write(&[1, 2, 3]).unwrap();
    let r = bus.one(Command::Lrd, Address::Logical(0), &[0; 0x80]);
    assert_eq!(r.wkc, 1);
    assert_eq!(&r.data[..4], &[1, 2, 3, 0]);
    assert_eq!(
        bus.one(Command::Lrd, Address::Logical(0), &[0; 0x80]).wkc,
        0,
        "empty again"
    );
}

/// An FMMU follows its sync manager as it is reconfigured: SM2 turned into a read SM refuses
/// the writes through the output FMMU, and a write FMMU over SM2 and SM3 at once meets the
/// rules of both (SM3 refuses it), whatever the accesses through the same FMMUs before.
#[test]
fn fmmus_follow_their_sync_managers_reconfigured() {
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    configure(&mut bus, 0x1001, 2, 2, 0, 2);
    assert_eq!(bus.lrw(0, &[0x11, 0x12, 0, 0]).wkc, 3);
    assert_eq!(bus.slaves[0].process_outputs(), Some(&[0x11, 0x12][..]));
    // Back to Pre-Op; SM2 becomes a read SM (control 0x20): the output FMMU writes nothing.
    bus.request_state(0x1001, 0x0002);
    let mut sm2 = SM2_START.to_le_bytes().to_vec();
    sm2.extend_from_slice(&2u16.to_le_bytes());
    sm2.extend_from_slice(&[0x20, 0, 1, 0]);
    bus.fpwr(0x1001, 0x0810, &sm2);
    let r = bus.one(Command::Lwr, Address::Logical(0), &[0x21, 0x22]);
    assert_eq!(r.wkc, 0, "a write into a read SM is refused");
    assert_eq!(bus.slaves[0].process_outputs(), None);
    // SM2 a write SM again, and a write FMMU over both windows (0x1100..0x1182).
    sm2[4] = 0x64;
    bus.fpwr(0x1001, 0x0810, &sm2);
    bus.fpwr(0x1001, 0x0600, &fmmu_bytes(0, 0x82, SM2_START, false, true));
    let r = bus.one(Command::Lwr, Address::Logical(0), &[0x31; 0x82]);
    assert_eq!(r.wkc, 0, "SM3 refuses the write");
    // The FMMU over SM2 alone again.
    bus.fpwr(0x1001, 0x0600, &fmmu_bytes(0, 2, SM2_START, false, true));
    assert_eq!(
        bus.one(Command::Lwr, Address::Logical(0), &[0x41, 0x42])
            .wkc,
        1
    );
    assert_eq!(bus.slaves[0].process_outputs(), Some(&[0x41, 0x42][..]));
}
