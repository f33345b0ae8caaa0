//! CMMP-AS homing (CiA 402 mode 6, CMMP-AS §7.2) on the virtual clock against the default
//! travel of `drive::travel` (limit switches from −20 / +64 revolutions, hard stops at −22 /
//! +66, home cam 40 000 … 90 000, index at 16 384 + k·65 536): every method of Tab. 7.1 ends at its
//! reference point, searching the right way, with the statusword bits and the group-11 errors.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use drive::device_control::State;
use drive::drive::{DriveEvent, DriveSettings};
use drive::travel::TravelSettings;
use od::{AbortCode, ObjectAccess};

const REV: i64 = 65536;

mod cmmp_rig;

use cmmp_rig::Rig;

impl Rig {
    /// Homing speeds that keep the tests short: search 600 min⁻¹, crawl 30 min⁻¹, 10000
    /// min⁻¹/s.
    fn fast(mut self) -> Self {
        self.w32(0x6099, 1, 600);
        self.w32(0x6099, 2, 30);
        self.w32(0x609A, 0, 10_000);
        self
    }
    fn w16(&mut self, index: u16, sub: u8, v: u16) {
        self.d.write(index, sub, &v.to_le_bytes()).unwrap();
    }
    fn method(&mut self, m: i8) {
        self.d.write(0x6098, 0, &[m as u8]).unwrap();
    }
    fn encoder(&self) -> i64 {
        self.d.axis().position_increments()
    }
    /// Homing mode, OPERATION ENABLED, bit 4 not yet set.
    fn ready(&mut self) {
        self.d.write(0x6060, 0, &[6]).unwrap();
        self.run_ms(5);
        self.cw(0x06);
        self.cw(0x07);
        self.cw(0x0F);
        assert_eq!(self.sw() & 0x6F, 0x27);
        assert_eq!(self.i(0x6061), 6);
    }
    /// Runs until homing attained or error (bits 12/13) or `limit_s`; returns the time.
    fn until_done(&mut self, limit_s: u64) -> Duration {
        let t0 = self.now;
        while self.sw() & 0x3000 == 0 && self.now.saturating_since(t0).as_secs() < limit_s {
            self.run_ms(10);
        }
        self.now.saturating_since(t0)
    }
    fn events(&mut self) -> Vec<DriveEvent> {
        std::iter::from_fn(|| self.d.take_event()).collect()
    }
}

/// The reference point each method must find on the default travel, and the direction it
/// starts in from the power-on position (0: no motion).
const EXPECTED: [(i8, i64, i64, i64); 17] = [
    // method, reference (encoder increments), tolerance, first direction
    (-27, 40_000, 40, -1),
    (-23, 90_000, 40, 1),
    (-18, 66 * REV, 2, 1),
    (-17, -22 * REV, 2, -1),
    (-2, 66 * REV - REV + 16_384, 0, 1),
    (-1, -22 * REV + 16_384, 0, -1),
    (1, -20 * REV + 16_384, 0, -1),
    (2, 64 * REV - REV + 16_384, 0, 1),
    (7, 16_384, 0, 1),
    (11, 16_384 + 2 * REV, 0, -1),
    (17, -20 * REV, 40, -1),
    (18, 64 * REV, 40, 1),
    (23, 40_000, 40, 1),
    (27, 90_000, 40, -1),
    (33, 16_384 - REV, 0, -1),
    (34, 16_384, 0, 1),
    (35, 0, 0, 0),
];

#[test]
fn every_method_ends_at_its_reference_with_the_home_offset_there() {
    for (method, reference, tol, direction) in EXPECTED {
        let mut r = Rig::new().fast();
        r.w32(0x607C, 0, 5000);
        r.method(method);
        r.ready();
        r.cw(0x1F);
        if method != 35 {
            assert_eq!(r.sw() & 0x3000, 0, "{method}: running");
        }
        r.run_ms(60);
        let v = r.i(0x606C);
        match direction {
            0 => assert_eq!(v, 0, "{method}: no motion"),
            d => assert!(v * d > 0, "{method}: starts towards {d}: {v}"),
        }
        let took = r.until_done(60);
        assert_eq!(
            r.sw() & 0xB000,
            0x9000,
            "{method}: attained, no error, referenced ({took:?}, errors {:?})",
            r.d.errors()
        );
        assert_ne!(r.sw() & 0x0400, 0, "{method}: target reached once done");
        // 6064h = home offset at the reference point.
        let at_reference = r.i(0x6064) - (r.encoder() - reference);
        assert!(
            (at_reference - 5000).abs() <= tol,
            "{method}: 6064h {} at encoder {} → {at_reference} at the reference",
            r.i(0x6064),
            r.encoder()
        );
        assert!(r.d.errors().is_empty(), "{method}: {:?}", r.d.errors());
    }
}

