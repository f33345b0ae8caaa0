//! A Kinco FD3 (`devices/kinco-fd3.toml`) as node 1 on the shared rig (`drive_rig`): the rig
//! of the Kinco drive-level tests, with the Kinco units and set-ups.
#![allow(dead_code)] // each test file uses a part of it

#[path = "../drive_rig/mod.rs"]
mod drive_rig;

use drive::drive::Drive;
use drive::drive::DriveSettings;
use drive::vendors::kinco::Kinco;

/// The rig of one Kinco drive.
pub type Rig = drive_rig::DeviceRig<Drive<Vec<u8>, Kinco>>;

/// Encoder increments per revolution of the twin's Kinco motor.
pub const INC_PER_REV: i64 = 10_000;

/// DEC of 1 rpm (rpm × 512 × 10 000 / 1875, as the sibling FD manuals give it).
pub fn dec_rpm(rpm: f64) -> i64 {
    (rpm * 512.0 * 10_000.0 / 1875.0).round() as i64
}

/// DEC of 1 rps/s (rps/s × 65536 × 10 000 / 4 000 000).
pub fn dec_rps2(rps2: f64) -> i64 {
    (rps2 * 65536.0 * 10_000.0 / 4_000_000.0).round() as i64
}

impl Rig {
    pub fn with(settings: DriveSettings) -> Self {
        Rig::device("kinco-fd3", 1, settings)
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
}
