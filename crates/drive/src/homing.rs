//! The homing search of CiA 402 homing mode 6 (the methods 6098h selects, as CiA 402 draws
//! them; a personality lists those it has,
//! [`crate::personality::Personality::homing_methods`]): each method is a short list of steps
//! ("at search speed negative until the negative limit switch is active", …) run against the switch inputs of [`crate::travel`]. This module finds the
//! reference point; the drive brakes, moves to zero (6510h:F0 bit 6) and sets the position.

use crate::travel::{Inputs, TravelSettings};

/// A switch input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Signal {
    NegativeLimit,
    PositiveLimit,
    Home,
}

impl Signal {
    fn of(self, i: &Inputs) -> bool {
        match self {
            Signal::NegativeLimit => i.negative_limit,
            Signal::PositiveLimit => i.positive_limit,
            Signal::Home => i.home,
        }
    }
}

/// What ends a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Until {
    Active(Signal),
    Inactive(Signal),
    /// The next index pulse in the direction of travel.
    Index,
    /// The hard stop (the motor stalls); limit switches are ignored.
    Stop,
    /// The hard stop or the limit switch ahead, whichever comes first.
    StopOrLimit,
}

/// 6099h:01 or 6099h:02.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Speed {
    Search,
    Crawl,
}

/// One line of a method's sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Step {
    /// −1 negative, +1 positive.
    pub direction: i8,
    pub speed: Speed,
    pub until: Until,
    /// Methods 7, 11, 23, 27: a hard stop or limit switch reached on the way reverses the
    /// search (CiA 402 §6.7.4).
    pub reverse: bool,
}

/// One step of a method's sequence, for the tables of the engine and of a vendor's own
/// methods.
pub const fn step(direction: i8, speed: Speed, until: Until, reverse: bool) -> Step {
    Step {
        direction,
        speed,
        until,
        reverse,
    }
}

use Signal::{Home, NegativeLimit as NegLim, PositiveLimit as PosLim};
use Speed::{Crawl, Search as Fast};
use Until::{Active, Inactive, Index, Stop, StopOrLimit};

/// The method `number` of `table`.
pub const fn find_method(table: &[Method], number: i8) -> Option<Method> {
    let mut rest = table;
    while let [m, tail @ ..] = rest {
        if m.0 == number {
            return Some(*m);
        }
        rest = tail;
    }
    None
}

/// The method `number` of the engine's tables ([`METHODS`], then [`HOME_SWITCH_METHODS`]),
/// for a personality's const table of the methods it offers.
// Only called in const tables: an unknown number fails the build, never a drive.
#[allow(clippy::panic)]
pub const fn engine_method(number: i8) -> Method {
    match find_method(&METHODS, number) {
        Some(m) => m,
        None => match find_method(&HOME_SWITCH_METHODS, number) {
            Some(m) => m,
            None => panic!("no such homing method"),
        },
    }
}

/// The home-switch methods 19 … 22 (CiA 402 §6.7.4.3), positive the clockwise direction.
///
/// Decision: the twin's home switch is logical (active on the cam); 19/21 (normally closed)
/// and 20/22 (normally open) differ only in the input's level, which the switch wiring of the
/// travel settings gives, so 19 and 22 run the same steps, as do 20 and 21.
pub const HOME_SWITCH_METHODS: [Method; 4] = [
    // 19: CW at the search speed 6099h:01 until the switch, then CCW at the creep speed
    // 6099h:02 until it is free.
    (
        19,
        &[
            step(1, Fast, Active(Home), false),
            step(-1, Crawl, Inactive(Home), false),
        ],
    ),
    // 20: CCW until the switch, CW off it.
    (
        20,
        &[
            step(-1, Fast, Active(Home), false),
            step(1, Crawl, Inactive(Home), false),
        ],
    ),
    // 21: CCW until the switch, CW off it.
    (
        21,
        &[
            step(-1, Fast, Active(Home), false),
            step(1, Crawl, Inactive(Home), false),
        ],
    ),
    // 22: CW until the switch, CCW off it.
    (
        22,
        &[
            step(1, Fast, Active(Home), false),
            step(-1, Crawl, Inactive(Home), false),
        ],
    ),
];

