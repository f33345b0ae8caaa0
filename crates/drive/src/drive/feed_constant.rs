//! The factor group of CiA 402 v2 as Nanotec uses it (Nanotec §1.2, §9.38–9.40): user
//! positions from the feed constant 6092h and the gear ratio 6091h (default 2000 units per
//! output revolution, "regardless of step mode"), velocities in units/s, accelerations in
//! units/s², and 6063h in the encoder increments of 608Fh. The CMMP-AS has the older
//! position / velocity / acceleration factors 6093h / 6094h / 6097h instead.

use super::*;
use crate::factor_group::{
    acceleration_factor, position_factor, velocity_factor, TIME_FACTOR_A_PER_SECOND_SQUARED,
    TIME_FACTOR_V_PER_SECOND,
};

/// The factor group of a gear ratio and a feed constant.
fn factor_group(gear: Ratio, feed: Ratio, polarity: u8) -> Option<FactorGroup> {
    Some(FactorGroup {
        position: position_factor(gear, feed).ok()?,
        velocity: velocity_factor(gear, feed, TIME_FACTOR_V_PER_SECOND).ok()?,
        acceleration: acceleration_factor(gear, feed, TIME_FACTOR_A_PER_SECOND_SQUARED).ok()?,
        polarity,
    })
}

/// The feed constant of the defaults (Nanotec §1.2: 2000 units = one output revolution).
const DEFAULT_FEED: Ratio = Ratio::new(2000, 1);

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// The factor group from 6091h and 6092h; the defaults where they break the rules.
    pub(crate) fn feed_constant_factor_group(&self) -> FactorGroup {
        let ratio = |index: u16, dflt: Ratio| {
            Ratio::new(
                self.od
                    .get_unsigned(index, 1)
                    .map_or(dflt.numerator, |v| v as u32),
                self.od
                    .get_unsigned(index, 2)
                    .map_or(dflt.divisor, |v| v as u32),
            )
        };
        let gear = ratio(0x6091, Ratio::new(1, 1));
        let feed = ratio(0x6092, DEFAULT_FEED);
        let polarity = self.od.get_unsigned(0x607E, 0).unwrap_or(0) as u8;
        factor_group(gear, feed, polarity)
            .or_else(|| factor_group(Ratio::new(1, 1), DEFAULT_FEED, polarity))
            .unwrap_or_default()
    }

    /// 6063h in encoder increments (608Fh position encoder resolution; Nanotec §3.4 "raw
    /// encoder position", default 2000 per revolution) from the internal 65536 per revolution.
    pub(crate) fn encoder_position(&self, internal: i64) -> i64 {
        let increments = self.cycle_value(0x608F, 1).max(1);
        let revolutions = self.cycle_value(0x608F, 2).max(1);
        // In i64 when the product and the divisor fit (an i128 division is a library call):
        // both divisions truncate towards zero, so the quotient is the same.
        let v = match (
            internal.checked_mul(increments),
            revolutions.checked_mul(65536),
        ) {
            (Some(n), Some(d)) => i128::from(n / d),
            _ => i128::from(internal) * i128::from(increments) / (i128::from(revolutions) * 65536),
        };
        v.clamp(i128::from(i32::MIN), i128::from(i32::MAX)) as i64
    }
}
