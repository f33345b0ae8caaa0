//! One drive of a device file (`devices/*.toml`, by its name) alone on the virtual clock, with
//! its CANopen node for SDO frames: the rig of the drive-level tests. The vendors' rigs
//! (`kinco_rig`, `nanotec_rig`) add their constructors and helpers in their own `impl Rig`.
#![allow(dead_code)] // each test file uses a part of it
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use drive::drive::{Drive, DriveEvent, DriveSettings};
use drive::personality::Vendor;
use drive::vendors::AnyDrive;
use od::{AbortCode, Instant, ObjectAccess, ObjectDictionary, Value};

/// What the rig needs of its drive: a drive of one vendor, or any drive.
pub trait RigDrive: ObjectAccess {
    fn power_on(od: ObjectDictionary<Vec<u8>>, settings: DriveSettings) -> Self;
    fn step_to(&mut self, now: Instant);
    fn dictionary(&self) -> &ObjectDictionary<Vec<u8>>;
    fn next_event(&mut self) -> Option<DriveEvent>;
}

impl<V: Vendor> RigDrive for Drive<Vec<u8>, V> {
    fn power_on(od: ObjectDictionary<Vec<u8>>, settings: DriveSettings) -> Self {
        Drive::new(od, settings)
    }
    fn step_to(&mut self, now: Instant) {
        self.step(now);
    }
    fn dictionary(&self) -> &ObjectDictionary<Vec<u8>> {
        self.od()
    }
    fn next_event(&mut self) -> Option<DriveEvent> {
        self.take_event()
    }
}

impl RigDrive for AnyDrive<Vec<u8>> {
    fn power_on(od: ObjectDictionary<Vec<u8>>, settings: DriveSettings) -> Self {
        AnyDrive::new(od, settings)
    }
    fn step_to(&mut self, now: Instant) {
        self.step(now);
    }
    fn dictionary(&self) -> &ObjectDictionary<Vec<u8>> {
        self.od()
    }
    fn next_event(&mut self) -> Option<DriveEvent> {
        self.take_event()
    }
}

/// The rig of any drive of the device files.
pub type Rig = DeviceRig<AnyDrive<Vec<u8>>>;

pub struct DeviceRig<D> {
    pub d: D,
    pub now: Instant,
    /// The drive's CANopen node.
    pub node: canopen::Node,
}

impl<D: RigDrive> DeviceRig<D> {
    /// The drive of device file `name` as node `node`, with `settings`, one millisecond after
    /// power-on.
    pub fn device(name: &str, node: u8, settings: DriveSettings) -> Self {
        let desc = devices::by_name(name).expect("a device file of that name");
        let od =
            ObjectDictionary::new(desc, node, vec![0; desc.storage_size]).expect("the dictionary");
        let mut r = DeviceRig {
            d: D::power_on(od, settings),
            now: Instant::ZERO,
            node: canopen::Node::new(node, desc.cia301),
        };
        r.node.boot(r.now, &r.d, &mut |_| {});
        r.run_ms(1);
        r
    }

    /// Steps the drive to `ms` later (it runs every cycle up to then).
    pub fn run_ms(&mut self, ms: u64) {
        self.now = self.now + Duration::from_millis(ms);
        self.d.step_to(self.now);
    }

    /// One SDO request to the node (600h + node-ID), the bytes as a manual prints them (short
    /// frames included); the answer on 580h + node-ID, its bytes.
    pub fn sdo(&mut self, request: &[u8]) -> Vec<u8> {
        let id = u16::from(self.node.node_id());
        let frame = canopen::CanFrame::new(0x600 + id, request).expect("a CAN frame");
        let mut answer = Vec::new();
        let now = self.now;
        self.node.on_frame(now, &frame, &mut self.d, &mut |f| {
            if f.id == 0x580 + u32::from(id) {
                answer = f.payload().to_vec();
            }
        });
        answer
    }

    /// Controlword `v` through the bus, then 2 ms.
    pub fn cw(&mut self, v: u16) {
        self.d.write(0x6040, 0, &v.to_le_bytes()).unwrap();
        self.run_ms(2);
    }

    pub fn try_cw(&mut self, v: u16) -> Result<(), AbortCode> {
        self.d.write(0x6040, 0, &v.to_le_bytes())
    }

    pub fn sw(&self) -> u16 {
        self.d.dictionary().get_unsigned(0x6041, 0).unwrap() as u16
    }

    /// A 32-bit write (`v` as its two's complement); it must be taken.
    pub fn w32(&mut self, index: u16, sub: u8, v: i64) {
        self.d.write(index, sub, &(v as u32).to_le_bytes()).unwrap();
    }

    pub fn w16(&mut self, index: u16, sub: u8, v: i64) {
        self.d.write(index, sub, &(v as u16).to_le_bytes()).unwrap();
    }

    pub fn w8(&mut self, index: u16, sub: u8, v: i8) {
        self.d.write(index, sub, &[v as u8]).unwrap();
    }

    /// The value of `index`:`sub` as i64.
    pub fn i(&self, index: u16, sub: u8) -> i64 {
        match self.d.dictionary().value(index, sub).unwrap() {
            Value::Signed(s) => s,
            Value::Unsigned(u) => u as i64,
            v => panic!("{v:?}"),
        }
    }

    /// Every event the drive has reported since the last call.
    pub fn events(&mut self) -> Vec<DriveEvent> {
        std::iter::from_fn(|| self.d.next_event()).collect()
    }

    /// Runs until the statusword has `mask` set, at most `ms`.
    pub fn until_sw(&mut self, mask: u16, ms: u64) -> bool {
        for _ in 0..ms / 5 {
            self.run_ms(5);
            if self.sw() & mask == mask {
                return true;
            }
        }
        false
    }
}