/// CMMP-HM-04.
#[test]
fn cmmp_hm_04_default_method_17_homes_at_the_default_speeds() {
    // CMMP-HM-04: 6098h is 17 after power-on; 100 / 10 min⁻¹ and 1000 min⁻¹/s reach the
    // negative limit switch 20 revolutions away well inside the default 60 s (2045h).
    let mut r = Rig::new();
    assert_eq!(r.i(0x6098), 17);
    r.ready();
    r.cw(0x1F);
    let took = r.until_done(60);
    assert_eq!(r.sw() & 0xB000, 0x9000, "{:?}", r.d.errors());
    assert!(
        took > Duration::from_secs(11),
        "20 revolutions at 100 min⁻¹: {took:?}"
    );
    assert!((r.i(0x6064) - (r.encoder() + 20 * REV)).abs() <= 10);
}

#[test]
fn homing_to_zero_moves_to_position_0() {
    // 6510h:F0 bit 6: after the reference the drive travels to the zero position.
    let mut r = Rig::new().fast();
    r.w16(0x6510, 0xF0, 0x0040);
    r.w32(0x607C, 0, -30_000);
    r.method(34);
    r.ready();
    r.cw(0x1F);
    r.until_done(10);
    assert_eq!(r.sw() & 0xB000, 0x9000);
    assert!(
        r.i(0x6064).abs() <= r.i(0x6067),
        "inside the position window: {}",
        r.i(0x6064)
    );
    r.run_ms(300);
    assert!(r.i(0x6064).abs() <= 20, "at zero: {}", r.i(0x6064));
    // The reference (index at 16 384) read −30 000, so zero is 30 000 further on.
    assert!(
        (r.encoder() - (16_384 + 30_000)).abs() <= 20,
        "{}",
        r.encoder()
    );
}

/// CMMP-HM-06 (EMCY frame: CMMP-EMCY-04): 2045h exceeded → 11-3, code 8A83h, register 01h.
#[test]
fn cmmp_hm_06_timeout_is_error_11_3() {
    let mut r = Rig::new();
    r.w16(0x2045, 0, 500);
    r.method(17);
    r.ready();
    r.events();
    r.cw(0x1F);
    r.until_done(5);
    assert_eq!(r.sw() & 0x3000, 0x2000, "homing error");
    assert_eq!(r.d.errors(), &[0x8A83]);
    assert!(r.events().contains(&DriveEvent::Error {
        code: 0x8A83,
        register: 0x01
    }));
    r.run_ms(500);
    assert_eq!(r.d.state(), State::Fault);
}

/// CMMP-HM-05: bit 4 rising starts, falling aborts; SW bits 13:12 = 00 while running or
/// aborted, 01 when completed (here and in every method test), 10 on an error
/// (`cmmp_hm_06_timeout_is_error_11_3`, `halt_aborts_with_homing_error`).
#[test]
fn cmmp_hm_05_bit_4_falling_aborts_without_a_result() {
    let mut r = Rig::new().fast();
    r.method(17);
    r.ready();
    r.cw(0x1F);
    r.run_ms(300);
    assert!(r.i(0x606C) < -100, "searching");
    assert_eq!(r.sw() & 0x3000, 0, "bits 13:12 = 00 while homing runs");
    r.cw(0x0F);
    r.run_ms(300);
    assert_eq!(r.i(0x606C), 0, "stopped");
    assert_eq!(
        r.sw() & 0xB000,
        0,
        "neither attained nor error, not referenced"
    );
    assert_ne!(r.sw() & 0x0400, 0, "target reached: stands");
    assert!(r.d.errors().is_empty());
    // A new rising edge starts again and completes.
    r.cw(0x1F);
    r.until_done(20);
    assert_eq!(r.sw() & 0xB000, 0x9000);
}

#[test]
fn halt_aborts_with_homing_error() {
    let mut r = Rig::new().fast();
    r.method(18);
    r.ready();
    r.cw(0x1F);
    r.run_ms(300);
    r.cw(0x11F);
    r.run_ms(300);
    assert_eq!(r.i(0x606C), 0);
    assert_eq!(r.sw() & 0x3000, 0x2000, "bit 13 homing_error");
    assert!(r.d.errors().is_empty(), "no EMCY for a halt");
    assert_eq!(r.d.state(), State::OperationEnabled);
    // Clearing halt does not resume.
    r.cw(0x1F);
    r.run_ms(200);
    assert_eq!(r.i(0x606C), 0);
}

