//! The ESC's local clock when its oscillator is off nominal: a drift (ppb) and a jitter (ns),
//! so that a master's DC control loop has a deviation to see and correct (spec §8.2 "Full
//! model": local oscillator drift, 0x092C difference).
//!
//! Every ESC counts its local time from its own oscillator (spec §8.2); the system time 0x0910 is that local time plus the offset 0x0920, and every system-time write
//! of the master (FRMW/ARMW 0x0910) measures the difference to the reference in 0x092C and
//! corrects the offset (`side_effects.rs`). A nominal clock (the default) adds nothing, so
//! no byte a master reads changes while no error is set.
//!
//! The jitter is a pure function of the seed and the instant read (SplitMix64), so the same
//! run on the virtual clock reads the same times.

use od::Instant;

/// How far a slave's oscillator is off nominal.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClockError {
    /// Rate error in parts per billion (50 ppm = 50 000): the local clock gains this many ns
    /// per second of real time (negative: loses).
    pub drift_ppb: i64,
    /// Each reading of the local clock is off by up to ± this many ns.
    pub jitter_ns: u32,
    /// Seed of the jitter's sequence.
    pub seed: u64,
}

impl ClockError {
    /// A nominal clock.
    pub const NONE: ClockError = ClockError {
        drift_ppb: 0,
        jitter_ns: 0,
        seed: 0,
    };

    pub fn is_none(&self) -> bool {
        self.drift_ppb == 0 && self.jitter_ns == 0
    }
}

/// The deviation of the local clock from `now` that a [`ClockError`] adds up to.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct LocalClock {
    error: ClockError,
    /// When the current error was set (ns of `now`).
    since: u64,
    /// The deviation accumulated before `since` (ns).
    base: i64,
}

impl LocalClock {
    /// Deviation (ns) of the local clock at `now` from `now` itself.
    pub(super) fn deviation(&self, now: Instant) -> i64 {
        if self.error.is_none() && self.base == 0 {
            return 0;
        }
        self.drifted(now).wrapping_add(self.jitter(now))
    }

    /// The drift part alone: what the clock gained since it was set, plus what it had then.
    fn drifted(&self, now: Instant) -> i64 {
        let dt = i128::from(now.as_nanos().saturating_sub(self.since));
        let gained = dt.saturating_mul(i128::from(self.error.drift_ppb)) / 1_000_000_000;
        self.base
            .wrapping_add(i64::try_from(gained).unwrap_or(i64::MAX))
    }

    fn jitter(&self, now: Instant) -> i64 {
        let j = u64::from(self.error.jitter_ns);
        if j == 0 {
            return 0;
        }
        let r = splitmix64(self.error.seed ^ now.as_nanos());
        // Uniform over [-j, j].
        (r % (2 * j + 1)) as i64 - j as i64
    }

    /// A new error from `now` on: the drift so far is kept, the rate changes from here.
    pub(super) fn set(&mut self, now: Instant, error: ClockError) {
        self.base = self.drifted(now);
        self.since = now.as_nanos();
        self.error = error;
    }

    pub(super) fn error(&self) -> ClockError {
        self.error
    }
}

/// SplitMix64 (Steele, Lea, Flood 2014): one 64-bit mix of a counter.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_nominal_clock_adds_nothing() {
        let c = LocalClock::default();
        assert_eq!(c.deviation(Instant::from_nanos(123_456_789)), 0);
    }

    #[test]
    fn fifty_ppm_gain_fifty_microseconds_a_second() {
        let mut c = LocalClock::default();
        let err = ClockError {
            drift_ppb: 50_000,
            ..ClockError::NONE
        };
        c.set(Instant::from_nanos(1_000_000_000), err);
        assert_eq!(c.deviation(Instant::from_nanos(2_000_000_000)), 50_000);
        // The rate changes, the drift so far stays.
        c.set(Instant::from_nanos(2_000_000_000), ClockError::NONE);
        assert_eq!(c.deviation(Instant::from_nanos(9_000_000_000)), 50_000);
    }

    #[test]
    fn jitter_is_bounded_and_repeats_for_the_same_seed() {
        let mut c = LocalClock::default();
        let err = ClockError {
            drift_ppb: 0,
            jitter_ns: 40,
            seed: 7,
        };
        c.set(Instant::ZERO, err);
        let a: [i64; 64] =
            core::array::from_fn(|i| c.deviation(Instant::from_nanos(i as u64 * 1000)));
        assert!(a.iter().all(|d| d.abs() <= 40));
        assert!(a.iter().any(|d| *d != a[0]), "it varies");
        let b: [i64; 64] =
            core::array::from_fn(|i| c.deviation(Instant::from_nanos(i as u64 * 1000)));
        assert_eq!(a, b);
    }
}
