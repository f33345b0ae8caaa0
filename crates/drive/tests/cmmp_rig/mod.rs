//! The CMMP-AS drive alone on the virtual clock: the rig of the drive-level tests. Each test
//! file adds the helpers it needs in its own `impl Rig`.
#![allow(dead_code)] // each test file uses a part of it
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use drive::drive::{Drive, DriveSettings};
use drive::vendors::festo_cmmp_as::CmmpAs;
use od::{Instant, ObjectAccess, ObjectDictionary, Value};

pub struct Rig {
    pub d: Drive<Vec<u8>, CmmpAs>,
    pub now: Instant,
}

impl Rig {
    /// The CMMP-AS with `settings`, one millisecond after power-on.
    pub fn with(settings: DriveSettings) -> Self {
        let desc = &devices::CMMP_AS;
        let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size])
            .expect("the CMMP-AS dictionary");
        let mut r = Rig {
            d: Drive::new(od, settings),
            now: Instant::ZERO,
        };
        r.run_ms(1);
        r
    }

    pub fn new() -> Self {
        Self::with(DriveSettings::default())
    }

    /// Steps the drive to `ms` later (it runs every cycle up to then).
    pub fn run_ms(&mut self, ms: u64) {
        self.now = self.now + Duration::from_millis(ms);
        self.d.step(self.now);
    }

    /// A 32-bit write (`v` as its two's complement); it must be taken.
    pub fn w32(&mut self, index: u16, sub: u8, v: i64) {
        self.d.write(index, sub, &(v as u32).to_le_bytes()).unwrap();
    }

    /// Controlword `v`, then 2 ms.
    pub fn cw(&mut self, v: u16) {
        self.d.write(0x6040, 0, &v.to_le_bytes()).unwrap();
        self.run_ms(2);
    }

    pub fn sw(&self) -> u16 {
        self.d.od().get_unsigned(0x6041, 0).unwrap() as u16
    }

    /// The value of `index`:00, signed or unsigned, as i64.
    pub fn i(&self, index: u16) -> i64 {
        match self.d.od().value(index, 0).unwrap() {
            Value::Signed(s) => s,
            Value::Unsigned(u) => u as i64,
            v => panic!("{v:?}"),
        }
    }
}
