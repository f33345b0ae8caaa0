//! Kinco position limits after homing (§7 Tab. 5-8 / 8-2, Error_State2 bits 9 and 10, lines
//! L1189-1191, L1976-1977 of the manual's text kept beside the project): "Positive limit (after
//! homing): the position limit raises the error only when Limit_Function 2010h:19 is 0", likewise
//! "Negative limit"; the Position Limit output (Tab. 6-2) shows "the position-limit function is
//! active".
//!
//! Decisions (the manual names the errors but not the limits' objects nor what happens
//! without the error):
//! - the limits are CiA 402's software position limits 607Dh:01 (negative) / :02 (positive),
//!   in Pos_Actual's increments, as the sibling FD manuals have them (EXT); both 0 = no limit
//!   (CiA 402), and they act only once the drive is homed ("after homing": statusword bit 15);
//! - Limit_Function = 0: the actual position crossing a limit from inside raises Positive /
//!   Negative limit (5442h / 5441h), and the drive reacts as to every error it shows (output
//!   stage off, `kinco_drive.rs`); Error_Mask2 2605h:04 bits 9 / 10 = 0 ignore it;
//! - beyond a limit, with any Limit_Function, the direction further out is blocked as a
//!   limit switch blocks it (velocity 0, torque 0, a move stopped with Profile_Dec), so that
//!   after the error is reset the master moves the axis back in; Limit_Function ≠ 0 only
//!   blocks ("presumably", the extract's §9.1 item 10). The error is raised again only on the next
//!   crossing from inside;
//! - jog (F006) ignores the limits as it ignores the limit switches ("independent of other
//!   settings").

use super::hooks::Kinco;
use crate::drive::Drive;

/// Positive limit, Error_State2 bit 9.
pub const POSITIVE_LIMIT: u16 = 0x5442;
/// Negative limit, Error_State2 bit 10.
pub const NEGATIVE_LIMIT: u16 = 0x5441;

/// Where the actual position is against the limits, at the last logic cycle.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct LimitState {
    /// Beyond the negative limit (below 607Dh:01).
    pub(crate) below: bool,
    /// Beyond the positive limit (above 607Dh:02).
    pub(crate) above: bool,
}

/// Which side of the limits `position` is on: (below min, above max); `(false, false)`
/// with min = max = 0 (no limits).
pub fn beyond(position: i64, min: i64, max: i64) -> (bool, bool) {
    if (min, max) == (0, 0) {
        return (false, false);
    }
    (position < min, position > max)
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Kinco> {
    /// The limits at Pos_Actual 6063h now: (below, above); none before homing.
    fn kinco_position_beyond(&self) -> (bool, bool) {
        if !self.referenced {
            return (false, false);
        }
        beyond(
            self.value(0x6063, 0),
            self.value(0x607D, 0x01),
            self.value(0x607D, 0x02),
        )
    }

    /// One logic cycle: a crossing raises its error where Limit_Function is 0.
    pub(crate) fn kinco_position_limits_cycle(&mut self) {
        let (below, above) = self.kinco_position_beyond();
        let before = self.vendor.limits;
        self.vendor.limits = LimitState { below, above };
        if self.cycle_value(0x2010, 0x19) != 0 {
            return;
        }
        for (now, was, code) in [
            (above, before.above, POSITIVE_LIMIT),
            (below, before.below, NEGATIVE_LIMIT),
        ] {
            if now && !was && !self.faults.contains(&code) {
                self.raise(code, super::error_register(code), true);
            }
        }
    }

    /// The directions the position limits block (negative, positive).
    pub(crate) fn kinco_position_limits_blocking(&self) -> (bool, bool) {
        (self.vendor.limits.below, self.vendor.limits.above)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_off_at_zero_and_strict_beyond() {
        assert_eq!(beyond(1_000_000, 0, 0), (false, false));
        assert_eq!(
            beyond(5000, -5000, 5000),
            (false, false),
            "on the limit is inside"
        );
        assert_eq!(beyond(5001, -5000, 5000), (false, true));
        assert_eq!(beyond(-5001, -5000, 5000), (true, false));
    }
}
