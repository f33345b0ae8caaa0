//! The cell loop's longest turns in real time, and what it did in them: a turn is one
//! wake-up, from the poll's return to the next wait. For each of the [`KEPT`] longest the
//! log keeps how long each part took (the devices' exchanges after a master's frames, the
//! devices run before a frame, the frames' passes and answers, the timers, the other
//! sockets, the rest), how many frames, exchanges and SYNC0 events it ran, and what the
//! thread used meanwhile (CPU time, page faults, involuntary switches): a turn whose wall
//! time far exceeds its CPU time was off its CPU (preempted, or the host did not run the
//! virtual CPU), one whose CPU time is as long did the work itself. Beside them, how many
//! turns took how long (powers of two).
//!
//! Recorded in place with no allocation: a clock read per part (the monotonic clock, read
//! without a system call) and one `getrusage` per turn that is not a frame's alone, after
//! its answers went out; printed when the loop stops (`drivetwin run`, after the timers'
//! lateness).

use std::fmt;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::sys::thread_usage::{thread_usage, ThreadUsage};

/// Longest turns kept.
pub const KEPT: usize = 8;

/// Buckets of turn lengths: below 1 µs, then [2^k, 2^(k+1)) µs (the last takes the rest).
const BUCKETS: usize = 24;

/// Where a turn spent its time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// The devices' part after the master's frames (outputs in, drives stepped, inputs out,
    /// mailbox): `SlaveChain::exchange_with`, deferred or not.
    Exchange,
    /// The devices run before a frame's pass: a SYNC0 event or a step past its grace that
    /// fell due before the frame arrived.
    CatchUp,
    /// Frames read, passed through the chains and sent back.
    Pass,
    /// The timers due: drive steps and SYNC0 events at their time, CAN buses, sessions,
    /// planned changes.
    Timers,
    /// The other sockets' events (CAN, TCP, serial).
    Sockets,
    /// The control handle's requests, the samples, the writes left over.
    Rest,
}

const PARTS: usize = 6;
const PART_NAMES: [&str; PARTS] = ["exchange", "catch-up", "pass", "timers", "sockets", "rest"];

/// One turn as the log keeps it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Turn {
    /// Its number since the loop started.
    pub index: u64,
    /// When it began, since the loop started.
    pub at: Duration,
    /// From the poll's return to the end of its work.
    pub wall: Duration,
    /// How long after the time it waited for the poll returned (zero when something else
    /// woke it first).
    pub woke_late: Duration,
    /// Time by [`Part`].
    pub parts: [Duration; PARTS],
    /// Frames answered.
    pub frames: u32,
    /// Devices' exchanges run (one per frame, of the whole chain).
    pub exchanges: u32,
    /// Runs of the chains' devices without a frame (catch-up and timers).
    pub polls: u32,
    /// SYNC0 events the chains' devices ran.
    pub sync0_events: u64,
    /// What the thread used from the end of the last turn that read it to the end of this
    /// one; `None` (and no faults or switches) for a turn that answered frames alone, whose
    /// master waited for the loop to sleep (`TurnLog::end`).
    pub cpu: Option<Duration>,
    pub minor_faults: u64,
    pub major_faults: u64,
    pub involuntary_switches: u64,
}

/// The log the loop writes while it runs.
#[derive(Debug)]
pub struct TurnLog {
    origin: Instant,
    current: Turn,
    last_mark: Instant,
    /// The time the loop's wait was for.
    waits_until: Option<Instant>,
    usage: ThreadUsage,
    sync0_total: u64,
    turns: u64,
    longest: [Turn; KEPT],
    lengths: [u64; BUCKETS],
    totals: Totals,
    published: Arc<Mutex<TurnReport>>,
}

/// Every turn's parts and counts added up: where the loop's time went on average, beside
/// the longest turns.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Totals {
    pub wall: Duration,
    pub cpu: Duration,
    pub parts: [Duration; PARTS],
    pub frames: u64,
    pub exchanges: u64,
    /// Exchanges that ran on a frame's path: the exchange after the frame before, still
    /// pending when the next frame came.
    pub exchanges_on_path: u64,
    pub polls: u64,
}

/// What the loop hands over when it stops.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TurnReport {
    pub turns: u64,
    /// Longest first.
    pub longest: Vec<Turn>,
    /// Turns by length: (lower bound, count), the empty buckets left out.
    pub lengths: Vec<(Duration, u64)>,
    /// Every turn added up.
    pub totals: Totals,
}

