//! The CMMP-AS's homing methods (§7.2 Tab. 7.1): CiA 402's 1, 2, 7, 11, 17, 18, 23, 27, 33,
//! 34, 35 and its manufacturer-specific ones, −1 / −2 (hard stop, then the index), −17 / −18
//! (hard stop) and −23 / −27 (hard stop or limit switch, then the home switch).
//!
//! Decision: 6510h:F0 bits 0/2 (homing_method_scheme) choose between CiA 402 and a legacy
//! numbering of 32 … 35 that the manual does not print; both use Tab. 7.1's 33/34/35, and 32
//! (in the printed range, in no table) is refused at the start.
//!
//! Decision: methods −23/−27 crawl "until the home switch becomes active" after the search has
//! already found it: the drive first crawls back out of the cam (not printed, but the only way
//! the switch can *become* active again), then onto it — reference: the positive edge for
//! −23, the negative edge for −27 (the manual's extract, part 3 §9: "keep this distinction").

use crate::homing::Signal::Home;
use crate::homing::Speed::{Crawl, Search as Fast};
use crate::homing::Until::{Active, Inactive, Index, Stop, StopOrLimit};
use crate::homing::{engine_method, step, Method};

/// Tab. 7.1, one row per method; the hard stop ignores the limit switches (footnote 2), and
/// 7, 11, 23, 27 reverse at a hard stop or limit switch on the way ("search in the opposite
/// direction").
pub const METHODS: [Method; 17] = [
    (
        -27,
        &[
            step(-1, Fast, StopOrLimit, false),
            step(1, Fast, Active(Home), false),
            step(-1, Crawl, Inactive(Home), false),
            step(1, Crawl, Active(Home), false),
        ],
    ),
    (
        -23,
        &[
            step(1, Fast, StopOrLimit, false),
            step(-1, Fast, Active(Home), false),
            step(1, Crawl, Inactive(Home), false),
            step(-1, Crawl, Active(Home), false),
        ],
    ),
    (-18, &[step(1, Fast, Stop, false)]),
    (-17, &[step(-1, Fast, Stop, false)]),
    (
        -2,
        &[step(1, Fast, Stop, false), step(-1, Crawl, Index, false)],
    ),
    (
        -1,
        &[step(-1, Fast, Stop, false), step(1, Crawl, Index, false)],
    ),
    engine_method(1),
    engine_method(2),
    engine_method(7),
    engine_method(11),
    engine_method(17),
    engine_method(18),
    engine_method(23),
    engine_method(27),
    engine_method(33),
    engine_method(34),
    engine_method(35),
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::homing::{HomingError, Search};

    #[test]
    fn every_method_of_tab_7_1_is_there_once() {
        let listed = [
            -27, -23, -18, -17, -2, -1, 1, 2, 7, 11, 17, 18, 23, 27, 33, 34, 35,
        ];
        for m in listed {
            assert_eq!(METHODS.iter().filter(|(n, _)| *n == m).count(), 1, "{m}");
        }
        assert_eq!(
            Search::start_in(&METHODS, 32, 0, 65536, 0).map(|_| ()),
            Err(HomingError::Start)
        );
    }
}
