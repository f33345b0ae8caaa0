//! Nanotec with a BLDC motor (Nanotec §1.2 and §11.5: 2004h:07 "Motortyp", 2004h:0C
//! "Hall-Sensor-Modus"): the Hall table, block commutation with the right and a wrong table, the
//! Hall-only position resolution, and a stepper that refuses BLDC.

mod nanotec_rig;

use drive::bldc::{self, BldcData, DB42_HALL_SEQUENCE, DB57_HALL_SEQUENCE};
use drive::drive::DriveSettings;
use drive::vendors::nanotec::units::{hall_mode, HALL_TYPE_1, HALL_TYPE_2};
use nanotec_rig::Rig;
use od::ObjectAccess;

/// A Nanotec with the default (DB57-like) BLDC connected and 2004h:07 = `motor_type`.
fn bldc_rig(motor_type: i8, data: BldcData) -> Rig {
    let mut r = Rig::with(DriveSettings {
        bldc: Some(data),
        ..DriveSettings::default()
    });
    r.w8(0x2004, 7, motor_type);
    r.run_ms(2);
    r
}

/// PP to `target` user units (2000 a revolution), started with 1Fh / 0Fh.
fn move_to(r: &mut Rig, target: i64) {
    r.enable_pp();
    r.w32(0x607A, 0, target);
    r.cw(0x1F);
    r.cw(0x0F);
}

/// NT-SC-07: the DB57 Hall sequence and the type-1 table give 243015h (the default); the
/// type-2 row on the same sequence gives the DB42 value 510342h (§9: "DB47" is DB42).
#[test]
fn nt_sc_07_hall_mode_of_db57_and_db42() {
    assert_eq!(hall_mode(&DB57_HALL_SEQUENCE, &HALL_TYPE_1), Some(0x243015));
    assert_eq!(0x243015, 2_371_605);
    assert_eq!(hall_mode(&DB57_HALL_SEQUENCE, &HALL_TYPE_2), Some(0x510342));
    // The drive's reading of the digits: for each Hall index the table's value.
    for index in 1..=6u8 {
        let i = usize::from(index - 1);
        assert_eq!(
            bldc::commutation_vector(0x243015, index),
            Some(HALL_TYPE_1[i])
        );
        assert_eq!(
            bldc::commutation_vector(0x510342, index),
            Some(HALL_TYPE_2[i])
        );
    }
    assert_eq!(bldc::commutation_vector(0x243015, 0), None);
    assert_eq!(bldc::commutation_vector(0x243015, 7), None);
    let r = Rig::new();
    assert_eq!(r.i(0x2004, 0x0C), 0x243015, "the default");
}

/// The right table turns the DB57 forwards in every sector (sin > 0.8), 510342h does not.
#[test]
fn the_commutation_of_each_sector() {
    let m = BldcData::default();
    let mut backwards = 0;
    for step in 0..240 {
        let angle = f64::from(step) * core::f64::consts::TAU / 240.0 + 1e-6;
        assert!(m.torque_factor(0x243015, angle) > 0.8, "at {angle}");
        if m.torque_factor(0x510342, angle) < 0.0 {
            backwards += 1;
        }
    }
    assert!(
        backwards > 40,
        "the wrong table pulls backwards in some sectors"
    );
}

/// With 2004h:07 = 2 (Hall + encoder) and the default table the BLDC moves to its target
/// in PP, and back.
#[test]
fn pp_with_the_default_table_reaches_the_target() {
    let mut r = bldc_rig(2, BldcData::default());
    move_to(&mut r, 3000);
    assert!(
        r.until_target_reached(5000),
        "target reached, at {}",
        r.position()
    );
    assert!((r.position() - 3000).abs() <= 5, "at {}", r.position());
    move_to(&mut r, -1000);
    assert!(
        r.until_target_reached(5000),
        "target reached, at {}",
        r.position()
    );
    assert!((r.position() + 1000).abs() <= 5, "at {}", r.position());
}

/// Type 1 (Hall only): the position moves in Hall edges, 6 × 4 pole pairs = 24 a turn, and a
/// PP move still ends within one edge of its target.
#[test]
fn hall_only_position_resolution() {
    let mut r = bldc_rig(1, BldcData::default());
    move_to(&mut r, 3000);
    let mut seen = std::collections::BTreeSet::new();
    for _ in 0..800 {
        r.run_ms(5);
        seen.insert(r.d.plant_position());
    }
    // Every position is a whole number of edges (65536 / 24 internal increments each).
    for p in &seen {
        let edges = (*p as f64 * 24.0 / 65536.0).round() as i64;
        assert!((edges * 65536 / 24 - p).abs() <= 1, "{p} is no Hall edge");
    }
    assert!(seen.len() > 10, "it moved through the edges: {seen:?}");
    let edge = 2000 / 24 + 1; // user units per Hall edge
    assert!((r.position() - 3000).abs() <= edge, "at {}", r.position());
}

