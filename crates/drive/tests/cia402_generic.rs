//! The standard CiA 402 drive (`vendors::cia402`) over a device file it was not written for:
//! every hook at CiA 402's behaviour, the modes 6502h lists, enable and a PP move.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::time::Duration;

use drive::drive::named_switches::{NamedSwitch, SwitchInput};
use drive::drive::{Drive, DriveSettings};
use drive::travel::{HomeSwitch, TravelSettings};
use drive::vendors::Cia402;
use od::{AbortCode, Instant, ObjectAccess, ObjectDictionary};

fn drive() -> (Drive<Vec<u8>, Cia402>, Instant) {
    let desc = &devices::CMMP_AS;
    let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap();
    let mut d: Drive<Vec<u8>, Cia402> = Drive::new(od, DriveSettings::default());
    let now = Instant::ZERO + Duration::from_millis(1);
    d.step(now);
    (d, now)
}

fn sw(d: &Drive<Vec<u8>, Cia402>) -> u16 {
    d.od().get_unsigned(0x6041, 0).unwrap() as u16
}

#[test]
fn modes_are_those_6502h_lists() {
    let (mut d, _) = drive();
    // The CMMP-AS file's 6502h: PP, PV, PT, HM, IP (6Dh); no velocity mode VL.
    assert_eq!(d.od().get_unsigned(0x6502, 0), Some(0x6D));
    assert_eq!(d.write(0x6060, 0, &[1]), Ok(()));
    assert_eq!(d.write(0x6060, 0, &[2]), Err(AbortCode::INVALID_VALUE));
    assert!(d.refusal(drive::drive::refusal::Request::Mode(2)).is_some());
}

#[test]
fn enables_and_moves_in_profile_position() {
    let (mut d, mut now) = drive();
    let mut run = |d: &mut Drive<Vec<u8>, Cia402>, ms: u64| {
        now = now + Duration::from_millis(ms);
        d.step(now);
    };
    d.write(0x6060, 0, &[1]).unwrap();
    for cw in [0x06u16, 0x07, 0x0F] {
        d.write(0x6040, 0, &cw.to_le_bytes()).unwrap();
        run(&mut d, 5);
    }
    // CiA 402 §6.3.2: OPERATION ENABLED, voltage enabled, remote.
    assert_eq!(sw(&d) & 0x027F, 0x0237, "{:#06x}", sw(&d));
    d.write(0x607A, 0, &10_000i32.to_le_bytes()).unwrap();
    d.write(0x6040, 0, &0x1Fu16.to_le_bytes()).unwrap();
    run(&mut d, 2);
    d.write(0x6040, 0, &0x0Fu16.to_le_bytes()).unwrap();
    for _ in 0..400 {
        run(&mut d, 5);
        if sw(&d) & 0x0400 != 0 {
            break;
        }
    }
    assert_ne!(sw(&d) & 0x0400, 0, "target reached");
    // Target reached: within the position window 6067h of the target.
    let Some(od::Value::Signed(pos)) = d.od().value(0x6064, 0) else {
        panic!("6064h");
    };
    let window = d.od().get_unsigned(0x6067, 0).unwrap() as i64;
    assert!((pos - 10_000).abs() <= window, "{pos}");
}

/// A drive over the Lexium-like EDS of the interop tests: no 6080h max_motor_speed, no
/// manufacturer objects.
fn eds_drive() -> (Drive<Vec<u8>, Cia402>, Instant) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/interop/data/eds/lexium32_like.eds");
    let eds = devdesc::eds::load_file(&path).unwrap();
    let desc = devdesc::runtime::leak(&eds.device);
    assert!(desc.object(0x6080).is_none());
    let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap();
    let mut d: Drive<Vec<u8>, Cia402> = Drive::new(od, DriveSettings::default());
    let now = Instant::ZERO + Duration::from_millis(1);
    d.step(now);
    (d, now)
}

