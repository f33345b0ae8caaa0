//! Nanotec units, scaling and velocity mode (Nanotec §1.2, ch. 6): the NT-SC vectors of the
//! catalogue of the manuals' worked examples kept beside the project.

mod nanotec_rig;

use drive::vendors::nanotec::units::{
    encoder_increments, hall_mode, load_angle_spacing_rpm, max_acceleration, max_velocity,
    step_angle_deg, torque_current_ma, HALL_TYPE_1, HALL_TYPE_2, STEP_MODES,
};
use drive::vendors::nanotec::NANOTEC;
use nanotec_rig::Rig;
use od::ObjectAccess;

const INC_PER_REV: i64 = 65536;

/// NT-SC-01: with the default feed constant 2000/1 a target of 2000 is exactly one turn of
/// the output shaft (and again after the step mode changes: the feed does not depend on it).
#[test]
fn nt_sc_01_feed_constant_2000_is_one_revolution() {
    let mut r = Rig::new();
    assert_eq!((r.i(0x6092, 1), r.i(0x6092, 2)), (2000, 1));
    r.enable_pp();
    let before = r.d.plant_position();
    r.w32(0x607A, 0, 2000);
    r.cw(0x001F);
    r.cw(0x000F);
    assert!(r.until_target_reached(5000));
    let moved = r.d.plant_position() - before;
    assert!((moved - INC_PER_REV).abs() < 400, "{moved} increments");
    assert_eq!(r.d.factor_group().position_to_internal(2000), INC_PER_REV);
}

/// NT-SC-02: a 500-line encoder gives 608Fh = 2000 increments per revolution (the default);
/// 6063h counts them: one revolution is 2000.
#[test]
fn nt_sc_02_encoder_resolution() {
    assert_eq!(encoder_increments(500), 2000);
    let mut r = Rig::new();
    assert_eq!((r.i(0x608F, 1), r.i(0x608F, 2)), (2000, 1));
    r.enable_pp();
    let before = r.i(0x6063, 0);
    r.w32(0x607A, 0, 2000);
    r.cw(0x001F);
    r.cw(0x000F);
    assert!(r.until_target_reached(5000));
    assert!(
        (r.i(0x6063, 0) - before - 2000).abs() <= 2,
        "{}",
        r.i(0x6063, 0)
    );
}

/// NT-SC-03: 50 pole pairs → 1.8°, 100 → 0.9°; 2006h sets the stepper's full steps at the
/// next power-on (reload), and 2000 units stay one revolution.
#[test]
fn nt_sc_03_step_angle_from_pole_pairs() {
    assert_eq!(step_angle_deg(50), 1.8);
    assert_eq!(step_angle_deg(100), 0.9);
    let mut r = Rig::new();
    assert_eq!(r.i(0x2006, 0), 50);
    assert_eq!(r.d.stepper().unwrap().data().full_steps_per_rev, 200);
    r.d.write(0x2006, 0, &100u16.to_le_bytes()).unwrap();
    r.d.reload();
    assert_eq!(
        r.d.stepper().unwrap().data().full_steps_per_rev,
        400,
        "0.9°"
    );
    r.enable_pp();
    let before = r.d.plant_position();
    r.w32(0x607A, 0, 2000);
    r.cw(0x001F);
    r.cw(0x000F);
    assert!(r.until_target_reached(5000));
    let moved = r.d.plant_position() - before;
    assert!((moved - INC_PER_REV).abs() < 400, "{moved} increments");
    assert_eq!(r.d.stepper().unwrap().lost_steps(), 0);
}

/// NT-SC-04: the §1.2 table: feed 200 × micro-steps (doubled for 0.9°), velocity at 4800
/// min⁻¹ (1.8°) or 2400 min⁻¹ (0.9°), acceleration 100 × velocity.
#[test]
fn nt_sc_04_step_mode_limits_table() {
    let feeds: Vec<u32> = STEP_MODES.iter().map(|m| m.feed_1_8).collect();
    assert_eq!(feeds, [200, 400, 800, 1000, 1600, 2000, 3200, 6400, 12800]);
    for m in STEP_MODES {
        assert_eq!(m.feed_1_8, 200 * m.microsteps, "{}", m.name);
        assert_eq!(m.feed_0_9, 2 * m.feed_1_8, "{}", m.name);
        assert_eq!(
            m.max_velocity,
            max_velocity(50, m.microsteps, 4800),
            "{}",
            m.name
        );
        assert_eq!(
            m.max_velocity,
            max_velocity(100, m.microsteps, 2400),
            "{}",
            m.name
        );
        assert_eq!(
            m.max_acceleration,
            max_acceleration(m.max_velocity),
            "{}",
            m.name
        );
    }
    assert_eq!(STEP_MODES[0].max_velocity, 16_000);
    assert_eq!(STEP_MODES[8].max_velocity, 1_024_000);
    assert_eq!(STEP_MODES[8].max_acceleration, 102_400_000);
}

