//! Kinco position limits after homing (manual §7 Tab. 5-8 / 8-2 Error_State2 bits 9 / 10,
//! L1189-1191 of its text kept beside the project): software limits 607Dh act once the drive is
//! homed; Limit_Function 2010h:19 = 0 makes a crossing an error (5442h / 5441h, output stage off),
//! any other value only blocks the direction.

mod kinco_rig;

use drive::drive::DriveEvent;
use kinco_rig::{dec_rpm, dec_rps2, Rig};

const HOMING_ATTAINED: u16 = 0x1000;
const FAULT: u16 = 0x0008;
/// Error_State2 bits 9 / 10, Error_State bit 0 (extended error).
const POSITIVE_LIMIT_BIT: i64 = 1 << 9;
const NEGATIVE_LIMIT_BIT: i64 = 1 << 10;

/// A drive with limits ±5000 inc (half a revolution), homed where it stands (method 35)
/// when `homed`, then in mode 3 with 300 rpm ramps of 100 rps/s.
fn rig(homed: bool, limit_function: i8) -> Rig {
    let mut r = Rig::new();
    r.w32(0x607D, 0x01, -5000);
    r.w32(0x607D, 0x02, 5000);
    r.w8(0x2010, 0x19, limit_function);
    if homed {
        r.w8(0x6098, 0, 35);
        r.enable_in(6);
        r.cw(0x1F);
        assert!(r.until_sw(HOMING_ATTAINED, 500), "homed");
        r.cw(0x0F);
    }
    r.w32(0x6083, 0, dec_rps2(100.0));
    r.w32(0x6084, 0, dec_rps2(100.0));
    r.enable_in(3);
    r.events();
    r
}

/// Runs `ms` at `rpm` in mode 3.
fn run_at(r: &mut Rig, rpm: f64, ms: u64) {
    r.w32(0x60FF, 0, dec_rpm(rpm));
    r.run_ms(ms);
}

/// Before homing the limits do nothing: the motor turns past them.
#[test]
fn limits_inactive_before_homing() {
    let mut r = rig(false, 0);
    run_at(&mut r, 300.0, 1500);
    assert!(r.position() > 20_000, "turned on: {}", r.position());
    assert_eq!(r.sw() & FAULT, 0);
    assert_eq!(r.i(0x2602, 0), 0);
}

/// Limit_Function = 0 (default): crossing +5000 after homing raises Positive limit —
/// Error_State2 bit 9, Error_State bit 0, EMCY 5442h — the output stage goes off. After the
/// reset the direction out stays blocked and the motor moves back in; crossing −5000 then
/// raises Negative limit (bit 10, 5441h).
#[test]
fn error_state2_bits_9_and_10_after_homing() {
    let mut r = rig(true, 0);
    run_at(&mut r, 300.0, 1500);
    assert_ne!(r.sw() & FAULT, 0, "fault, sw {:04X}", r.sw());
    assert_eq!(r.i(0x2602, 0), POSITIVE_LIMIT_BIT, "Error_State2 bit 9");
    assert_eq!(r.i(0x2601, 0) & 1, 1, "Error_State bit 0");
    let events = r.events();
    assert!(
        events
            .iter()
            .any(|e| matches!(e, DriveEvent::Error { code: 0x5442, .. })),
        "{events:?}"
    );
    assert_eq!(
        r.d.kinco_led(),
        Some(*b"000.1"),
        "an Error_State2 error on the panel"
    );
    // The output stage is off: the motor coasts; then reset and enable again.
    r.run_ms(500);
    r.cw(0x06);
    r.cw(0x86);
    r.cw(0x06);
    assert_eq!(r.sw() & FAULT, 0, "reset");
    assert_eq!(r.i(0x2602, 0), 0);
    let out = r.position();
    assert!(out > 5000, "beyond the limit: {out}");
    r.w32(0x60FF, 0, dec_rpm(300.0));
    r.cw(0x0F);
    r.run_ms(300);
    assert!(
        r.position() <= out + 5,
        "outward blocked: {} from {out}",
        r.position()
    );
    assert_eq!(r.sw() & FAULT, 0, "no new error while beyond");
    run_at(&mut r, -300.0, 3000);
    assert_ne!(r.sw() & FAULT, 0, "crossed −5000: sw {:04X}", r.sw());
    assert_eq!(r.i(0x2602, 0), NEGATIVE_LIMIT_BIT, "Error_State2 bit 10");
    assert!(r.position() < -5000);
}

/// Error_Mask2 2605h:04 bit 9 = 0: the crossing is ignored (no error), the direction is
/// still blocked.
#[test]
fn masked_limit_error_only_blocks() {
    let mut r = rig(true, 0);
    r.w16(0x2605, 0x04, 0xFFFF & !(1 << 9));
    run_at(&mut r, 300.0, 1500);
    assert_eq!(r.sw() & FAULT, 0);
    assert_eq!(r.i(0x2602, 0), 0);
    assert!(r.rpm().abs() < 1.0, "stopped: {} rpm", r.rpm());
}

/// Limit_Function ≠ 0: no error; the drive stops from the limit on with Profile_Dec (5 rps
/// at 100 rps/s: 0.125 rev = 1250 inc past it), the Position Limit output (0200h) shows it,
/// and the motor turns back in.
#[test]
fn limit_function_1_blocks_without_error() {
    let mut r = rig(true, 1);
    r.w16(0x2010, 0x0F, 0x0200);
    run_at(&mut r, 300.0, 1500);
    assert_eq!(r.sw() & FAULT, 0, "no error");
    assert_eq!(r.i(0x2602, 0), 0);
    assert!(r.rpm().abs() < 1.0, "stopped: {} rpm", r.rpm());
    let p = r.position();
    assert!(
        (6000..6500).contains(&p),
        "stopped 1250 inc past +5000: {p}"
    );
    assert_eq!(r.i(0x2010, 0x14) & 1, 1, "OUT1 Position Limit");
    run_at(&mut r, -60.0, 500);
    assert!(r.position() < p - 1000, "back in: {}", r.position());
    assert_eq!(r.i(0x2010, 0x14) & 1, 0, "inside again");
}
