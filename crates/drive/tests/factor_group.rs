//! The CiA 402 factor group (6093h, 6094h, 6097h, 607Eh) in the engine's internal units, checked
//! against the CMMP-AS's worked examples (the vector catalogue kept beside the project §1.7:
//! CMMP-FG-01 … CMMP-FG-17, each named in full at its test; CMMP-FG-18, the CMMP-AS's own
//! 2²⁴ bound, is tested in its vendor folder), plus rounding, round trips, polarity, zero
//! divisors and the INT32 edges. The drive applying them through its dictionary:
//! crates/drive/tests/drive.rs.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drive::factor_group::{
    acceleration_factor, feed_constant, position_factor, velocity_factor, FactorError, FactorGroup,
    FactorObject, Ratio, TIME_FACTOR_A_PER_MINUTE_PER_SECOND, TIME_FACTOR_A_PER_MINUTE_SQUARED,
    TIME_FACTOR_A_PER_SECOND_SQUARED, TIME_FACTOR_V_PER_MINUTE, TIME_FACTOR_V_PER_SECOND,
};
use drive::vendors::festo_cmmp_as::factor_limit::{factor_limit, FACTOR_LIMIT};

const GEAR_1_1: Ratio = Ratio::new(1, 1);
const GEAR_2_3: Ratio = Ratio::new(2, 3);
const GEAR_4_5: Ratio = Ratio::new(4, 5);

/// feed_constant from "units per output revolution" and NK, as column 2 of the tables.
fn feed(per_rev: Ratio, nk: u8) -> Ratio {
    feed_constant(per_rev, nk).expect("feed constant fits")
}

/// 1/10 mm at a feed of 63.15 mm per output revolution: 631.5 (mm/10) per R_OUT.
fn feed_mm_631_5() -> Ratio {
    feed(Ratio::new(6315, 100), 1)
}

fn with_position(r: Ratio) -> FactorGroup {
    FactorGroup {
        position: r,
        ..FactorGroup::DEFAULT
    }
}

fn with_velocity(r: Ratio) -> FactorGroup {
    FactorGroup {
        velocity: r,
        ..FactorGroup::DEFAULT
    }
}

fn with_acceleration(r: Ratio) -> FactorGroup {
    FactorGroup {
        acceleration: r,
        ..FactorGroup::DEFAULT
    }
}

/// Position round trip user → internal → user and the expected internal value.
fn position_both_ways(fg: &FactorGroup, user: i32, internal: i64) {
    assert_eq!(fg.position_to_internal(user), internal, "write {user}");
    assert_eq!(fg.position_from_internal(internal), user, "read {internal}");
}

fn velocity_both_ways(fg: &FactorGroup, user: i32, internal: i64) {
    assert_eq!(fg.velocity_to_internal(user), internal, "write {user}");
    assert_eq!(fg.velocity_from_internal(internal), user, "read {internal}");
    // Magnitude objects (6081h …) use the same factor without polarity.
    let mag = u32::try_from(user).expect("test values are positive");
    assert_eq!(fg.velocity_magnitude_to_internal(mag), internal);
    assert_eq!(fg.velocity_magnitude_from_internal(internal), mag);
}

fn acceleration_both_ways(fg: &FactorGroup, user: u32, internal: i64) {
    assert_eq!(fg.acceleration_to_internal(user), internal, "write {user}");
    assert_eq!(
        fg.acceleration_from_internal(internal),
        user,
        "read {internal}"
    );
}

// ---------------------------------------------------------------------------------------------
// Tab. 5.5: position factor
// ---------------------------------------------------------------------------------------------

/// CMMP-FG-01.
#[test]
fn cmmp_fg_01_position_increments_default() {
    // increments, 0 NK; feed 65536 inc per R_OUT; gear 1/1 → 1/1 (= the default).
    let f = position_factor(GEAR_1_1, feed(Ratio::new(65536, 1), 0)).unwrap();
    assert_eq!(f, Ratio::new(1, 1));
    assert_eq!(FactorGroup::DEFAULT.position, f);
    assert_eq!(FactorGroup::default(), FactorGroup::DEFAULT);
    let fg = with_position(f);
    position_both_ways(&fg, 65536, 65536);
    position_both_ways(&fg, -123_456, -123_456);
    position_both_ways(&fg, i32::MAX, i64::from(i32::MAX));
    position_both_ways(&fg, i32::MIN, i64::from(i32::MIN));
}

