//! Sub-millisecond sleeps for the cell loop. epoll counts its timeout in whole milliseconds
//! (mio rounds a wait up), so a timer due in 200 µs woke the loop up to a millisecond late: a
//! serial line at 115200 Bd, whose characters are 87 µs apart, paid for it. A timerfd armed
//! for the exact wait wakes the loop on time; the rounded timeout stays as the fallback.

use std::io;
use std::os::fd::AsRawFd;
use std::time::{Duration, Instant};

use mio::unix::SourceFd;
use mio::{Interest, Registry, Token};

use super::wake_up::WakeUp;
use crate::sys::timer::Timer;

/// A one-shot timerfd registered with the loop's poll.
pub(super) struct FineTimer {
    timer: Timer,
    /// The deadline the timer is armed for, until it fires. Arming a timer is a system call
    /// that reprograms the CPU's timer, several microseconds on a VM: a loop answering
    /// requests one after another under the same deadline (a Modbus client between two
    /// cycles) arms it once, not once per request.
    armed: Option<Instant>,
}

impl FineTimer {
    pub(super) fn new(registry: &Registry, token: Token) -> io::Result<Self> {
        let timer = Timer::new()?;
        registry.register(&mut SourceFd(&timer.as_raw_fd()), token, Interest::READABLE)?;
        Ok(FineTimer { timer, armed: None })
    }

    /// Wakes the loop at `wake.at`, `wait` from now. A zero wait needs no timer: the poll
    /// then does not sleep. A timer already armed for `wake.latest` or earlier is left as it
    /// is ([`WakeUp::served_by`]): it wakes the loop early at worst, and the loop arms it then
    /// for what is due. Only a wake-up earlier than the armed one, or one that must not come
    /// as early, costs a system call on the path that moved it.
    pub(super) fn arm(&mut self, wake: WakeUp, wait: Duration) {
        if wait.is_zero() || self.serves(wake) {
            return;
        }
        match self.timer.arm(wait) {
            Ok(_) => self.armed = Some(wake.at),
            Err(e) => {
                // The poll's rounded timeout still wakes the loop, a little late.
                self.armed = None;
                tracing::debug!(error = %e, "timerfd not armed");
            }
        }
    }

    /// The time it is armed for, until it fires.
    pub(super) fn armed(&self) -> Option<Instant> {
        self.armed
    }

    /// Whether it is armed (and has not fired yet) for a time that serves `wake`.
    pub(super) fn serves(&self, wake: WakeUp) -> bool {
        self.armed.is_some_and(|at| wake.served_by(at))
    }

