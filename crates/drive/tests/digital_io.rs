//! Digital inputs and outputs of the CMMP-AS (CMMP-AS §5.13, §5.14): 60FDh from the input
//! levels and the switch assignment 6510h:11 … :14, 60FEh host control of the brake and the
//! outputs (the vector catalogue kept beside the project, §1.15).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drive::device_control::State;
use drive::vendors::festo_cmmp_as::digital_inputs::{DIN0, DIN4, DIN5, DIN6, DIN7, DIN8, DIN9};
use od::ObjectAccess;

mod cmmp_rig;

use cmmp_rig::Rig;

/// Every DIN the tests drive.
const ALL: u16 = 0x03FF;

impl Rig {
    fn w16(&mut self, index: u16, sub: u8, v: u16) {
        self.d.write(index, sub, &v.to_le_bytes()).unwrap();
    }
    fn u(&self, index: u16, sub: u8) -> u32 {
        self.d.od().get_unsigned(index, sub).unwrap() as u32
    }
    /// The levels of all of DIN0 … DIN9 (enables kept present) and one cycle.
    fn levels(&mut self, high: u16) -> u32 {
        self.d.force_inputs(ALL, high | DIN4 | DIN5);
        self.run_ms(1);
        self.u(0x60FD, 0)
    }
}

/// CMMP-IO-01: 6510h:12 = 0 (default): DIN6 is E0, the negative limit switch → 60FDh bit 0.
#[test]
fn cmmp_io_01_din6_is_the_negative_limit_switch_by_default() {
    let mut r = Rig::new();
    assert_eq!(r.u(0x6510, 0x12), 0);
    assert_eq!(r.levels(DIN6) & 0x3, 0x1);
    assert_eq!(r.levels(DIN7) & 0x3, 0x2);
    assert_eq!(r.levels(0) & 0x3, 0x0);
}

/// CMMP-IO-02: 6510h:12 = 1: DIN6 is E1, the positive limit switch → 60FDh bit 1.
#[test]
fn cmmp_io_02_selector_1_makes_din6_the_positive_limit_switch() {
    let mut r = Rig::new();
    r.w16(0x6510, 0x12, 1);
    assert_eq!(r.levels(DIN6) & 0x3, 0x2);
    assert_eq!(r.levels(DIN7) & 0x3, 0x1);
}

/// CMMP-IO-03: a normally open switch (6510h:11 = 1) is active on HIGH, a normally closed one
/// (0) on LOW; 6510h:14 does the same for the home switch.
#[test]
fn cmmp_io_03_polarity_normally_open_and_normally_closed() {
    let mut r = Rig::new();
    assert_eq!(r.u(0x6510, 0x11), 1, "default normally open");
    assert_eq!(r.levels(DIN6 | DIN7) & 0x1, 0x1, "NO, HIGH: active");
    assert_eq!(r.levels(0) & 0x1, 0x0, "NO, LOW: inactive");
    r.w16(0x6510, 0x11, 0);
    assert_eq!(r.levels(0) & 0x1, 0x1, "NC, LOW: active");
    assert_eq!(r.levels(DIN6 | DIN7) & 0x3, 0x0, "NC, HIGH: inactive");
    // Home switch (DIN9 by default).
    assert_eq!(r.u(0x6510, 0x14), 1);
    assert_eq!(r.levels(DIN6 | DIN7 | DIN9) & 0x4, 0x4);
    r.w16(0x6510, 0x14, 0);
    assert_eq!(
        r.levels(DIN6 | DIN7) & 0x4,
        0x4,
        "NC home switch, LOW: active"
    );
    assert_eq!(r.levels(DIN6 | DIN7 | DIN9) & 0x4, 0x0);
}

/// CMMP-IO-04: 6510h:13 = 0 (default) reads the home switch on DIN9, 1 on DIN8.
#[test]
fn cmmp_io_04_home_switch_selector() {
    let mut r = Rig::new();
    assert_eq!(r.u(0x6510, 0x13), 0);
    assert_eq!(r.levels(DIN9) & 0x4, 0x4);
    assert_eq!(r.levels(DIN8) & 0x4, 0x0);
    r.w16(0x6510, 0x13, 1);
    assert_eq!(r.levels(DIN8) & 0x4, 0x4);
    assert_eq!(r.levels(DIN9) & 0x4, 0x0);
}