/// The EDS drive with `travel` and the hardware enables as `enables_present`, one cycle run.
fn eds_drive_on(travel: TravelSettings, enables_present: bool) -> Drive<Vec<u8>, Cia402> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/interop/data/eds/lexium32_like.eds");
    let eds = devdesc::eds::load_file(&path).unwrap();
    let desc = devdesc::runtime::leak(&eds.device);
    let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap();
    let settings = DriveSettings {
        travel,
        enables_present,
        ..DriveSettings::default()
    };
    let mut d: Drive<Vec<u8>, Cia402> = Drive::new(od, settings);
    d.step(Instant::ZERO + Duration::from_millis(1));
    d
}

/// CiA 402 §6.6.4: 60FDh of the standard drive has the profile's bits only: at the positive
/// limit switch bit 1, on the home cam bit 2, without its hardware enable bit 3 interlock, at
/// the negative limit switch bit 0; no manufacturer bit (16 … 31), no vendor's DIN in bits
/// 24 … 29. By name, a switch is the input of its 60FDh bit, actuated HIGH.
#[test]
fn digital_inputs_show_the_profile_bits_only() {
    let di = |d: &Drive<Vec<u8>, Cia402>| d.od().get_unsigned(0x60FD, 0).unwrap() as u32;
    let positive = TravelSettings {
        positive_limit: Some(0),
        home_switch: Some(HomeSwitch { low: -10, high: 10 }),
        ..TravelSettings::NONE
    };
    let mut d = eds_drive_on(positive, true);
    assert_eq!(di(&d), 0b0110, "positive limit and home switch");
    assert_eq!(
        di(&eds_drive_on(positive, false)),
        0b1110,
        "interlock without the enable"
    );
    let negative = TravelSettings {
        negative_limit: Some(0),
        ..TravelSettings::NONE
    };
    assert_eq!(di(&eds_drive_on(negative, true)), 0b0001);

    assert_eq!(
        d.switch_input(NamedSwitch::LimitNegative),
        Some(SwitchInput {
            mask: 1 << 0,
            actuated_high: true
        })
    );
    d.set_switch(NamedSwitch::LimitNegative, Some(true));
    d.set_switch(NamedSwitch::Home, Some(false));
    d.step(Instant::ZERO + Duration::from_millis(2));
    assert_eq!(di(&d), 0b0011, "negative forced on, home forced off");
}

fn signed(d: &Drive<Vec<u8>, Cia402>, index: u16) -> i64 {
    match d.od().value(index, 0) {
        Some(od::Value::Signed(v)) => v,
        Some(od::Value::Unsigned(v)) => v as i64,
        v => panic!("{index:04X}h: {v:?}"),
    }
}

/// Enables in profile velocity with the ramps 6083h / 6084h and asks for `target`.
fn profile_velocity(
    d: &mut Drive<Vec<u8>, Cia402>,
    now: &mut Instant,
    acceleration: u32,
    target: i32,
) {
    d.write(0x6060, 0, &[3]).unwrap();
    d.write(0x6083, 0, &acceleration.to_le_bytes()).unwrap();
    d.write(0x6084, 0, &acceleration.to_le_bytes()).unwrap();
    for cw in [0x06u16, 0x07, 0x0F] {
        d.write(0x6040, 0, &cw.to_le_bytes()).unwrap();
        *now = *now + Duration::from_millis(5);
        d.step(*now);
    }
    assert_eq!(sw(d) & 0x006F, 0x0027, "{:#06x}", sw(d));
    d.write(0x60FF, 0, &target.to_le_bytes()).unwrap();
}

/// CiA 402 §6.5: 6080h max_motor_speed is optional; a drive without it runs profile
/// velocity to the target, uncapped.
#[test]
fn profile_velocity_runs_without_6080h() {
    let (mut d, mut now) = eds_drive();
    profile_velocity(&mut d, &mut now, 100_000, 300);
    for _ in 0..600 {
        now = now + Duration::from_millis(5);
        d.step(now);
    }
    let v = signed(&d, 0x606C);
    assert!((v - 300).abs() <= 15, "606Ch {v}");
}

