//! The CMMP-AS drive end to end on the virtual clock: device control through the
//! dictionary, profile position / velocity / torque with the simulated motor, quick stop,
//! following error, fault and reset, and the object rules of the manual.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use drive::device_control::State;
use drive::drive::{Drive, DriveEvent, DriveSettings};
use od::{AbortCode, Instant, ObjectAccess, ObjectDictionary, Value};

mod cmmp_rig;

use cmmp_rig::Rig;

impl Rig {
    /// A mode change of 2 ms keeps the tests short.
    fn quick() -> Self {
        Rig::with(DriveSettings {
            mode_change_time: Duration::from_millis(2),
            ..DriveSettings::default()
        })
    }
    fn w16(&mut self, index: u16, v: u16) {
        self.d.write(index, 0, &v.to_le_bytes()).unwrap();
    }
    fn w8(&mut self, index: u16, v: i8) {
        self.d.write(index, 0, &[v as u8]).unwrap();
    }
    fn enable(&mut self) {
        self.cw(0x06);
        self.cw(0x07);
        self.cw(0x0F);
        assert_eq!(self.sw() & 0x6F, 0x27);
    }
    fn mode(&mut self, m: i8) {
        self.w8(0x6060, m);
        self.run_ms(10);
        assert_eq!(self.i(0x6061), m as i64);
    }
}

/// CMMP-CW-01, CMMP-CW-02, CMMP-CW-03 through the dictionary: 0006h → 0021h, 0007h → 0023h
/// with the output stage on, 000Fh → 0027h with the holding brake released.
#[test]
fn enable_sequence_in_the_statusword() {
    let mut r = Rig::quick();
    assert_eq!(r.sw() & 0x4F, 0x40, "SWITCH ON DISABLED after power-up");
    assert_ne!(r.sw() & 0x0200, 0, "remote: enable logic 2 (CMMP-SDO-16)");
    assert_eq!(r.d.od().get_unsigned(0x6510, 0x10), Some(2));
    r.cw(0x06);
    assert_eq!(r.sw() & 0x6F, 0x21);
    r.cw(0x07);
    assert_eq!(r.sw() & 0x6F, 0x23);
    assert_ne!(r.sw() & 0x10, 0, "voltage enabled with the output stage on");
    r.cw(0x0F);
    assert_eq!(r.sw() & 0x6F, 0x27);
    assert!(!r.d.axis().motor().brake(), "holding brake released");
    r.cw(0x00);
    assert_eq!(r.sw() & 0x4F, 0x40);
}

#[test]
fn mode_change_shows_minus_one_for_the_change_time() {
    let mut r = Rig::quick();
    assert_eq!(r.i(0x6061), 3, "6061h default 3");
    r.w8(0x6060, 1);
    r.run_ms(1);
    assert_eq!(r.i(0x6061), -1);
    r.run_ms(5);
    assert_eq!(r.i(0x6061), 1);
    assert_eq!(
        r.d.write(0x6060, 0, &[2]),
        Err(AbortCode::INVALID_VALUE),
        "2 is not a CMMP-AS mode"
    );
    assert_eq!(r.d.write(0x6060, 0, &[5]), Err(AbortCode::INVALID_VALUE));
}

/// CMMP-CW-15: 001Fh → set_point_acknowledge (bit 12), cleared with bit 4; target reached
/// (bit 10) inside 6067h for 6068h.
#[test]
fn profile_position_move_takes_the_trapezoid_time_and_ends_in_the_window() {
    let mut r = Rig::quick();
    r.mode(1);
    r.enable();
    // 10 revolutions at 1000 rpm, 10000 rpm/s (the defaults of 6081h/6083h/6084h).
    r.w32(0x607A, 0, 10 * 65536);
    r.cw(0x1F);
    assert_ne!(r.sw() & 0x1000, 0, "set-point acknowledged");
    assert_eq!(
        r.sw() & 0x0400,
        0,
        "target reached cleared by the new set-point"
    );
    r.cw(0x0F);
    assert_eq!(r.sw() & 0x1000, 0, "acknowledge drops with bit 4");
    let start = r.now;
    let mut max_fe = 0i64;
    let mut max_current = 0i64;
    while r.sw() & 0x0400 == 0 {
        r.run_ms(1);
        max_fe = max_fe.max(r.i(0x60F4).abs());
        max_current = max_current.max(r.i(0x6078).abs());
        assert!(
            r.now.saturating_since(start) < Duration::from_secs(3),
            "never reached"
        );
    }
    let took = r.now.saturating_since(start).as_secs_f64();
    // Trapezoid: 0.1 s + 0.1 s + 0.5 s of cruise = 0.7 s, plus settling.
    assert!((0.69..0.85).contains(&took), "{took}");
    assert!((r.i(0x6064) - 10 * 65536).abs() <= 1820, "inside 6067h");
    assert!(max_fe < 9101, "following error inside 6065h: {max_fe}");
    assert!(
        max_current <= 2023,
        "current never above 6073h: {max_current}‰"
    );
    assert_eq!(r.sw() & 0x2000, 0);
}

