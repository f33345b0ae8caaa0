//! CAN frames into the CiA 301 stack of a CMMP-AS (NMT, SYNC, PDO, SDO expedited, segmented
//! and block, LSS, guarding, any identifier) with pauses between them: no panic, every SDO
//! response carries 8 bytes, and the node's deadline always moves on after its poll (a
//! deadline that stays would make the runtime spin).
//!
//! Speed (about 2·10^3 executions/s before, most of it polling a node whose fuzzed 1017h or
//! 1006h made it due every millisecond through the pauses): the dictionary with its defaults
//! is built once and copied for every input, and an input gets at most [`MAX_POLLS`] polls
//! (the rest of it is skipped). A deadline that does not move on is caught within
//! [`STUCK_POLLS`] polls at one instant.
#![no_main]

use canopen::{CanFrame, Node, NodeEvent};
use libfuzzer_sys::fuzz_target;
use od::{Instant, ObjectDictionary};
use std::sync::OnceLock;

const NODE: u8 = 1;
/// Polls per input.
const MAX_POLLS: u32 = 2_000;
/// Polls in a row at one instant that mean the deadline stays.
const STUCK_POLLS: u32 = 1_000;

struct Bench {
    node: Node,
    od: ObjectDictionary<Vec<u8>>,
    now: Instant,
    polls: u32,
}

/// The CMMP-AS dictionary with its defaults, built once.
fn dictionary() -> Option<ObjectDictionary<Vec<u8>>> {
    static OD: OnceLock<Option<ObjectDictionary<Vec<u8>>>> = OnceLock::new();
    OD.get_or_init(|| {
        let desc = &devices::CMMP_AS;
        ObjectDictionary::new(desc, NODE, vec![0; desc.storage_size]).ok()
    })
    .clone()
}

impl Bench {
    fn boot(&mut self) {
        self.node.boot(self.now, &self.od, &mut check);
    }

    fn events(&mut self) {
        while let Some(e) = self.node.take_event() {
            if matches!(
                e,
                NodeEvent::ResetApplication | NodeEvent::ResetCommunication
            ) {
                self.boot();
            }
        }
    }

    /// Time passes; false when the input's polls are used up.
    fn advance(&mut self, ms: u64) -> bool {
        let target = Instant::from_nanos(self.now.as_nanos() + ms * 1_000_000);
        let mut same_instant = 0u32;
        while let Some(t) = self.node.deadline().filter(|t| *t <= target) {
            if self.polls >= MAX_POLLS {
                return false;
            }
            self.polls += 1;
            same_instant = if t <= self.now { same_instant + 1 } else { 0 };
            assert!(
                same_instant < STUCK_POLLS,
                "the deadline stays at {t:?} after its poll"
            );
            self.now = t.max(self.now);
            self.node.poll(self.now, &mut self.od, &mut check);
            self.events();
        }
        self.now = target;
        true
    }
}

fn check(f: CanFrame) {
    if f.id == 0x580 + u32::from(NODE) {
        assert_eq!(f.len, 8, "SDO responses carry 8 bytes: {f:?}");
    }
}

/// The input, record by record (`seeds.py` writes the same format from the manuals'
/// frames): `FF lo hi` is a pause of `lo | hi << 8` ms (at most 1000); any other first byte
/// `n` is a frame of `n % 9` data bytes with the 11-bit identifier `lo | hi << 8` after it.
fn run(mut data: &[u8]) {
    let Some(od) = dictionary() else {
        return;
    };
    let mut b = Bench {
        node: Node::new(NODE, devices::CMMP_AS.cia301),
        od,
        now: Instant::ZERO,
        polls: 0,
    };
    b.boot();
    while let [tag, lo, hi, rest @ ..] = data {
        let word = u16::from_le_bytes([*lo, *hi]);
        if *tag == 0xFF {
            if !b.advance(u64::from(word.min(1000))) {
                return;
            }
            data = rest;
            continue;
        }
        let len = usize::from(tag % 9).min(rest.len());
        let (payload, rest) = rest.split_at(len);
        if let Ok(f) = CanFrame::new(word & 0x7FF, payload) {
            b.node.on_frame(b.now, &f, &mut b.od, &mut check);
            b.events();
        }
        data = rest;
    }
    let _ = b.advance(2_000);
}

fuzz_target!(|data: &[u8]| run(data));