/// CiA 402 §6.5: the velocity set-point ramps by 6083h profile acceleration towards the
/// target and by 6084h profile deceleration back to 0.
#[test]
fn profile_velocity_ramps_by_6083h_and_6084h() {
    let (mut d, mut now) = eds_drive();
    // 600 per s to 300: half a second.
    profile_velocity(&mut d, &mut now, 600, 300);
    for _ in 0..20 {
        now = now + Duration::from_millis(5);
        d.step(now);
    }
    let early = signed(&d, 0x606B);
    assert!((40..=80).contains(&early), "606Bh after 100 ms: {early}");
    for _ in 0..200 {
        now = now + Duration::from_millis(5);
        d.step(now);
    }
    assert_eq!(signed(&d, 0x606B), 300);
    d.write(0x60FF, 0, &0i32.to_le_bytes()).unwrap();
    for _ in 0..20 {
        now = now + Duration::from_millis(5);
        d.step(now);
    }
    let braking = signed(&d, 0x606B);
    assert!(
        (220..=260).contains(&braking),
        "606Bh 100 ms into braking: {braking}"
    );
}

/// CiA 402 §6.3.2 Tab. 30: FAULT reads xxxx xxxx x0xx 1000 (0008h), whatever a vendor
/// object at 6510h:F0 holds.
#[test]
fn fault_reads_0008h() {
    let (mut d, mut now) = drive();
    for compat in [0u64, 0x80] {
        d.od_mut()
            .set_value(0x6510, 0xF0, od::Value::Unsigned(compat))
            .unwrap();
        d.inject_fault(0x8611, 0x01);
        now = now + Duration::from_millis(50);
        d.step(now);
        assert_eq!(sw(&d) & 0x004F, 0x0008, "{:#06x}", sw(&d));
        d.clear_fault(0x8611);
        d.write(0x6040, 0, &0x80u16.to_le_bytes()).unwrap();
        now = now + Duration::from_millis(5);
        d.step(now);
        d.write(0x6040, 0, &0u16.to_le_bytes()).unwrap();
    }
}

/// CiA 402 §6.3.2: bit 9 remote, the controlword processed: the drive is controlled over the
/// fieldbus, whatever a vendor object at 6510h:10 holds.
#[test]
fn remote_is_set_whatever_6510h_10_holds() {
    let (mut d, mut now) = drive();
    for logic in [0u64, 2] {
        d.od_mut()
            .set_value(0x6510, 0x10, od::Value::Unsigned(logic))
            .unwrap();
        now = now + Duration::from_millis(5);
        d.step(now);
        assert_ne!(sw(&d) & 0x0200, 0, "{:#06x}", sw(&d));
    }
}

/// The manufacturer area (2000h–5FFFh) and 6510h keep their values: the standard drive gives
/// them no meaning, neither reads nor writes them.
#[test]
fn manufacturer_objects_are_left_alone() {
    let (mut d, mut now) = drive();
    let before: Vec<_> = [(0x2000u16, 1u8), (0x2074, 0), (0x200F, 0), (0x6510, 0x34)]
        .iter()
        .map(|&(i, s)| d.od().value(i, s))
        .collect();
    // 6510h:37 = 1 with a minimum above the supply would be the CMMP-AS's undervoltage.
    d.od_mut()
        .set_value(0x6510, 0x36, od::Value::Unsigned(1_000_000))
        .unwrap();
    d.od_mut()
        .set_value(0x6510, 0x37, od::Value::Unsigned(1))
        .unwrap();
    d.set_dc_link_voltage(Some(200_000));
    for cw in [0x06u16, 0x07, 0x0F] {
        d.write(0x6040, 0, &cw.to_le_bytes()).unwrap();
        now = now + Duration::from_millis(5);
        d.step(now);
    }
    assert_eq!(sw(&d) & 0x006F, 0x0027, "{:#06x}", sw(&d));
    let after: Vec<_> = [(0x2000u16, 1u8), (0x2074, 0), (0x200F, 0), (0x6510, 0x34)]
        .iter()
        .map(|&(i, s)| d.od().value(i, s))
        .collect();
    assert_eq!(before, after);
}

