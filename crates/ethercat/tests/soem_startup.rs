//! The datagrams SOEM 1.4 / pysoem send to a single slave from `config_init()` through
//! `config_map()`, `config_dc()`, `dc_sync()` to cyclic Op and shutdown, in order, with the working
//! counters and data a real slave returns (the ESC reference kept beside the project, §2.8,
//! §9.1–§9.3). The CoE PDO discovery of step 38 is represented by one mailbox round trip answered
//! by a stand-in device (CoE itself is a later part).

mod common;

use common::*;
use ethercat::datagram::Command::*;
use ethercat::frame::Address;
use ethercat::{AlState, FixedProcessData};

const O: u16 = 3; // outputs: controlword + mode of operation
const I: u16 = 6; // inputs: statusword + position (4 bytes)

fn bwr1(bus: &mut Bus, ado: u16, data: &[u8]) {
    let r = bus.bwr(ado, data);
    assert_eq!(r.wkc, 1, "BWR {ado:#06x}");
    assert_eq!(r.data, data);
}

#[test]
fn soem_config_init_map_dc_op() {
    let mut bus = Bus::with_sii(1);
    let mut dev = FixedProcessData {
        outputs: O,
        inputs: I,
    };

    // --- ecx_config_init (spec §9.1) ---
    bwr1(&mut bus, 0x0103, &[0x00]); // 1
    bwr1(&mut bus, 0x0120, &[0x11]); // 2
    bwr1(&mut bus, 0x0120, &[0x11]); // 3
    let r = bus.brd(0x0000, 2); // 4: slave count
    assert_eq!(r.wkc, 1);
    bwr1(&mut bus, 0x0101, &[0x00]); // 5
    bwr1(&mut bus, 0x0200, &[0x04, 0x00]); // 6
    bwr1(&mut bus, 0x0300, &[0; 8]); // 7
    bwr1(&mut bus, 0x0600, &[0; 48]); // 8
    bwr1(&mut bus, 0x0800, &[0; 32]); // 9
    bwr1(&mut bus, 0x0981, &[0]); // 10
    bwr1(&mut bus, 0x0910, &[0; 4]); // 11
    bwr1(&mut bus, 0x0930, &[0x00, 0x10]); // 12
    bwr1(&mut bus, 0x0934, &[0x00, 0x0C]); // 13
    bwr1(&mut bus, 0x0103, &[0x00]); // 14
    bwr1(&mut bus, 0x0120, &[0x11]); // 15
    bwr1(&mut bus, 0x0500, &[0x02]); // 16
    bwr1(&mut bus, 0x0500, &[0x00]); // 17
    let r = bus.aprd(0, 0x0140, 2); // 18
    assert_eq!((r.wkc, r.data.clone()), (1, vec![0x05, 0x00]));
    assert_eq!(bus.apwr(0, 0x0010, &[0x01, 0x10]).wkc, 1); // 19
    assert_eq!(bus.apwr(0, 0x0100, &[0x01, 0x00]).wkc, 1); // 20
    let r = bus.aprd(0, 0x0010, 2); // 21
    assert_eq!((r.wkc, r.u16()), (1, 0x1001));
    let st = r.u16();
    assert_eq!(bus.fprd(st, 0x0012, 2).u16(), 0); // 22
    let eep8 = bus.fprd(st, 0x0502, 2).u16() & 0x0040 != 0; // 23
    assert!(eep8);
    // 24, 25: identity and mailbox words.
    assert_eq!(bus.sii_read(st, 0x08, 4), vec![0x1D, 0, 0, 0]);
    assert_eq!(bus.sii_read(st, 0x0A, 4), vec![0x78, 0x56, 0x34, 0x12]);
    assert_eq!(bus.sii_read(st, 0x0C, 4), vec![0x02, 0, 0, 0]);
    assert_eq!(bus.sii_read(st, 0x18, 4), vec![0x00, 0x10, 0x80, 0x00]);
    assert_eq!(bus.sii_read(st, 0x1A, 4), vec![0x80, 0x10, 0x80, 0x00]);
    // 26: request word 0x1C, fetched later (step 31).
    assert_eq!(bus.fprd(st, 0x0502, 2).u16() & 0x8000, 0);
    assert_eq!(
        bus.fpwr(st, 0x0502, &[0x00, 0x01, 0x1C, 0x00, 0x00, 0x00])
            .wkc,
        1
    );
    assert_eq!(bus.fprd(st, 0x0008, 2).u16() & 0x0004, 0x0004); // 27: DC
    assert_eq!(bus.fprd(st, 0x0110, 2).u16(), 0x5613); // 28
    assert_eq!(bus.fprd(st, 0x0007, 2).data[0], 0x0F); // 29
    assert_eq!(bus.fprd(st, 0x0130, 6).data, vec![1, 0, 0, 0, 0, 0]); // 30
    assert_eq!(bus.fprd(st, 0x0502, 2).u16() & 0x8000, 0); // 31
    assert_eq!(bus.fprd(st, 0x0508, 4).data, vec![0x04, 0x00, 0x00, 0x00]);
    // 32: SII walk from word 0x40 (General, SyncM): 8-byte chunks until End.
    let mut w = 0x40u32;
    let mut seen_syncm = false;
    loop {
        let head = bus.sii_read(st, w, 8);
        let kind = u16::from_le_bytes([head[0], head[1]]);
        if kind == 0xFFFF {
            break;
        }
        let len = u16::from_le_bytes([head[2], head[3]]);
        if kind == 41 {
            seen_syncm = true;
            assert_eq!(&head[4..8], &[0x00, 0x10, 0x80, 0x00]);
        }
        w += 2 + u32::from(len);
    }
    assert!(seen_syncm);
    // 33: SM0 + SM1 in one 16-byte FPWR.
    bus.write_mailbox_sms(st);
    assert_eq!(bus.fpwr(st, 0x0500, &[0x01]).wkc, 1); // 34
                                                      // 35: Pre-Op + ack.
    let mut f = build(&[req(Fpwr, phys(st, 0x0120), &[0x12, 0x00])]);
    bus.slaves[0].process_with(bus.now, &mut f, &mut dev);
    assert_eq!(parse(&f)[0].wkc, 1);
    assert_eq!(bus.al(st), (0x0002, 0));

    // --- ecx_config_map_group (spec §9.2) ---
    assert_eq!(bus.al(st).0 & 0x0F, 2); // 36
                                        // 38 (represented): one SDO upload round trip through the mailbox.
    let r = bus.fprd(st, 0x080D, 2);
    assert_eq!((r.wkc, r.data[0] & 0x08), (1, 0), "nothing stale in SM1");
    assert_eq!(bus.fprd(st, 0x0805, 1).data[0] & 0x08, 0, "SM0 empty");
    let mut sdo = vec![0u8; 0x80];
    sdo[..16].copy_from_slice(&[
        10, 0, 0, 0, 0, 0x13, 0x00, 0x20, 0x40, 0x00, 0x1C, 0x00, 0, 0, 0, 0,
    ]);
    assert_eq!(bus.fpwr(st, 0x1000, &sdo).wkc, 1);
    assert_eq!(bus.fprd(st, 0x080D, 2).data[0] & 0x08, 0, "no reply yet");
    {
        let esc = &mut bus.slaves[0];
        let got = esc.mailbox_read().expect("request").to_vec();
        assert_eq!(&got[8..12], &[0x40, 0x00, 0x1C, 0x00]);
        // 0x1C00:00 = 4, expedited 1 byte.
        esc.mailbox_write(&[
            10, 0, 0, 0, 0, 0x13, 0x00, 0x30, 0x4F, 0x00, 0x1C, 0x00, 4, 0, 0, 0,
        ])
        .unwrap();
    }
    assert_eq!(bus.fprd(st, 0x080D, 2).data[0] & 0x08, 0x08);
    let r = bus.fprd(st, 0x1080, 0x80);
    assert_eq!((r.wkc, r.data[12]), (1, 4));
    // 40, 41: SM2, SM3.
    let mut sm2 = SM2_START.to_le_bytes().to_vec();
    sm2.extend_from_slice(&O.to_le_bytes());
    sm2.extend_from_slice(&[0x64, 0, 0x01, 0]);
    assert_eq!(bus.fpwr(st, 0x0810, &sm2).wkc, 1);
    let mut sm3 = SM3_START.to_le_bytes().to_vec();
    sm3.extend_from_slice(&I.to_le_bytes());
    sm3.extend_from_slice(&[0x20, 0, 0x01, 0]);
    assert_eq!(bus.fpwr(st, 0x0818, &sm3).wkc, 1);
    // 42, 43: FMMU0 outputs at logical 0, FMMU1 inputs at logical O; SOEM 2's FMMU2 maps
    // the SM1 status byte at logical O + I.
    assert_eq!(
        bus.fpwr(st, 0x0600, &fmmu_bytes(0, O, SM2_START, false, true))
            .wkc,
        1
    );
    assert_eq!(
        bus.fpwr(
            st,
            0x0610,
            &fmmu_bytes(u32::from(O), I, SM3_START, true, false)
        )
        .wkc,
        1
    );
    assert_eq!(
        bus.fpwr(
            st,
            0x0620,
            &fmmu_bytes(u32::from(O + I), 1, 0x080D, true, false)
        )
        .wkc,
        1
    );
    // 44: Safe-Op; the device's hook checks SM2/SM3 sizes.
    let mut f = build(&[req(Fpwr, phys(st, 0x0120), &[0x04, 0x00])]);
    bus.slaves[0].process_with(bus.now, &mut f, &mut dev);
    assert_eq!(bus.al(st), (0x0004, 0));

    // --- config_dc, dc_sync (spec §9.3 steps 45–46) ---
    bus.now = od::Instant::from_millis(20);
    assert_eq!(bus.bwr(0x0900, &[0; 4]).wkc, 1);
    let rx0 = bus.fprd(st, 0x0900, 4).u32();
    let rxpu = bus.fprd(st, 0x0918, 8).u64();
    assert_eq!(u64::from(rx0), rxpu);
    let master_time = 800_000_000_000_000_000u64;
    assert_eq!(
        bus.fpwr(st, 0x0920, &(master_time - rxpu).to_le_bytes())
            .wkc,
        1
    );
    for a in [0x0904, 0x0908, 0x090C] {
        assert_eq!(bus.fprd(st, a, 4).wkc, 1);
    }
    assert_eq!(bus.fpwr(st, 0x0981, &[0]).wkc, 1);
    assert_eq!(bus.fpwr(st, 0x0980, &[0]).wkc, 1);
    let t = bus.fprd(st, 0x0910, 8).u64();
    assert_eq!(t, master_time);
    let cycle = 1_000_000u64;
    let start = (t + 100_000_000) / cycle * cycle + cycle;
    assert_eq!(bus.fpwr(st, 0x0990, &start.to_le_bytes()).wkc, 1);
    assert_eq!(bus.fpwr(st, 0x09A0, &(cycle as u32).to_le_bytes()).wkc, 1);
    assert_eq!(bus.fpwr(st, 0x0981, &[0x03]).wkc, 1);
    // 47
    let r = bus.brd(0x0130, 2);
    assert_eq!((r.wkc, r.data.clone()), (1, vec![0x04, 0x00]));

    // 48: LRW [O + I + 1] + FRMW 0x0910 in one frame, in Safe-Op.
    bus.slaves[0]
        .set_inputs(&[0x37, 0x02, 0x10, 0x20, 0x30, 0x40])
        .unwrap();
    let r = bus.send(&[
        req(
            Lrw,
            Address::Logical(0),
            &[0x0F, 0x00, 0x08, 0, 0, 0, 0, 0, 0, 0],
        ),
        req(Frmw, phys(st, 0x0910), &[0; 8]),
    ]);
    assert_eq!(
        r[0].wkc, 3,
        "outputs +2, inputs and status FMMU: one read increment only"
    );
    assert_eq!(&r[0].data[..3], &[0x0F, 0x00, 0x08]);
    assert_eq!(&r[0].data[3..9], &[0x37, 0x02, 0x10, 0x20, 0x30, 0x40]);
    assert_eq!(r[1].wkc, 1);
    assert_eq!(r[1].u64(), master_time);
    // In Safe-Op the ESC hands outputs over; the drive ignores them until Op.
    assert_eq!(
        bus.slaves[0].process_outputs(),
        Some(&[0x0F, 0x00, 0x08][..])
    );
    assert_eq!(bus.slaves[0].al_state(), AlState::SafeOp);

    // 49: Op by BWR, then cyclic exchange at 1 kHz for 200 cycles.
    bwr1(&mut bus, 0x0120, &[0x08, 0x00]);
    let r = bus.brd(0x0130, 2);
    assert_eq!((r.wkc, r.u16()), (1, 0x0008));
    let mut last_time = 0;
    for k in 0..200u32 {
        bus.now = od::Instant::from_nanos(bus.now.as_nanos() + 1_000_000);
        let sw = (k as u16).to_le_bytes();
        bus.slaves[0]
            .set_inputs(&[sw[0], sw[1], 0, 0, 0, 0])
            .unwrap();
        let cw = (k as u16 ^ 0x5A5A).to_le_bytes();
        let r = bus.send(&[
            req(
                Lrw,
                Address::Logical(0),
                &[cw[0], cw[1], 8, 0, 0, 0, 0, 0, 0, 0],
            ),
            req(Frmw, phys(st, 0x0910), &[0; 8]),
        ]);
        assert_eq!(r[0].wkc, 3);
        assert_eq!(&r[0].data[3..5], &sw);
        assert_eq!(
            bus.slaves[0].process_outputs(),
            Some(&[cw[0], cw[1], 8][..])
        );
        assert!(r[1].u64() > last_time);
        last_time = r[1].u64();
        assert!(
            bus.slaves[0].poll(bus.now).is_some(),
            "watchdog armed, not expired"
        );
    }
    assert_eq!(bus.slaves[0].al_state(), AlState::Op);
    assert_eq!(
        bus.slaves[0].next_sync0_at(bus.now).map(|n| n % cycle),
        Some(0)
    );

    // 51: shutdown to Init.
    bwr1(&mut bus, 0x0120, &[0x01, 0x00]);
    assert_eq!(bus.al(st), (0x0001, 0));
    assert!(!bus.slaves[0].mailbox_running());
}