/// CMMP-FG-02.
#[test]
fn cmmp_fg_02_position_tenth_degree() {
    // degrees, 1 NK; feed 3600 per R_OUT; gear 1/1 → 65536/3600 → 4096/225.
    let fc = feed(Ratio::new(360, 1), 1);
    assert_eq!(fc, Ratio::new(3600, 1));
    let f = position_factor(GEAR_1_1, fc).unwrap();
    assert_eq!(f, Ratio::new(4096, 225));
    assert_eq!(Ratio::new(65536, 3600).reduced(), f);
    let fg = with_position(f);
    position_both_ways(&fg, 3600, 65536); // 360.0° = one revolution
    position_both_ways(&fg, 900, 16384); // 90.0°
    position_both_ways(&fg, -1800, -32768);
    // 0.1° = 18.204… increments → 18, and back 18 × 225/4096 = 0.989 → 1.
    position_both_ways(&fg, 1, 18);
}

/// CMMP-FG-03.
#[test]
fn cmmp_fg_03_position_hundredth_revolution() {
    // revolutions, 2 NK; feed 100; gear 1/1 → 65536/100 → 16384/25.
    let fc = feed(Ratio::new(1, 1), 2);
    assert_eq!(fc, Ratio::new(100, 1));
    let f = position_factor(GEAR_1_1, fc).unwrap();
    assert_eq!(f, Ratio::new(16384, 25));
    assert_eq!(Ratio::new(65536, 100).reduced(), f);
    let fg = with_position(f);
    position_both_ways(&fg, 100, 65536);
    position_both_ways(&fg, 1, 655); // 655.36 → 655
    position_both_ways(&fg, -250, -163_840);
}

/// CMMP-FG-04.
#[test]
fn cmmp_fg_04_position_hundredth_revolution_gear_2_3() {
    // revolutions, 2 NK; feed 100; gear 2/3 → 131072/300 → 32768/75.
    let f = position_factor(GEAR_2_3, feed(Ratio::new(1, 1), 2)).unwrap();
    assert_eq!(f, Ratio::new(32768, 75));
    assert_eq!(Ratio::new(131072, 300).reduced(), f);
    let fg = with_position(f);
    // 3 output revolutions = 2 motor revolutions.
    position_both_ways(&fg, 300, 131_072);
    position_both_ways(&fg, -300, -131_072);
}

/// CMMP-FG-05.
#[test]
fn cmmp_fg_05_position_tenth_mm_feed_63_15_gear_4_5() {
    // mm, 1 NK; feed 63.15 mm/rev = 631.5; gear 4/5 → 2621440/31575 → 524288/6315.
    let fc = feed_mm_631_5();
    assert_eq!(fc, Ratio::new(1263, 2)); // 631.5 in lowest terms
    let f = position_factor(GEAR_4_5, fc).unwrap();
    assert_eq!(f, Ratio::new(524_288, 6315));
    assert_eq!(Ratio::new(2_621_440, 31_575).reduced(), f);
    // The same with the feed given unreduced as 6315/10.
    assert_eq!(position_factor(GEAR_4_5, Ratio::new(6315, 10)).unwrap(), f);
    let fg = with_position(f);
    // 631.5 mm = 10 output revolutions = 8 motor revolutions.
    position_both_ways(&fg, 6315, 524_288);
    position_both_ways(&fg, -6315, -524_288);
}

// ---------------------------------------------------------------------------------------------
// Tab. 5.7: velocity factor
// ---------------------------------------------------------------------------------------------

/// CMMP-FG-06.
#[test]
fn cmmp_fg_06_velocity_rpm_default() {
    // rpm, 0 NK; feed 1 R_OUT; time factor 4096; gear 1/1 → 4096/1 (= the default).
    let f = velocity_factor(
        GEAR_1_1,
        feed(Ratio::new(1, 1), 0),
        TIME_FACTOR_V_PER_MINUTE,
    )
    .unwrap();
    assert_eq!(f, Ratio::new(4096, 1));
    assert_eq!(FactorGroup::DEFAULT.velocity, f);
    let fg = with_velocity(f);
    velocity_both_ways(&fg, 1, 4096); // §8.8: 1 rpm → 4096 internal
    velocity_both_ways(&fg, 3000, 12_288_000);
}

/// CMMP-FG-07.
#[test]
fn cmmp_fg_07_velocity_hundredth_rpm_gear_2_3() {
    // 1/100 rpm, 2 NK; feed 100; time factor 4096; gear 2/3 → 8192/300 → 2048/75.
    let f = velocity_factor(
        GEAR_2_3,
        feed(Ratio::new(1, 1), 2),
        TIME_FACTOR_V_PER_MINUTE,
    )
    .unwrap();
    assert_eq!(f, Ratio::new(2048, 75));
    assert_eq!(Ratio::new(8192, 300).reduced(), f);
    let fg = with_velocity(f);
    // 75 rpm at the output = 50 rpm at the motor.
    velocity_both_ways(&fg, 7500, 204_800);
}