/// CiA 402's factor group bounds no quotient numerator / divisor (the CMMP-AS's 2²⁴ is its
/// own, §5.3); a zero numerator or divisor stays refused.
#[test]
fn factors_have_no_quotient_limit() {
    let (mut d, _) = drive();
    let above = (1u32 << 24) + 1;
    d.write(0x6093, 2, &1u32.to_le_bytes()).unwrap();
    assert_eq!(d.write(0x6093, 1, &above.to_le_bytes()), Ok(()));
    assert_eq!(d.factor_group().position.numerator, above);
    assert_eq!(d.write(0x6094, 1, &above.to_le_bytes()), Ok(()));
    assert_eq!(
        d.write(0x6093, 2, &0u32.to_le_bytes()),
        Err(AbortCode::INVALID_VALUE)
    );
    // A stored set beyond 2²⁴ is kept at a reload, not replaced by the defaults.
    d.reload();
    assert_eq!(d.factor_group().position.numerator, above);
}

/// No undervoltage or I²t error of its own: CiA 402 names no threshold for either.
#[test]
fn no_supply_or_i2t_error_without_a_vendor() {
    let (mut d, mut now) = drive();
    d.set_dc_link_voltage(Some(1));
    for _ in 0..20 {
        now = now + Duration::from_millis(5);
        d.step(now);
    }
    assert!(d.errors().is_empty(), "{:04X?}", d.errors());
    assert_eq!(d.od().get_unsigned(0x6079, 0), Some(1));
}

/// Interpolated position as CiA 402 has it: 60C4h:06 buffer_clear opens 60C1h (closed, the
/// file's default 0, 60C1h:01 is refused with 0800 0022h), a new 60C2h is in force at once
/// (SYNCs every 2 ms synchronise after 60C2h = 2 ms without a reset), and each set-point of
/// 60C1h:01 is taken at the next SYNC and interpolated.
#[test]
fn interpolated_position_from_60c1h_on_the_sync_grid() {
    let (mut d, mut now) = drive();
    assert_eq!(
        d.write(0x60C1, 1, &100i32.to_le_bytes()),
        Err(AbortCode::DEVICE_STATE)
    );
    d.write(0x60C4, 6, &[1]).unwrap();
    // Any period units × 10^index s (the CMMP-AS takes 1…10 ms at index −3 only).
    d.write(0x60C2, 1, &[20]).unwrap();
    assert_eq!(d.interpolation_period(), Duration::from_millis(20));
    d.write(0x60C2, 1, &[2]).unwrap();
    assert_eq!(d.interpolation_period(), Duration::from_millis(2));
    d.write(0x6060, 0, &[7]).unwrap();
    for cw in [0x06u16, 0x07, 0x0F] {
        d.write(0x6040, 0, &cw.to_le_bytes()).unwrap();
        now = now + Duration::from_millis(5);
        d.step(now);
    }
    let tick = |d: &mut Drive<Vec<u8>, Cia402>, now: &mut Instant| {
        for _ in 0..2 {
            *now = *now + Duration::from_millis(1);
            d.step(*now);
        }
        d.sync(*now);
    };
    for _ in 0..4 {
        tick(&mut d, &mut now);
    }
    assert!(d.ip_synchronised());
    d.write(0x60C1, 1, &0i32.to_le_bytes()).unwrap();
    d.write(0x6040, 0, &0x1Fu16.to_le_bytes()).unwrap();
    tick(&mut d, &mut now);
    assert_ne!(sw(&d) & 0x1000, 0, "ip mode active: {:#06x}", sw(&d));
    // 100 increments per 2 ms, to 20 000.
    for k in 1..=200i32 {
        d.write(0x60C1, 1, &(k * 100).to_le_bytes()).unwrap();
        tick(&mut d, &mut now);
    }
    for _ in 0..200 {
        tick(&mut d, &mut now);
    }
    let demand = signed(&d, 0x6062);
    assert!((demand - 20_000).abs() <= 100, "6062h {demand}");
    // 0 clears and locks the buffer again.
    d.write(0x60C4, 6, &[0]).unwrap();
    assert_eq!(
        d.write(0x60C1, 1, &0i32.to_le_bytes()),
        Err(AbortCode::DEVICE_STATE)
    );
}

