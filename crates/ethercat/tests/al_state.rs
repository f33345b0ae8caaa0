//! AL state machine: every transition accepted and refused, status codes, error acknowledge, hook
//! (the ESC reference kept beside the project, §4; the CMMP-AS manual's extract, part 1 §4.2).

mod common;

use common::*;
use ethercat::al_control::{check_transition, AlState};
use ethercat::{AlHook, AlStatusCode, Esc, FixedProcessData};

const ST: u16 = 0x1001;

fn preop_bus() -> Bus {
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    bus.write_mailbox_sms(ST);
    bus.request_state(ST, 0x0002);
    assert_eq!(bus.al(ST), (0x0002, 0));
    bus
}

fn write_pd_sms(bus: &mut Bus, out_len: u16, in_len: u16) {
    let mut sm2 = vec![];
    sm2.extend_from_slice(&SM2_START.to_le_bytes());
    sm2.extend_from_slice(&out_len.to_le_bytes());
    sm2.extend_from_slice(&[0x64, 0, u8::from(out_len > 0), 0]);
    assert_eq!(bus.fpwr(ST, 0x0810, &sm2).wkc, 1);
    let mut sm3 = vec![];
    sm3.extend_from_slice(&SM3_START.to_le_bytes());
    sm3.extend_from_slice(&in_len.to_le_bytes());
    sm3.extend_from_slice(&[0x20, 0, u8::from(in_len > 0), 0]);
    assert_eq!(bus.fpwr(ST, 0x0818, &sm3).wkc, 1);
}

#[test]
fn transition_table() {
    use AlState::*;
    let ok = |from, req| check_transition(from, req, false);
    assert_eq!(ok(Init, 2), Ok(PreOp));
    assert_eq!(ok(Init, 1), Ok(Init));
    assert_eq!(
        ok(Init, 4),
        Err(AlStatusCode::INVALID_REQUESTED_STATE_CHANGE)
    );
    assert_eq!(
        ok(Init, 8),
        Err(AlStatusCode::INVALID_REQUESTED_STATE_CHANGE)
    );
    assert_eq!(ok(Init, 3), Err(AlStatusCode::BOOTSTRAP_NOT_SUPPORTED));
    assert_eq!(check_transition(Init, 3, true), Ok(Bootstrap));
    assert_eq!(
        ok(PreOp, 8),
        Err(AlStatusCode::INVALID_REQUESTED_STATE_CHANGE)
    );
    assert_eq!(
        ok(PreOp, 3),
        Err(AlStatusCode::INVALID_REQUESTED_STATE_CHANGE)
    );
    assert_eq!(ok(PreOp, 4), Ok(SafeOp));
    assert_eq!(ok(PreOp, 1), Ok(Init));
    assert_eq!(ok(SafeOp, 8), Ok(Op));
    assert_eq!(ok(SafeOp, 2), Ok(PreOp));
    assert_eq!(ok(SafeOp, 1), Ok(Init));
    assert_eq!(ok(Op, 4), Ok(SafeOp));
    assert_eq!(ok(Op, 2), Ok(PreOp));
    assert_eq!(ok(Op, 1), Ok(Init));
    assert_eq!(
        check_transition(Bootstrap, 2, true),
        Err(AlStatusCode::INVALID_REQUESTED_STATE_CHANGE)
    );
    assert_eq!(check_transition(Bootstrap, 1, true), Ok(Init));
    for bad in [0u8, 5, 6, 7, 9, 10, 11, 12, 13, 14, 15] {
        assert_eq!(
            ok(Op, bad),
            Err(AlStatusCode::UNKNOWN_REQUESTED_STATE),
            "{bad}"
        );
    }
}

#[test]
fn init_to_preop_needs_valid_mailbox_sms_then_ack() {
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    // No SMs: refused with 0x0016, status Init + error.
    bus.request_state(ST, 0x0002);
    assert_eq!(bus.al(ST), (0x0011, 0x0016));
    // Without ack nothing happens, even with valid SMs now.
    bus.write_mailbox_sms(ST);
    bus.request_state(ST, 0x0002);
    assert_eq!(bus.al(ST), (0x0011, 0x0016));
    // Ack alone (Init + ack) clears the error.
    bus.request_state(ST, 0x0011);
    assert_eq!(bus.al(ST), (0x0001, 0));
    // Pre-Op + ack (SOEM's 0x0012): accepted.
    bus.request_state(ST, 0x0012);
    assert_eq!(bus.al(ST), (0x0002, 0));
    assert!(bus.slaves[0].mailbox_running());
}

