//! The interpolation periods the CMMP-AS takes in 60C2h (§7.4.2): ip_time_index −3 with
//! ip_time_units 1…10 (1…10 ms) or ip_time_index −4 with 10…100 (1…10 ms in 0.1 ms steps).
//! CiA 402 allows any units × 10^index s; a period outside these ranges runs at the default
//! 1 ms ([`Vendor::ip_period`](crate::personality::Vendor::ip_period)).

use core::time::Duration;

/// The interpolation period of 60C2h (units × 10^index s); `None` outside the ranges §7.4.2
/// prints.
pub fn period_from_60c2(units: u8, index: i8) -> Option<Duration> {
    match index {
        -3 if (1..=10).contains(&units) => Some(Duration::from_millis(u64::from(units))),
        -4 if (10..=100).contains(&units) => Some(Duration::from_micros(u64::from(units) * 100)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ip_08_both_encodings_mean_4_ms() {
        // CMMP-IP-08: (−3, 4) and (−4, 40) are both 4 ms.
        assert_eq!(period_from_60c2(4, -3), Some(Duration::from_millis(4)));
        assert_eq!(period_from_60c2(40, -4), Some(Duration::from_millis(4)));
        assert_eq!(period_from_60c2(11, -3), None);
        assert_eq!(period_from_60c2(5, -4), None);
    }

    #[test]
    fn outside_the_ranges_where_cia_402_has_a_period() {
        // 20 ms at −3 and 250 µs at −6 are CiA 402 periods, not the CMMP-AS's.
        assert_eq!(period_from_60c2(20, -3), None);
        assert_eq!(period_from_60c2(250, -6), None);
    }
}