#[test]
fn no_index_pulse_is_error_11_2() {
    let travel = TravelSettings {
        index_phase: None,
        ..TravelSettings::default()
    };
    let mut r = Rig::with(DriveSettings {
        travel,
        ..DriveSettings::default()
    })
    .fast();
    r.method(34);
    r.ready();
    r.cw(0x1F);
    r.until_done(20);
    assert_eq!(r.sw() & 0x3000, 0x2000);
    assert_eq!(r.d.errors(), &[0x8A82]);
    assert!(r.encoder() > REV, "crawled more than a revolution first");
}

#[test]
fn both_limit_switches_active_is_error_11_4() {
    // A wiring fault: both switches read active at the power-on position.
    let travel = TravelSettings {
        negative_limit: Some(REV),
        positive_limit: Some(-REV),
        ..TravelSettings::default()
    };
    let mut r = Rig::with(DriveSettings {
        travel,
        ..DriveSettings::default()
    })
    .fast();
    r.method(23);
    r.ready();
    r.cw(0x1F);
    r.until_done(2);
    assert_eq!(r.sw() & 0x3000, 0x2000);
    assert_eq!(r.d.errors(), &[0x8A84]);
}

#[test]
fn a_missing_limit_switch_ends_on_the_stop_with_11_4() {
    let travel = TravelSettings {
        negative_limit: None,
        ..TravelSettings::default()
    };
    let mut r = Rig::with(DriveSettings {
        travel,
        ..DriveSettings::default()
    })
    .fast();
    r.method(17);
    r.ready();
    r.cw(0x1F);
    r.until_done(20);
    assert_eq!(r.d.errors(), &[0x8A84]);
    assert!((r.encoder() + 22 * REV).abs() <= 2, "stalled on the stop");
}

#[test]
fn end_of_search_distance_is_error_11_6() {
    let mut r = Rig::with(DriveSettings {
        travel: TravelSettings::NONE,
        homing_max_distance: 3 * REV,
        ..DriveSettings::default()
    })
    .fast();
    r.method(-17);
    r.ready();
    r.cw(0x1F);
    r.until_done(20);
    assert_eq!(r.d.errors(), &[0x8A86]);
    assert!(r.encoder() < -3 * REV);
}

#[test]
fn start_without_controller_enable_is_error_11_0() {
    let mut r = Rig::new();
    r.d.write(0x6060, 0, &[6]).unwrap();
    r.run_ms(5);
    r.cw(0x06);
    r.cw(0x07);
    assert_eq!(r.d.state(), State::SwitchedOn);
    r.cw(0x17);
    assert_eq!(r.d.errors(), &[0x8A80]);
    assert_ne!(r.sw() & 0x2000, 0);
}

#[test]
fn method_32_is_refused_at_the_start() {
    // In the printed 6098h range, in neither numbering the manual gives (decision in drive.rs).
    let mut r = Rig::new();
    r.method(32);
    r.ready();
    r.cw(0x1F);
    r.run_ms(10);
    assert_eq!(r.d.errors(), &[0x8A80]);
}

#[test]
fn homing_method_is_locked_while_homing_runs() {
    let mut r = Rig::new().fast();
    r.ready();
    r.cw(0x1F);
    assert_eq!(r.d.write(0x6098, 0, &[18]), Err(AbortCode::DEVICE_STATE));
    r.until_done(20);
    r.cw(0x0F);
    r.method(18);
    assert_eq!(r.i(0x6098), 18);
}

/// CMMP-HM-01, CMMP-HM-02, CMMP-HM-03: the INT8 bytes of Tab. 7.1 (27 is 1Bh, the manual's
/// "18h" corrected) are accepted and read back as the method numbers.
#[test]
fn cmmp_hm_01_to_03_methods_are_accepted_as_int8() {
    let mut r = Rig::new();
    for (m, b) in [
        (-1, 0xFF),
        (-2, 0xFE),
        (-17, 0xEF),
        (-18, 0xEE),
        (-23, 0xE9),
        (-27, 0xE5),
        (1, 0x01),
        (2, 0x02),
        (7, 0x07),
        (17, 0x11),
        (18, 0x12),
        (23, 0x17),
        (27, 0x1B),
        (33, 0x21),
        (34, 0x22),
        (35, 0x23),
    ] {
        r.d.write(0x6098, 0, &[b]).unwrap();
        assert_eq!(r.i(0x6098), m);
    }
}