#[test]
fn relative_move_counts_from_the_set_point() {
    let mut r = Rig::quick();
    r.mode(1);
    r.enable();
    r.w32(0x607A, 0, 65536);
    r.cw(0x1F);
    r.cw(0x0F);
    r.run_ms(600);
    r.w32(0x607A, 0, 65536);
    r.cw(0x5F);
    r.cw(0x4F);
    r.run_ms(600);
    assert!(
        (r.i(0x6062) - 2 * 65536).abs() <= 1,
        "demand at 2 rev: {}",
        r.i(0x6062)
    );
}

#[test]
fn profile_velocity_ramps_and_reports_target_reached() {
    let mut r = Rig::quick();
    r.mode(3);
    r.enable();
    r.w32(0x60FF, 0, 1500);
    r.run_ms(60);
    let v = r.i(0x606C);
    assert!(v > 500 && v < 1500, "ramping at 14100 rpm/s: {v}");
    assert_eq!(r.sw() & 0x0400, 0);
    r.run_ms(200);
    assert!((r.i(0x606C) - 1500).abs() <= 4, "{}", r.i(0x606C));
    assert_ne!(r.sw() & 0x0400, 0, "target reached inside 606Dh");
    assert_eq!(r.sw() & 0x1000, 0, "not at speed 0");
    assert_ne!(r.sw() & 0x0100, 0, "drive is moving");
    // Halt: to zero with 6084h, and back when it is cleared.
    r.cw(0x010F);
    r.run_ms(300);
    assert!(r.i(0x606C).abs() <= 10);
    assert_ne!(r.sw() & 0x1000, 0, "speed 0");
    r.cw(0x000F);
    r.run_ms(300);
    assert!((r.i(0x606C) - 1500).abs() <= 4);
}

#[test]
fn profile_torque_step_accelerates_the_motor() {
    let mut r = Rig::quick();
    r.mode(4);
    r.enable();
    // 6087h 10000 ‰/s: 500 ‰ after 50 ms (CMMP-TQ-01 gives 1000 ‰/s for rated torque in 1 s).
    r.w32(0x6087, 0, 10000);
    r.w16(0x6071, 500);
    r.run_ms(25);
    let td = r.i(0x6074);
    assert!((200..=300).contains(&td), "ramping: {td}");
    r.run_ms(50);
    assert!(
        (r.i(0x6077) - 500).abs() < 60,
        "torque actual {}",
        r.i(0x6077)
    );
    assert!(r.i(0x606C) > 100, "the motor accelerates: {}", r.i(0x606C));
}

/// CMMP-CW-06: 0002h in OPERATION_ENABLE: 0007h while braking with 6085h, then 0040h.
#[test]
fn quick_stop_ramps_down_then_switch_on_disabled() {
    let mut r = Rig::quick();
    r.mode(3);
    r.enable();
    r.w32(0x60FF, 0, 1000);
    r.run_ms(300);
    r.cw(0x02);
    assert_eq!(r.sw() & 0x6F, 0x07, "QUICK STOP ACTIVE while braking");
    r.run_ms(200);
    assert_eq!(r.sw() & 0x4F, 0x40, "then SWITCH ON DISABLED (605Ah = 2)");
    assert!(r.i(0x606C).abs() <= 20);
}

