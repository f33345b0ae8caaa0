//! A Nanotec SMCI47-S (`devices/nanotec-smci47s.toml`) as node 34 (22h, as in the manual's
//! §2.4 examples) on the shared rig (`drive_rig`): the rig of the Nanotec drive-level tests.
#![allow(dead_code)] // each test file uses a part of it

#[path = "../drive_rig/mod.rs"]
mod drive_rig;

use drive::drive::Drive;
use drive::drive::DriveSettings;
use drive::vendors::nanotec::Nanotec;

/// The rig of one Nanotec drive.
pub type Rig = drive_rig::DeviceRig<Drive<Vec<u8>, Nanotec>>;

impl Rig {
    /// The Nanotec drive with `settings`, one millisecond after power-on.
    pub fn with(settings: DriveSettings) -> Self {
        Rig::device("nanotec-smci47s", 34, settings)
    }

    pub fn new() -> Self {
        Self::with(DriveSettings::default())
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

    /// Runs until the statusword has target reached (bit 10), at most `ms`.
    pub fn until_target_reached(&mut self, ms: u64) -> bool {
        self.until_sw(0x0400, ms)
    }
}