/// CMMP-FG-08.
#[test]
fn cmmp_fg_08_velocity_tenth_degree_per_second() {
    // 1/10 °/s, 1 NK; feed 3600; 1 s⁻¹ = 60·4096; gear 1/1 → 245760/3600 → 1024/15.
    assert_eq!(TIME_FACTOR_V_PER_SECOND, Ratio::new(60 * 4096, 1));
    let f = velocity_factor(
        GEAR_1_1,
        feed(Ratio::new(360, 1), 1),
        TIME_FACTOR_V_PER_SECOND,
    )
    .unwrap();
    assert_eq!(f, Ratio::new(1024, 15));
    assert_eq!(Ratio::new(245_760, 3600).reduced(), f);
    let fg = with_velocity(f);
    velocity_both_ways(&fg, 3600, 245_760); // 360 °/s = 60 rpm
    velocity_both_ways(&fg, 15, 1024);
}

/// CMMP-FG-09.
#[test]
fn cmmp_fg_09_velocity_tenth_mm_per_second_gear_4_5() {
    // 1/10 mm/s, 1 NK; feed 631.5; 60·4096; gear 4/5 → 1966080/6315 → 131072/421.
    let f = velocity_factor(GEAR_4_5, feed_mm_631_5(), TIME_FACTOR_V_PER_SECOND).unwrap();
    assert_eq!(f, Ratio::new(131_072, 421));
    assert_eq!(Ratio::new(1_966_080, 6315).reduced(), f);
    let fg = with_velocity(f);
    // 631.5 mm/s = 10 output rev/s = 600 rpm output = 480 rpm motor = 1966080 internal.
    velocity_both_ways(&fg, 6315, 1_966_080);
}

// ---------------------------------------------------------------------------------------------
// Tab. 5.9: acceleration factor
// ---------------------------------------------------------------------------------------------

/// CMMP-FG-10.
#[test]
fn cmmp_fg_10_acceleration_rpm_per_second_default() {
    // rpm/s, 0 NK; feed 1 R_OUT; 1 min⁻¹/s = 256; gear 1/1 → 256/1 (= the default).
    let f = acceleration_factor(
        GEAR_1_1,
        feed(Ratio::new(1, 1), 0),
        TIME_FACTOR_A_PER_MINUTE_PER_SECOND,
    )
    .unwrap();
    assert_eq!(f, Ratio::new(256, 1));
    assert_eq!(FactorGroup::DEFAULT.acceleration, f);
    let fg = with_acceleration(f);
    acceleration_both_ways(&fg, 1, 256);
    acceleration_both_ways(&fg, 10_000, 2_560_000); // 6083h default 10000 min⁻¹/s
}

/// CMMP-FG-11.
#[test]
fn cmmp_fg_11_acceleration_tenth_degree_per_second_squared() {
    // 1/10 °/s², 1 NK; feed 3600; 1 s⁻² = 60·256; gear 1/1 → 15360/3600 → 64/15.
    assert_eq!(TIME_FACTOR_A_PER_SECOND_SQUARED, Ratio::new(60 * 256, 1));
    let f = acceleration_factor(
        GEAR_1_1,
        feed(Ratio::new(360, 1), 1),
        TIME_FACTOR_A_PER_SECOND_SQUARED,
    )
    .unwrap();
    assert_eq!(f, Ratio::new(64, 15));
    assert_eq!(Ratio::new(15_360, 3600).reduced(), f);
    let fg = with_acceleration(f);
    acceleration_both_ways(&fg, 3600, 15_360);
    acceleration_both_ways(&fg, 15, 64);
}

/// CMMP-FG-12.
#[test]
fn cmmp_fg_12_acceleration_hundredth_rev_per_minute_squared_gear_2_3() {
    // 1/100 rev/min², 2 NK; feed 100; 1 min⁻² = 256/60; gear 2/3 → 512/18000 → 32/1125.
    assert_eq!(TIME_FACTOR_A_PER_MINUTE_SQUARED, Ratio::new(256, 60));
    let f = acceleration_factor(
        GEAR_2_3,
        feed(Ratio::new(1, 1), 2),
        TIME_FACTOR_A_PER_MINUTE_SQUARED,
    )
    .unwrap();
    assert_eq!(f, Ratio::new(32, 1125));
    assert_eq!(Ratio::new(512, 18_000).reduced(), f);
    let fg = with_acceleration(f);
    // 112.5 rev/min² at the output = 75 rev/min² at the motor = 1.25 rpm/s = 320 internal.
    acceleration_both_ways(&fg, 11_250, 320);
    // The factor is < 1, so user values lose resolution: 100 → 2.84 → 3 → 105.47 → 105,
    // but internal → user → internal is exact.
    assert_eq!(fg.acceleration_to_internal(100), 3);
    assert_eq!(fg.acceleration_from_internal(3), 105);
    assert_eq!(fg.acceleration_to_internal(105), 3);
}