/// CMMP-CW-11 (a): FAULT reads 000Fh with 6510h:F0 bit 7 = 0 (default).
#[test]
fn blocked_load_raises_following_error_then_fault_and_reset() {
    let mut r = Rig::quick();
    r.mode(1);
    r.enable();
    r.d.axis_mut().set_blocked(true);
    r.w32(0x607A, 0, 20 * 65536);
    r.cw(0x1F);
    r.cw(0x0F);
    r.run_ms(300);
    assert_ne!(r.sw() & 0x2000, 0, "following error bit 13");
    // With the hard limit 6510h:22 the drive switches off with error 17-0 (EMCY 8611h).
    r.w32(0x6510, 0x22, 20000);
    r.run_ms(2);
    assert_eq!(
        r.d.state(),
        State::Fault,
        "critical: output stage off at once"
    );
    assert_eq!(
        r.d.take_event(),
        Some(DriveEvent::Error {
            code: 0x8611,
            register: 0x01
        })
    );
    assert_eq!(r.sw() & 0x4F, 0x0F, "CMMP-AS FAULT reads 000Fh by default");
    // Cause still there (limit exceeded) until the load is free and the limit is off.
    r.w32(0x6510, 0x22, 0);
    r.d.clear_fault(0x8611);
    r.d.axis_mut().set_blocked(false);
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.sw() & 0x4F, 0x40);
    assert_eq!(r.d.take_event(), Some(DriveEvent::Cleared { code: 0x8611 }));
}

/// CMMP-CW-11 (b): FAULT reads 0008h with 6510h:F0 bit 7 = 1 ((a) 000Fh: see
/// `blocked_load_raises_following_error_then_fault_and_reset`).
#[test]
fn cia402_fault_value_with_compatibility_bit_7() {
    let mut r = Rig::quick();
    r.d.write(0x6510, 0xF0, &0x0080u16.to_le_bytes()).unwrap();
    r.d.inject_fault(0x5114, 0x05);
    r.run_ms(2);
    assert_eq!(r.sw() & 0x4F, 0x08);
}

#[test]
fn compatibility_bits_0_and_2_mirror_each_other() {
    // CMMP-SDO-15.
    let mut r = Rig::quick();
    r.d.write(0x6510, 0xF0, &0x0004u16.to_le_bytes()).unwrap();
    assert_eq!(r.d.od().get_unsigned(0x6510, 0xF0), Some(0x0005));
}

#[test]
fn restore_is_refused_with_the_output_stage_on() {
    // CMMP-SDO-10.
    let mut r = Rig::quick();
    r.enable();
    assert_eq!(r.d.write(0x1011, 1, b"load"), Err(AbortCode::DEVICE_STATE));
    r.cw(0x00);
    assert_eq!(r.d.write(0x1011, 1, b"load"), Ok(()));
}

#[test]
fn position_factor_above_2_pow_24_is_refused() {
    let mut r = Rig::quick();
    assert_eq!(
        r.d.write(0x6093, 1, &0x0100_0001u32.to_le_bytes()),
        Err(AbortCode::VALUE_TOO_HIGH)
    );
    assert_eq!(
        r.d.write(0x6093, 2, &0u32.to_le_bytes()),
        Err(AbortCode::INVALID_VALUE)
    );
    // CMMP-SDO-05: with divisor 19 first, 12345678h is within the limit.
    r.w32(0x6093, 2, 19);
    r.w32(0x6093, 1, 0x1234_5678);
    assert_eq!(r.d.od().get_unsigned(0x6093, 1), Some(0x1234_5678));
}

#[test]
fn ramps_6083_6084_are_the_2090_values() {
    let mut r = Rig::quick();
    r.w32(0x6083, 0, 5000);
    r.w32(0x6084, 0, 7000);
    assert_eq!(r.i2(0x2090, 2), 5000);
    assert_eq!(r.i2(0x2090, 4), 5000);
    assert_eq!(r.i2(0x2090, 3), 7000);
    assert_eq!(r.i2(0x2090, 5), 7000);
}

impl Rig {
    fn i2(&self, index: u16, sub: u8) -> i64 {
        match self.d.od().value(index, sub).unwrap() {
            Value::Signed(s) => s,
            Value::Unsigned(u) => u as i64,
            v => panic!("{v:?}"),
        }
    }
}

