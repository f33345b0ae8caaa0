//! EMCY frames and the error history 1003h of the CMMP-AS over CANopen, on the virtual clock:
//! errors the drive raises go out as EMCY through the CiA 301 stack (the vector catalogue kept
//! beside the project §1.6).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use canopen::CanFrame;
use drive::device_control::State;

#[path = "support/can_bench.rs"]
mod can_bench;

use can_bench::CanBench as Bench;

fn emcy(frames: &[CanFrame]) -> Vec<[u8; 8]> {
    frames
        .iter()
        .filter(|f| f.id == 0x081)
        .map(|f| f.data)
        .collect()
}

/// CMMP-EMCY-03: motor over-temperature 03-0 (code 4310h, Tab. 3.9 temperature bit) with a
/// stopping reaction: `081: 10 43 09 00 00 00 00 00`, and the drive goes to FAULT.
#[test]
fn cmmp_emcy_03_motor_over_temperature() {
    let mut b = Bench::new(None);
    b.enable();
    b.sent();
    b.drive()
        .inject_fault(0x4310, canopen::emcy::register::TEMPERATURE);
    b.run_ms(2);
    assert_eq!(emcy(&b.sent()), vec![[0x10, 0x43, 0x09, 0, 0, 0, 0, 0]]);
    b.run_ms(500);
    // The cell sets 6510h:F0 bit 7 (CiA 402 FAULT value 0008h) for CiA 402 masters.
    assert_eq!(
        b.statusword() & 0x4F,
        0x08,
        "FAULT after the stopping reaction"
    );
    assert_eq!(b.drive().state(), State::Fault);
}

/// CMMP-EMCY-07: `601: 2F 03 10 00 00` clears the history (`581: 60 03 10 00`, then 1003h:00
/// reads 0), and does not acknowledge the error: the drive stays in FAULT and sends no EMCY.
/// The acknowledgement through the state machine then sends `081: 00 …` (CMMP-EMCY-01).
#[test]
fn cmmp_emcy_07_clearing_the_history_does_not_acknowledge() {
    let mut b = Bench::new(None);
    b.enable();
    b.drive()
        .inject_fault(0x4310, canopen::emcy::register::TEMPERATURE);
    b.run_ms(500);
    assert_eq!(
        b.sdo(&[0x40, 0x03, 0x10, 0x00]),
        [0x4F, 0x03, 0x10, 0x00, 0x01, 0, 0, 0]
    );
    b.sent();
    assert_eq!(
        b.sdo(&[0x2F, 0x03, 0x10, 0x00, 0x00]),
        [0x60, 0x03, 0x10, 0x00, 0, 0, 0, 0]
    );
    assert!(emcy(&b.sent()).is_empty(), "no EMCY for the history write");
    assert_eq!(
        b.sdo(&[0x40, 0x03, 0x10, 0x00]),
        [0x4F, 0x03, 0x10, 0x00, 0x00, 0, 0, 0]
    );
    b.run_ms(10);
    assert!(emcy(&b.sent()).is_empty(), "no EMCY");
    assert_eq!(b.statusword() & 0x4F, 0x08, "still FAULT");
    assert_eq!(b.drive().state(), State::Fault);
    assert_eq!(b.drive().errors(), &[0x4310]);
    // The cause removed and the error acknowledged: the reset EMCY.
    b.drive().clear_fault(0x4310);
    b.sdo(&[0x2B, 0x40, 0x60, 0x00, 0x00, 0x00]);
    b.run_ms(2);
    b.sdo(&[0x2B, 0x40, 0x60, 0x00, 0x80, 0x00]);
    b.run_ms(2);
    let frames = b.sent();
    assert_eq!(b.statusword() & 0x4F, 0x40);
    assert_eq!(emcy(&frames), vec![[0; 8]]);
}

/// CMMP-EMCY-02, CMMP-EMCY-06 from the drive's own I²t monitor: 6510h:38 = 1, the shaft
/// blocked at maximum current; after iit_time_motor (2 s) the I²t reaches 100 % and error 31-0
/// goes out as `081: 12 23 03 00 00 00 00 00` (generic + current); 1003h holds it.
#[test]
fn cmmp_emcy_02_i2t_motor_error_31_0() {
    let mut b = Bench::new(None);
    b.sdo(&[0x2B, 0x10, 0x65, 0x38, 0x01, 0x00]);
    b.sdo(&[0x2F, 0x60, 0x60, 0x00, 0x03]);
    b.run_ms(10);
    b.enable();
    b.drive().axis_mut().set_blocked(true);
    b.sdo(&[0x23, 0xFF, 0x60, 0x00, 0xE8, 0x03, 0x00, 0x00]); // 60FFh := 1000 min⁻¹
    b.sent();
    b.run_ms(1900);
    assert!(emcy(&b.sent()).is_empty(), "not before 2 s at I_max");
    b.run_ms(200);
    assert_eq!(emcy(&b.sent()), vec![[0x12, 0x23, 0x03, 0, 0, 0, 0, 0]]);
    assert_eq!(
        b.sdo(&[0x40, 0x03, 0x10, 0x00]),
        [0x4F, 0x03, 0x10, 0x00, 0x01, 0, 0, 0]
    );
    assert_eq!(
        b.sdo(&[0x40, 0x03, 0x10, 0x01]),
        [0x43, 0x03, 0x10, 0x01, 0x12, 0x23, 0x00, 0x00]
    );
    b.run_ms(500);
    assert_eq!(b.drive().state(), State::Fault);
}

/// CMMP-EMCY-04: the homing timeout 11-3 (2045h exceeded, CMMP-HM-06) goes out as the whole
/// frame `081: 83 8A 01 00 00 00 00 00`: code 8A83h, error register 01h (no category bit of
/// Tab. 3.9 applies), manufacturer bytes 0.
#[test]
fn cmmp_emcy_04_homing_timeout_frame() {
    let mut b = Bench::new(None);
    for (index, value) in [
        (0x2045, &500u16.to_le_bytes()[..]),
        (0x6098, &[17]),
        (0x6060, &[6]),
    ] {
        assert_eq!(b.write(index, 0, value)[0], 0x60, "{index:04X}h written");
    }
    b.enable();
    b.sent();
    assert_eq!(b.write(0x6040, 0, &0x001Fu16.to_le_bytes())[0], 0x60);
    b.run_ms(1_000);
    assert_eq!(
        emcy(&b.sent()),
        vec![[0x83, 0x8A, 0x01, 0, 0, 0, 0, 0]],
        "one EMCY, the whole frame as the manual's layout gives it"
    );
}
