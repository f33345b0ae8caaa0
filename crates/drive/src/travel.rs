//! The travel of the simulated CMMP-AS axis: what the homing methods (CMMP-AS §7.2, Tab. 7.1)
//! and the limit-switch supervision look at. Negative and positive limit switches, the home
//! (reference) switch, the encoder's index pulse once per motor revolution, and mechanical
//! hard stops beyond the limit switches.
//!
//! All positions are motor encoder increments (65536 per revolution) in the plant's own frame:
//! the encoder reads 0 at power-on, and neither homing nor 2030h moves the switches.

/// Where the switches and stops sit; `None` leaves a part out (a drive without that switch).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TravelSettings {
    /// Mechanical stop below the negative limit switch.
    pub negative_stop: Option<i64>,
    /// The negative limit switch is active at and below this position.
    pub negative_limit: Option<i64>,
    /// The home switch: a cam, active from `low` to `high` (both included).
    pub home_switch: Option<HomeSwitch>,
    /// The positive limit switch is active at and above this position.
    pub positive_limit: Option<i64>,
    /// Mechanical stop above the positive limit switch.
    pub positive_stop: Option<i64>,
    /// The index pulse: at every position ≡ this (mod increments per revolution). `None` for
    /// an encoder without index.
    pub index_phase: Option<u32>,
}

/// The cam of the home switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HomeSwitch {
    pub low: i64,
    pub high: i64,
}

/// One revolution in increments.
const REV: i64 = 65536;

impl Default for TravelSettings {
    /// A stroke of 88 revolutions, short on the negative side and long on the positive one:
    /// - hard stops at −22 and +66 revolutions (−1 441 792 / +4 325 376),
    /// - limit switches from −20 and +64 revolutions (−1 310 720 / +4 194 304) outwards,
    /// - the home switch cam from 40 000 to 90 000 (0.61 … 1.37 revolutions): inactive at
    ///   power-on, so the home-switch methods show their search,
    /// - the index pulse a quarter revolution into every revolution (16 384 + k·65 536).
    ///
    /// At the default speeds (6099h: 100 / 10 min⁻¹, 1.7 revolutions/s) the default method
    /// 17 takes 12 s and every other method of Tab. 7.1 ends inside the default 60 s timeout
    /// (2045h) except −23, which travels to the positive limit and back (76 s): it needs a
    /// faster search (6099h:01 ≥ 130 min⁻¹) or 2045h = 0. The long positive side leaves
    /// room for what the other interfaces' tests do from power-on (an EtherCAT CSP session
    /// runs 50 revolutions positive).
    fn default() -> Self {
        TravelSettings {
            negative_stop: Some(-22 * REV),
            negative_limit: Some(-20 * REV),
            home_switch: Some(HomeSwitch {
                low: 40_000,
                high: 90_000,
            }),
            positive_limit: Some(64 * REV),
            positive_stop: Some(66 * REV),
            index_phase: Some(16_384),
        }
    }
}

/// The switch inputs at one position.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Inputs {
    pub negative_limit: bool,
    pub positive_limit: bool,
    pub home: bool,
}

impl Inputs {
    /// The limit switch ahead in `direction` (−1 / +1) is active.
    pub fn limit_ahead(&self, direction: i8) -> bool {
        if direction < 0 {
            self.negative_limit
        } else {
            self.positive_limit
        }
    }
}

impl TravelSettings {
    /// A travel without switches, index or stops (an endless axis).
    pub const NONE: TravelSettings = TravelSettings {
        negative_stop: None,
        negative_limit: None,
        home_switch: None,
        positive_limit: None,
        positive_stop: None,
        index_phase: None,
    };

    pub fn inputs(&self, position: i64) -> Inputs {
        Inputs {
            negative_limit: self.negative_limit.is_some_and(|l| position <= l),
            positive_limit: self.positive_limit.is_some_and(|l| position >= l),
            home: self
                .home_switch
                .is_some_and(|h| position >= h.low && position <= h.high),
        }
    }

    /// The first index-pulse position passed moving from `from` to `to` (`from` excluded,
    /// `to` included), with `per_rev` increments per revolution. The CMMP-AS latches the
    /// index in hardware, so it is exact whatever the sampling.
    pub fn index_crossed(&self, from: i64, to: i64, per_rev: u32) -> Option<i64> {
        let phase = i64::from(self.index_phase?);
        let rev = i64::from(per_rev.max(1));
        if to > from {
            let p = from + 1 + (phase - (from + 1)).rem_euclid(rev);
            (p <= to).then_some(p)
        } else if to < from {
            let p = from - 1 - (from - 1 - phase).rem_euclid(rev);
            (p >= to).then_some(p)
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_found_in_either_direction() {
        let t = TravelSettings::default();
        assert_eq!(t.index_crossed(0, 20_000, 65536), Some(16_384));
        assert_eq!(t.index_crossed(16_384, 20_000, 65536), None);
        assert_eq!(t.index_crossed(15_000, 16_384, 65536), Some(16_384));
        assert_eq!(t.index_crossed(0, -60_000, 65536), Some(16_384 - 65_536));
        assert_eq!(t.index_crossed(16_384, 0, 65536), None, "start excluded");
        assert_eq!(t.index_crossed(16_385, 16_384, 65536), Some(16_384));
    }

    #[test]
    fn switches_by_position() {
        let t = TravelSettings::default();
        assert_eq!(t.inputs(0), Inputs::default());
        assert!(t.inputs(-20 * REV).negative_limit);
        assert!(!t.inputs(-20 * REV + 1).negative_limit);
        assert!(t.inputs(64 * REV).positive_limit);
        assert!(!t.inputs(64 * REV - 1).positive_limit);
        assert!(t.inputs(40_000).home && t.inputs(90_000).home && !t.inputs(90_001).home);
    }
}