impl TurnLog {
    pub fn new(origin: Instant) -> Self {
        TurnLog {
            origin,
            current: Turn::default(),
            last_mark: origin,
            waits_until: None,
            usage: ThreadUsage::default(),
            sync0_total: 0,
            turns: 0,
            longest: [Turn::default(); KEPT],
            lengths: [0; BUCKETS],
            totals: Totals::default(),
            published: Arc::default(),
        }
    }

    /// Where the report goes when the loop stops ([`publish`](Self::publish)).
    pub fn report(&self) -> Arc<Mutex<TurnReport>> {
        Arc::clone(&self.published)
    }

    /// The loop's thread starts counting (its usage so far is not the turns').
    pub fn start(&mut self, sync0_total: u64) {
        self.usage = thread_usage();
        self.sync0_total = sync0_total;
    }

    /// The loop waits for `at` (or for a socket, whichever comes first).
    pub fn waits_until(&mut self, at: Option<Instant>) {
        self.waits_until = at;
    }

    /// The poll returned at `now`: a turn begins.
    pub fn begin(&mut self, now: Instant) {
        self.current = Turn {
            index: self.turns,
            at: now.saturating_duration_since(self.origin),
            woke_late: self
                .waits_until
                .take()
                .map_or(Duration::ZERO, |d| now.saturating_duration_since(d)),
            ..Turn::default()
        };
        self.last_mark = now;
    }

    /// What ran since the last mark was `part`.
    #[inline]
    pub fn mark(&mut self, part: Part) {
        let now = Instant::now();
        if let Some(p) = self.current.parts.get_mut(part as usize) {
            *p += now.saturating_duration_since(self.last_mark);
        }
        self.last_mark = now;
    }

    /// A frame was answered.
    pub fn frame(&mut self) {
        self.current.frames += 1;
    }

    /// The chains' devices exchanged after a frame.
    pub fn exchange(&mut self) {
        self.current.exchanges += 1;
    }

    /// The exchange after the frame before ran first on a frame's path.
    pub fn exchange_on_path(&mut self) {
        self.totals.exchanges_on_path += 1;
    }

    /// The chains' devices ran without a frame.
    pub fn poll(&mut self) {
        self.current.polls += 1;
    }

    /// The turn's work is done at `now`; `sync0_total`: the SYNC0 events the chains' devices
    /// have run so far. With `read_usage`, the thread's usage is read (two system calls);
    /// without, the turn's is counted in the next turn that reads it.
    pub fn end(&mut self, now: Instant, sync0_total: u64, read_usage: bool) {
        let t = &mut self.current;
        t.wall = now.saturating_duration_since(self.origin + t.at);
        t.sync0_events = sync0_total.saturating_sub(self.sync0_total);
        if read_usage {
            let usage = thread_usage();
            t.cpu = Some(usage.cpu.saturating_sub(self.usage.cpu));
            t.minor_faults = usage.minor_faults.saturating_sub(self.usage.minor_faults);
            t.major_faults = usage.major_faults.saturating_sub(self.usage.major_faults);
            t.involuntary_switches = usage
                .involuntary_switches
                .saturating_sub(self.usage.involuntary_switches);
            self.usage = usage;
        }
        self.sync0_total = sync0_total;
        self.turns += 1;
        let micros = t.wall.as_micros();
        let bucket = if micros == 0 {
            0
        } else {
            (1 + micros.ilog2() as usize).min(BUCKETS - 1)
        };
        if let Some(b) = self.lengths.get_mut(bucket) {
            *b += 1;
        }
        let all = &mut self.totals;
        all.wall += t.wall;
        all.cpu += t.cpu.unwrap_or_default();
        for (sum, part) in all.parts.iter_mut().zip(t.parts) {
            *sum += part;
        }
        all.frames += u64::from(t.frames);
        all.exchanges += u64::from(t.exchanges);
        all.polls += u64::from(t.polls);
        // The shortest kept is replaced by a longer one.
        if let Some(slot) = self
            .longest
            .iter_mut()
            .min_by_key(|k| k.wall)
            .filter(|k| k.wall < t.wall)
        {
            *slot = *t;
        }
    }

    /// Hands the report over (when the loop stops).
    pub fn publish(&self) {
        let mut longest: Vec<Turn> = self
            .longest
            .iter()
            .filter(|t| !t.wall.is_zero())
            .copied()
            .collect();
        longest.sort_by_key(|t| std::cmp::Reverse(t.wall));
        let lengths = self
            .lengths
            .iter()
            .enumerate()
            .filter(|(_, n)| **n > 0)
            .map(|(i, n)| (lower_bound(i), *n))
            .collect();
        let report = TurnReport {
            turns: self.turns,
            longest,
            lengths,
            totals: self.totals,
        };
        *self.published.lock().unwrap_or_else(|e| e.into_inner()) = report;
    }
}

