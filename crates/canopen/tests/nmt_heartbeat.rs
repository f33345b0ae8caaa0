//! NMT slave, boot-up and heartbeat producer/consumer (CiA 301 §7.2.8; CMMP-AS §3.6–3.8).

mod common;
use canopen::heartbeat::ConsumerEvent;
use canopen::{NmtState, NodeEvent};
use common::*;

fn bench() -> Bench {
    Bench::new(&devices::TESTBENCH, 1)
}

#[test]
fn nmt_commands_addressed_and_broadcast() {
    let mut b = bench();
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    // CMMP-NMT-02: 000: 01 00 starts all nodes.
    assert!(b.send(0x000, &[0x01, 0x00]).is_empty(), "NMT has no answer");
    assert_eq!(b.node.nmt_state(), NmtState::Operational);
    // CMMP-NMT-03.
    b.send(0x000, &[0x80, 0x01]);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    // Addressed to another node: ignored.
    b.send(0x000, &[0x02, 0x05]);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    // Unknown command specifier and wrong length: ignored.
    b.send(0x000, &[0x07, 0x01]);
    b.send(0x000, &[0x02]);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    // CMMP-NMT-04: stopped nodes do not answer SDO.
    b.send(0x000, &[0x02, 0x01]);
    assert_eq!(b.node.nmt_state(), NmtState::Stopped);
    assert!(b.sdo(&[0x40, 0x41, 0x60, 0x00]).is_empty());
    b.send(0x000, &[0x01, 0x01]);
    assert_eq!(b.node.nmt_state(), NmtState::Operational);
    assert_eq!(
        b.events(),
        vec![
            NodeEvent::State(NmtState::PreOperational),
            NodeEvent::State(NmtState::Operational),
            NodeEvent::State(NmtState::PreOperational),
            NodeEvent::State(NmtState::Stopped),
            NodeEvent::State(NmtState::Operational),
        ]
    );
}

#[test]
fn resets_ask_the_runtime_and_boot_again() {
    let mut b = bench();
    b.events();
    // Reset communication, then reset node, each followed by boot-up 700h+id: 00.
    b.send(0x000, &[0x82, 0x01]);
    assert_eq!(b.node.nmt_state(), NmtState::Initialising, "CMMP-NMT-05");
    assert_eq!(
        b.events(),
        vec![NodeEvent::ResetCommunication],
        "CMMP-NMT-05"
    );
    assert!(
        b.sdo(&[0x40, 0x00, 0x10, 0x00]).is_empty(),
        "no SDO while initialising"
    );
    assert_eq!(b.boot(), vec![frame(0x701, &[0x00])], "CMMP-NMT-05");
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    b.send(0x000, &[0x81, 0x00]);
    assert_eq!(
        b.events(),
        vec![
            NodeEvent::State(NmtState::PreOperational),
            NodeEvent::ResetApplication
        ],
        "CMMP-NMT-06"
    );
}

#[test]
fn heartbeat_producer_follows_1017h() {
    let mut b = bench();
    assert!(b.advance_ms(5000).is_empty(), "heartbeat off by default");
    // CMMP-NMT-07: 1017h := 100 ms.
    assert_eq!(
        b.sdo1(&[0x2B, 0x17, 0x10, 0x00, 0x64, 0x00]),
        p8(&[0x60, 0x17, 0x10, 0x00])
    );
    let out = b.advance_ms(350);
    assert_eq!(out, vec![frame(0x701, &[0x7F]); 3]);
    b.send(0x000, &[0x01, 0x01]);
    assert_eq!(b.advance_ms(100), vec![frame(0x701, &[0x05])]);
    b.send(0x000, &[0x02, 0x01]);
    assert_eq!(
        b.advance_ms(100),
        vec![frame(0x701, &[0x04])],
        "heartbeat runs in Stopped"
    );
}

#[test]
fn boot_up_counts_as_the_first_heartbeat() {
    // CMMP-NMT-08: with 1017h ≠ 0 at boot, the next heartbeat is one period after boot-up.
    let mut b = bench();
    b.sdo1(&[0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03]);
    b.send(0x000, &[0x82, 0x01]);
    assert_eq!(b.boot(), vec![frame(0x701, &[0x00])]);
    assert!(b.advance_ms(999).is_empty());
    assert_eq!(b.advance_ms(1), vec![frame(0x701, &[0x7F])]);
}

#[test]
fn heartbeat_consumer_reports_loss_and_return() {
    let mut b = bench();
    b.events();
    // 1016h:01 := node 5, 200 ms.
    let v = (5u32 << 16 | 200).to_le_bytes();
    b.sdo1(&[0x23, 0x16, 0x10, 0x01, v[0], v[1], v[2], v[3]]);
    // Monitoring starts with the first heartbeat.
    assert!(b.advance_ms(1000).is_empty());
    assert!(b.events().is_empty());
    b.send(0x705, &[0x05]);
    b.advance_ms(150);
    b.send(0x705, &[0x05]);
    b.advance_ms(199);
    assert!(b.events().is_empty());
    b.advance_ms(2);
    assert_eq!(
        b.events(),
        vec![NodeEvent::Heartbeat(ConsumerEvent::Lost { node: 5 })]
    );
    b.send(0x705, &[0x05]);
    assert_eq!(
        b.events(),
        vec![NodeEvent::Heartbeat(ConsumerEvent::Resumed { node: 5 })]
    );
}