#[test]
fn wrong_mailbox_sm_variants_are_refused() {
    let cases: [[u8; 16]; 4] = [
        // SM0 length differs from SII word 0x19.
        [
            0x00, 0x10, 0x40, 0x00, 0x26, 0, 1, 0, 0x80, 0x10, 0x80, 0, 0x22, 0, 1, 0,
        ],
        // SM0 buffered instead of mailbox.
        [
            0x00, 0x10, 0x80, 0x00, 0x24, 0, 1, 0, 0x80, 0x10, 0x80, 0, 0x22, 0, 1, 0,
        ],
        // SM1 disabled.
        [
            0x00, 0x10, 0x80, 0x00, 0x26, 0, 1, 0, 0x80, 0x10, 0x80, 0, 0x22, 0, 0, 0,
        ],
        // SM1 wrong direction.
        [
            0x00, 0x10, 0x80, 0x00, 0x26, 0, 1, 0, 0x80, 0x10, 0x80, 0, 0x26, 0, 1, 0,
        ],
    ];
    for sms in cases {
        let mut bus = Bus::with_sii(1);
        bus.assign_addresses();
        bus.fpwr(ST, 0x0800, &sms);
        bus.request_state(ST, 0x0012);
        assert_eq!(bus.al(ST), (0x0011, 0x0016), "{sms:02x?}");
    }
}

#[test]
fn skipped_unknown_and_bootstrap_requests() {
    let mut bus = Bus::with_sii(1);
    bus.assign_addresses();
    bus.request_state(ST, 0x0008);
    assert_eq!(bus.al(ST), (0x0011, 0x0011));
    bus.request_state(ST, 0x0011);
    bus.request_state(ST, 0x0004);
    assert_eq!(bus.al(ST), (0x0011, 0x0011));
    bus.request_state(ST, 0x0011);
    bus.request_state(ST, 0x0003);
    assert_eq!(bus.al(ST), (0x0011, 0x0013), "CMMP-AS: no bootstrap");
    bus.request_state(ST, 0x0015); // unknown state 5, with ack
    assert_eq!(bus.al(ST), (0x0011, 0x0012));
    bus.request_state(ST, 0x0011);
    assert_eq!(bus.al(ST), (0x0001, 0));
    // Pre-Op → Op is refused as well.
    bus.write_mailbox_sms(ST);
    bus.request_state(ST, 0x0002);
    bus.request_state(ST, 0x0008);
    assert_eq!(bus.al(ST), (0x0012, 0x0011));
}

#[test]
fn preop_to_safeop_checks_process_data_sms() {
    // Structural checks of the ESC itself.
    let mut bus = preop_bus();
    // SM2 as a mailbox: invalid output configuration.
    bus.fpwr(ST, 0x0810, &[0x00, 0x11, 2, 0, 0x26, 0, 1, 0]);
    bus.request_state(ST, 0x0004);
    assert_eq!(bus.al(ST), (0x0012, 0x001D));
    // SM3 written as a "write" SM: invalid input configuration.
    write_pd_sms(&mut bus, 2, 2);
    bus.fpwr(ST, 0x0818, &[0x80, 0x11, 2, 0, 0x24, 0, 1, 0]);
    bus.request_state(ST, 0x0014);
    assert_eq!(bus.al(ST), (0x0012, 0x001E));
    // Overlapping three-buffer windows: 0x0017.
    write_pd_sms(&mut bus, 0x40, 2);
    bus.request_state(ST, 0x0014);
    assert_eq!(bus.al(ST), (0x0012, 0x0017));
    // Valid.
    write_pd_sms(&mut bus, 2, 2);
    bus.request_state(ST, 0x0014);
    assert_eq!(bus.al(ST), (0x0004, 0));
}