#[test]
fn hard_stop_stalls_the_motor_with_the_current_at_the_limit() {
    // Method −17 pushes into the negative stop: the position stops while the set-point runs
    // on, the current rises until the stall is seen.
    let mut r = Rig::new().fast();
    r.method(-17);
    r.ready();
    r.cw(0x1F);
    let mut peak = 0i64;
    let t0 = r.now;
    while r.sw() & 0x3000 == 0 && r.now.saturating_since(t0).as_secs() < 20 {
        r.run_ms(1);
        peak = peak.max(r.i(0x6078).abs());
    }
    assert!(peak > 1000, "current above rated at the stop: {peak} ‰");
    assert!(r.encoder() >= -22 * REV - 1);
}

#[test]
fn limit_switch_outside_homing_stops_with_43_1_and_allows_the_way_back() {
    let mut r = Rig::new();
    r.d.write(0x6060, 0, &[3]).unwrap();
    r.run_ms(5);
    r.cw(0x06);
    r.cw(0x07);
    r.cw(0x0F);
    r.w32(0x60FF, 0, 3000);
    let t0 = r.now;
    while r.d.state() == State::OperationEnabled && r.now.saturating_since(t0).as_secs() < 5 {
        r.run_ms(5);
    }
    assert_eq!(r.d.errors(), &[0x8082], "43-1 positive limit switch");
    r.run_ms(500);
    assert_eq!(r.d.state(), State::Fault);
    assert!(
        r.encoder() >= 64 * REV && r.encoder() < 66 * REV,
        "{}",
        r.encoder()
    );
    // Reset, enable and drive back out.
    r.w32(0x60FF, 0, -300);
    r.cw(0x80);
    r.cw(0x06);
    r.cw(0x07);
    r.cw(0x0F);
    r.run_ms(3000);
    assert_eq!(r.d.state(), State::OperationEnabled);
    assert!(r.encoder() < 64 * REV, "{}", r.encoder());
}

#[test]
fn limit_switches_set_to_normally_closed_read_both_active_11_4() {
    // 6510h:11 = 0 (normally closed) against the simulated normally-open switches: both
    // limit switches read active, as on a drive wired to the wrong switch type.
    let mut r = Rig::new().fast();
    r.w16(0x6510, 0x11, 0);
    r.method(17);
    r.ready();
    r.cw(0x1F);
    r.run_ms(10);
    assert_eq!(r.d.errors(), &[0x8A84]);
}

#[test]
fn swapped_limit_switch_inputs_send_method_17_to_the_positive_end() {
    // 6510h:12 = 1: DIN6/DIN7 swapped. Method 17 searches negative for a switch that is
    // wired to the positive end and finds the hard stop instead (11-4, switch not connected).
    let mut r = Rig::new().fast();
    r.w16(0x6510, 0x12, 1);
    r.method(17);
    r.ready();
    r.cw(0x1F);
    r.until_done(20);
    assert_eq!(r.d.errors(), &[0x8A84]);
}

#[test]
fn methods_outside_the_range_are_refused_at_the_write() {
    let mut r = Rig::new();
    for m in [0i8, 3, 19, -3] {
        assert_eq!(
            r.d.write(0x6098, 0, &[m as u8]),
            Err(AbortCode::INVALID_VALUE),
            "{m}"
        );
    }
    for m in [36i8, 37, -28] {
        assert!(
            r.d.write(0x6098, 0, &[m as u8]).is_err(),
            "{m}: out of range"
        );
    }
    assert_eq!(r.i(0x6098), 17, "unchanged");
    r.method(32);
    assert_eq!(r.i(0x6098), 32, "32 is in the printed range");
}

#[test]
fn minus_23_at_the_default_speeds_needs_the_timeout_off() {
    // −23 goes to the positive limit switch (64 revolutions) and back to the home cam: 76 s
    // at 100 min⁻¹, beyond the default 60 s of 2045h (documented in TravelSettings).
    let mut r = Rig::new();
    r.method(-23);
    r.ready();
    r.cw(0x1F);
    r.until_done(90);
    assert_eq!(r.d.errors(), &[0x8A83], "11-3 at 60 s");
    let mut r = Rig::new();
    r.w16(0x2045, 0, 0);
    r.method(-23);
    r.ready();
    r.cw(0x1F);
    let took = r.until_done(120);
    assert_eq!(r.sw() & 0xB000, 0x9000, "{:?}", r.d.errors());
    assert!(took > Duration::from_secs(60), "{took:?}");
}
