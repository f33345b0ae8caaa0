//! Faults on the wire of a cell's bus, on the virtual clock. A cut cable silences a node both ways
//! and its heartbeat consumer reacts by itself (CiA 301 §7.2.8.3.2.2: EMCY 8130h); a corrupted
//! frame is an error frame the receivers count, never a wrong payload; a stopped SYNC takes 080h
//! only; a delayed frame arrives later.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use canopen::CanFrame;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::station::{Commissioning, Station};
use drivetwin::cell::wire_faults::{FaultKind, Reach, WireFault};
use od::Instant;

fn drive(device: &str, node: u8, objects: &[(u16, u8, Vec<u8>)]) -> Station {
    let desc = devices::by_name(device).expect("device");
    let commissioning = objects
        .iter()
        .map(|(index, sub, bytes)| Commissioning {
            index: *index,
            sub: *sub,
            bytes: bytes.clone(),
        })
        .collect();
    Station::new(desc, node, None, commissioning).expect("drive")
}

/// Node 1 (a test bench) beats every 100 ms; node 2 (a Kinco FD, whose 1016h is a real consumer) watches it with 250 ms.
fn cell() -> CanCell {
    CanCell::one_bus(vec![
        drive(
            "testbench",
            1,
            &[(0x1017, 0, 100u16.to_le_bytes().to_vec())],
        ),
        drive(
            "kinco-fd3",
            2,
            &[(0x1016, 1, 0x0001_00FAu32.to_le_bytes().to_vec())],
        ),
    ])
}

/// Runs `cell` from `from` to `to` on the virtual clock; the frames that reach the outside.
fn run(
    cell: &mut CanCell,
    from: Instant,
    to: Instant,
    inputs: &[(Instant, CanFrame)],
) -> Vec<(u64, CanFrame)> {
    let mut seen = Vec::new();
    let mut out = Vec::new();
    let mut now = from;
    let mut next = 0;
    loop {
        for f in out.drain(..) {
            seen.push((now.as_nanos() / 1_000_000, f));
        }
        let input = inputs.get(next).map(|(t, _)| *t);
        let wake = match (cell.deadline(), input) {
            (Some(a), Some(b)) => a.min(b),
            (a, b) => match a.or(b) {
                Some(t) => t,
                None => break,
            },
        };
        if wake > to {
            break;
        }
        now = wake.max(now);
        if input == Some(wake) {
            if let Some((_, f)) = inputs.get(next) {
                cell.on_frame(0, now, f, &mut out);
            }
            next += 1;
        } else {
            cell.poll(0, now, &mut out);
        }
    }
    seen
}

fn ms(t: u64) -> Instant {
    Instant::from_millis(t)
}

fn start_all() -> (Instant, CanFrame) {
    (ms(1), CanFrame::new(0x000, &[0x01, 0x00]).expect("frame"))
}

#[test]
fn a_cut_cable_silences_the_node_and_its_consumer_reports_8130h() {
    let mut c = cell();
    let mut out = Vec::new();
    c.boot(0, ms(0), &mut out);
    let before = run(&mut c, ms(0), ms(500), &[start_all()]);
    assert!(
        before.iter().any(|(_, f)| f.id == 0x701),
        "node 1 beats: {before:?}"
    );
    c.buses[0]
        .add_wire_fault(
            ms(500),
            WireFault::cable_break(Reach::Node(1), Some(Duration::from_millis(1000))),
        )
        .expect("fault");
    let during = run(&mut c, ms(500), ms(1499), &[]);
    assert!(
        during.iter().all(|(_, f)| f.id != 0x701),
        "no heartbeat of node 1 while its cable is cut: {during:?}"
    );
    let emcy = during
        .iter()
        .find(|(_, f)| f.id == 0x082)
        .unwrap_or_else(|| panic!("node 2 EMCY: {during:?}"));
    assert_eq!(
        emcy.1.payload().get(..2),
        Some(&[0x30, 0x81][..]),
        "CiA 301: heartbeat consumer error 8130h"
    );
    let after = run(&mut c, ms(1499), ms(1800), &[]);
    assert!(
        after.iter().any(|(_, f)| f.id == 0x701),
        "node 1 beats again"
    );
}