#[test]
fn hook_checks_sizes_and_learns_states() {
    #[derive(Default)]
    struct Dev {
        pd: FixedProcessData,
        seen: Vec<(AlState, AlState)>,
    }
    impl AlHook for Dev {
        fn check_transition(
            &mut self,
            esc: &Esc<'_>,
            from: AlState,
            to: AlState,
        ) -> Result<(), AlStatusCode> {
            self.pd.check_transition(esc, from, to)
        }
        fn state_changed(&mut self, esc: &mut Esc<'_>, from: AlState, to: AlState) {
            self.seen.push((from, to));
            if to == AlState::SafeOp {
                esc.set_inputs(&[0x37, 0x02]).unwrap();
            }
        }
    }
    let mut dev = Dev {
        pd: FixedProcessData {
            outputs: 2,
            inputs: 2,
        },
        ..Default::default()
    };
    let image: &'static [u8] = Box::leak(test_sii().into_boxed_slice());
    let mut esc = Esc::with_sii(image);
    let now = od::Instant::ZERO;
    let run = |esc: &mut Esc<'_>, dev: &mut Dev, reqs: &[Req]| {
        let mut f = build(reqs);
        esc.process_with(now, &mut f, dev);
        parse(&f)
    };
    use ethercat::Command::*;
    run(
        &mut esc,
        &mut dev,
        &[req(Apwr, phys(0, 0x10), &ST.to_le_bytes())],
    );
    let mut sms = vec![
        0x00, 0x10, 0x80, 0x00, 0x26, 0, 1, 0, 0x80, 0x10, 0x80, 0, 0x22, 0, 1, 0,
    ];
    sms.extend_from_slice(&[0x00, 0x11, 4, 0, 0x64, 0, 1, 0]); // SM2: 4 bytes, the device wants 2
    sms.extend_from_slice(&[0x80, 0x11, 2, 0, 0x20, 0, 1, 0]);
    run(
        &mut esc,
        &mut dev,
        &[
            req(Fpwr, phys(ST, 0x800), &sms),
            req(Fpwr, phys(ST, 0x120), &[2, 0]),
        ],
    );
    assert_eq!(esc.al_state(), AlState::PreOp);
    run(&mut esc, &mut dev, &[req(Fpwr, phys(ST, 0x120), &[4, 0])]);
    assert_eq!(esc.read_u16(0x0130), 0x0012);
    assert_eq!(
        esc.al_status_code(),
        AlStatusCode::INVALID_OUTPUT_CONFIGURATION
    );
    run(
        &mut esc,
        &mut dev,
        &[
            req(Fpwr, phys(ST, 0x812), &[2, 0]),
            req(Fpwr, phys(ST, 0x120), &[0x14, 0]),
        ],
    );
    assert_eq!(esc.al_state(), AlState::SafeOp);
    // The inputs the hook posted on entering Safe-Op are in SM3.
    assert_eq!(&esc.memory()[0x1180..0x1182], &[0x37, 0x02]);
    run(&mut esc, &mut dev, &[req(Fpwr, phys(ST, 0x120), &[8, 0])]);
    run(&mut esc, &mut dev, &[req(Fpwr, phys(ST, 0x120), &[1, 0])]);
    use AlState::*;
    assert_eq!(
        dev.seen,
        vec![(Init, PreOp), (PreOp, SafeOp), (SafeOp, Op), (Op, Init)]
    );
    assert!(!esc.mailbox_running());
}

#[test]
fn every_downward_transition() {
    for (up_to, down) in [
        (0x0004u16, 0x0002u16),
        (0x0004, 0x0001),
        (0x0008, 0x0004),
        (0x0008, 0x0002),
        (0x0008, 0x0001),
        (0x0002, 0x0001),
    ] {
        let mut bus = preop_bus();
        write_pd_sms(&mut bus, 2, 2);
        if up_to >= 4 {
            bus.request_state(ST, 0x0004);
        }
        if up_to == 8 {
            bus.request_state(ST, 0x0008);
        }
        assert_eq!(bus.al(ST), (up_to, 0));
        bus.request_state(ST, down);
        assert_eq!(bus.al(ST), (down, 0), "{up_to:#x} → {down:#x}");
        assert_eq!(bus.slaves[0].mailbox_running(), down != 1);
    }
}

#[test]
fn error_ack_with_same_state_clears_error() {
    let mut bus = preop_bus();
    bus.request_state(ST, 0x0008);
    assert_eq!(bus.al(ST), (0x0012, 0x0011));
    bus.request_state(ST, 0x0012);
    assert_eq!(bus.al(ST), (0x0002, 0));
}

#[test]
fn safeop_to_op_can_require_outputs() {
    let image: &'static [u8] = Box::leak(test_sii().into_boxed_slice());
    let mut cfg = ethercat::EscConfig::from_sii(image);
    cfg.require_outputs_for_op = true;
    let mut bus = Bus::new(vec![Esc::new(cfg, ethercat::Eeprom::ReadOnly(image))]);
    bus.assign_addresses();
    bus.write_mailbox_sms(ST);
    bus.request_state(ST, 2);
    write_pd_sms(&mut bus, 2, 2);
    bus.fpwr(ST, 0x0600, &fmmu_bytes(0, 2, SM2_START, false, true));
    bus.request_state(ST, 4);
    bus.request_state(ST, 8);
    assert_eq!(bus.al(ST), (0x0014, 0x0019));
    assert_eq!(bus.lrw(0, &[1, 2]).wkc, 2);
    bus.request_state(ST, 0x18);
    assert_eq!(bus.al(ST), (0x0008, 0));
}

