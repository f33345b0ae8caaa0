//! Whatever arrives on the bus, the node goes on: any sequence of frames (NMT, SYNC, TIME,
//! PDOs, SDO, LSS, guarding, or any identifier) with any payload, at any pace, leaves the
//! CANopen stack of a CMMP-AS (and of a Nanotec SMCI47-S) answering without a panic; the SDO server's frames always
//! carry 8 bytes and a server command specifier CiA 301 defines; and after an NMT reset the
//! node boots and answers an SDO upload of 1018h:01 again, whatever state the sequence left.

mod common;

use canopen::CanFrame;
use common::Bench;
use proptest::prelude::*;

const NODE: u16 = 1;

/// Identifiers the stack listens to, and any other.
fn identifier() -> impl Strategy<Value = u16> {
    prop_oneof![
        Just(0x000),
        Just(0x080),
        Just(0x100),
        (0u16..4).prop_map(|n| 0x200 + 0x100 * n + NODE),
        Just(0x600 + NODE),
        Just(0x700 + NODE),
        Just(0x7E5),
        0u16..0x800,
    ]
}

/// A frame, or a pause of the given milliseconds.
#[derive(Debug, Clone)]
enum Event {
    Frame(u16, Vec<u8>),
    Pause(u64),
}

fn event() -> impl Strategy<Value = Event> {
    prop_oneof![
        4 => (identifier(), prop::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(id, data)| Event::Frame(id, data)),
        1 => (0u64..200).prop_map(Event::Pause),
    ]
}

fn check_sent(frames: &[CanFrame], node: u8) -> Result<(), TestCaseError> {
    for f in frames.iter().filter(|f| f.id == 0x580 + u32::from(node)) {
        prop_assert_eq!(f.len, 8, "SDO responses carry 8 bytes: {:?}", f);
        prop_assert_ne!(f.data[0] >> 5, 7, "no server command specifier 7: {:?}", f);
    }
    Ok(())
}

/// What the application does with the node's events: a reset boots the node again (the
/// drive would reload its dictionary first).
fn boot_after_reset(b: &mut Bench) {
    while let Some(e) = b.node.take_event() {
        if matches!(
            e,
            canopen::NodeEvent::ResetApplication | canopen::NodeEvent::ResetCommunication
        ) {
            b.boot();
        }
    }
}

/// Runs the node's clock `ms` on, deadline by deadline; a deadline that does not move on
/// after its poll would stall the runtime and fails the case.
fn advance(b: &mut Bench, ms: u64) -> Result<Vec<CanFrame>, TestCaseError> {
    let target = od::Instant::from_nanos(b.now.as_nanos() + ms * 1_000_000);
    let mut out = Vec::new();
    let mut polls = 0u32;
    while let Some(t) = b.node.deadline().filter(|t| *t <= target) {
        polls += 1;
        prop_assert!(
            polls < 100_000,
            "the deadline stays at {:?} after its poll",
            t
        );
        b.now = t.max(b.now);
        b.node.poll(b.now, &mut b.od, &mut |f| out.push(f));
    }
    b.now = target;
    b.node.poll(b.now, &mut b.od, &mut |f| out.push(f));
    Ok(out)
}

/// The property for one personality: any events, then a reset, then 1018h:01 answers.
fn any_frames(desc: &'static od::DeviceDescription, events: &[Event]) -> Result<(), TestCaseError> {
    let mut b = Bench::new(desc, NODE as u8);
    for e in events {
        let sent = match e {
            Event::Frame(id, data) => b.send(*id, data),
            Event::Pause(ms) => advance(&mut b, *ms)?,
        };
        check_sent(&sent, b.node.node_id())?;
        boot_after_reset(&mut b);
    }
    // Back to a known state: LSS waiting, then NMT reset node for all nodes.
    b.send(0x7E5, &[0x04, 0x00, 0, 0, 0, 0, 0, 0]);
    b.send(0x000, &[0x81, 0x00]);
    boot_after_reset(&mut b);
    advance(&mut b, 10)?;
    let id = b.node.node_id();
    if (1..=127).contains(&id) {
        let r = b.send(0x600 + u16::from(id), &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]);
        let answer = r.iter().find(|f| f.id == 0x580 + u32::from(id));
        prop_assert!(answer.is_some(), "no SDO answer after the reset: {:?}", r);
        if let Some(a) = answer {
            let [v0, v1, v2, v3] = desc.vendor_id.to_le_bytes();
            prop_assert_eq!(a.data, [0x43, 0x18, 0x10, 0x01, v0, v1, v2, v3]);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn any_frames_leave_the_node_answering(events in prop::collection::vec(event(), 1..80)) {
        any_frames(&devices::CMMP_AS, &events)?;
    }

    /// The same for the Nanotec SMCI47-S, whose node answers NMT commands with its state,
    /// fills in PDO mapping lengths and maps dummy objects.
    #[test]
    fn any_frames_leave_the_nanotec_node_answering(events in prop::collection::vec(event(), 1..80)) {
        any_frames(&devices::NANOTEC_SMCI47S, &events)?;
    }
}

/// A node reset by NMT waits for its application to boot it, and until then nothing is due:
/// a deadline left at the reset's instant would make a runtime that polls on `deadline()`
/// before booting it spin for ever.
#[test]
fn a_reset_node_has_no_deadline_until_it_is_booted() {
    let mut b = Bench::new(&devices::CMMP_AS, NODE as u8);
    b.send(0x000, &[0x81, NODE as u8]);
    assert_eq!(b.node.deadline(), None);
    b.node.poll(b.now, &mut b.od, &mut |_| {});
    assert_eq!(b.node.deadline(), None, "still nothing due after a poll");
    b.boot();
    assert!(
        b.node.deadline().is_some(),
        "heartbeat and the rest run again"
    );
}
