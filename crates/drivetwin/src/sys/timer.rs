//! One-shot timers a poll waits for as for a socket (a Linux timerfd): a wait shorter than a
//! millisecond, which epoll's timeout cannot express. Elsewhere none is made and the poll's
//! timeout alone wakes the loop.

use std::io;
use std::os::fd::{AsRawFd, OwnedFd, RawFd};
use std::time::Duration;

/// A monotonic one-shot timer, non-blocking.
#[derive(Debug)]
pub struct Timer {
    fd: OwnedFd,
}

#[cfg(target_os = "linux")]
impl Timer {
    pub fn new() -> io::Result<Timer> {
        use rustix::time::{timerfd_create, TimerfdClockId, TimerfdFlags};
        let fd = timerfd_create(
            TimerfdClockId::Monotonic,
            TimerfdFlags::NONBLOCK | TimerfdFlags::CLOEXEC,
        )?;
        Ok(Timer { fd })
    }

    /// Fires `wait` from now (replacing what it was armed for).
    pub fn arm(&self, wait: Duration) -> io::Result<()> {
        use rustix::time::{timerfd_settime, Itimerspec, TimerfdTimerFlags, Timespec};
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
        timerfd_settime(&self.fd, TimerfdTimerFlags::empty(), &spec)?;
        Ok(())
    }

    /// Takes the expirations, so that the descriptor is quiet again.
    pub fn clear(&self) {
        let mut expirations = [0u8; 8];
        let _ = rustix::io::read(&self.fd, &mut expirations);
    }
}

#[cfg(not(target_os = "linux"))]
impl Timer {
    /// timerfd is Linux's.
    pub fn new() -> io::Result<Timer> {
        Err(io::Error::new(
            io::ErrorKind::Unsupported,
            "timerfd is Linux's",
        ))
    }

    pub fn arm(&self, _wait: Duration) -> io::Result<()> {
        Err(io::ErrorKind::Unsupported.into())
    }

    pub fn clear(&self) {}
}

impl AsRawFd for Timer {
    fn as_raw_fd(&self) -> RawFd {
        self.fd.as_raw_fd()
    }
}
