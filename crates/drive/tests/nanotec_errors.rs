//! Nanotec errors (Nanotec §13.3; the extract's §7.1): the bit-valued EMCY codes and the reaction
//! table, legacy (2020h = 1, the default) and new (2020h = 0), at standstill and moving.

mod nanotec_rig;

use drive::device_control::State;
use drive::drive::DriveEvent;
use drive::vendors::nanotec::{emcy, Reaction, REACTIONS};
use nanotec_rig::Rig;

/// Operation Enabled in PP, moving towards a far target.
fn moving(r: &mut Rig) {
    r.enable_pp();
    r.w32(0x607A, 0, 1_000_000);
    r.cw(0x001F);
    r.cw(0x000F);
    r.run_ms(200);
    assert!(r.i(0x6062, 0) > 0, "moving");
}

/// Runs until the state machine settles (a ramp has ended), at most 3 s.
fn settle(r: &mut Rig) -> State {
    for _ in 0..300 {
        r.run_ms(10);
        if !matches!(
            r.d.state(),
            State::QuickStopActive | State::FaultReactionActive
        ) {
            break;
        }
    }
    r.d.state()
}

#[test]
fn the_table_has_every_code_of_7_1_once() {
    let codes: Vec<u16> = REACTIONS.iter().map(|r| r.code).collect();
    assert_eq!(
        codes,
        [
            0x0001, 0x0002, 0x0004, 0x0008, 0x0020, 0x0040, 0x0080, 0x0100, 0x0200, 0x0400, 0x0800,
            0x1000
        ]
    );
    assert!(codes.iter().all(|c| c.count_ones() == 1), "bit-valued");
}

/// Legacy: overtemperature at standstill switches the power off: Fault, EMCY 0002h.
#[test]
fn legacy_overtemperature_at_standstill_is_power_off() {
    let mut r = Rig::new();
    assert_eq!(r.i(0x2020, 0), 1, "legacy by default");
    r.enable();
    r.events();
    r.d.inject_fault(emcy::OVERTEMPERATURE, 0x01);
    r.run_ms(5);
    assert_eq!(r.d.state(), State::Fault);
    assert_eq!(r.sw() & 0x004F, 0x0008);
    assert_eq!(
        r.events(),
        [DriveEvent::Error {
            code: 0x0002,
            register: 0x01
        }]
    );
}

/// Legacy: undervoltage while moving: the quick-stop ramp, then the power off (Fault).
#[test]
fn legacy_undervoltage_moving_is_quick_stop_then_power_off() {
    let mut r = Rig::new();
    moving(&mut r);
    r.d.inject_fault(emcy::UNDERVOLTAGE, 0x01);
    r.run_ms(2);
    assert_eq!(r.d.state(), State::FaultReactionActive, "braking first");
    assert_eq!(settle(&mut r), State::Fault);
}

/// New (2020h = 0): lifeguard at standstill is the EMCY only; while moving a quick stop
/// (no fault) into Switch On Disabled.
#[test]
fn new_lifeguard_message_at_standstill_quick_stop_moving() {
    let mut r = Rig::new();
    r.w8(0x2020, 0, 0);
    r.enable_pp();
    r.events();
    r.d.inject_fault(emcy::LIFEGUARD, 0x11);
    r.run_ms(5);
    assert_eq!(
        r.d.state(),
        State::OperationEnabled,
        "the motor stays enabled"
    );
    assert_eq!(
        r.events(),
        [DriveEvent::Error {
            code: 0x0004,
            register: 0x11
        }]
    );
    r.d.clear_fault(emcy::LIFEGUARD);
    assert_eq!(r.events(), [DriveEvent::Cleared { code: 0x0004 }]);
    r.w32(0x607A, 0, 1_000_000);
    r.cw(0x001F);
    r.cw(0x000F);
    r.run_ms(200);
    r.d.inject_fault(emcy::LIFEGUARD, 0x11);
    r.run_ms(2);
    assert_eq!(r.d.state(), State::QuickStopActive);
    assert_eq!(
        settle(&mut r),
        State::SwitchOnDisabled,
        "quick stop, no fault"
    );
}

/// New: an internal travel-direction error lets the motor finish its job.
#[test]
fn new_travel_direction_error_finishes_the_job() {
    let row = REACTIONS.iter().find(|r| r.code == 0x0020).unwrap();
    assert_eq!(row.reaction(false, true), Reaction::MessageOnly);
    assert_eq!(row.reaction(true, true), Reaction::QuickStopPowerOff);
    let mut r = Rig::new();
    r.w8(0x2020, 0, 0);
    moving(&mut r);
    r.d.inject_fault(emcy::TRAVEL_DIRECTION, 0x01);
    r.run_ms(200);
    assert_eq!(r.d.state(), State::OperationEnabled);
}