/// CMMP-FG-13.
#[test]
fn cmmp_fg_13_acceleration_tenth_mm_per_second_squared_gear_4_5() {
    // 1/10 mm/s², 1 NK; feed 631.5; 60·256; gear 4/5 → 122880/6315 → 8192/421.
    let f =
        acceleration_factor(GEAR_4_5, feed_mm_631_5(), TIME_FACTOR_A_PER_SECOND_SQUARED).unwrap();
    assert_eq!(f, Ratio::new(8192, 421));
    assert_eq!(Ratio::new(122_880, 6315).reduced(), f);
    let fg = with_acceleration(f);
    // 631.5 mm/s² = 600 rpm/s output = 480 rpm/s motor = 122880 internal.
    acceleration_both_ways(&fg, 6315, 122_880);
}

// ---------------------------------------------------------------------------------------------
// Derived conversion vectors
// ---------------------------------------------------------------------------------------------

/// CMMP-FG-14.
#[test]
fn cmmp_fg_14_write_and_read_target_position_tenth_degree() {
    // 6093h = 4096/225; write 607Ah := 3600 → 65536 increments; reading returns 3600.
    let mut fg = FactorGroup::DEFAULT;
    fg.set_factor(FactorObject::Position, Ratio::new(4096, 225))
        .unwrap();
    let stored = fg.position_to_internal(3600);
    assert_eq!(stored, 65_536);
    assert_eq!(fg.position_from_internal(stored), 3600);
}

/// CMMP-FG-15.
#[test]
fn cmmp_fg_15_write_target_velocity_tenth_degree_per_second() {
    // 6094h = 1024/15; write 60FFh := 3600 (360.0 °/s) → 245760 = 60 rpm × 4096.
    let mut fg = FactorGroup::DEFAULT;
    fg.set_factor(FactorObject::Velocity, Ratio::new(1024, 15))
        .unwrap();
    let stored = fg.velocity_to_internal(3600);
    assert_eq!(stored, 245_760);
    assert_eq!(stored, 60 * 4096);
    assert_eq!(fg.velocity_from_internal(stored), 3600);
}

/// CMMP-FG-16.
#[test]
fn cmmp_fg_16_write_profile_acceleration_tenth_degree_per_second_squared() {
    // 6097h = 64/15; write 6083h := 3600 (360.0 °/s²) → 15360 = 60 rpm/s × 256.
    let mut fg = FactorGroup::DEFAULT;
    fg.set_factor(FactorObject::Acceleration, Ratio::new(64, 15))
        .unwrap();
    let stored = fg.acceleration_to_internal(3600);
    assert_eq!(stored, 15_360);
    assert_eq!(stored, 60 * 256);
    assert_eq!(fg.acceleration_from_internal(stored), 3600);
}

/// CMMP-FG-17.
#[test]
fn cmmp_fg_17_polarity_c0_then_0() {
    // `601: 2F 7E 60 00 C0`: expedited 1-byte download of 607Eh:00 := C0h. (The SDO answer
    // `581: 60 7E 60 00` belongs to the CANopen layer; here the decoded write is applied.)
    let frame = [0x2F_u8, 0x7E, 0x60, 0x00, 0xC0];
    assert_eq!(u16::from_le_bytes([frame[1], frame[2]]), 0x607E);
    assert_eq!(frame[3], 0x00);
    let mut fg = FactorGroup::DEFAULT;
    fg.set_polarity(frame[4]).unwrap();
    assert!(fg.position_inverted() && fg.velocity_inverted());

    // Write 607Ah := 1000 → stored internal target −1000; read 607Ah → 1000.
    let stored = fg.position_to_internal(1000);
    assert_eq!(stored, -1000);
    assert_eq!(fg.position_from_internal(stored), 1000);

    // 607Eh := 0: the stored value is not converted; read 607Ah → −1000.
    fg.set_polarity(0).unwrap();
    assert_eq!(stored, -1000);
    assert_eq!(fg.position_from_internal(stored), -1000);
}

// CMMP-FG-18 (the CMMP-AS's 2²⁴ bound on 6093h / 6094h) is the vendor's rule and is tested
// with it: `drive::vendors::festo_cmmp_as::factor_limit`.

// ---------------------------------------------------------------------------------------------
// Zero divisor, polarity range
// ---------------------------------------------------------------------------------------------

#[test]
fn cia402_bounds_no_quotient() {
    for obj in [
        FactorObject::Position,
        FactorObject::Velocity,
        FactorObject::Acceleration,
    ] {
        assert_eq!(Ratio::new(u32::MAX, 1).check(obj), Ok(()));
        let mut fg = FactorGroup::DEFAULT;
        assert_eq!(fg.set_factor(obj, Ratio::new(0x0100_0001, 1)), Ok(()));
        assert_eq!(fg.factor(obj), Ratio::new(0x0100_0001, 1));
    }
}