#[test]
fn ethercrab_like_init_over_three_slaves() {
    // ethercrab init_single_group (spec §9.4 steps 1–5, 10) over a chain of three.
    let mut bus = Bus::with_sii(3);
    assert_eq!(bus.one(Brd, phys(0, 0x0000), &[0]).wkc, 3);
    bus.bwr(0x0120, &[0x11, 0x00]);
    for i in 0..16u16 {
        assert_eq!(bus.bwr(0x0600 + 16 * i, &[0; 16]).wkc, 3);
        assert_eq!(bus.bwr(0x0800 + 8 * i, &[0; 8]).wkc, 3);
    }
    for (a, n) in [
        (0x0910, 8),
        (0x0920, 8),
        (0x0928, 4),
        (0x092C, 4),
        (0x0981, 1),
        (0x0990, 4),
        (0x09A0, 4),
        (0x09A4, 4),
    ] {
        assert_eq!(bus.bwr(a, &vec![0; n]).wkc, 3);
    }
    for i in 0..3u16 {
        let r = bus.apwr(i.wrapping_neg(), 0x0010, &(0x1000 + i).to_le_bytes());
        assert_eq!(r.wkc, 1);
    }
    for i in 0..3u16 {
        assert_eq!(bus.fprd(0x1000 + i, 0x0130, 2).u16(), 1);
    }
    assert_eq!(
        bus.bwr(0x0900, &[0; 4]).wkc,
        3,
        "WKC = DC slave count (ethercrab #63)"
    );
    for i in 0..3u16 {
        assert_eq!(bus.fprd(0x1000 + i, 0x0900, 16).wkc, 1);
    }
    // LRW over three slaves with one output byte and one input byte each.
    for i in 0..3u16 {
        let st = 0x1000 + i;
        bus.write_mailbox_sms(st);
        bus.request_state(st, 2);
        bus.fpwr(st, 0x0810, &[0x00, 0x11, 1, 0, 0x64, 0, 1, 0]);
        bus.fpwr(st, 0x0818, &[0x80, 0x11, 1, 0, 0x20, 0, 1, 0]);
        // ethercrab: inputs first (logical 0..3), outputs after (3..6).
        bus.fpwr(
            st,
            0x0600,
            &fmmu_bytes(3 + u32::from(i), 1, 0x1100, false, true),
        );
        bus.fpwr(
            st,
            0x0610,
            &fmmu_bytes(u32::from(i), 1, 0x1180, true, false),
        );
        bus.request_state(st, 4);
        bus.request_state(st, 8);
        assert_eq!(bus.al(st), (8, 0));
        bus.slaves[usize::from(i)]
            .set_inputs(&[0xA0 + i as u8])
            .unwrap();
    }
    let r = bus.send(&[
        req(Lrw, Address::Logical(0), &[0, 0, 0, 1, 2, 3]),
        req(Fprd, phys(0x1000, 0x0130), &[0, 0]),
        req(Fprd, phys(0x1001, 0x0130), &[0, 0]),
        req(Fprd, phys(0x1002, 0x0130), &[0, 0]),
    ]);
    assert_eq!(r[0].wkc, 9);
    assert_eq!(r[0].data, vec![0xA0, 0xA1, 0xA2, 1, 2, 3]);
    for d in &r[1..4] {
        assert_eq!((d.wkc, d.u16()), (1, 8));
    }
    for i in 0..3 {
        assert_eq!(bus.slaves[i].process_outputs(), Some(&[1 + i as u8][..]));
    }
}
