//! How late the cell loop serves its timers in real time: each time a bus, chain or Modbus
//! cycle is due, the time between its deadline and the loop reaching it. A histogram of
//! powers of two (no allocation, atomics so that any thread reads it while the loop runs),
//! printed when the loop stops and read by the soak.

use std::fmt;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Buckets: below 1 µs, then [2^k, 2^(k+1)) µs for k = 0 … 30 (the last takes the rest).
const BUCKETS: usize = 32;

/// The loop's lateness so far.
#[derive(Debug, Default)]
pub struct Lateness {
    buckets: [AtomicU64; BUCKETS],
    max_nanos: AtomicU64,
}

/// What [`Lateness::figures`] reads: the quantiles as bucket upper bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LatenessFigures {
    pub served: u64,
    pub p50: Duration,
    pub p99: Duration,
    pub p999: Duration,
    pub max: Duration,
}

impl Lateness {
    /// A timer due `late` ago was served now.
    pub fn record(&self, late: Duration) {
        let micros = late.as_micros();
        let bucket = if micros == 0 {
            0
        } else {
            (1 + micros.ilog2() as usize).min(BUCKETS - 1)
        };
        if let Some(b) = self.buckets.get(bucket) {
            b.fetch_add(1, Ordering::Relaxed);
        }
        let nanos = u64::try_from(late.as_nanos()).unwrap_or(u64::MAX);
        self.max_nanos.fetch_max(nanos, Ordering::Relaxed);
    }

    pub fn figures(&self) -> LatenessFigures {
        let counts: [u64; BUCKETS] =
            core::array::from_fn(|i| self.buckets.get(i).map_or(0, |b| b.load(Ordering::Relaxed)));
        let served: u64 = counts.iter().sum();
        let quantile = |q: f64| {
            let rank = (served as f64 * q).ceil() as u64;
            let mut seen = 0;
            for (i, c) in counts.iter().enumerate() {
                seen += c;
                if seen >= rank.max(1) {
                    return upper_bound(i);
                }
            }
            Duration::ZERO
        };
        LatenessFigures {
            served,
            p50: quantile(0.5),
            p99: quantile(0.99),
            p999: quantile(0.999),
            max: Duration::from_nanos(self.max_nanos.load(Ordering::Relaxed)),
        }
    }
}

/// The upper bound of bucket `i`: 1 µs, then 2^i µs.
fn upper_bound(i: usize) -> Duration {
    Duration::from_micros(1u64 << i.min(40))
}

impl fmt::Display for LatenessFigures {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} timers served, late p50 ≤ {:?}, p99 ≤ {:?}, p99.9 ≤ {:?}, max {:?}",
            self.served, self.p50, self.p99, self.p999, self.max
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_are_bucket_bounds() {
        let l = Lateness::default();
        for _ in 0..990 {
            l.record(Duration::from_micros(20)); // [16, 32) µs
        }
        for _ in 0..10 {
            l.record(Duration::from_millis(3)); // [2048, 4096) µs
        }
        let f = l.figures();
        assert_eq!(f.served, 1000);
        assert_eq!(f.p50, Duration::from_micros(32));
        assert_eq!(f.p99, Duration::from_micros(32));
        assert_eq!(f.p999, Duration::from_micros(4096));
        assert_eq!(f.max, Duration::from_millis(3));
        assert_eq!(Lateness::default().figures().p99, Duration::ZERO);
    }

    #[test]
    fn on_time_and_very_late_land_in_the_end_buckets() {
        let l = Lateness::default();
        l.record(Duration::ZERO);
        l.record(Duration::from_secs(100_000));
        let f = l.figures();
        assert_eq!(f.p50, Duration::from_micros(1));
        assert_eq!(f.served, 2);
    }
}