/// CMMP-CW-12, CMMP-CW-14 end to end (every input combination: crates/drive/tests/
/// device_control.rs): bit 14 from the drive's own 2000h:01.
#[test]
fn manufacturer_status_bit_14_examples() {
    // The CMMP-AS manual's extract, part 2 §8.8 (a): homed → bit 14 with mask 1; (c) not ready for
    // enable OR homed.
    let mut r = Rig::quick();
    r.w32(0x2005, 1, 0x1);
    r.run_ms(1);
    assert_eq!(r.sw() & 0x4000, 0, "not homed");
    r.mode(6);
    r.w8(0x6098, 35);
    r.enable();
    r.cw(0x1F);
    assert_ne!(r.sw() & 0x8000, 0, "referenced");
    assert_ne!(r.sw() & 0x4000, 0, "(a) homed");
    assert_ne!(r.sw() & 0x1000, 0, "homing attained");
    r.w32(0x200A, 1, 0x4);
    r.w32(0x2005, 1, 0x5);
    r.run_ms(1);
    assert_ne!(r.sw() & 0x4000, 0, "(c) enabled (not ready) or homed");
}

#[test]
fn same_inputs_same_trajectory_bit_for_bit() {
    let run = || {
        let mut r = Rig::quick();
        r.mode(1);
        r.enable();
        r.w32(0x607A, 0, 3 * 65536 + 123);
        r.cw(0x1F);
        r.cw(0x0F);
        let mut trace = Vec::new();
        for _ in 0..500 {
            r.run_ms(1);
            trace.push((r.i(0x6064), r.i(0x606C), r.i(0x6078)));
        }
        trace
    };
    assert_eq!(run(), run());
}

#[test]
fn jerk_free_profile_takes_longer_but_ends_in_the_window() {
    let time_for = |profile: i16| {
        let mut r = Rig::quick();
        r.mode(1);
        r.d.write(0x6086, 0, &profile.to_le_bytes()).unwrap();
        r.enable();
        r.w32(0x607A, 0, 5 * 65536);
        r.cw(0x1F);
        r.cw(0x0F);
        let start = r.now;
        let mut max_fe = 0;
        while r.sw() & 0x0400 == 0 {
            r.run_ms(1);
            max_fe = max_fe.max(r.i(0x60F4).abs());
            assert!(r.now.saturating_since(start) < Duration::from_secs(3));
        }
        assert!((r.i(0x6064) - 5 * 65536).abs() <= 1820);
        (r.now.saturating_since(start).as_secs_f64(), max_fe)
    };
    let (linear, fe_linear) = time_for(0);
    let (smooth, fe_smooth) = time_for(2);
    // The moving average delays the profile by half its window (0.05 s here).
    assert!(smooth > linear + 0.02, "{smooth} vs {linear}");
    assert!(smooth < linear + 0.15, "{smooth} vs {linear}");
    assert!(
        fe_smooth <= fe_linear,
        "smoother set-points lag less: {fe_smooth} vs {fe_linear}"
    );
}

/// CMMP-CW-15 (note): bit 10 is also set at standstill after Halt (bit 8).
#[test]
fn halt_in_profile_position_stops_with_target_reached() {
    let mut r = Rig::quick();
    r.mode(1);
    r.enable();
    r.w32(0x607A, 0, 50 * 65536);
    r.cw(0x1F);
    r.cw(0x0F);
    r.run_ms(300);
    r.cw(0x010F);
    r.run_ms(200);
    assert!(r.i(0x606C).abs() <= 10, "stopped: {}", r.i(0x606C));
    assert_ne!(r.sw() & 0x0400, 0, "target reached after the halt");
    assert!(r.i(0x6064) < 50 * 65536 / 2, "the job was abandoned");
    // Clearing halt does not resume the job (CMMP-AS Tab. 6.5).
    r.cw(0x000F);
    r.run_ms(200);
    assert!(r.i(0x606C).abs() <= 10);
}

#[test]
fn mode_change_with_halt_set() {
    let mut r = Rig::quick();
    r.mode(3);
    r.enable();
    r.cw(0x010F);
    r.w8(0x6060, 1);
    r.run_ms(10);
    assert_eq!(r.i(0x6061), 1, "the mode changes while halted");
    r.w32(0x607A, 0, 65536);
    r.cw(0x011F);
    r.cw(0x010F);
    r.run_ms(300);
    assert!(r.i(0x6064).abs() < 1000, "halted: no motion");
    assert_eq!(r.d.state(), State::OperationEnabled);
}

#[test]
fn brake_follows_the_output_stage_and_60fe_bit_0_when_masked() {
    let mut r = Rig::quick();
    assert!(
        r.d.axis().motor().brake(),
        "applied with the output stage off"
    );
    r.enable();
    assert!(
        !r.d.axis().motor().brake(),
        "released with the output stage on"
    );
    // Manual control: mask bit 0, then 60FEh:01 bit 0 applies the brake.
    r.w32(0x60FE, 2, 1);
    r.w32(0x60FE, 1, 1);
    r.run_ms(1);
    assert!(r.d.axis().motor().brake());
    r.w32(0x60FE, 1, 0);
    r.run_ms(1);
    assert!(!r.d.axis().motor().brake());
}

