//! The standard CiA 402 drive (`vendors::cia402`) over a device file it was not written for:
//! every hook at CiA 402's behaviour, the modes 6502h lists, enable and a PP move.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::time::Duration;

use drive::drive::{Drive, DriveSettings};
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
