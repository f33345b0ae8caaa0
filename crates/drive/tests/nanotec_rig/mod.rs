//! A Nanotec SMCI47-S (`devices/nanotec-smci47s.toml`) alone on the virtual clock, with its
//! CANopen node for the manual's frames: the rig of the Nanotec drive-level tests.
#![allow(dead_code)] // each test file uses a part of it

use std::time::Duration;

use drive::drive::{Drive, DriveEvent, DriveSettings};
use od::{Instant, ObjectAccess, ObjectDictionary, Value};

pub struct Rig {
    pub d: Drive<Vec<u8>>,
    pub now: Instant,
    /// The drive's CANopen node (node 34 = 22h, as in the manual's §2.4 examples).
    pub node: canopen::Node,
}

impl Rig {
    /// The Nanotec drive with `settings`, one millisecond after power-on.
    pub fn with(settings: DriveSettings) -> Self {
        let desc = &devices::NANOTEC_SMCI47S;
        let od = ObjectDictionary::new(desc, 34, vec![0; desc.storage_size])
            .expect("the Nanotec dictionary");
        let mut r = Rig {
            d: Drive::new(od, settings),
            now: Instant::ZERO,
            node: canopen::Node::new(34, desc.cia301),
        };
        r.node.boot(r.now, &r.d, &mut |_| {});
        r.run_ms(1);
        r
    }

    pub fn new() -> Self {
        Self::with(DriveSettings::default())
    }

    pub fn run_ms(&mut self, ms: u64) {
        self.now = self.now + Duration::from_millis(ms);
        self.d.step(self.now);
    }

    /// One SDO request to node 34 (COB-ID 622h), the bytes as the manual prints them (short
    /// frames included); the answer on 5A2h, its bytes.
    pub fn sdo(&mut self, request: &[u8]) -> Vec<u8> {
        let frame = canopen::CanFrame::new(0x622, request).expect("a CAN frame");
        let mut answer = Vec::new();
        let now = self.now;
        self.node.on_frame(now, &frame, &mut self.d, &mut |f| {
            if f.id == 0x5A2 {
                answer = f.payload().to_vec();
            }
        });
        answer
    }

    /// Controlword `v`, then 2 ms.
    pub fn cw(&mut self, v: u16) {
        self.d.write(0x6040, 0, &v.to_le_bytes()).unwrap();
        self.run_ms(2);
    }

    pub fn sw(&self) -> u16 {
        self.d.od().get_unsigned(0x6041, 0).unwrap() as u16
    }

    /// A 32-bit write (`v` as its two's complement); it must be taken.
    pub fn w32(&mut self, index: u16, sub: u8, v: i64) {
        self.d.write(index, sub, &(v as u32).to_le_bytes()).unwrap();
    }

    pub fn w8(&mut self, index: u16, sub: u8, v: i8) {
        self.d.write(index, sub, &[v as u8]).unwrap();
    }

    /// The value of `index`:`sub` as i64.
    pub fn i(&self, index: u16, sub: u8) -> i64 {
        match self.d.od().value(index, sub).unwrap() {
            Value::Signed(s) => s,
            Value::Unsigned(u) => u as i64,
            v => panic!("{v:?}"),
        }
    }

    /// 6064h position actual value, user units.
    pub fn position(&self) -> i64 {
        self.i(0x6064, 0)
    }

    /// Operation Enabled through 06h, 07h, 0Fh.
    pub fn enable(&mut self) {
        self.cw(0x0006);
        self.cw(0x0007);
        self.cw(0x000F);
        self.run_ms(20);
    }

    /// PP selected and enabled.
    pub fn enable_pp(&mut self) {
        self.enable();
        self.w8(0x6060, 0, 1);
        self.run_ms(5);
    }

    /// Every event the drive has reported since the last call.
    pub fn events(&mut self) -> Vec<DriveEvent> {
        std::iter::from_fn(|| self.d.take_event()).collect()
    }

    /// Runs until the statusword has target reached (bit 10), at most `ms`.
    pub fn until_target_reached(&mut self, ms: u64) -> bool {
        for _ in 0..ms / 5 {
            self.run_ms(5);
            if self.sw() & 0x0400 != 0 {
                return true;
            }
        }
        false
    }
}