    /// After its event: takes the expirations so that the descriptor is quiet again.
    pub(super) fn clear(&mut self) {
        self.armed = None;
        self.timer.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mio::{Events, Poll};
    use std::time::Instant;

    /// A 300 µs wait ends after 300 µs, not after the millisecond epoll would round it to.
    #[test]
    fn a_sub_millisecond_wait_wakes_the_poll() {
        let mut poll = Poll::new().expect("poll");
        let mut timer = FineTimer::new(poll.registry(), Token(7)).expect("timerfd");
        let mut events = Events::with_capacity(4);
        let mut best = Duration::MAX;
        // The best of several: a loaded machine delays a wake-up, never advances it.
        for _ in 0..20 {
            let start = Instant::now();
            let wait = Duration::from_micros(300);
            timer.arm(WakeUp::exact(start + wait), wait);
            poll.poll(&mut events, Some(Duration::from_secs(1)))
                .expect("poll");
            let took = start.elapsed();
            assert!(
                events.iter().any(|e| e.token() == Token(7)),
                "the timer's event"
            );
            timer.clear();
            assert!(took >= Duration::from_micros(300), "{took:?}");
            best = best.min(took);
        }
        assert!(best < Duration::from_micros(900), "woke after {best:?}");
    }

    /// The deadline it is armed for is not armed again (no second wake-up is lost either:
    /// the first arming still fires), and after it fired the same deadline arms it anew.
    #[test]
    fn the_same_deadline_is_armed_once() {
        let mut poll = Poll::new().expect("poll");
        let mut timer = FineTimer::new(poll.registry(), Token(7)).expect("timerfd");
        let mut events = Events::with_capacity(4);
        let wait = Duration::from_micros(500);
        let deadline = Instant::now() + wait;
        timer.arm(WakeUp::exact(deadline), wait);
        assert_eq!(timer.armed, Some(deadline));
        // Armed again for the same deadline with a shorter wait (time has passed): no change.
        timer.arm(WakeUp::exact(deadline), Duration::from_micros(100));
        poll.poll(&mut events, Some(Duration::from_secs(1)))
            .expect("poll");
        assert!(events.iter().any(|e| e.token() == Token(7)));
        assert!(
            Instant::now() >= deadline,
            "it fired at the first arming's time"
        );
        timer.clear();
        assert_eq!(timer.armed, None);
        let later = Instant::now() + wait;
        timer.arm(WakeUp::exact(later), wait);
        assert_eq!(timer.armed, Some(later));
    }

    /// A deadline that moves later leaves the timer as it is (it fires early, and the loop
    /// arms it then); one that moves earlier arms it anew, so no deadline is passed asleep.
    #[test]
    fn only_an_earlier_deadline_arms_it_again() {
        let mut poll = Poll::new().expect("poll");
        let mut timer = FineTimer::new(poll.registry(), Token(7)).expect("timerfd");
        let mut events = Events::with_capacity(4);
        let start = Instant::now();
        let first = start + Duration::from_micros(800);
        timer.arm(WakeUp::exact(first), Duration::from_micros(800));
        timer.arm(
            WakeUp::exact(first + Duration::from_millis(1)),
            Duration::from_micros(1800),
        );
        assert_eq!(timer.armed, Some(first), "a later deadline keeps the timer");
        assert!(timer.serves(WakeUp::exact(first + Duration::from_millis(1))));
        let earlier = start + Duration::from_micros(300);
        timer.arm(WakeUp::exact(earlier), Duration::from_micros(300));
        assert_eq!(timer.armed, Some(earlier), "an earlier one arms it");
        poll.poll(&mut events, Some(Duration::from_secs(1)))
            .expect("poll");
        assert!(events.iter().any(|e| e.token() == Token(7)));
        let woke = start.elapsed();
        assert!(woke >= Duration::from_micros(300), "{woke:?}");
        timer.clear();
        assert!(!timer.serves(WakeUp::exact(first)));
    }

    /// A wake-up due 300 µs after `start`, by 450 µs, not before 200 µs: a chain's exchange
    /// between two frames.
    fn stretch(start: Instant) -> WakeUp {
        WakeUp {
            at: start + Duration::from_micros(300),
            latest: start + Duration::from_micros(450),
            earliest: Some(start + Duration::from_micros(200)),
        }
    }

    /// A timer armed for `planned_us` after a start, then asked for `wake(start)`: the time
    /// the timer is armed for after that, the planned one and the wake-up's.
    fn armed_after(
        planned_us: u64,
        wake: impl Fn(Instant) -> WakeUp,
    ) -> (Option<Instant>, Instant, Instant) {
        let poll = Poll::new().expect("poll");
        let mut timer = FineTimer::new(poll.registry(), Token(7)).expect("timerfd");
        let start = Instant::now();
        let planned = start + Duration::from_micros(planned_us);
        timer.arm(WakeUp::exact(planned), Duration::from_micros(planned_us));
        let wake = wake(start);
        timer.arm(wake, wake.at.saturating_duration_since(Instant::now()));
        (timer.armed(), planned, wake.at)
    }

    /// A wake-up that may come later than its time (a chain's exchange between two frames)
    /// keeps a timer armed within its stretch: no system call.
    #[test]
    fn a_timer_armed_within_the_stretch_is_kept() {
        let (armed, planned, _) = armed_after(400, stretch);
        assert_eq!(armed, Some(planned), "kept");
        let tight = |start: Instant| WakeUp {
            at: start + Duration::from_micros(300),
            latest: start + Duration::from_micros(350),
            earliest: None,
        };
        let (armed, _, at) = armed_after(400, tight);
        assert_eq!(armed, Some(at), "armed anew for its time");
    }

    /// A timer armed before a wake-up's earliest time (planned for a frame that then came
    /// late) is armed anew for the wake-up's time, though it would fire before its latest.
    #[test]
    fn a_timer_armed_before_the_stretch_is_armed_anew() {
        let (armed, _, at) = armed_after(100, stretch);
        assert_eq!(armed, Some(at), "armed anew");
        // Without a lower bound the earlier timer would have been kept.
        let (armed, planned, _) = armed_after(100, |start| WakeUp {
            earliest: None,
            ..stretch(start)
        });
        assert_eq!(armed, Some(planned), "kept");
    }
}