#[test]
fn divisor_and_numerator_zero_refused_for_every_object() {
    for obj in [
        FactorObject::Position,
        FactorObject::Velocity,
        FactorObject::Acceleration,
    ] {
        let mut fg = FactorGroup::DEFAULT;
        assert_eq!(
            fg.set_factor(obj, Ratio::new(1, 0)),
            Err(FactorError::DivisorZero(obj))
        );
        assert_eq!(
            fg.set_factor(obj, Ratio::new(0, 0)),
            Err(FactorError::DivisorZero(obj))
        );
        assert_eq!(
            fg.set_factor(obj, Ratio::new(0, 1)),
            Err(FactorError::NumeratorZero(obj))
        );
        assert_eq!(fg, FactorGroup::DEFAULT);
        let mut raw = FactorGroup::DEFAULT;
        match obj {
            FactorObject::Position => raw.position.divisor = 0,
            FactorObject::Velocity => raw.velocity.divisor = 0,
            FactorObject::Acceleration => raw.acceleration.divisor = 0,
        }
        assert_eq!(raw.validate(), Err(FactorError::DivisorZero(obj)));
        let text = format!("{}", FactorError::DivisorZero(obj));
        assert!(text.contains(&format!("{:04X}h", obj.index())), "{text}");
    }
    assert_eq!(FactorObject::Position.index(), 0x6093);
    assert_eq!(FactorObject::Velocity.index(), 0x6094);
    assert_eq!(FactorObject::Acceleration.index(), 0x6097);
}

#[test]
fn validate_reports_the_first_bad_object() {
    let fg = FactorGroup {
        position: Ratio::new(1, 1),
        velocity: Ratio::new(1 << 25, 1),
        acceleration: Ratio::new(1, 0),
        polarity: 0x01,
    };
    // With the CMMP-AS's bound the first bad object is 6094h; CiA 402 bounds none.
    assert_eq!(
        fg.validate_within(factor_limit),
        Err(FactorError::ExceedsLimit(
            FactorObject::Velocity,
            FACTOR_LIMIT
        ))
    );
    assert_eq!(
        fg.validate(),
        Err(FactorError::DivisorZero(FactorObject::Acceleration))
    );
    let fg = FactorGroup {
        velocity: Ratio::new(1, 1),
        ..fg
    };
    assert_eq!(
        fg.validate(),
        Err(FactorError::DivisorZero(FactorObject::Acceleration))
    );
    let fg = FactorGroup {
        acceleration: Ratio::new(1, 1),
        ..fg
    };
    assert_eq!(fg.validate(), Err(FactorError::PolarityReservedBits(0x01)));
    assert_eq!(FactorGroup::DEFAULT.validate(), Ok(()));
}

#[test]
fn polarity_accepts_only_bits_6_and_7() {
    let mut fg = FactorGroup::DEFAULT;
    for p in [0x00, 0x40, 0x80, 0xC0] {
        assert_eq!(fg.set_polarity(p), Ok(()));
        assert_eq!(fg.polarity, p);
    }
    for p in [0x01, 0x20, 0x41, 0xFF] {
        assert_eq!(
            fg.set_polarity(p),
            Err(FactorError::PolarityReservedBits(p))
        );
        assert_eq!(fg.polarity, 0xC0, "refused write keeps the old value");
    }
}