/// The lower bound of bucket `i`: 0, then 2^(i−1) µs.
fn lower_bound(i: usize) -> Duration {
    match i {
        0 => Duration::ZERO,
        i => Duration::from_micros(1u64 << (i - 1).min(40)),
    }
}

impl fmt::Display for Turn {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:.1} µs at {:.6} s (turn {}): cpu {}, {} involuntary switches, {} minor / {} major page faults, woke {:.1} µs late; {} frames, {} exchanges, {} polls, {} SYNC0 events;",
            self.wall.as_secs_f64() * 1e6,
            self.at.as_secs_f64(),
            self.index,
            self.cpu.map_or("not read".to_owned(), |c| format!(
                "{:.1} µs",
                c.as_secs_f64() * 1e6
            )),
            self.involuntary_switches,
            self.minor_faults,
            self.major_faults,
            self.woke_late.as_secs_f64() * 1e6,
            self.frames,
            self.exchanges,
            self.polls,
            self.sync0_events,
        )?;
        for (name, d) in PART_NAMES.iter().zip(self.parts) {
            write!(f, " {name} {:.1}", d.as_secs_f64() * 1e6)?;
        }
        write!(f, " µs")
    }
}

impl fmt::Display for TurnReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} turns; by length:", self.turns)?;
        for (from, n) in &self.lengths {
            write!(f, " ≥{}µs {n}", from.as_micros())?;
        }
        let all = &self.totals;
        write!(
            f,
            "\n  in all: {:.1} ms (cpu {:.1} ms); {} frames, {} exchanges ({} on a frame's path), {} polls;",
            all.wall.as_secs_f64() * 1e3,
            all.cpu.as_secs_f64() * 1e3,
            all.frames,
            all.exchanges,
            all.exchanges_on_path,
            all.polls
        )?;
        for (name, d) in PART_NAMES.iter().zip(all.parts) {
            write!(f, " {name} {:.1}", d.as_secs_f64() * 1e3)?;
        }
        write!(f, " ms")?;
        if all.frames > 0 {
            // Per frame: what a master's frame costs the loop, on its path or after it.
            let per = |d: Duration| d.as_secs_f64() * 1e6 / all.frames as f64;
            write!(
                f,
                "; per frame {:.1} µs (cpu {:.1} µs):",
                per(all.wall),
                per(all.cpu)
            )?;
            for (name, d) in PART_NAMES.iter().zip(all.parts) {
                write!(f, " {name} {:.1}", per(d))?;
            }
            write!(f, " µs")?;
        }
        for t in &self.longest {
            write!(f, "\n  longest: {t}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_the_longest_turns_longest_first() {
        let origin = Instant::now();
        let mut log = TurnLog::new(origin);
        log.start(0);
        let micros = [5u64, 300, 7, 2000, 1, 40, 60, 80, 90, 100, 9];
        for (k, us) in micros.iter().enumerate() {
            let at = origin + Duration::from_millis(10 * k as u64);
            log.waits_until(Some(at - Duration::from_micros(3)));
            log.begin(at);
            log.frame();
            log.end(at + Duration::from_micros(*us), 2 * k as u64, k % 2 == 0);
        }
        log.publish();
        let report = log.report().lock().unwrap().clone();
        assert_eq!(report.turns, 11);
        let walls: Vec<u64> = report
            .longest
            .iter()
            .map(|t| t.wall.as_micros() as u64)
            .collect();
        assert_eq!(walls, [2000, 300, 100, 90, 80, 60, 40, 9]);
        let first = report.longest[0];
        assert_eq!((first.index, first.frames, first.sync0_events), (3, 1, 2));
        assert_eq!(first.woke_late, Duration::from_micros(3));
        // Every turn, not only the longest, adds to the totals.
        assert_eq!(report.totals.frames, 11);
        assert_eq!(
            report.totals.wall,
            Duration::from_micros(micros.iter().sum::<u64>())
        );
        // Powers of two: 1 µs; 5 and 7; 9; 40 and 60; 80, 90 and 100; 300; 2000.
        let counted: Vec<(u128, u64)> = report
            .lengths
            .iter()
            .map(|(d, n)| (d.as_micros(), *n))
            .collect();
        assert_eq!(
            counted,
            [
                (1, 1),
                (4, 2),
                (8, 1),
                (32, 2),
                (64, 3),
                (256, 1),
                (1024, 1)
            ]
        );
    }
}
