//! The Nanotec's and the Kinco's own supervision of their plant's physics
//! (`drive::drive::plant_supervision`): the rows of their manuals' error tables raised from
//! the temperatures and the encoder, with their reactions.
// The Kinco and the Nanotec rig each build on the shared `drive_rig`; this file uses both.
#![allow(clippy::duplicate_mod)]

use drive::device_control::State;
use drive::drive::DriveEvent;
use drive::encoder_fault::EncoderFault;
use drive::thermal::ThermalData;
use od::ObjectAccess;

mod kinco_rig;
mod nanotec_rig;

fn quick_heat() -> ThermalData {
    ThermalData {
        motor_time_constant_s: 1.0,
        stage_time_constant_s: 1.0,
        ..ThermalData::default()
    }
}

/// Nanotec §7.1 0002h Overtemperature: a power stage above the CHOSEN 90 °C (a hot cabinet)
/// switches the power off (both reaction tables: Power Off).
#[test]
fn nanotec_overtemperature_0002h_from_a_hot_power_stage() {
    let mut r = nanotec_rig::Rig::new();
    r.d.set_thermal_data(quick_heat());
    r.d.set_ambient_temperature(95.0);
    r.run_ms(3000);
    assert!(r.d.plant_watch().thermal.stage_c() > 90.0);
    assert!(r.d.errors().contains(&0x0002), "{:?}", r.d.errors());
    assert_eq!(r.d.state(), State::Fault);
    let events = std::iter::from_fn(|| r.d.take_event()).collect::<Vec<_>>();
    assert!(
        events
            .iter()
            .any(|e| matches!(e, DriveEvent::Error { code: 0x0002, .. })),
        "{events:?}"
    );
    // Cooled: the fault reset is taken.
    r.d.set_ambient_temperature(25.0);
    r.run_ms(10_000);
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
}

/// Nanotec §7.1 has no encoder row: a pulled cable is not reported (the reading stands still).
#[test]
fn nanotec_has_no_encoder_message() {
    let mut r = nanotec_rig::Rig::new();
    r.d.set_encoder_fault(EncoderFault::Disconnected);
    r.run_ms(50);
    assert!(r.d.errors().is_empty(), "{:?}", r.d.errors());
}

/// Kinco §7 Error_State bit 1 "Encoder not connected" (EMCY 7331h) and bit 13 "Motor
/// Temperature" (4310h), both with the output stage off; Error_State 2601h shows the bits.
#[test]
fn kinco_encoder_not_connected_and_motor_temperature() {
    let mut r = kinco_rig::Rig::new();
    r.d.set_encoder_fault(EncoderFault::Disconnected);
    r.run_ms(5);
    assert!(r.d.errors().contains(&0x7331), "{:?}", r.d.errors());
    assert_eq!(r.i(0x2601, 0) & 0x0002, 0x0002, "Error_State bit 1");
    r.d.set_encoder_fault(EncoderFault::Connected);
    r.run_ms(5);
    r.cw(0x00);
    r.cw(0x80);
    r.run_ms(5);
    assert!(r.d.errors().is_empty(), "{:?}", r.d.errors());

    let mut r = kinco_rig::Rig::new();
    r.d.set_thermal_data(quick_heat());
    r.d.set_ambient_temperature(105.0);
    r.run_ms(3000);
    assert!(r.d.errors().contains(&0x4310), "{:?}", r.d.errors());
    assert_eq!(r.i(0x2601, 0) & 0x2000, 0x2000, "Error_State bit 13");
    assert!(r.i(0x60F7, 0x0B) > 90, "Temp_Device shows the power stage");
}

mod cmmp_rig;

use drive::drive::named_switches::NamedSwitch;

/// The switches by name on the CMMP-AS (§5.14): positive limit E1 on DIN7, read in 60FDh bit
/// 1; with 6510h:12 = 1 (limits swapped) it is DIN6; home on DIN9, DIN8 with 6510h:13 = 1; a
/// normally closed set-up (6510h:11 = 0) actuates it LOW.
#[test]
fn cmmp_switches_by_name_follow_6510h_11_to_14() {
    use drive::vendors::festo_cmmp_as::digital_inputs::{DIN6, DIN7, DIN8, DIN9};
    let mut r = cmmp_rig::Rig::new();
    assert_eq!(
        NamedSwitch::parse("limit_positive"),
        Some(NamedSwitch::LimitPositive)
    );
    assert_eq!(
        NamedSwitch::parse("P limit-"),
        Some(NamedSwitch::LimitNegative)
    );
    assert_eq!(NamedSwitch::parse("home"), Some(NamedSwitch::Home));
    assert_eq!(NamedSwitch::parse("nonsense"), None);
    let input =
        r.d.set_switch(NamedSwitch::LimitPositive, Some(true))
            .unwrap();
    assert_eq!((input.mask, input.actuated_high), (DIN7, true));
    r.run_ms(2);
    let din = |r: &cmmp_rig::Rig| r.d.od().get_unsigned(0x60FD, 0).unwrap();
    assert_eq!(din(&r) & 0b111, 0b010, "60FDh bit 1 positive limit");
    r.d.set_switch(NamedSwitch::LimitPositive, None);
    r.run_ms(2);
    assert_eq!(din(&r) & 0b111, 0);
    r.d.write(0x6510, 0x12, &1u16.to_le_bytes()).unwrap();
    r.d.write(0x6510, 0x13, &1u16.to_le_bytes()).unwrap();
    r.run_ms(2);
    assert_eq!(
        r.d.switch_input(NamedSwitch::LimitPositive).unwrap().mask,
        DIN6
    );
    assert_eq!(
        r.d.switch_input(NamedSwitch::LimitNegative).unwrap().mask,
        DIN7
    );
    assert_eq!(r.d.switch_input(NamedSwitch::Home).unwrap().mask, DIN8);
    r.d.set_switch(NamedSwitch::Home, Some(true));
    r.run_ms(2);
    assert_eq!(din(&r) & 0b111, 0b100, "60FDh bit 2 home");
    r.d.write(0x6510, 0x11, &0u16.to_le_bytes()).unwrap();
    let input = r.d.switch_input(NamedSwitch::LimitNegative).unwrap();
    assert_eq!((input.mask, input.actuated_high), (DIN7, false));
    let _ = DIN9;
}

/// The Kinco's switches by name are the DINs whose function codes have them (factory set-up:
/// DIN5 P limit+, DIN6 P limit−, DIN7 Home Signal); a limit (normally closed) is actuated at
/// 0 and blocks its direction; a function moved to another DIN moves the switch with it.
#[test]
fn kinco_switches_by_name_follow_the_din_functions() {
    let mut r = kinco_rig::Rig::new();
    let input = r.d.switch_input(NamedSwitch::LimitPositive).unwrap();
    assert_eq!(
        (input.mask, input.actuated_high),
        (1 << 4, false),
        "DIN5, NC"
    );
    let input = r.d.switch_input(NamedSwitch::Home).unwrap();
    assert_eq!(
        (input.mask, input.actuated_high),
        (1 << 6, true),
        "DIN7, NO"
    );
    r.d.set_switch(NamedSwitch::LimitPositive, Some(true));
    r.run_ms(2);
    assert_eq!(r.i(0x2010, 0x0A) & (1 << 4), 0, "Din_Real DIN5 low");
    // P limit+ moved to DIN2.
    r.w16(0x2010, 0x04, 0x0010);
    r.w16(0x2010, 0x07, 0x0000);
    r.run_ms(2);
    assert_eq!(
        r.d.switch_input(NamedSwitch::LimitPositive).unwrap().mask,
        1 << 1
    );
}