#[test]
fn process_data_watchdog_drops_op_to_safeop() {
    let mut bus = preop_bus();
    write_pd_sms(&mut bus, 2, 2);
    bus.fpwr(ST, 0x0600, &fmmu_bytes(0, 2, SM2_START, false, true));
    bus.fpwr(ST, 0x0610, &fmmu_bytes(2, 2, SM3_START, true, false));
    bus.request_state(ST, 4);
    bus.request_state(ST, 8);
    assert_eq!(bus.al(ST), (0x0008, 0));
    // Default: 1000 × 100 µs = 100 ms.
    for _ in 0..10 {
        bus.now = od::Instant::from_nanos(bus.now.as_nanos() + 50_000_000);
        assert_eq!(bus.lrw(0, &[0; 4]).wkc, 3);
    }
    let deadline = bus.slaves[0].poll(bus.now).expect("armed");
    assert_eq!(deadline.as_nanos(), bus.now.as_nanos() + 100_000_000);
    bus.now = od::Instant::from_nanos(bus.now.as_nanos() + 100_000_001);
    assert_eq!(bus.slaves[0].poll(bus.now), None);
    assert_eq!(bus.al(ST), (0x0014, 0x001B));
    assert_eq!(bus.fprd(ST, 0x0440, 2).u16() & 1, 0);
    assert_eq!(bus.fprd(ST, 0x0442, 1).data, vec![1]);
    // Back in Op, a complete SM2 write restarts it: 0x0440 shows it running again.
    bus.request_state(ST, 0x0018);
    assert_eq!(bus.al(ST), (0x0008, 0));
    assert_eq!(bus.lrw(0, &[0; 4]).wkc, 3);
    assert_eq!(bus.fprd(ST, 0x0440, 2).u16() & 1, 1);
    // A new time in 0x0420 counts from the next poll: 10 × 100 µs.
    bus.fpwr(ST, 0x0420, &[10, 0]);
    let deadline = bus.slaves[0].poll(bus.now).expect("armed");
    assert_eq!(deadline.as_nanos(), bus.now.as_nanos() + 1_000_000);
    // 0x0420 = 0 disables it.
    bus.fpwr(ST, 0x0420, &[0, 0]);
    bus.now = od::Instant::from_nanos(bus.now.as_nanos() + 10_000_000_000);
    assert_eq!(bus.slaves[0].poll(bus.now), None);
    assert_eq!(bus.al(ST), (0x0008, 0));
}

#[test]
fn reconfiguring_sms_in_use_falls_back() {
    let mut bus = preop_bus();
    write_pd_sms(&mut bus, 2, 2);
    bus.request_state(ST, 4);
    // SM2 rewritten as a mailbox while in Safe-Op.
    bus.fpwr(ST, 0x0810, &[0x00, 0x11, 2, 0, 0x26, 0, 1, 0]);
    assert_eq!(bus.al(ST), (0x0012, 0x001D));
    // Mailbox SM0 disabled while in Pre-Op.
    bus.fpwr(ST, 0x0806, &[0]);
    assert_eq!(bus.al(ST), (0x0011, 0x0016));
    assert!(!bus.slaves[0].mailbox_running());
}

#[test]
fn device_fall_back() {
    let mut bus = preop_bus();
    write_pd_sms(&mut bus, 2, 2);
    bus.request_state(ST, 4);
    bus.request_state(ST, 8);
    bus.slaves[0].fall_back(AlState::SafeOp, AlStatusCode::SYNCHRONIZATION_ERROR);
    assert_eq!(bus.al(ST), (0x0014, 0x001A));
    // Without ack, a request is ignored.
    bus.request_state(ST, 8);
    assert_eq!(bus.al(ST), (0x0014, 0x001A));
    bus.request_state(ST, 0x18);
    assert_eq!(bus.al(ST), (0x0008, 0));
}

#[test]
fn brd_al_status_over_three_slaves() {
    let mut bus = Bus::with_sii(3);
    bus.assign_addresses();
    let r = bus.brd(0x0130, 2);
    assert_eq!((r.wkc, r.u16()), (3, 0x0001));
    for i in 0..3 {
        bus.write_mailbox_sms(0x1001 + i);
    }
    assert_eq!(bus.bwr(0x0120, &[0x02, 0x00]).wkc, 3);
    let r = bus.brd(0x0130, 2);
    assert_eq!((r.wkc, r.u16()), (3, 0x0002));
}