#[test]
fn brake_delay_holds_the_set_point_after_enable() {
    let mut r = Rig::quick();
    r.d.write(0x6510, 0x18, &200u16.to_le_bytes()).unwrap();
    r.mode(3);
    r.enable();
    r.w32(0x60FF, 0, 1000);
    r.run_ms(150);
    assert!(
        r.i(0x606C).abs() <= 5,
        "no motion during the brake delay: {}",
        r.i(0x606C)
    );
    r.run_ms(200);
    assert!(r.i(0x606C) > 500, "moving after it: {}", r.i(0x606C));
}

#[test]
fn cyclic_synchronous_position_only_over_ethercat_and_follows_the_set_points() {
    let mut r = Rig::quick();
    assert_eq!(
        r.d.write(0x6060, 0, &[8]),
        Err(AbortCode::INVALID_VALUE),
        "CSP is EtherCAT only"
    );

    let desc = &devices::CMMP_AS;
    let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap();
    let settings = DriveSettings {
        ethercat: true,
        ..DriveSettings::default()
    };
    let mut r = Rig {
        d: Drive::new(od, settings),
        now: Instant::ZERO,
    };
    r.run_ms(1);
    assert_eq!(r.d.od().get_unsigned(0x6502, 0).unwrap() & 0x80, 0x80);
    r.mode(8);
    r.enable();
    // A 1 kHz master: 500 rpm = 8192/60 increments per ms... send a ramp of set-points.
    let mut target = 0i64;
    let mut max_fe = 0;
    for ms in 0..1000 {
        let speed = (ms.min(200) as i64) * 3; // increments per ms, ramping up
        target += speed;
        r.w32(0x607A, 0, target);
        r.run_ms(1);
        max_fe = max_fe.max((r.i(0x6064) - target).abs());
    }
    assert!(
        (r.i(0x6064) - target).abs() < 2000,
        "{} vs {}",
        r.i(0x6064),
        target
    );
    assert!(max_fe < 9101, "following error inside the window: {max_fe}");
    // Set-points stop: the axis stands at the last one.
    r.run_ms(200);
    assert!((r.i(0x6064) - target).abs() < 50);
    assert!(r.i(0x606C).abs() < 5);
}

/// CMMP-CW-07, CMMP-CW-08, CMMP-CW-09 through the dictionary: from OPERATION_ENABLE 0000h →
/// 0040h and 0006h → 0021h with the output stage off (statusword bit 4 voltage enabled
/// clears once the brake has closed); 0007h → 0023h.
#[test]
fn leaving_operation_enabled_switches_the_output_stage_as_the_manual_says() {
    for (cw, mask, state, output_stage) in [
        (0x00, 0x4F, 0x40, false),
        (0x06, 0x6F, 0x21, false),
        (0x07, 0x6F, 0x23, true),
    ] {
        let mut r = Rig::quick();
        r.mode(3);
        r.enable();
        r.cw(cw);
        assert_eq!(r.sw() & mask, state, "{cw:#06x}");
        r.run_ms(500);
        assert_eq!(r.sw() & mask, state, "{cw:#06x}");
        assert_eq!(
            r.sw() & 0x10 != 0,
            output_stage,
            "{cw:#06x}: {:#06x}",
            r.sw()
        );
        assert_eq!(
            r.d.demand() != drive::axis::Demand::Off,
            output_stage,
            "{cw:#06x}"
        );
    }
}

/// CMMP-CW-10 through the dictionary: FAULT with the cause removed; 0000h then 0080h → 0040h.
/// A new fault while 0080h is still held is not reset by it: only the next rising edge.
#[test]
fn cmmp_cw_10_fault_reset_on_the_rising_edge_of_bit_7() {
    let mut r = Rig::quick();
    r.enable();
    r.d.inject_fault(0x5114, 0x05);
    r.run_ms(200);
    assert_eq!(r.d.state(), State::Fault);
    r.d.clear_fault(0x5114);
    r.cw(0x00);
    assert_eq!(r.d.state(), State::Fault, "0000h alone does not reset");
    r.cw(0x80);
    assert_eq!(r.sw() & 0x4F, 0x40);
    // 0080h held: a new error is not acknowledged by the level.
    r.d.inject_fault(0x5114, 0x05);
    r.run_ms(2);
    r.d.clear_fault(0x5114);
    r.cw(0x80);
    r.run_ms(10);
    assert_eq!(r.d.state(), State::Fault, "no edge while 0080h is held");
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.sw() & 0x4F, 0x40);
}

