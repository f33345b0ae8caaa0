//! Sub-millisecond sleeps for the cell loop. epoll counts its timeout in whole milliseconds
//! (mio rounds a wait up), so a timer due in 200 µs woke the loop up to a millisecond late: a
//! serial line at 115200 Bd, whose characters are 87 µs apart, paid for it. A timerfd armed
//! for the exact wait wakes the loop on time; the rounded timeout stays as the fallback.

use std::io;
use std::os::fd::{AsRawFd, OwnedFd};
use std::time::Duration;

use mio::unix::SourceFd;
use mio::{Interest, Registry, Token};
use rustix::time::{
    timerfd_create, timerfd_settime, Itimerspec, TimerfdClockId, TimerfdFlags, TimerfdTimerFlags,
    Timespec,
};

/// A one-shot timerfd registered with the loop's poll.
pub(super) struct FineTimer {
    fd: OwnedFd,
}

impl FineTimer {
    pub(super) fn new(registry: &Registry, token: Token) -> io::Result<Self> {
        let fd = timerfd_create(
            TimerfdClockId::Monotonic,
            TimerfdFlags::NONBLOCK | TimerfdFlags::CLOEXEC,
        )?;
        registry.register(&mut SourceFd(&fd.as_raw_fd()), token, Interest::READABLE)?;
        Ok(FineTimer { fd })
    }

    /// Wakes the loop after `wait` (replacing the last wait). A zero wait needs no timer:
    /// the poll then does not sleep.
    pub(super) fn arm(&self, wait: Duration) {
        if wait.is_zero() {
            return;
        }
        let spec = Itimerspec {
            it_interval: Timespec {
                tv_sec: 0,
                tv_nsec: 0,
            },
            it_value: Timespec {
                tv_sec: i64::try_from(wait.as_secs()).unwrap_or(i64::MAX),
                tv_nsec: i64::from(wait.subsec_nanos()),
            },
        };
        if let Err(e) = timerfd_settime(&self.fd, TimerfdTimerFlags::empty(), &spec) {
            // The poll's rounded timeout still wakes the loop, a little late.
            tracing::debug!(error = %e, "timerfd not armed");
        }
    }

    /// After its event: takes the expirations so that the descriptor is quiet again.
    pub(super) fn clear(&self) {
        let mut expirations = [0u8; 8];
        let _ = rustix::io::read(&self.fd, &mut expirations);
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
        let timer = FineTimer::new(poll.registry(), Token(7)).expect("timerfd");
        let mut events = Events::with_capacity(4);
        let mut best = Duration::MAX;
        // The best of several: a loaded machine delays a wake-up, never advances it.
        for _ in 0..20 {
            let start = Instant::now();
            timer.arm(Duration::from_micros(300));
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
}