#[test]
fn polarity_flags_are_independent_and_skip_magnitudes_and_acceleration() {
    let base = FactorGroup {
        position: Ratio::new(4096, 225),
        velocity: Ratio::new(1024, 15),
        acceleration: Ratio::new(64, 15),
        polarity: 0,
    };
    // Position flag only.
    let p = FactorGroup {
        polarity: 0x80,
        ..base
    };
    assert_eq!(p.position_to_internal(3600), -65_536);
    assert_eq!(p.position_from_internal(-65_536), 3600);
    assert_eq!(p.position_from_internal(65_536), -3600);
    assert_eq!(p.velocity_to_internal(3600), 245_760);
    assert_eq!(p.position_magnitude_to_internal(3600), 65_536);
    assert_eq!(p.position_magnitude_from_internal(65_536), 3600);
    // Velocity flag only.
    let v = FactorGroup {
        polarity: 0x40,
        ..base
    };
    assert_eq!(v.position_to_internal(3600), 65_536);
    assert_eq!(v.velocity_to_internal(3600), -245_760);
    assert_eq!(v.velocity_from_internal(-245_760), 3600);
    assert_eq!(v.velocity_magnitude_to_internal(3600), 245_760);
    assert_eq!(v.velocity_magnitude_from_internal(245_760), 3600);
    // Acceleration never changes sign.
    for fg in [
        base,
        p,
        v,
        FactorGroup {
            polarity: 0xC0,
            ..base
        },
    ] {
        assert_eq!(fg.acceleration_to_internal(3600), 15_360);
        assert_eq!(fg.acceleration_from_internal(15_360), 3600);
    }
    // Polarity negates exactly, including on rounded values.
    let both = FactorGroup {
        polarity: 0xC0,
        ..base
    };
    for x in [-7, -1, 0, 1, 2, 13, 12_345, i32::MAX] {
        assert_eq!(both.position_to_internal(x), -base.position_to_internal(x));
        assert_eq!(both.velocity_to_internal(x), -base.velocity_to_internal(x));
        let i = i64::from(x) * 3;
        assert_eq!(
            both.position_from_internal(i),
            -base.position_from_internal(i)
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Rounding, round trips
// ---------------------------------------------------------------------------------------------

#[test]
fn rounding_is_to_nearest_ties_away_from_zero() {
    let half = Ratio::new(1, 2);
    assert_eq!(half.scale(1), Some(1)); // 0.5 → 1
    assert_eq!(half.scale(-1), Some(-1)); // −0.5 → −1
    assert_eq!(half.scale(3), Some(2)); // 1.5 → 2
    assert_eq!(half.scale(-3), Some(-2));
    assert_eq!(half.scale(5), Some(3)); // 2.5 → 3 (not banker's 2)
    let third = Ratio::new(1, 3);
    assert_eq!(third.scale(1), Some(0)); // 0.33 → 0
    assert_eq!(third.scale(2), Some(1)); // 0.67 → 1
    assert_eq!(third.scale(-2), Some(-1));
    let two = Ratio::new(2, 1);
    assert_eq!(two.unscale(1), Some(1)); // 0.5 → 1
    assert_eq!(two.unscale(-1), Some(-1));
    assert_eq!(two.unscale(-3), Some(-2)); // −1.5 → −2

    let fg = with_position(half);
    assert_eq!(fg.position_to_internal(5), 3);
    assert_eq!(fg.position_to_internal(-5), -3);
    let fg = with_position(two);
    assert_eq!(fg.position_from_internal(5), 3);
    assert_eq!(fg.position_from_internal(-5), -3);
}

/// The manual's factors (Tab. 5.5, 5.7, 5.9).
const MANUAL_FACTORS: [Ratio; 13] = [
    Ratio::new(1, 1),
    Ratio::new(4096, 225),
    Ratio::new(16384, 25),
    Ratio::new(32768, 75),
    Ratio::new(524_288, 6315),
    Ratio::new(4096, 1),
    Ratio::new(2048, 75),
    Ratio::new(1024, 15),
    Ratio::new(131_072, 421),
    Ratio::new(256, 1),
    Ratio::new(64, 15),
    Ratio::new(32, 1125),
    Ratio::new(8192, 421),
];

/// Deterministic sample of i32 values: edges plus an LCG.
fn samples() -> Vec<i32> {
    let mut v = vec![
        0,
        1,
        -1,
        2,
        -2,
        7,
        -7,
        1000,
        -1000,
        i32::MAX,
        i32::MIN,
        i32::MAX - 1,
        i32::MIN + 1,
    ];
    let mut s: u64 = 0x2545_F491_4F6C_DD1D;
    for _ in 0..2000 {
        s = s
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let x = (s >> 32) as u32 as i32;
        v.push(x);
        v.push(x >> 12); // smaller magnitudes too
    }
    v
}

#[test]
fn round_trip_user_internal_user_for_factors_at_least_one() {
    for f in MANUAL_FACTORS.iter().filter(|f| f.numerator >= f.divisor) {
        for polarity in [0x00, 0xC0] {
            let fg = FactorGroup {
                position: *f,
                velocity: *f,
                acceleration: *f,
                polarity,
            };
            for &x in &samples() {
                assert_eq!(
                    fg.position_from_internal(fg.position_to_internal(x)),
                    x,
                    "{f:?} {x}"
                );
                assert_eq!(
                    fg.velocity_from_internal(fg.velocity_to_internal(x)),
                    x,
                    "{f:?} {x}"
                );
                let m = x.unsigned_abs();
                assert_eq!(
                    fg.acceleration_from_internal(fg.acceleration_to_internal(m)),
                    m,
                    "{f:?} {m}"
                );
            }
        }
    }
}

#[test]
fn round_trip_internal_user_internal_for_factors_at_most_one() {
    let small = [
        Ratio::new(1, 1),
        Ratio::new(32, 1125),
        Ratio::new(1, 3),
        Ratio::new(7, 1_000_000),
    ];
    assert!(MANUAL_FACTORS.contains(&small[1]));
    for f in small {
        let fg = FactorGroup {
            position: f,
            acceleration: f,
            ..FactorGroup::DEFAULT
        };
        for &x in &samples() {
            let i = i64::from(x);
            // Only internal values whose user value fits INT32 can round-trip.
            let u = fg.position_from_internal(i);
            if u != i32::MAX && u != i32::MIN {
                assert_eq!(fg.position_to_internal(u), i, "{f:?} {i}");
            }
            let m = i64::from(x.unsigned_abs());
            let a = fg.acceleration_from_internal(m);
            if a != u32::MAX {
                assert_eq!(fg.acceleration_to_internal(a), m, "{f:?} {m}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// INT32 / UINT32 edges, saturation, overflow
// ---------------------------------------------------------------------------------------------

#[test]
fn reads_saturate_at_the_int32_edges() {
    let fg = FactorGroup::DEFAULT;
    let max = i64::from(i32::MAX);
    let min = i64::from(i32::MIN);
    assert_eq!(fg.position_from_internal(max), i32::MAX);
    assert_eq!(fg.position_from_internal(max + 1), i32::MAX);
    assert_eq!(fg.position_from_internal(i64::MAX), i32::MAX);
    assert_eq!(fg.position_from_internal(min), i32::MIN);
    assert_eq!(fg.position_from_internal(min - 1), i32::MIN);
    assert_eq!(fg.position_from_internal(i64::MIN), i32::MIN);
    // Velocity default 4096/1: 2^31 rpm would need 2^43 internal.
    assert_eq!(fg.velocity_from_internal(max * 4096), i32::MAX);
    assert_eq!(fg.velocity_from_internal(max * 4096 + 4096), i32::MAX);
    assert_eq!(fg.velocity_from_internal(min * 4096), i32::MIN);
    assert_eq!(fg.velocity_from_internal(i64::MIN), i32::MIN);
    // UINT32 objects saturate at 0 and u32::MAX.
    assert_eq!(fg.acceleration_from_internal(-256), 0);
    assert_eq!(fg.acceleration_from_internal(i64::MAX), u32::MAX);
    assert_eq!(fg.position_magnitude_from_internal(-1), 0);
    assert_eq!(fg.velocity_magnitude_from_internal(i64::MAX), u32::MAX);
    // A fine user unit: 1 increment = 1000 user units; 2^31 increments no longer fit.
    let fine = with_position(Ratio::new(1, 1000));
    assert_eq!(fine.position_from_internal(2_147_483), 2_147_483_000);
    assert_eq!(fine.position_from_internal(2_147_484), i32::MAX);
    assert_eq!(fine.position_from_internal(-2_147_484), i32::MIN);
}

#[test]
fn polarity_at_int32_min() {
    let fg = FactorGroup {
        polarity: 0xC0,
        ..FactorGroup::DEFAULT
    };
    // −(−2^31) = 2^31 does not fit INT32 but is fine internally, and reads back exactly.
    assert_eq!(fg.position_to_internal(i32::MIN), 1 << 31);
    assert_eq!(fg.position_from_internal(1 << 31), i32::MIN);
    // The mirror image saturates: internal −2^31 reads as +2^31 → i32::MAX.
    assert_eq!(fg.position_from_internal(-(1 << 31)), i32::MAX);
    assert_eq!(fg.velocity_to_internal(i32::MIN), (1_i64 << 31) * 4096);
    assert_eq!(fg.velocity_from_internal((1_i64 << 31) * 4096), i32::MIN);
}

#[test]
fn writes_at_the_largest_factors_do_not_overflow() {
    let top = with_position(Ratio::new(FACTOR_LIMIT, 1));
    assert_eq!(top.validate(), Ok(()));
    assert_eq!(
        top.position_to_internal(i32::MAX),
        i64::from(i32::MAX) << 24
    );
    assert_eq!(
        top.position_to_internal(i32::MIN),
        i64::from(i32::MIN) << 24
    );
    assert_eq!(
        top.position_from_internal(i64::from(i32::MAX) << 24),
        i32::MAX
    );
    assert_eq!(
        top.position_from_internal(i64::from(i32::MIN) << 24),
        i32::MIN
    );
    // 6097h has no limit: u32::MAX × u32::MAX exceeds i64 and saturates.
    let acc = with_acceleration(Ratio::new(u32::MAX, 1));
    assert_eq!(acc.validate(), Ok(()));
    assert_eq!(acc.acceleration_to_internal(u32::MAX), i64::MAX);
    assert_eq!(acc.acceleration_to_internal(1), i64::from(u32::MAX));
    // Even an unvalidated u32::MAX/1 position factor stays within i64 for INT32 input.
    let raw = with_position(Ratio::new(u32::MAX, 1));
    assert_eq!(
        raw.position_to_internal(i32::MIN),
        i64::from(i32::MIN) * i64::from(u32::MAX)
    );
}

#[test]
fn ratio_scale_reports_overflow_and_zero() {
    assert_eq!(Ratio::new(2, 1).scale(i64::MAX), None);
    assert_eq!(Ratio::new(1, 2).unscale(i64::MIN), None);
    assert_eq!(Ratio::new(1, 0).scale(5), None);
    assert_eq!(Ratio::new(0, 1).unscale(5), None);
    assert_eq!(Ratio::new(1, 1).scale(i64::MIN), Some(i64::MIN));
    assert_eq!(Ratio::new(3, 3).unscale(i64::MAX), Some(i64::MAX));
}

#[test]
fn unvalidated_zero_factors_saturate_instead_of_panicking() {
    let fg = FactorGroup {
        position: Ratio::new(1, 0),
        velocity: Ratio::new(0, 1),
        acceleration: Ratio::new(0, 0),
        polarity: 0,
    };
    assert_eq!(fg.position_to_internal(5), i64::MAX);
    assert_eq!(fg.position_to_internal(-5), i64::MIN);
    assert_eq!(fg.position_to_internal(0), 0);
    assert_eq!(fg.position_from_internal(5), 0);
    assert_eq!(fg.velocity_to_internal(5), 0);
    assert_eq!(fg.velocity_from_internal(5), i32::MAX);
    assert_eq!(fg.velocity_from_internal(-5), i32::MIN);
    assert_eq!(fg.acceleration_to_internal(5), i64::MAX);
    assert_eq!(fg.acceleration_from_internal(5), u32::MAX);
    assert_eq!(fg.acceleration_from_internal(-5), 0);
}

// ---------------------------------------------------------------------------------------------
// Factor helper edge cases
// ---------------------------------------------------------------------------------------------

#[test]
fn helper_refuses_bad_descriptions() {
    let fc = Ratio::new(3600, 1);
    assert_eq!(
        position_factor(Ratio::new(0, 1), fc),
        Err(FactorError::NumeratorZero(FactorObject::Position))
    );
    assert_eq!(
        position_factor(Ratio::new(1, 0), fc),
        Err(FactorError::DivisorZero(FactorObject::Position))
    );
    assert_eq!(
        velocity_factor(GEAR_1_1, Ratio::new(0, 1), TIME_FACTOR_V_PER_MINUTE),
        Err(FactorError::DivisorZero(FactorObject::Velocity))
    );
    // 1000:1 gear on increments: 65536000, unbounded in CiA 402 (the CMMP-AS's 2²⁴ is
    // checked with its vendor).
    assert_eq!(
        position_factor(Ratio::new(1000, 1), Ratio::new(1, 1)),
        Ok(Ratio::new(65_536_000, 1))
    );
    // 256:1 gear is exactly 2^24.
    assert_eq!(
        position_factor(Ratio::new(256, 1), Ratio::new(1, 1)),
        Ok(Ratio::new(1 << 24, 1))
    );
    // Two large primes: the reduced fraction needs more than 32 bits.
    let gear = Ratio::new(4_294_967_291, 4_294_967_279);
    assert_eq!(
        position_factor(gear, Ratio::new(1, 1)),
        Err(FactorError::NotRepresentable(FactorObject::Position))
    );
    assert_eq!(
        acceleration_factor(gear, Ratio::new(1, 1), TIME_FACTOR_A_PER_MINUTE_SQUARED),
        Err(FactorError::NotRepresentable(FactorObject::Acceleration))
    );
}

#[test]
fn feed_constant_scales_by_ten_to_the_nk() {
    assert_eq!(
        feed_constant(Ratio::new(360, 1), 1),
        Some(Ratio::new(3600, 1))
    );
    assert_eq!(
        feed_constant(Ratio::new(360, 1), 0),
        Some(Ratio::new(360, 1))
    );
    assert_eq!(
        feed_constant(Ratio::new(6315, 100), 1),
        Some(Ratio::new(1263, 2))
    );
    assert_eq!(
        feed_constant(Ratio::new(6315, 100), 2),
        Some(Ratio::new(6315, 1))
    );
    assert_eq!(feed_constant(Ratio::new(1, 0), 1), None);
    assert_eq!(feed_constant(Ratio::new(u32::MAX, 1), 1), None);
    assert_eq!(feed_constant(Ratio::new(1, 1), 40), None);
    assert_eq!(
        feed_constant(Ratio::new(1, 1_000_000_000), 9),
        Some(Ratio::new(1, 1))
    );
}

#[test]
fn reduced_matches_manual_and_edge_cases() {
    assert_eq!(Ratio::new(0, 0).reduced(), Ratio::new(0, 0));
    assert_eq!(Ratio::new(0, 7).reduced(), Ratio::new(0, 1));
    assert_eq!(Ratio::new(7, 0).reduced(), Ratio::new(1, 0));
    assert_eq!(Ratio::new(u32::MAX, u32::MAX).reduced(), Ratio::new(1, 1));
    // Every printed result is already in lowest terms.
    for f in MANUAL_FACTORS {
        assert_eq!(f.reduced(), f);
    }
}