/// 510342h (the DB42 table) on the DB57: the motor stalls, the target is not reached.
#[test]
fn a_wrong_table_does_not_reach_the_target() {
    let mut r = bldc_rig(2, BldcData::default());
    r.w32(0x2004, 0x0C, 0x510342);
    move_to(&mut r, 6000);
    assert!(!r.until_target_reached(3000), "at {}", r.position());
    // It jerks forward to the first sector boundary (60° electrical = 1/24 turn = 83 units)
    // and stalls there; the following error grows (bit 13).
    assert!((r.position() - 83).abs() <= 2, "at {}", r.position());
    assert_eq!(r.d.plant_velocity_rpm(), 0.0);
    assert_ne!(r.sw() & 0x2000, 0, "following error");
}

/// A DB42-like motor (the other Hall order) runs with 510342h.
#[test]
fn db42_with_its_table_reaches_the_target() {
    let mut r = bldc_rig(
        2,
        BldcData {
            hall_sequence: DB42_HALL_SEQUENCE,
            ..BldcData::default()
        },
    );
    r.w32(0x2004, 0x0C, 0x510342);
    move_to(&mut r, 3000);
    assert!(
        r.until_target_reached(5000),
        "target reached, at {}",
        r.position()
    );
}

/// 2004h:07 = 1 with the stepper connected: the stepper refuses to run (no current).
#[test]
fn bldc_type_with_a_stepper_connected_does_not_turn_it() {
    let mut r = Rig::new();
    r.w8(0x2004, 7, 1);
    r.run_ms(2);
    move_to(&mut r, 3000);
    r.run_ms(2000);
    assert!(
        r.d.plant_position().abs() < 100,
        "at {}",
        r.d.plant_position()
    );
}

/// Velocity mode (6060h = 2, 6042h in user units, 604Ch = 60/2000): 2000 → 60 min⁻¹ with
/// the BLDC too.
#[test]
fn vl_runs_the_bldc_at_its_speed() {
    let mut r = bldc_rig(2, BldcData::default());
    r.enable();
    r.w8(0x6060, 0, 2);
    r.run_ms(5);
    r.d.write(0x6042, 0, &2000i16.to_le_bytes()).unwrap();
    r.run_ms(2000);
    let before = r.d.plant_position();
    r.run_ms(1000);
    let rpm = (r.d.plant_position() - before) as f64 / 65536.0 * 60.0;
    assert!((rpm - 60.0).abs() < 1.0, "{rpm} min⁻¹");
}

/// Torque mode: a BLDC is closed loop (200Ah = 1), 6071h accelerates it to the 607Fh limit.
#[test]
fn torque_mode_runs_the_bldc_to_its_speed_limit() {
    let mut r = bldc_rig(2, BldcData::default());
    assert_eq!(r.i(0x200A, 0), 1, "closed loop");
    r.enable();
    r.w8(0x6060, 0, 4);
    r.run_ms(5);
    assert_eq!(r.i(0x6061, 0), 4);
    r.d.write(0x2004, 1, &[100]).unwrap();
    r.w32(0x607F, 0, 300);
    r.d.write(0x6071, 0, &500i16.to_le_bytes()).unwrap();
    r.run_ms(2000);
    let rpm = r.d.plant_velocity_rpm();
    assert!(rpm > 250.0 && rpm < 310.0, "{rpm} min⁻¹");
}

/// A new 2004h:07 applies once the output stage is off: written in Operation Enabled it
/// waits for the next disable.
#[test]
fn the_motor_type_applies_with_the_output_stage_off() {
    let mut r = bldc_rig(2, BldcData::default());
    r.enable();
    r.w8(0x2004, 7, 0);
    r.run_ms(10);
    assert_eq!(r.i(0x200A, 0), 1, "still the BLDC");
    r.cw(0x0006);
    r.run_ms(10);
    assert_eq!(r.i(0x200A, 0), 0, "type 0 taken");
}

/// Homing method 33 (to the index mark) with the BLDC and its encoder: homing attained.
#[test]
fn homing_to_the_index_mark_with_the_bldc() {
    let mut r = bldc_rig(2, BldcData::default());
    r.enable();
    r.w8(0x6098, 0, 33);
    r.w8(0x6060, 0, 6);
    r.run_ms(5);
    r.cw(0x001F);
    for _ in 0..6000 {
        r.run_ms(1);
        if r.sw() & 0x3000 != 0 {
            break;
        }
    }
    assert_eq!(r.sw() & 0x3000, 0x1000, "attained: {:#06x}", r.sw());
}

/// The largest |current| (A) during a 3000-unit PP move.
fn peak_current_of_a_move(r: &mut Rig) -> f64 {
    r.w32(0x6081, 0, 100_000);
    r.w32(0x6083, 0, 20_000_000);
    r.w32(0x6084, 0, 20_000_000);
    move_to(r, 3000);
    let mut peak: f64 = 0.0;
    for _ in 0..500 {
        r.run_ms(1);
        peak = peak.max(r.d.axis().motor().current().abs());
    }
    peak
}

