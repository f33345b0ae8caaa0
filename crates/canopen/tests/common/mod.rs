//! A booted node on a dictionary, driven frame by frame with hand-made instants.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]
#![allow(dead_code)]

use canopen::{CanFrame, Node, NodeEvent};
use od::{Instant, ObjectDictionary};

pub struct Bench {
    pub node: Node,
    pub od: ObjectDictionary<Vec<u8>>,
    pub now: Instant,
}

impl Bench {
    pub fn new(desc: &'static od::DeviceDescription, node_id: u8) -> Self {
        let od = ObjectDictionary::new(desc, node_id, vec![0; desc.storage_size])
            .expect("storage sized from the description");
        let mut b = Bench {
            node: Node::new(node_id, desc.cia301),
            od,
            now: Instant::ZERO,
        };
        let frames = b.boot();
        assert_eq!(frames, vec![frame(0x700 + node_id as u16, &[0x00])]);
        b
    }

    pub fn boot(&mut self) -> Vec<CanFrame> {
        let mut out = Vec::new();
        self.node.boot(self.now, &self.od, &mut |f| out.push(f));
        out
    }

    pub fn send(&mut self, id: u16, data: &[u8]) -> Vec<CanFrame> {
        let f = CanFrame::new(id, data).expect("test frame");
        let mut out = Vec::new();
        self.node
            .on_frame(self.now, &f, &mut self.od, &mut |f| out.push(f));
        out
    }

    /// One SDO request to node `id`; returns the data of every response frame.
    pub fn sdo(&mut self, data: &[u8]) -> Vec<[u8; 8]> {
        let id = self.node.node_id() as u16;
        self.send(0x600 + id, data)
            .into_iter()
            .map(|f| {
                assert_eq!(f.id, 0x580 + id as u32);
                assert_eq!(f.len, 8, "the server always answers with 8 bytes");
                f.data
            })
            .collect()
    }

    /// One request, exactly one response.
    pub fn sdo1(&mut self, data: &[u8]) -> [u8; 8] {
        let r = self.sdo(data);
        assert_eq!(
            r.len(),
            1,
            "expected one response to {data:02X?}, got {r:02X?}"
        );
        r[0]
    }

    pub fn advance_ms(&mut self, ms: u64) -> Vec<CanFrame> {
        let target = Instant::from_nanos(self.now.as_nanos() + ms * 1_000_000);
        let mut out = Vec::new();
        loop {
            let next = self.node.deadline();
            match next {
                Some(t) if t <= target => {
                    self.now = t;
                    self.node.poll(self.now, &mut self.od, &mut |f| out.push(f));
                }
                _ => break,
            }
        }
        self.now = target;
        self.node.poll(self.now, &mut self.od, &mut |f| out.push(f));
        out
    }

    pub fn events(&mut self) -> Vec<NodeEvent> {
        std::iter::from_fn(|| self.node.take_event()).collect()
    }
}

pub fn frame(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::new(id, data).expect("test frame")
}

/// Pads to 8 bytes, as the server answers.
pub fn p8(data: &[u8]) -> [u8; 8] {
    let mut b = [0u8; 8];
    b[..data.len()].copy_from_slice(data);
    b
}

pub fn abort(index: u16, sub: u8, code: u32) -> [u8; 8] {
    let i = index.to_le_bytes();
    let c = code.to_le_bytes();
    [0x80, i[0], i[1], sub, c[0], c[1], c[2], c[3]]
}