/// CMMP-IO-05: output-stage enable (DIN4) or controller enable (DIN5) missing → 60FDh bit 3
/// interlock, and transition 2 does not happen.
#[test]
fn cmmp_io_05_missing_enable_is_the_interlock_bit() {
    let mut r = Rig::new();
    assert_eq!(r.u(0x60FD, 0) & 0x8, 0, "enables present");
    for missing in [DIN4, DIN5] {
        r.d.force_inputs(ALL, (DIN4 | DIN5) & !missing);
        r.run_ms(1);
        assert_eq!(r.u(0x60FD, 0) & 0x8, 0x8, "{missing:#x}");
        r.w16(0x6040, 0, 0x06);
        r.run_ms(2);
        assert_eq!(r.d.state(), State::SwitchOnDisabled, "{missing:#x}");
    }
    r.d.force_inputs(0, 0);
    r.run_ms(2);
    assert_eq!(r.u(0x60FD, 0) & 0x8, 0);
    assert_eq!(
        r.d.state(),
        State::ReadyToSwitchOn,
        "Shutdown taken once enabled"
    );
}

/// CMMP-IO-06: DIN0 and DIN9 HIGH, everything else inactive → 60FDh = 21000000h.
///
/// Decision: DIN9 is also the home switch input by default (6510h:13 = 0, normally open), so
/// with the defaults the drive reads the home switch active too (bit 2: 21000004h); the
/// vector's "everything else inactive" holds with the home switch on DIN8 (6510h:13 = 1).
#[test]
fn cmmp_io_06_din0_and_din9_bits() {
    let mut r = Rig::new();
    r.w16(0x6510, 0x13, 1);
    assert_eq!(r.levels(DIN0 | DIN9), 0x2100_0000);
    r.w16(0x6510, 0x13, 0);
    assert_eq!(r.levels(DIN0 | DIN9), 0x2100_0004);
    // DIN0 … DIN3 in bits 24 … 27, DIN8 in bit 28.
    r.w16(0x6510, 0x13, 1);
    assert_eq!(r.levels(0x000F) & 0x0F00_0000, 0x0F00_0000);
    assert_eq!(r.levels(DIN8), 0x1000_0004);
    // Nothing forced: the travel at power-on touches no switch.
    r.d.force_inputs(0, 0);
    r.run_ms(1);
    assert_eq!(r.u(0x60FD, 0), 0);
}

/// CMMP-IO-07: 60FEh:02 := 1 (brake under host control), 60FEh:01 := 0 releases the holding
/// brake with the output stage off; 60FEh:01 reads the brake's state back.
#[test]
fn cmmp_io_07_brake_released_by_the_host() {
    let mut r = Rig::new();
    assert!(r.d.axis().motor().brake(), "applied at power-on");
    assert_eq!(r.u(0x60FE, 1) & 1, 1);
    r.w32(0x60FE, 2, 0x0000_0001);
    r.w32(0x60FE, 1, 0x0000_0000);
    r.run_ms(10);
    assert!(!r.d.axis().motor().brake(), "released under host control");
    assert_eq!(r.d.digital_outputs() & 1, 0);
    assert_eq!(r.u(0x60FE, 1) & 1, 0);
    r.w32(0x60FE, 1, 0x0000_0001);
    r.run_ms(10);
    assert!(r.d.axis().motor().brake());
    // Back to the drive: with the output stage on the brake opens and 60FEh:01 shows it.
    r.w32(0x60FE, 2, 0);
    for cw in [0x06, 0x07, 0x0F] {
        r.w16(0x6040, 0, cw);
        r.run_ms(2);
    }
    r.run_ms(10);
    assert!(!r.d.axis().motor().brake());
    assert_eq!(r.u(0x60FE, 1) & 1, 0, "bit 0 follows the brake");
}

/// CMMP-IO-08: 60FEh:02 := 00FF0000h puts the CAMC-D-8E8A outputs (bits 16 … 23) under bus
/// control, 0E000000h DOUT1 … DOUT3 (bits 25 … 27); the manual prints the first mask as
/// "0E000000h", a copy of the DOUT row.
#[test]
fn cmmp_io_08_output_masks() {
    let mut r = Rig::new();
    r.w32(0x60FE, 1, 0x0FFF_0001);
    r.run_ms(10);
    assert_eq!(
        r.d.digital_outputs(),
        0x0000_0001,
        "nothing under bus control"
    );
    r.w32(0x60FE, 2, 0x00FF_0000);
    r.run_ms(10);
    assert_eq!(r.d.digital_outputs(), 0x00FF_0001);
    r.w32(0x60FE, 2, 0x0E00_0000);
    r.run_ms(10);
    assert_eq!(r.d.digital_outputs(), 0x0E00_0001);
    r.w32(0x60FE, 1, 0x0200_0001);
    r.run_ms(10);
    assert_eq!(r.d.digital_outputs(), 0x0200_0001, "DOUT1 only");
}
