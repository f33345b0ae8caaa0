//! A Kinco FD3 (`devices/kinco-fd3.toml`) alone on the virtual clock, node 1, with its
//! CANopen node for SDO frames: the rig of the Kinco drive-level tests.
#![allow(dead_code)] // each test file uses a part of it

use std::time::Duration;

use drive::drive::{Drive, DriveEvent, DriveSettings};
use od::{AbortCode, Instant, ObjectAccess, ObjectDictionary, Value};

/// Encoder increments per revolution of the twin's Kinco motor.
pub const INC_PER_REV: i64 = 10_000;

/// DEC of 1 rpm (spec/kinco-fd-cd.md §6 item 12: rpm × 512 × 10 000 / 1875).
pub fn dec_rpm(rpm: f64) -> i64 {
    (rpm * 512.0 * 10_000.0 / 1875.0).round() as i64
}

/// DEC of 1 rps/s (rps/s × 65536 × 10 000 / 4 000 000).
pub fn dec_rps2(rps2: f64) -> i64 {
    (rps2 * 65536.0 * 10_000.0 / 4_000_000.0).round() as i64
}

pub struct Rig {
    pub d: Drive<Vec<u8>>,
    pub now: Instant,
    pub node: canopen::Node,
}

impl Rig {
    pub fn with(settings: DriveSettings) -> Self {
        let desc = devices::by_name("kinco-fd3").expect("the Kinco FD3 device file");
        let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size])
            .expect("the Kinco dictionary");
        let mut r = Rig {
            d: Drive::new(od, settings),
            now: Instant::ZERO,
            node: canopen::Node::new(1, desc.cia301),
        };
        r.node.boot(r.now, &r.d, &mut |_| {});
        r.run_ms(1);
        r
    }

    /// The factory set-up: DIN1 Enable, DIN3 Operation Mode Sel, … (ch. 9).
    pub fn factory() -> Self {
        Self::with(DriveSettings::default())
    }

    /// As a bus master sets the drive up (EA02 = 8 "protocol"): no DIN owns the controlword
    /// or the mode (Din1_Function, Din3_Function := 0); ramps and speeds set.
    pub fn new() -> Self {
        let mut r = Self::factory();
        r.w16(0x2010, 0x03, 0);
        r.w16(0x2010, 0x05, 0);
        r.w32(0x6081, 0, dec_rpm(600.0));
        r.w32(0x6083, 0, dec_rps2(100.0));
        r.w32(0x6084, 0, dec_rps2(100.0));
        r.run_ms(2);
        r
    }

    pub fn run_ms(&mut self, ms: u64) {
        self.now = self.now + Duration::from_millis(ms);
        self.d.step(self.now);
    }

    /// One SDO request to node 1 (601h); the answer on 581h.
    pub fn sdo(&mut self, request: &[u8]) -> Vec<u8> {
        let frame = canopen::CanFrame::new(0x601, request).expect("a CAN frame");
        let mut answer = Vec::new();
        let now = self.now;
        self.node.on_frame(now, &frame, &mut self.d, &mut |f| {
            if f.id == 0x581 {
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
        self.d.od().get_unsigned(0x6041, 0).unwrap() as u16
    }

    pub fn w32(&mut self, index: u16, sub: u8, v: i64) {
        self.d.write(index, sub, &(v as u32).to_le_bytes()).unwrap();
    }

    pub fn w16(&mut self, index: u16, sub: u8, v: i64) {
        self.d.write(index, sub, &(v as u16).to_le_bytes()).unwrap();
    }

    pub fn w8(&mut self, index: u16, sub: u8, v: i8) {
        self.d.write(index, sub, &[v as u8]).unwrap();
    }

    pub fn i(&self, index: u16, sub: u8) -> i64 {
        match self.d.od().value(index, sub).unwrap() {
            Value::Signed(s) => s,
            Value::Unsigned(u) => u as i64,
            v => panic!("{v:?}"),
        }
    }

    /// Pos_Actual 6063h, increments.
    pub fn position(&self) -> i64 {
        self.i(0x6063, 0)
    }

    /// The motor speed, rpm.
    pub fn rpm(&self) -> f64 {
        f64::from(self.d.plant_velocity_rpm())
    }

    /// Mode `m` selected, then 0Fh from 06h (Tab. 6-5).
    pub fn enable_in(&mut self, m: i8) {
        self.w8(0x6060, 0, m);
        self.cw(0x06);
        self.cw(0x0F);
        self.run_ms(10);
    }

    pub fn events(&mut self) -> Vec<DriveEvent> {
        std::iter::from_fn(|| self.d.take_event()).collect()
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
