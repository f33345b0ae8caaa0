//! The CMMP-AS's bound on its factor group (§5.3): "position_factor must not exceed 2²⁴"
//! (L2504) and "velocity_encoder_factor must not exceed 2²⁴" (L2573). The *quotient*
//! numerator / divisor is bounded, so 2²⁴ itself is allowed and 01000001h/2 is allowed,
//! 01000001h/1 is not (vector CMMP-FG-18). The manual prints no bound for
//! acceleration_factor (L2641–2645), so 6097h has none. CiA 402 bounds none of the three
//! (`crate::factor_group`).

use crate::factor_group::FactorObject;

/// The bound (inclusive) on position_factor and velocity_encoder_factor (L2504, L2573).
pub const FACTOR_LIMIT: u32 = 1 << 24;

/// The bound on the quotient of `object`'s factor: 2²⁴ for 6093h and 6094h, none for 6097h.
pub const fn factor_limit(object: FactorObject) -> Option<u32> {
    match object {
        FactorObject::Position | FactorObject::Velocity => Some(FACTOR_LIMIT),
        FactorObject::Acceleration => None,
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::factor_group::{position_factor, FactorError, FactorGroup, Ratio};
    use std::format;

    /// CMMP-FG-18.
    #[test]
    fn cmmp_fg_18_position_factor_above_2_pow_24_rejected() {
        // 6093h:01 := 01000001h with 6093h:02 = 1 → rejected (factor > 2²⁴).
        let object = FactorObject::Position;
        let mut fg = FactorGroup::DEFAULT;
        let result = fg.set_factor_within(object, Ratio::new(0x0100_0001, 1), factor_limit(object));
        let err = FactorError::ExceedsLimit(object, FACTOR_LIMIT);
        assert_eq!(result, Err(err));
        assert_eq!(fg, FactorGroup::DEFAULT, "a refused write changes nothing");
        let text = format!("{err}");
        assert!(
            text.contains("6093h") && text.contains("position_factor"),
            "{text}"
        );
        let raw = FactorGroup {
            position: Ratio::new(0x0100_0001, 1),
            ..FactorGroup::DEFAULT
        };
        assert_eq!(raw.validate_within(factor_limit), Err(err));
        // CiA 402 bounds no quotient.
        assert_eq!(raw.validate(), Ok(()));
    }

    #[test]
    fn limit_is_on_the_quotient_and_inclusive() {
        assert_eq!(FACTOR_LIMIT, 1 << 24);
        let check = |r: Ratio, obj: FactorObject| r.check_within(obj, factor_limit(obj));
        for obj in [FactorObject::Position, FactorObject::Velocity] {
            assert_eq!(
                check(Ratio::new(1 << 24, 1), obj),
                Ok(()),
                "2^24 itself is allowed"
            );
            assert_eq!(check(Ratio::new(0x0100_0001, 2), obj), Ok(()));
            assert_eq!(
                check(Ratio::new(u32::MAX, 255), obj),
                Err(FactorError::ExceedsLimit(obj, FACTOR_LIMIT))
            );
            assert_eq!(check(Ratio::new(u32::MAX, 256), obj), Ok(()));
            assert_eq!(
                check(Ratio::new(0x0100_0001, 1), obj),
                Err(FactorError::ExceedsLimit(obj, FACTOR_LIMIT))
            );
        }
        // The CANopen tests write 6093h = 12345678h / 13h: 16074731 ≤ 2^24.
        assert_eq!(
            check(Ratio::new(0x1234_5678, 0x13), FactorObject::Position),
            Ok(()),
            "CMMP-SDO-05 (6093h:01), CMMP-SDO-06 (6093h:02)"
        );
        // 6097h has no printed limit.
        assert_eq!(
            check(Ratio::new(u32::MAX, 1), FactorObject::Acceleration),
            Ok(())
        );
        let text = format!(
            "{}",
            FactorError::ExceedsLimit(FactorObject::Velocity, FACTOR_LIMIT)
        );
        assert!(text.contains("6094h") && text.contains("2^24"), "{text}");
    }

    #[test]
    fn a_unit_description_beyond_the_bound_is_refused() {
        // 1000:1 gear on increments: 65536000 > 2^24 (CiA 402 takes it).
        let f = position_factor(Ratio::new(1000, 1), Ratio::new(1, 1));
        assert_eq!(f, Ok(Ratio::new(65_536_000, 1)));
        assert_eq!(
            Ratio::new(65_536_000, 1)
                .check_within(FactorObject::Position, factor_limit(FactorObject::Position)),
            Err(FactorError::ExceedsLimit(
                FactorObject::Position,
                FACTOR_LIMIT
            ))
        );
        // 256:1 gear is exactly 2^24 and allowed.
        assert_eq!(
            Ratio::new(1 << 24, 1)
                .check_within(FactorObject::Position, factor_limit(FactorObject::Position)),
            Ok(())
        );
    }
}