/// CMMP-CW-05 through the dictionary: 000Fh in SWITCH_ON_DISABLED leaves it there.
#[test]
fn cmmp_cw_05_enable_operation_does_not_leave_switch_on_disabled() {
    let mut r = Rig::quick();
    r.cw(0x0F);
    r.run_ms(10);
    assert_eq!(r.sw() & 0x4F, 0x40);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
}

/// CMMP-CW-12 through the dictionary: invert 0, mask 1; bit 14 follows IS_REFERENCED, 1 after
/// homing, 0 again when a new homing run starts (the reference is lost until it ends).
#[test]
fn cmmp_cw_12_bit_14_follows_is_referenced() {
    let mut r = Rig::quick();
    r.w32(0x200A, 1, 0);
    r.w32(0x2005, 1, 1);
    r.mode(6);
    r.w8(0x6098, 35);
    r.enable();
    r.run_ms(1);
    assert_eq!(r.sw() & 0x4000, 0, "not referenced");
    r.cw(0x1F);
    assert_eq!(r.d.od().get_unsigned(0x2000, 1).unwrap() & 1, 1);
    assert_ne!(r.sw() & 0x4000, 0, "referenced");
    r.cw(0x0F);
    r.w8(0x6098, 17);
    r.cw(0x1F);
    assert_eq!(r.d.od().get_unsigned(0x2000, 1).unwrap() & 1, 0);
    assert_eq!(r.sw() & 0x4000, 0, "homing again: not referenced");
}

/// CMMP-EMCY-05: (a) a second error while in FAULT sends its own EMCY (event) with the new
/// code; (b) acknowledging while a cause is still present sends nothing and FAULT stays.
#[test]
fn cmmp_emcy_05_second_error_and_acknowledge_with_the_cause_present() {
    let mut r = Rig::quick();
    r.enable();
    r.d.inject_fault(0x5114, 0x05);
    r.run_ms(200);
    assert_eq!(r.d.state(), State::Fault);
    assert_eq!(
        r.d.take_event(),
        Some(DriveEvent::Error {
            code: 0x5114,
            register: 0x05
        })
    );
    // (a)
    r.d.inject_fault(0x4310, 0x09);
    r.run_ms(2);
    assert_eq!(
        r.d.take_event(),
        Some(DriveEvent::Error {
            code: 0x4310,
            register: 0x09
        })
    );
    assert_eq!(r.d.state(), State::Fault);
    // (b) one cause removed, the other still present.
    r.d.clear_fault(0x5114);
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.d.take_event(), None, "no EMCY");
    assert_eq!(r.d.state(), State::Fault);
    assert_eq!(r.d.errors(), &[0x5114, 0x4310]);
    // Both causes gone: the acknowledgement clears both (CMMP-EMCY-01 is the frame).
    r.d.clear_fault(0x4310);
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.sw() & 0x4F, 0x40);
    let mut cleared = Vec::new();
    while let Some(e) = r.d.take_event() {
        cleared.push(e);
    }
    assert_eq!(cleared.len(), 2, "{cleared:?}");
}

/// CMMP-FG-14 through the dictionary: 6093h = 4096/225 (1/10°), 607Ah := 3600 moves one
/// revolution (65536 increments in 6063h) and 6064h reads 3600.
#[test]
fn cmmp_fg_14_target_in_tenth_degrees_moves_one_revolution() {
    let mut r = Rig::quick();
    r.w32(0x6093, 1, 4096);
    r.w32(0x6093, 2, 225);
    r.mode(1);
    r.enable();
    r.w32(0x607A, 0, 3600);
    assert_eq!(r.i(0x607A), 3600);
    r.cw(0x1F);
    r.cw(0x0F);
    r.run_ms(1000);
    assert_ne!(r.sw() & 0x0400, 0, "target reached");
    assert!((r.i(0x6063) - 65536).abs() <= 2, "{}", r.i(0x6063));
    assert!((r.i(0x6064) - 3600).abs() <= 1, "{}", r.i(0x6064));
}