#[test]
fn corrupted_frames_are_error_frames_the_receivers_count() {
    let mut c = cell();
    let mut out = Vec::new();
    c.boot(0, ms(0), &mut out);
    run(&mut c, ms(0), ms(50), &[start_all()]);
    c.buses[0]
        .add_wire_fault(
            ms(50),
            WireFault {
                reach: Reach::Outside,
                kind: FaultKind::Corrupt { share: 1.0 },
                cob_id: None,
                frames: Some(3),
                lasting: None,
            },
        )
        .expect("fault");
    // Three SDO uploads from outside fail their CRC: nobody answers, both nodes count 3.
    let sdo = |t| {
        (
            ms(t),
            CanFrame::new(0x602, &[0x40, 0x00, 0x10, 0, 0, 0, 0, 0]).expect("frame"),
        )
    };
    let seen = run(&mut c, ms(50), ms(90), &[sdo(60), sdo(70), sdo(80)]);
    assert!(seen.iter().all(|(_, f)| f.id != 0x582), "{seen:?}");
    for (_, f) in c.buses[0].node_faults() {
        assert_eq!(f.confinement.counters(), (0, 3), "REC +1 per error frame");
    }
    // The fault has taken its three frames: the fourth is answered.
    let seen = run(&mut c, ms(90), ms(110), &[sdo(100)]);
    assert!(seen.iter().any(|(_, f)| f.id == 0x582));
}

#[test]
fn a_corrupted_node_frame_is_sent_again() {
    let mut c = cell();
    let mut out = Vec::new();
    c.boot(0, ms(0), &mut out);
    run(&mut c, ms(0), ms(50), &[start_all()]);
    c.buses[0]
        .add_wire_fault(
            ms(50),
            WireFault {
                reach: Reach::Node(1),
                kind: FaultKind::Corrupt { share: 1.0 },
                cob_id: Some(0x701),
                frames: Some(1),
                lasting: None,
            },
        )
        .expect("fault");
    let seen = run(&mut c, ms(50), ms(160), &[]);
    // The heartbeat still goes out once (the automatic retransmission after the error frame).
    assert_eq!(seen.iter().filter(|(_, f)| f.id == 0x701).count(), 1);
    assert_eq!(
        c.buses[0]
            .node_faults()
            .next()
            .expect("node 1's controller")
            .1
            .confinement
            .counters()
            .0,
        8 - 1,
        "TEC +8, -1"
    );
}

#[test]
fn a_delayed_request_is_answered_later_and_a_stopped_sync_takes_only_080h() {
    let mut c = cell();
    let mut out = Vec::new();
    c.boot(0, ms(0), &mut out);
    run(&mut c, ms(0), ms(50), &[start_all()]);
    c.buses[0]
        .add_wire_fault(ms(50), WireFault::stopped_sync(None))
        .expect("fault");
    c.buses[0]
        .add_wire_fault(
            ms(50),
            WireFault {
                reach: Reach::Outside,
                kind: FaultKind::Delay {
                    by: Duration::from_millis(7),
                },
                cob_id: Some(0x602),
                frames: None,
                lasting: None,
            },
        )
        .expect("fault");
    let sdo = CanFrame::new(0x602, &[0x40, 0x00, 0x10, 0, 0, 0, 0, 0]).expect("frame");
    let seen = run(&mut c, ms(50), ms(90), &[(ms(60), sdo)]);
    let answer = seen.iter().find(|(_, f)| f.id == 0x582).expect("answer");
    assert_eq!(answer.0, 67, "the request arrived 7 ms late");
}

/// A disturbance names its station by id: a station of another bus is refused; the bus's own
/// sends its boot-up once with an error frame and once more (TEC +8, −1), and its controller
/// is listed under its id.
#[test]
fn a_disturbance_reaches_the_station_named_by_its_id() {
    let mut c = CanCell::one_bus(vec![drive("kinco-fd3", 2, &[])]);
    c.add_bus(vec![drive("testbench", 1, &[])]);
    let kinco = c.buses[0].members()[0];
    let bench = c.buses[1].members()[0];
    assert!(!c.buses[1].disturb(kinco, 1), "the Kinco is on bus 0");
    assert!(c.buses[1].disturb(bench, 1));
    let mut out = Vec::new();
    c.boot(0, ms(0), &mut out);
    c.boot(1, ms(0), &mut out);
    let tec = |c: &CanCell, bus: usize| -> Vec<_> {
        c.buses[bus]
            .node_faults()
            .map(|(id, f)| (id, f.confinement.counters().0))
            .collect()
    };
    assert_eq!(
        tec(&c, 1),
        [(bench, 8 - 1)],
        "the bench's boot-up, sent again"
    );
    assert_eq!(tec(&c, 0), [(kinco, 0)], "the Kinco undisturbed");
}
