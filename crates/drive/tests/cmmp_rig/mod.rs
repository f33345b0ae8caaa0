//! The CMMP-AS drive alone on the virtual clock: the rig of the drive-level tests. Each test
//! file adds the helpers it needs in its own `impl Rig`.
#![allow(dead_code)] // each test file uses a part of it

use std::time::Duration;

use drive::drive::{Drive, DriveSettings};
use od::{Instant, ObjectDictionary};

pub struct Rig {
    pub d: Drive<Vec<u8>>,
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
}
