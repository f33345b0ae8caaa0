//! When the cell loop wakes next, and how much later its timer may wake it without harm.
//!
//! Arming the timer earlier than it is armed reprograms the CPU's timer: 3–7 µs on these VMs,
//! which a master sharing the loop's CPU waits for when the loop does it after a frame's
//! answer and before it sleeps. Most of what is due must run at its time (a drive's step, a
//! SYNC0 event), but a chain's deferred exchange only has to run somewhere between the
//! master's frames: a timer armed anywhere in that stretch does. So the loop arms its timer
//! for the next exchange while it runs the one before, at the time the master's next frame
//! will leave it, and the frame finds the timer armed and leaves it as it is.

use std::time::{Duration, Instant};

use crate::ecat::chain::{STEP_GRACE, TICK};

/// A deferred exchange longer than this runs between the master's frames rather than on the
/// next frame's path: about what a wake-up of the loop between two frames costs the next one.
pub(super) const LONG_EXCHANGE: Duration = Duration::from_micros(10);

/// The loop wakes at `at`; a timer armed for any time up to `latest` wakes it as well, unless
/// it falls before `earliest`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct WakeUp {
    pub at: Instant,
    pub latest: Instant,
    /// Before this a timer wakes the loop to harm: a chain's exchange run then keeps a master
    /// that shares the loop's CPU from the answer it has not read yet. `None`: a timer armed
    /// earlier wakes the loop early at worst.
    pub earliest: Option<Instant>,
}

impl WakeUp {
    /// Due at `at`, and not later.
    pub(super) fn exact(at: Instant) -> Self {
        WakeUp {
            at,
            latest: at,
            earliest: None,
        }
    }

    /// The earlier of two: the loop wakes for the first, by the latest either allows, and not
    /// before the earliest either allows unless the other wakes it before then anyway.
    pub(super) fn first(a: Option<WakeUp>, b: Option<WakeUp>) -> Option<WakeUp> {
        match (a, b) {
            (Some(a), Some(b)) => Some(WakeUp {
                at: a.at.min(b.at),
                latest: a.latest.min(b.latest),
                earliest: match (a.earliest, b.earliest) {
                    (None, None) => None,
                    (Some(e), None) => Some(e.min(b.at)),
                    (None, Some(e)) => Some(e.min(a.at)),
                    (Some(x), Some(y)) => Some(x.min(y)),
                },
            }),
            (a, b) => a.or(b),
        }
    }

    /// Whether a timer armed for `timer` serves: by the latest, and not before the earliest.
    pub(super) fn served_by(&self, timer: Instant) -> bool {
        timer <= self.latest && self.earliest.is_none_or(|e| timer >= e)
    }
}

/// What the loop knows of a chain's master and of its devices' exchange: when to run the
/// exchange it deferred after a frame, and when the next one will come.
#[derive(Debug, Clone, Copy)]
pub(super) struct ChainPace {
    /// The devices' exchange after the last frame, at that frame's time on the cell's clock,
    /// while it is still to run: the loop runs it before anything reads the chain again, or
    /// between the master's frames ([`ChainPace::wake_up`]).
    pending: Option<od::Instant>,
    /// When the last frame arrived: a frame's time never goes back.
    last_frame: Instant,
    /// The master's cycle as the loop sees it ([`master_cycle`]; `Duration::MAX` before the
    /// first frame, whose gap counts from the loop's start).
    cycle: Duration,
    /// How long the deferred exchange takes, as the loop sees it ([`ChainPace::exchanged`]).
    exchange_cost: Duration,
}

impl ChainPace {
    /// Before the first frame, as of `now`.
    pub(super) fn new(now: Instant) -> Self {
        ChainPace {
            pending: None,
            last_frame: now,
            cycle: Duration::MAX,
            exchange_cost: Duration::ZERO,
        }
    }