/// 2004h:01 (20 % of the motor's 1.3 A by default) limits the BLDC's current; 2004h:0D above
/// it (here 60 %) lets it reach the peak for a while (2004h:0E = 500 ms).
#[test]
fn drive_current_and_peak_current_limit_the_bldc() {
    let rated = DriveSettings::default().motor.rated_current;
    let mut r = bldc_rig(2, BldcData::default());
    let plain = peak_current_of_a_move(&mut r);
    assert!(plain <= 0.2 * rated * 1.05, "{plain} A");
    assert!(plain >= 0.2 * rated * 0.8, "{plain} A");
    let mut r = bldc_rig(2, BldcData::default());
    r.w32(0x2004, 0x0D, 60);
    r.w32(0x2004, 0x0E, 500);
    r.run_ms(2);
    let peak = peak_current_of_a_move(&mut r);
    assert!(peak > 0.4 * rated, "{peak} A");
    assert!(peak <= 0.6 * rated * 1.05, "{peak} A");
}

/// Appendix 18.2: 2004h:07 selecting a BLDC loads the BLDC's default load-angle curve into
/// 200Ch:01 … 07 (16384, 16500, 17000 … 19000); back to the stepper (0) the stepper's of
/// 18.1; 1 ↔ 2 (the same BLDC) and a curve written after the type are kept.
#[test]
fn appendix_18_2_bldc_load_angles_follow_the_motor_type() {
    use drive::vendors::nanotec::{BLDC_LOAD_ANGLES, STEPPER_LOAD_ANGLES};
    let curve = |r: &Rig| -> Vec<i64> { (1..=7).map(|n| r.i(0x200C, n)).collect() };
    let mut r = Rig::with(DriveSettings {
        bldc: Some(BldcData::default()),
        ..DriveSettings::default()
    });
    // The dictionary's defaults (§11.13) before any type is chosen.
    assert_eq!(
        curve(&r),
        vec![16384, 17000, 17500, 17750, 18000, 18000, 18000]
    );
    r.w8(0x2004, 7, 1);
    let bldc: Vec<i64> = BLDC_LOAD_ANGLES.iter().map(|a| i64::from(*a)).collect();
    assert_eq!(curve(&r), bldc, "18.2 at 2004h:07 = 1");
    assert_eq!(
        bldc,
        vec![16384, 16500, 17000, 17500, 18000, 18500, 19000],
        "the appendix's values"
    );
    assert_eq!(r.i(0x200C, 8), 18000, "sub 8 is not used and stays");
    r.d.write(0x200C, 3, &17250u16.to_le_bytes()).unwrap();
    r.w8(0x2004, 7, 2);
    assert_eq!(
        r.i(0x200C, 3),
        17250,
        "1 → 2: the same motor family, the curve stays"
    );
    r.w8(0x2004, 7, 0);
    let stepper: Vec<i64> = STEPPER_LOAD_ANGLES.iter().map(|a| i64::from(*a)).collect();
    assert_eq!(curve(&r), stepper, "18.1 back at the stepper");
    // An out-of-range type is refused and changes nothing.
    assert!(r.d.write(0x2004, 7, &[3]).is_err());
    assert_eq!(curve(&r), stepper);
}

/// The long test run (6060h = −1) with a BLDC measures Appendix 18.2's curve.
#[test]
fn the_long_test_run_of_a_bldc_measures_the_bldc_curve() {
    use drive::vendors::nanotec::BLDC_LOAD_ANGLES;
    let mut r = bldc_rig(2, BldcData::default());
    // A curve of its own first: the test run overwrites it.
    r.d.write(0x200C, 2, &20000u16.to_le_bytes()).unwrap();
    r.enable();
    r.w8(0x6060, 0, -1);
    r.run_ms(5);
    r.cw(0x001F);
    r.run_ms(2200);
    assert_ne!(r.sw() & 0x0400, 0, "done");
    for (n, angle) in (1u8..).zip(BLDC_LOAD_ANGLES) {
        assert_eq!(r.i(0x200C, n), i64::from(angle), "200Ch:{n}");
        assert_eq!(r.i(0x2013, n), i64::from(angle), "2013h:{n}");
    }
    assert!(r.i(0x2012, 1) > 0, "the BLDC's rated current");
}

/// Type 1 (Hall only) settles at its PP target: on the target's Hall edge the cascade holds without
/// hunting, so once target reached (bit 10) 6064h stays constant and bit 10 set for the next
/// second, the position on the target's edge (inside 6067h); there and back, and to a second
/// target.
#[test]
fn hall_only_pp_settles_at_the_target() {
    let mut r = bldc_rig(1, BldcData::default());
    for target in [3000, -1000, 2500] {
        move_to(&mut r, target);
        assert!(
            r.until_target_reached(5000),
            "{target}: target reached, at {}",
            r.position()
        );
        let held = r.position();
        assert!(
            (held - target).abs() <= r.i(0x6067, 0),
            "{target}: at {held}"
        );
        for ms in 0..1000 {
            r.run_ms(1);
            assert_eq!(r.position(), held, "{target}: 6064h moved after {ms} ms");
            assert_ne!(r.sw() & 0x0400, 0, "{target}: bit 10 dropped after {ms} ms");
        }
    }
}
