//! Kinco mode −4, pulse / gear (manual §6.5, §5.5.3; KINCO-SC-04) with the simulated pulse input:
//! the gear set the Multifunction inputs select, the counters Gear_Master / Gear_Slave and the
//! Overfrequency error.

mod kinco_rig;

use kinco_rig::Rig;

/// Mode −4, enabled, the factory gear 1000 / 1000.
fn pulse_rig() -> Rig {
    let mut r = Rig::new();
    r.enable_in(-4);
    r
}

/// 10 000 pulses per second for one second with the gear 1000 / 1000: one revolution,
/// counted before and after the gear.
#[test]
fn pulses_move_the_motor_through_the_gear() {
    let mut r = pulse_rig();
    r.d.set_pulse_input(10_000.0);
    r.run_ms(1000);
    r.d.set_pulse_input(0.0);
    r.run_ms(200);
    assert_eq!(r.i(0x2508, 0x04), 10_000, "Gear_Master");
    assert_eq!(r.i(0x2508, 0x05), 10_000, "Gear_Slave");
    assert!((r.position() - 10_000).abs() <= 10, "{}", r.position());
    assert_ne!(
        r.sw() & 0x0400,
        0,
        "no pulse for 2508h:09: position reached"
    );
}

/// KINCO-SC-04: Multifunction0 = 0, Multifunction1 = 1, Multifunction2 = 1 selects gear set
/// 6 (Gear_Factor[6] / Gear_Divider[6] = 2509h:0B / :0C).
#[test]
fn kinco_sc_04_gear_set_6() {
    let mut r = Rig::new();
    r.w16(0x2010, 0x06, 0x8004); // DIN4 Multifunction0
    r.w16(0x2010, 0x07, 0x8008); // DIN5 Multifunction1
    r.w16(0x2010, 0x08, 0x8010); // DIN6 Multifunction2
    r.w16(0x2509, 0x0B, 3000);
    r.w16(0x2509, 0x0C, 1000);
    r.w16(0x2010, 0x02, (1 << 4) | (1 << 5));
    r.enable_in(-4);
    r.d.set_pulse_input(-2_000.0);
    r.run_ms(500);
    r.d.set_pulse_input(0.0);
    r.run_ms(200);
    assert_eq!(r.i(0x2508, 0x04), -1000, "Gear_Master");
    assert_eq!(r.i(0x2508, 0x05), -3000, "Gear_Slave: × 3");
    assert!((r.position() + 3000).abs() <= 10, "{}", r.position());
}

/// More than Frequency_Check 2508h:08 (600 pulses/ms) is Overfrequency: Error_State bit
/// 12, EMCY 8A80h, fault.
#[test]
fn overfrequency() {
    let mut r = pulse_rig();
    r.d.set_pulse_input(700_000.0);
    r.run_ms(5);
    assert_eq!(r.sw() & 0x4F, 0x08, "fault");
    assert_eq!(r.i(0x2601, 0), 1 << 12);
}