    /// A frame arrived at `arrived`: the master's cycle follows it. Returns the frame's time,
    /// which is never before the frame before it.
    pub(super) fn frame(&mut self, arrived: Instant) -> Instant {
        self.cycle = master_cycle(
            self.cycle,
            arrived.saturating_duration_since(self.last_frame),
        );
        self.last_frame = arrived.max(self.last_frame);
        self.last_frame
    }

    /// The exchange after the last frame, at its time `t`, waits.
    pub(super) fn defer(&mut self, t: od::Instant) {
        self.pending = Some(t);
    }

    /// Whether an exchange waits.
    pub(super) fn pending(&self) -> bool {
        self.pending.is_some()
    }

    /// The exchange that waits, to run now: its frame's time.
    pub(super) fn take(&mut self) -> Option<od::Instant> {
        self.pending.take()
    }

    /// The exchange taken ran and took `took`. Its cost is the longest of the recent ones,
    /// each exchange taking an eighth off: 64 CMMP-AS take 28 µs on the frames where their
    /// device logic runs (every 500 µs) and 13 µs on the others (in process, warm). Judged
    /// by the last alone, one that came in under [`LONG_EXCHANGE`] made the chain short for
    /// a frame: nothing was planned between the frames, and the next one found its exchange
    /// still to run (at 4 kHz, 64 drives: 0.4–1 % of the frames before, 0–0.3 % after).
    pub(super) fn exchanged(&mut self, took: Duration) {
        self.exchange_cost = took.max(self.exchange_cost - self.exchange_cost / 8);
    }

    /// When the loop wakes for the chain's deferred exchange.
    ///
    /// A long one (64 drives: tens of µs) runs half-way between the master's frames (half
    /// its cycle), or wherever a timer armed already falls between a quarter and three
    /// quarters of the way: a master that shares the loop's CPU has its answer and its time
    /// after it first, and its next frame finds the devices' work done rather than waiting
    /// behind it. While none is pending, the wake-up of the next one is planned from the
    /// master's pace (its next frame a cycle after the last), so the timer is armed for it
    /// now, between the frames, not on the frame's path; a master that stops costs one
    /// wake-up for nothing. A frame that comes more than a quarter cycle later than planned
    /// has the timer armed anew: kept, it would run the exchange while the master, preempted
    /// right after its send, has still to read its answer (a scheduler trace at 4 kHz: most
    /// of the round trips in the slowest percent were those, each waiting out an exchange).
    ///
    /// A short one (a few drives) waits for the next frame, as a wake-up of its own between
    /// the frames would cost that frame more than the exchange (one CMMP-AS at 1 kHz: p50
    /// 2.2–2.5× the floor with it, 1.2–1.35× without).
    ///
    /// At the latest an exchange runs when its own step would fall due (`TICK` +
    /// `STEP_GRACE`). It runs at its frame's time whenever the loop gets to it, so its
    /// results do not depend on this choice.
    pub(super) fn wake_up(&self, now: Instant) -> Option<WakeUp> {
        let step = TICK + STEP_GRACE;
        let long = self.exchange_cost > LONG_EXCHANGE;
        let gap = self.cycle;
        // The exchange that waits is the last frame's.
        let frame = self.last_frame;
        match self.pending {
            Some(_) if long => Some(WakeUp {
                at: frame + step.min(gap / 2),
                latest: frame + step.min(gap / 4 * 3),
                earliest: Some(frame + step.min(gap / 4)),
            }),
            Some(_) => Some(WakeUp::exact(frame + step)),
            None if long && gap <= step => {
                let next = frame + gap;
                Some(WakeUp {
                    at: next + gap / 2,
                    latest: next + gap / 4 * 3,
                    earliest: Some(next + gap / 4),
                })
                .filter(|w| w.at > now)
            }
            None => None,
        }
    }
}

