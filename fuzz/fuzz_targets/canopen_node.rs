//! CAN frames into the CiA 301 stack of a CMMP-AS (NMT, SYNC, PDO, SDO expedited, segmented
//! and block, LSS, guarding, any identifier) with pauses between them: no panic, every SDO
//! response carries 8 bytes, and the node's deadline always moves on after its poll (a
//! deadline that stays would make the runtime spin).
#![no_main]

use canopen::{CanFrame, Node, NodeEvent};
use libfuzzer_sys::fuzz_target;
use od::{Instant, ObjectDictionary};

const NODE: u8 = 1;

struct Bench {
    node: Node,
    od: ObjectDictionary<Vec<u8>>,
    now: Instant,
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

    fn advance(&mut self, ms: u64) {
        let target = Instant::from_nanos(self.now.as_nanos() + ms * 1_000_000);
        let mut polls = 0u32;
        while let Some(t) = self.node.deadline().filter(|t| *t <= target) {
            polls += 1;
            assert!(
                polls < 100_000,
                "the deadline stays at {t:?} after its poll"
            );
            self.now = t.max(self.now);
            self.node.poll(self.now, &mut self.od, &mut check);
            self.events();
        }
        self.now = target;
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
    let desc = &devices::CMMP_AS;
    let Ok(od) = ObjectDictionary::new(desc, NODE, vec![0; desc.storage_size]) else {
        return;
    };
    let mut b = Bench {
        node: Node::new(NODE, desc.cia301),
        od,
        now: Instant::ZERO,
    };
    b.boot();
    while let [tag, lo, hi, rest @ ..] = data {
        let word = u16::from_le_bytes([*lo, *hi]);
        if *tag == 0xFF {
            b.advance(u64::from(word.min(1000)));
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
    b.advance(2_000);
}

fuzz_target!(|data: &[u8]| run(data));
