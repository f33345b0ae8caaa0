//! Power-on values of the CMMP-AS dictionary that the manual prints (the vector catalogue kept
//! beside the project §1.9, §1.11, §1.12): read through the dictionary as a master's SDO upload
//! would.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use od::{AbortCode, ObjectAccess, ObjectDictionary, Value};

fn cmmp() -> ObjectDictionary<Vec<u8>> {
    let d = &devices::CMMP_AS;
    ObjectDictionary::new(d, 1, vec![0; d.storage_size]).unwrap()
}

fn int(od: &ObjectDictionary<Vec<u8>>, index: u16, sub: u8) -> i64 {
    match od.value(index, sub) {
        Some(Value::Signed(s)) => s,
        Some(Value::Unsigned(u)) => u as i64,
        v => panic!("{index:04X}h:{sub:02X}h: {v:?}"),
    }
}

/// CMMP-TQ-03: 6087h torque_slope after power-on is 0E310F94h = 238 096 276.
#[test]
fn cmmp_tq_03_torque_slope_default() {
    let od = cmmp();
    assert_eq!(int(&od, 0x6087, 0), 0x0E31_0F94);
    assert_eq!(int(&od, 0x6087, 0), 238_096_276);
}

/// CMMP-TQ-05 (defaults in the dictionary): 6075h = 296 mA, 6073h = 2023 ‰.
#[test]
fn cmmp_tq_05_current_defaults() {
    let od = cmmp();
    assert_eq!(int(&od, 0x6075, 0), 296);
    assert_eq!(int(&od, 0x6073, 0), 2023);
}

/// CMMP-GAIN-07: 60F6h:01 = 768 (3.0), 60F6h:02 = 1020 µs, 60F9h:01 = 256 (1.0),
/// 60F9h:02 = 2000 µs, 60FBh:01 = 102 (≈ 0.398).
#[test]
fn cmmp_gain_07_controller_defaults_in_the_dictionary() {
    let od = cmmp();
    assert_eq!(int(&od, 0x60F6, 1), 768);
    assert_eq!(int(&od, 0x60F6, 2), 1020);
    assert_eq!(int(&od, 0x60F9, 1), 256);
    assert_eq!(int(&od, 0x60F9, 2), 2000);
    assert_eq!(int(&od, 0x60FB, 1), 102);
}

/// CMMP-GAIN-06: 60FBh:02 position_control_time. Decision: the object table prints it ro with
/// range 0 and default 0 (L3383–3386) while the text converts 4.0 ms to 4000 (L3360); the
/// twin follows the object table, so a master's write is refused with 0601 0002h (the
/// conversion itself is tested in crates/drive/tests/axis.rs).
#[test]
fn cmmp_gain_06_position_control_time_is_read_only() {
    let mut od = cmmp();
    assert_eq!(int(&od, 0x60FB, 2), 0);
    assert_eq!(
        od.write(0x60FB, 2, &4000u16.to_le_bytes()),
        Err(AbortCode::READ_ONLY)
    );
}

/// CMMP-GAIN-08: 6065h = 9101 (50°), 6067h = 1820 (10°), 60FBh:05 = 2 (1/32768 rev).
#[test]
fn cmmp_gain_08_window_defaults() {
    let od = cmmp();
    assert_eq!(int(&od, 0x6065, 0), 9101);
    assert_eq!(int(&od, 0x6067, 0), 1820);
    assert_eq!(int(&od, 0x60FB, 5), 2);
}

/// CMMP-GAIN-09: 6410h:11 encoder_offset_angle: −45° is E000h (−8192), the factory setting;
/// +180° is 7FFFh.
#[test]
fn cmmp_gain_09_encoder_offset_angle() {
    use drive::control::encoder_offset_angle_from_degrees as angle;
    let od = cmmp();
    assert_eq!(int(&od, 0x6410, 0x11), -8192);
    assert_eq!(angle(-45.0), -8192);
    assert_eq!(angle(-45.0) as u16, 0xE000);
    assert_eq!(angle(180.0), 32767);
    assert_eq!(angle(180.0) as u16, 0x7FFF);
    assert_eq!(angle(-180.0), -32767);
    assert_eq!(angle(0.0), 0);
}

/// CMMP-GAIN-10: 6510h:B0 … B3 = 7Dh, FAh, 1F4h, 3E8h (125, 250, 500, 1000 µs).
#[test]
fn cmmp_gain_10_cycle_times_in_the_dictionary() {
    let od = cmmp();
    assert_eq!(int(&od, 0x6510, 0xB0), 0x7D);
    assert_eq!(int(&od, 0x6510, 0xB1), 0xFA);
    assert_eq!(int(&od, 0x6510, 0xB2), 0x1F4);
    assert_eq!(int(&od, 0x6510, 0xB3), 0x3E8);
}

/// CMMP-GAIN-11: 1018h:01 = 0000001Dh (Festo), 6510h:AC firmware_type = 000000F2h (the
/// manual's seven-digit "00000F2h" corrected).
#[test]
fn cmmp_gain_11_vendor_id_and_firmware_type() {
    let od = cmmp();
    let mut buf = [0u8; 4];
    assert_eq!(od.read(0x1018, 1, &mut buf), Ok(4));
    assert_eq!(buf, [0x1D, 0, 0, 0]);
    assert_eq!(int(&od, 0x6510, 0xAC), 0xF2);
}