/// A homing method: its 6098h number and its steps.
pub type Method = (i8, &'static [Step]);

/// The CiA 402 homing methods the engine runs (CiA 402 §6.7.4: 1, 2 on a limit switch with
/// the index, 7, 11, 23, 27 on the home switch, 17, 18 on a limit switch, 33, 34 on the
/// index, 35 here), one row per method; a vendor's manufacturer-specific methods (negative
/// numbers) are in its folder. The last step's end is the reference point; an `Active`
/// search that finds its switch already active is skipped ("if … inactive: travel …").
///
/// Decision: the home switch is a cam with two edges. Methods 23/7 approach it positive and
/// crawl out negative, so their reference is its negative edge; 27/11 its positive edge.
pub const METHODS: [Method; 11] = [
    (
        1,
        &[
            step(-1, Fast, Active(NegLim), false),
            step(1, Crawl, Inactive(NegLim), false),
            step(1, Crawl, Index, false),
        ],
    ),
    (
        2,
        &[
            step(1, Fast, Active(PosLim), false),
            step(-1, Crawl, Inactive(PosLim), false),
            step(-1, Crawl, Index, false),
        ],
    ),
    (
        7,
        &[
            step(1, Fast, Active(Home), true),
            step(-1, Crawl, Inactive(Home), false),
            step(-1, Crawl, Index, false),
        ],
    ),
    (
        11,
        &[
            step(-1, Fast, Active(Home), true),
            step(1, Crawl, Inactive(Home), false),
            step(1, Crawl, Index, false),
        ],
    ),
    (
        17,
        &[
            step(-1, Fast, Active(NegLim), false),
            step(1, Crawl, Inactive(NegLim), false),
        ],
    ),
    (
        18,
        &[
            step(1, Fast, Active(PosLim), false),
            step(-1, Crawl, Inactive(PosLim), false),
        ],
    ),
    (
        23,
        &[
            step(1, Fast, Active(Home), true),
            step(-1, Crawl, Inactive(Home), false),
        ],
    ),
    (
        27,
        &[
            step(-1, Fast, Active(Home), true),
            step(1, Crawl, Inactive(Home), false),
        ],
    ),
    (33, &[step(-1, Crawl, Index, false)]),
    (34, &[step(1, Crawl, Index, false)]),
    (35, &[]),
];

/// Why a homing run fails (statusword bit 13 homing error, CiA 402 homing mode); the
/// personality names the error each raises ([`crate::personality::Fault::Homing`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HomingError {
    /// Started without controller enable, or an unknown method.
    Start,
    /// Aborted during homing.
    Aborted,
    /// The index pulse the method needs did not come.
    NoIndex,
    /// 2045h homing_timeout exceeded.
    Timeout,
    /// Limit switch missing, both active, or reached where it must not be.
    LimitSwitch,
    /// Following error (the axis stalled on a hard stop it was not looking for).
    FollowingError,
    /// The maximum search distance travelled without the reference.
    SearchDistance,
}

/// The axis as the search sees it in one cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sense {
    /// Motor encoder, increments (the travel's frame).
    pub position: i64,
    pub inputs: Inputs,
    /// The set-point runs away from the actual position: the motor stands on a hard stop.
    pub stalled: bool,
}

/// What the search asks of the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// Travel in `direction` at `speed`; `restart`: the motor stalled, take the set-point
    /// back to the actual position first.
    Run {
        direction: i8,
        speed: Speed,
        restart: bool,
    },
    /// The reference point is at this encoder position; `stalled` as for `Run::restart`.
    Reference {
        at: i64,
        stalled: bool,
    },
    Failed(HomingError),
}

/// One homing search in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Search {
    steps: &'static [Step],
    index: usize,
    direction: i8,
    reversed: bool,
    last: i64,
    step_from: i64,
    per_rev: u32,
    max_distance: i64,
}

impl Search {
    /// Starts `method` at `position`; `max_distance` increments per step (0 = no limit).
    pub fn start(
        method: i8,
        position: i64,
        per_rev: u32,
        max_distance: i64,
    ) -> Result<Search, HomingError> {
        Self::start_in(&METHODS, method, position, per_rev, max_distance)
    }

    /// As [`Search::start`], with the method table of a personality.
    pub fn start_in(
        methods: &'static [Method],
        method: i8,
        position: i64,
        per_rev: u32,
        max_distance: i64,
    ) -> Result<Search, HomingError> {
        let steps = methods
            .iter()
            .find(|(m, _)| *m == method)
            .map(|(_, s)| *s)
            .ok_or(HomingError::Start)?;
        Ok(Search {
            steps,
            index: 0,
            direction: steps.first().map(|s| s.direction).unwrap_or(1),
            reversed: false,
            last: position,
            step_from: position,
            per_rev: per_rev.max(1),
            max_distance,
        })
    }