/// CMMP-FG-17 through the dictionary: 607Eh := C0h; 607Ah := 1000 is internal −1000 (the
/// drive moves to −1000 increments) and reads 1000; after 607Eh := 0 the stored value is not
/// converted, so 607Ah reads −1000. (The SDO frames `601: 2F 7E 60 00 C0` /
/// `581: 60 7E 60 00` are the CANopen layer's; the write here is the decoded one.)
#[test]
fn cmmp_fg_17_polarity_through_the_dictionary() {
    let mut r = Rig::quick();
    assert_eq!(r.d.write(0x607E, 0, &[0xC0]), Ok(()));
    r.mode(1);
    r.enable();
    r.w32(0x607A, 0, 1000);
    r.cw(0x1F);
    r.cw(0x0F);
    r.run_ms(300);
    assert!((r.i(0x6063) + 1000).abs() <= 2, "internal {}", r.i(0x6063));
    assert!((r.i(0x6064) - 1000).abs() <= 2, "user {}", r.i(0x6064));
    assert_eq!(r.i(0x607A), 1000);
    assert_eq!(r.d.write(0x607E, 0, &[0x00]), Ok(()));
    assert_eq!(r.i(0x607A), -1000);
    // The velocity flag turns a stored 60FFh over the same way.
    r.w32(0x60FF, 0, 500);
    r.d.write(0x607E, 0, &[0x40]).unwrap();
    assert_eq!(r.i(0x60FF), -500);
}

/// CMMP-TQ-01 through the drive: 6087h = 1000 ‰/s takes the torque set-point from 0 to the
/// rated torque (1000 ‰) in 1 s.
#[test]
fn cmmp_tq_01_torque_slope_1000_reaches_rated_torque_in_one_second() {
    let mut r = Rig::quick();
    r.mode(4);
    r.d.axis_mut().set_blocked(true);
    r.enable();
    r.w32(0x6087, 0, 1000);
    r.w16(0x6071, 1000);
    r.run_ms(500);
    let half = r.i(0x6074);
    assert!((half - 500).abs() <= 15, "half-way after 0.5 s: {half}");
    r.run_ms(520);
    assert!((r.i(0x6074) - 1000).abs() <= 15, "{}", r.i(0x6074));
}

/// CMMP-TQ-02 through the drive: 6072h = 2000 permits a brief 2-fold overload and no more:
/// a 3000 ‰ set-point is limited to 2000 ‰.
#[test]
fn cmmp_tq_02_max_torque_limits_the_set_point() {
    let mut r = Rig::quick();
    r.mode(4);
    r.d.axis_mut().set_blocked(true);
    r.enable();
    r.w16(0x6072, 2000);
    r.w16(0x6071, 3000);
    r.run_ms(50);
    assert!((r.i(0x6074) - 2000).abs() <= 20, "{}", r.i(0x6074));
}

/// CMMP-TQ-04 through the drive: 6073h := 4000 (overload factor 4) lets 4 × 6075h flow
/// (1184 mA with the default 296 mA), bounded by 6510h:41 peak_current.
#[test]
fn cmmp_tq_04_max_current_4000_in_the_drive() {
    let mut r = Rig::quick();
    r.w16(0x6073, 4000);
    r.run_ms(2);
    assert!((r.d.axis().gains().i_max - 1.184).abs() < 1e-9);
    // 6075h := 2000 mA after it (the manual asks for 6073h to be written again): 8 A is
    // above the 5 A peak current, which bounds it.
    r.w32(0x6075, 0, 2000);
    r.run_ms(2);
    assert!((r.d.axis().gains().i_max - 5.0).abs() < 1e-9);
}

/// A master that writes 0000h and 0080h back to back (python-canopen's SDOs within one
/// control cycle) after an attempt while the cause was present: the rising edge still counts.
#[test]
fn fault_reset_edge_written_within_one_cycle() {
    let mut r = Rig::quick();
    r.enable();
    r.d.raise_diagnostic("05-0").expect("App. B 05-0");
    r.run_ms(200);
    assert_eq!(r.d.state(), State::Fault);
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.d.state(), State::Fault, "the cause is still raised");
    r.d.clear_diagnostic("05-0").expect("raised");
    r.d.write(0x6040, 0, &[0x00, 0x00]).expect("controlword");
    r.d.write(0x6040, 0, &[0x80, 0x00]).expect("controlword");
    r.run_ms(2);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
}
