//! The CiA 301 side of the Kinco FD3 (Kinco CD3 / FD3 manual ch. 11; the vector catalogue kept
//! beside the project, §4.5): its KINCO-CAN vectors, each at its test, frame by frame, on the
//! device description `devices/kinco-fd3.toml` alone. What the drive does with a controlword is the
//! personality's, not tested here.

mod common;
use canopen::{CanFrame, NmtState, NodeEvent};
use common::*;

fn fd3(node: u8) -> Bench {
    Bench::new(&devices::KINCO_FD3, node)
}

fn rtr(b: &mut Bench, id: u16) -> Vec<CanFrame> {
    let f = CanFrame::remote(id, 1);
    let mut out = Vec::new();
    b.node.on_frame(b.now, &f, &mut b.od, &mut |f| out.push(f));
    out
}

/// KINCO-CAN-01: node 2 Operational; `000: 80 02` → Pre-Operational, no reply (§11.2, L2522).
#[test]
fn kinco_can_01_enter_pre_operational() {
    let mut b = fd3(2);
    assert!(b.send(0x000, &[0x01, 0x02]).is_empty(), "NMT has no reply");
    assert_eq!(b.node.nmt_state(), NmtState::Operational);
    assert!(b.send(0x000, &[0x80, 0x02]).is_empty());
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
}

/// KINCO-CAN-02: `01 n`, `02 n`, `80 n`, `81 n`, `82 n`, node-ID 0 = all nodes; after a reset
/// the node boots into Pre-Operational with the boot-up message (transition 6, L2503).
#[test]
fn kinco_can_02_nmt_commands() {
    let mut b = fd3(1);
    for (cs, state) in [
        (0x01, NmtState::Operational),
        (0x02, NmtState::Stopped),
        (0x80, NmtState::PreOperational),
    ] {
        for node in [1, 0] {
            b.send(0x000, &[cs, node]);
            assert_eq!(b.node.nmt_state(), state, "{cs:02X} {node}");
        }
    }
    b.send(0x000, &[0x01, 0x07]);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational, "another node");
    for (cs, event) in [
        (0x81, NodeEvent::ResetApplication),
        (0x82, NodeEvent::ResetCommunication),
    ] {
        b.events();
        assert!(b.send(0x000, &[cs, 0x01]).is_empty());
        assert_eq!(b.node.take_event(), Some(event));
        assert_eq!(b.boot(), vec![frame(0x701, &[0x00])]);
        assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    }
}

/// KINCO-CAN-03: heartbeat `701: 00` at boot-up, then `7F` / `05` / `04` by state
/// (producer time 1017h, L2463-2469).
#[test]
fn kinco_can_03_heartbeat_states() {
    let mut b = fd3(1);
    assert_eq!(b.sdo1(&[0x2B, 0x17, 0x10, 0x00, 100, 0, 0, 0])[0], 0x60);
    let beats = |b: &mut Bench| -> Vec<u8> {
        b.advance_ms(100)
            .into_iter()
            .filter(|f| f.id == 0x701)
            .map(|f| f.data[0])
            .collect()
    };
    assert_eq!(beats(&mut b), vec![0x7F]);
    b.send(0x000, &[0x01, 0x01]);
    assert_eq!(beats(&mut b), vec![0x05]);
    b.send(0x000, &[0x02, 0x01]);
    assert_eq!(beats(&mut b), vec![0x04]);
}

/// KINCO-CAN-04: node 1 Pre-Operational, `RTR 701` twice → `701: 7F`, then `701: FF`: the
/// toggle bit 7 is 0 in the first reply (L2471-2483).
#[test]
fn kinco_can_04_guarding_toggle() {
    let mut b = fd3(1);
    assert_eq!(rtr(&mut b, 0x701), vec![frame(0x701, &[0x7F])]);
    assert_eq!(rtr(&mut b, 0x701), vec![frame(0x701, &[0xFF])]);
}

/// KINCO-CAN-05: node 1 answers SDO requests on 601h from 581h (L2405-2406); an upload of
/// the statusword 6041h answers 4Bh.
#[test]
fn kinco_can_05_sdo_on_601_581() {
    let mut b = fd3(1);
    let r = b.sdo1(&[0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0]);
    assert_eq!(&r[..4], &[0x4B, 0x41, 0x60, 0x00]);
    let r = b.sdo1(&[0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0]);
    assert_eq!(r, p8(&[0x43, 0x18, 0x10, 0x02, 0xD3, 0x0F]));
    assert!(
        b.send(0x602, &[0x40, 0x41, 0x60, 0x00]).is_empty(),
        "node 2's channel"
    );
}