    /// One cycle.
    pub fn step(&mut self, s: &Sense, travel: &TravelSettings) -> Command {
        let pos = s.position;
        let moved = pos - self.last;
        let crossed = travel
            .index_crossed(self.last, pos, self.per_rev)
            .filter(|_| moved.signum() == i64::from(self.direction));
        self.last = pos;
        let Some(step) = self.steps.get(self.index).copied() else {
            // Method 35: the current position is the reference.
            return Command::Reference {
                at: pos,
                stalled: false,
            };
        };
        let i = &s.inputs;
        let ignores_limits = matches!(step.until, Stop);
        if i.negative_limit && i.positive_limit && !ignores_limits {
            // B.3 11-4: both limit switches active at once.
            return Command::Failed(HomingError::LimitSwitch);
        }
        let limit_ahead = i.limit_ahead(self.direction);
        let found = match step.until {
            Active(sig) => sig.of(i).then_some(pos),
            Inactive(sig) => (!sig.of(i)).then_some(pos),
            Index => crossed,
            Stop => s.stalled.then_some(pos),
            StopOrLimit => (s.stalled || limit_ahead).then_some(pos),
        };
        if let Some(at) = found {
            return self.advance(at, pos, s.stalled);
        }
        let wanted_limit = matches!(
            step.until,
            Active(NegLim | PosLim) | Inactive(NegLim | PosLim)
        );
        let blocked = s.stalled || (limit_ahead && !ignores_limits && !wanted_limit);
        if blocked {
            if step.reverse && !self.reversed {
                self.reversed = true;
                self.direction = -self.direction;
                self.step_from = pos;
                return Command::Run {
                    direction: self.direction,
                    speed: step.speed,
                    restart: s.stalled,
                };
            }
            let e = match step.until {
                // B.3 11-4: "associated limit switch not connected" (a stop came first).
                Active(NegLim | PosLim) => HomingError::LimitSwitch,
                _ if !s.stalled => HomingError::LimitSwitch,
                // B.3 11-5: "no home switch between the hard stops", "index-pulse method hit
                // a hard stop".
                _ => HomingError::FollowingError,
            };
            return Command::Failed(e);
        }
        let travelled = (pos - self.step_from).abs();
        if step.until == Index && travelled > i64::from(self.per_rev) * 3 / 2 {
            // More than a revolution without an index pulse (B.3 11-2).
            return Command::Failed(HomingError::NoIndex);
        }
        if self.max_distance > 0 && travelled > self.max_distance {
            return Command::Failed(HomingError::SearchDistance);
        }
        Command::Run {
            direction: self.direction,
            speed: step.speed,
            restart: false,
        }
    }

    fn advance(&mut self, at: i64, pos: i64, stalled: bool) -> Command {
        let found_index = self.steps.get(self.index).map(|s| s.until) == Some(Index);
        self.index += 1;
        match self.steps.get(self.index) {
            None => Command::Reference { at, stalled },
            Some(next) => {
                if found_index {
                    // A mark just found lies behind the shaft, even where it stands right on
                    // it, so that a step back over it (a method that ends with 33 / 34's
                    // step) sees it.
                    self.last = at + i64::from(self.direction);
                }
                self.direction = next.direction;
                self.reversed = false;
                self.step_from = pos;
                Command::Run {
                    direction: next.direction,
                    speed: next.speed,
                    restart: stalled,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_method_of_the_summary_table_is_there_once() {
        let listed = [1, 2, 7, 11, 17, 18, 23, 27, 33, 34, 35];
        for m in listed {
            assert_eq!(METHODS.iter().filter(|(n, _)| *n == m).count(), 1, "{m}");
        }
        assert_eq!(Search::start(32, 0, 65536, 0), Err(HomingError::Start));
        assert_eq!(Search::start(3, 0, 65536, 0), Err(HomingError::Start));
    }

    #[test]
    fn a_search_that_finds_its_switch_active_is_skipped() {
        let t = TravelSettings::default();
        let mut s = Search::start(17, -30 * 65536, 65536, 0).unwrap();
        let sense = Sense {
            position: -21 * 65536,
            inputs: t.inputs(-21 * 65536),
            stalled: false,
        };
        assert_eq!(
            s.step(&sense, &t),
            Command::Run {
                direction: 1,
                speed: Speed::Crawl,
                restart: false
            }
        );
    }
}