/// The master's cycle after a frame `gap` after the one before, from its cycle so far: each
/// gap moves it an eighth of the way, and counts as at most twice the cycle. A master's
/// frames come a cycle apart, give or take its wake-ups' jitter; a frame that came late (the
/// loop's own long exchange held the master off the CPU) and the early-looking one after it
/// would each move a half-way point planned from the last gap alone by half their jitter, to
/// where the next frame finds the exchange still to run. A master that stalls moves it an
/// eighth up; one that changes its cycle is followed within a few dozen frames.
pub(super) fn master_cycle(cycle: Duration, gap: Duration) -> Duration {
    if cycle == Duration::MAX {
        return gap;
    }
    let gap = gap.min(cycle.saturating_mul(2));
    if gap >= cycle {
        cycle + (gap - cycle) / 8
    } else {
        cycle - (cycle - gap) / 8
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GAP: Duration = Duration::from_micros(250);

    /// A chain whose last frame came at `start`, a cycle of [`GAP`] after the one before,
    /// its exchange still `pending` or not; the exchange before took `took_us`.
    fn pace(start: Instant, pending: bool, took_us: u64) -> ChainPace {
        pace_of(GAP, start, pending, took_us)
    }

    /// As [`pace`], a master's cycle of `gap`.
    fn pace_of(gap: Duration, start: Instant, pending: bool, took_us: u64) -> ChainPace {
        let mut pace = ChainPace::new(start - gap * 2);
        pace.frame(start - gap);
        pace.frame(start);
        pace.exchanged(Duration::from_micros(took_us));
        if pending {
            pace.defer(od::Instant::from_millis(1));
        }
        pace
    }

    /// A long exchange is due half-way to the next frame, and may run until three quarters.
    #[test]
    fn a_long_exchange_runs_half_way_between_frames() {
        let t = Instant::now();
        let w = pace(t, true, 30).wake_up(t).expect("pending");
        assert_eq!(w.at, t + GAP / 2);
        assert_eq!(w.latest, t + GAP / 4 * 3);
    }

    /// With none pending, the wake-up for the next frame's exchange is planned from the
    /// master's pace: the timer armed for it then is within what that frame's exchange
    /// allows, so the frame leaves it as it is, even when it comes a little early or late.
    #[test]
    fn the_next_exchange_is_planned_from_the_masters_pace() {
        let t = Instant::now();
        let planned = pace(t, false, 30).wake_up(t + GAP / 2).expect("planned");
        assert_eq!(planned.at, t + GAP + GAP / 2);
        for early_or_late in [-40i64, 0, 40] {
            let frame = if early_or_late < 0 {
                t + GAP - Duration::from_micros(early_or_late.unsigned_abs())
            } else {
                t + GAP + Duration::from_micros(early_or_late.unsigned_abs())
            };
            let due = pace(frame, true, 30).wake_up(frame).expect("pending");
            assert!(due.served_by(planned.at), "{early_or_late} µs");
        }
    }

    /// A master that stopped gets one planned wake-up, not one after another.
    #[test]
    fn no_plan_once_the_next_frame_is_overdue() {
        let t = Instant::now();
        assert_eq!(pace(t, false, 30).wake_up(t + GAP * 2), None);
    }

    /// A short exchange waits for the next frame (or its step's time), and plans nothing.
    #[test]
    fn a_short_exchange_waits_for_the_next_frame() {
        let t = Instant::now();
        assert_eq!(
            pace(t, true, 5).wake_up(t),
            Some(WakeUp::exact(t + TICK + STEP_GRACE))
        );
        assert_eq!(pace(t, false, 5).wake_up(t), None);
    }

    /// A master slower than the drives' step plans nothing: the step wakes the loop anyway.
    #[test]
    fn a_slow_master_plans_nothing() {
        let t = Instant::now();
        let slow = pace_of(Duration::from_millis(20), t, false, 30);
        assert_eq!(slow.wake_up(t), None);
    }

    /// A chain whose exchanges alternate between long and just short stays long; one that
    /// turns short for good is short within a few dozen exchanges.
    #[test]
    fn the_exchange_cost_remembers_the_long_ones() {
        let us = Duration::from_micros;
        let t = Instant::now();
        let mut p = pace(t, false, 28);
        for _ in 0..50 {
            p.exchanged(us(9));
            assert!(p.wake_up(t).is_some(), "planned while the long ones recur");
            p.exchanged(us(28));
        }
        for _ in 0..40 {
            p.exchanged(us(2));
        }
        assert_eq!(p.wake_up(t), None, "short now: waits for the frame");
    }

    /// A frame stamped before the last one (the kernel's stamps of two sockets, a clock
    /// step) takes the last one's time: a frame's time never goes back.
    #[test]
    fn a_frames_time_never_goes_back() {
        let t = Instant::now();
        let mut p = pace(t, false, 30);
        assert_eq!(p.frame(t - GAP / 2), t);
        assert_eq!(p.frame(t + GAP), t + GAP);
    }

    /// The exchange deferred is taken once, at its frame's time.
    #[test]
    fn a_deferred_exchange_is_taken_once() {
        let t = Instant::now();
        let mut p = pace(t, false, 30);
        p.defer(od::Instant::from_millis(7));
        assert!(p.pending());
        assert_eq!(p.take(), Some(od::Instant::from_millis(7)));
        assert!(!p.pending());
        assert_eq!(p.take(), None);
    }

    /// A late frame and the early-looking one after it barely move the cycle; a stall moves
    /// it an eighth up; a new cycle is followed.
    #[test]
    fn the_cycle_follows_the_master_not_its_jitter() {
        let us = Duration::from_micros;
        assert_eq!(master_cycle(Duration::MAX, us(250)), us(250));
        let late = master_cycle(us(250), us(310));
        let after = master_cycle(late, us(190));
        assert!(after.abs_diff(us(250)) < us(10), "{after:?}");
        assert_eq!(master_cycle(us(250), us(40_000)), us(250) + us(250) / 8);
        let mut cycle = us(1000);
        for _ in 0..48 {
            cycle = master_cycle(cycle, us(250));
        }
        assert!(cycle.abs_diff(us(250)) < us(2), "{cycle:?}");
    }

    /// A wake-up due a cycle after `t`, by two at the latest, not before half a cycle.
    fn stretch(t: Instant) -> WakeUp {
        WakeUp {
            at: t + GAP,
            latest: t + GAP * 2,
            earliest: Some(t + GAP / 2),
        }
    }

    #[test]
    fn the_earlier_wake_up_keeps_the_tighter_latest() {
        let t = Instant::now();
        let a = stretch(t);
        let b = WakeUp::exact(t + GAP + GAP / 2);
        let both = WakeUp::first(Some(a), Some(b)).expect("both");
        assert_eq!((both.at, both.latest), (a.at, b.at));
        assert_eq!(both.earliest, a.earliest, "b allows any earlier timer");
        assert_eq!(WakeUp::first(None, Some(b)), Some(b));
    }

    /// A wake-up due before another's earliest time wakes the loop then anyway: a timer up to
    /// it serves both.
    #[test]
    fn an_exact_wake_up_before_the_stretch_lowers_its_bound() {
        let t = Instant::now();
        let a = stretch(t);
        let b = WakeUp::exact(t + GAP / 4);
        let both = WakeUp::first(Some(a), Some(b)).expect("both");
        assert_eq!(both.earliest, Some(b.at));
        assert!(both.served_by(b.at));
        assert!(!both.served_by(b.at + GAP / 8));
    }

    /// The plan for an on-time frame serves that frame's exchange; once the frame comes more
    /// than a quarter cycle late, the planned timer would run the exchange before the master
    /// has read its answer, and does not serve.
    #[test]
    fn a_late_frame_does_not_keep_the_planned_timer() {
        let t = Instant::now();
        let planned = pace(t, false, 30).wake_up(t + GAP / 2).expect("planned");
        let on_time = pace(t + GAP, true, 30).wake_up(t + GAP).expect("pending");
        assert!(on_time.served_by(planned.at));
        let late = t + GAP + GAP / 4 + Duration::from_micros(10);
        let pending = pace(late, true, 30).wake_up(late).expect("pending");
        assert!(!pending.served_by(planned.at));
        assert!(pending.served_by(pending.at));
    }
}