/// NT-SC-05: 604Ch = 60/2000, VL target 2000 → 60 min⁻¹ (one turn per second).
#[test]
fn nt_sc_05_vl_dimension_factor() {
    let mut r = Rig::new();
    assert_eq!((r.i(0x604C, 1), r.i(0x604C, 2)), (60, 2000));
    r.enable();
    r.w8(0x6060, 0, 2);
    r.run_ms(5);
    r.d.write(0x6042, 0, &2000i16.to_le_bytes()).unwrap();
    r.run_ms(3000);
    // The mean speed over a second (a micro-stepped rotor's instantaneous speed ripples).
    let before = r.d.plant_position();
    r.run_ms(1000);
    let rpm = (r.d.plant_position() - before) as f64 / 65536.0 * 60.0;
    assert!((rpm - 60.0).abs() < 0.5, "{rpm} min⁻¹");
    assert_eq!(r.i(0x6043, 0), 2000, "6043h demand in user units");
}

/// NT-SC-06: SMCI47-S, 7.5 A rated, 2004h:01 = 20 %, 6071h = 500 → 0.75 A.
#[test]
fn nt_sc_06_torque_current() {
    assert_eq!(torque_current_ma(500, 20, 7500), 750.0);
    let r = Rig::new();
    assert_eq!(r.i(0x2004, 1), 20, "2004h:01 default 20 %");
}

/// The DB57 Hall sequence of the manual's worked example (H1, H2, H3).
const DB57: [(u8, u8, u8); 6] = [
    (0, 0, 1),
    (0, 1, 1),
    (0, 1, 0),
    (1, 1, 0),
    (1, 0, 0),
    (1, 0, 1),
];

/// NT-SC-07: the type-1 table on the DB57 sequence gives 243015h, the 2004h:0C default.
#[test]
fn nt_sc_07_hall_mode_db57() {
    assert_eq!(hall_mode(&DB57, &HALL_TYPE_1), Some(0x243015));
    assert_eq!(0x243015, 2_371_605);
    let r = Rig::new();
    assert_eq!(r.i(0x2004, 0x0C), 0x243015);
}

/// NT-SC-08: the type-2 table on the same sequence gives 510342h, the DB42 value of §1.2.
#[test]
fn nt_sc_08_hall_mode_type_2_is_db42() {
    assert_eq!(hall_mode(&DB57, &HALL_TYPE_2), Some(0x510342));
}

/// NT-SC-09: 2004h:08 = 8192 → 1000 min⁻¹; 4096 (default) → 500 min⁻¹.
#[test]
fn nt_sc_09_load_angle_spacing() {
    assert_eq!(load_angle_spacing_rpm(8192), 1000.0);
    assert_eq!(load_angle_spacing_rpm(4096), 500.0);
    let r = Rig::new();
    assert_eq!(r.i(0x2004, 8), 4096);
}

/// NT-SC-10: 6502h = 6Bh (PP, VL, TQ, HM, IP; no PV), from the personality's modes and in
/// the device file; 6060h = 3 (PV) is refused.
#[test]
fn nt_sc_10_supported_drive_modes() {
    assert_eq!(NANOTEC.supported_drive_modes(false), 0x6B);
    let mut r = Rig::new();
    assert_eq!(r.i(0x6502, 0), 0x6B);
    assert_eq!(
        r.sdo(&[0x2F, 0x60, 0x60, 0x00, 0x03]),
        [0x80, 0x60, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06]
    );
}

/// NT-SC-11: 6046h min 30, max 1000; target 10 → 30, 0 → stop, 2000 → 1000 with bit 11.
#[test]
fn nt_sc_11_vl_min_max_clamping() {
    let mut r = Rig::new();
    r.enable();
    r.w8(0x6060, 0, 2);
    r.w32(0x6046, 1, 30);
    r.w32(0x6046, 2, 1000);
    r.run_ms(5);
    let target = |r: &mut Rig, v: i16| {
        r.d.write(0x6042, 0, &v.to_le_bytes()).unwrap();
        r.run_ms(2000);
        (r.i(0x6043, 0), r.sw() & 0x0800 != 0)
    };
    assert_eq!(target(&mut r, 10), (30, false));
    assert_eq!(target(&mut r, 0), (0, false));
    assert!(f64::from(r.d.plant_velocity_rpm()).abs() < 0.5, "stopped");
    assert_eq!(target(&mut r, 2000), (1000, true));
    assert_eq!(target(&mut r, -2000), (-1000, true));
    assert_eq!(
        target(&mut r, 500),
        (500, false),
        "bit 11 clears inside the range"
    );
}

/// §6.1: halt brakes with 6049h and its falling edge accelerates again; a quick stop brakes
/// with 604Ah and ends in Switch On Disabled.
#[test]
fn vl_halt_and_quick_stop() {
    let mut r = Rig::new();
    r.enable();
    r.w8(0x6060, 0, 2);
    r.run_ms(5);
    r.d.write(0x6042, 0, &2000i16.to_le_bytes()).unwrap();
    r.run_ms(2000);
    assert_eq!(r.i(0x6043, 0), 2000);
    r.cw(0x010F);
    r.run_ms(2000);
    assert_eq!(r.i(0x6043, 0), 0, "halted");
    r.cw(0x000F);
    r.run_ms(2000);
    assert_eq!(r.i(0x6043, 0), 2000, "running again");
    r.cw(0x000B);
    r.run_ms(1000);
    assert_eq!(
        r.sw() & 0x004F,
        0x0040,
        "Switch On Disabled after the quick stop"
    );
}