/// Halt during homing interrupts it (CiA 402: homing_error 0, homing_attained 0, target
/// reached once stopped: "interrupted or not started"), not an error as on the CMMP-AS; with
/// bit 4 still set it does not start again until bit 4 rises anew.
#[test]
fn halt_interrupts_homing_without_an_error() {
    let (mut d, mut now) = drive();
    let mut run = |d: &mut Drive<Vec<u8>, Cia402>, ms: u64| {
        for _ in 0..ms {
            now = now + Duration::from_millis(1);
            d.step(now);
        }
    };
    d.write(0x6060, 0, &[6]).unwrap();
    d.write(0x6098, 0, &[17]).unwrap();
    for cw in [0x06u16, 0x07, 0x0F] {
        d.write(0x6040, 0, &cw.to_le_bytes()).unwrap();
        run(&mut d, 5);
    }
    d.write(0x6040, 0, &0x1Fu16.to_le_bytes()).unwrap();
    run(&mut d, 100);
    assert!(signed(&d, 0x606C) != 0, "searching");
    d.write(0x6040, 0, &0x11Fu16.to_le_bytes()).unwrap();
    run(&mut d, 500);
    assert_eq!(sw(&d) & 0x3400, 0x0400, "{:#06x}", sw(&d));
    // Halt released, bit 4 still set: no new start.
    d.write(0x6040, 0, &0x1Fu16.to_le_bytes()).unwrap();
    run(&mut d, 200);
    assert_eq!(signed(&d, 0x606C), 0);
    assert_eq!(sw(&d) & 0x3400, 0x0400, "{:#06x}", sw(&d));
    // A new rising edge of bit 4 starts it again.
    d.write(0x6040, 0, &0x0Fu16.to_le_bytes()).unwrap();
    run(&mut d, 2);
    d.write(0x6040, 0, &0x1Fu16.to_le_bytes()).unwrap();
    run(&mut d, 100);
    assert!(signed(&d, 0x606C) != 0, "searching again");
}

/// CiA 402 leaves the sub-indices of 60F6h, 60F9h and 60FBh to the manufacturer: the
/// standard drive keeps the engine's standard gains (`ControlParams::default`) whatever they
/// hold, where the CMMP-AS over the same device file reads them as its §5.5–5.7 parameter
/// sets.
#[test]
fn parameter_sets_keep_the_standard_gains() {
    use drive::control::ControlParams;
    use drive::vendors::festo_cmmp_as::CmmpAs;

    let standard = ControlParams::default();
    let (mut d, now) = drive();
    let desc = &devices::CMMP_AS;
    let od = ObjectDictionary::new(desc, 1, vec![0; desc.storage_size]).unwrap();
    let mut cmmp: Drive<Vec<u8>, CmmpAs> = Drive::new(od, DriveSettings::default());
    cmmp.step(now);
    for (index, sub, value) in [(0x60F6, 1, 512u16), (0x60F9, 1, 512), (0x60FB, 1, 204)] {
        d.write(index, sub, &value.to_le_bytes()).unwrap();
        cmmp.write(index, sub, &value.to_le_bytes()).unwrap();
    }
    let later = now + Duration::from_millis(2);
    d.step(later);
    cmmp.step(later);
    let p = d.axis().params();
    assert_eq!(
        (
            p.torque_control_gain,
            p.velocity_control_gain,
            p.position_control_gain
        ),
        (
            standard.torque_control_gain,
            standard.velocity_control_gain,
            standard.position_control_gain
        )
    );
    let c = cmmp.axis().params();
    assert_eq!(
        (
            c.torque_control_gain,
            c.velocity_control_gain,
            c.position_control_gain
        ),
        (512, 512, 204)
    );
}
