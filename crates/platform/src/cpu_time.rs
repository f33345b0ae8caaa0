//! Clocks a measurement reads: the CPU time of the calling thread (the machine is shared, and
//! wall time would count the processes that preempt a bench), the CPU time of the whole
//! process, and `CLOCK_MONOTONIC` as perf stamps its events.

use std::io;
use std::time::Duration;

/// `clock_gettime(clock)` as a [`Duration`].
fn clock(clock: libc::clockid_t) -> io::Result<Duration> {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec for the call to fill.
    super::cvt(unsafe { libc::clock_gettime(clock, &mut ts) })?;
    Ok(Duration::new(
        u64::try_from(ts.tv_sec).unwrap_or(0),
        u32::try_from(ts.tv_nsec).unwrap_or(0),
    ))
}

/// The CPU time the calling thread has used (`CLOCK_THREAD_CPUTIME_ID`); zero where the
/// clock cannot be read.
pub fn thread() -> Duration {
    clock(libc::CLOCK_THREAD_CPUTIME_ID).unwrap_or(Duration::ZERO)
}

/// `CLOCK_MONOTONIC` now, in ns (the clock `perf record -k CLOCK_MONOTONIC` stamps its
/// events with).
pub fn monotonic_ns() -> u64 {
    let t = clock(libc::CLOCK_MONOTONIC).unwrap_or(Duration::ZERO);
    u64::try_from(t.as_nanos()).unwrap_or(u64::MAX)
}

/// The process's CPU time, user and system, of every thread (ended ones too); zero where it
/// cannot be read.
pub fn process() -> Duration {
    // SAFETY: `rusage` is plain old data; all-zero is a valid value.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `usage` is valid for writes for the duration of the call.
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } != 0 {
        return Duration::ZERO;
    }
    let tv = |t: libc::timeval| {
        Duration::new(
            u64::try_from(t.tv_sec).unwrap_or(0),
            u32::try_from(t.tv_usec).unwrap_or(0) * 1000,
        )
    };
    tv(usage.ru_utime) + tv(usage.ru_stime)
}

/// Clock ticks per second, the unit of the CPU times in `/proc/*/stat` (`_SC_CLK_TCK`; at
/// least 1).
pub fn ticks_per_second() -> u64 {
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    u64::try_from(hz).unwrap_or(1).max(1)
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_thread_that_works_uses_cpu_time() {
        let t = super::thread();
        let mut x = 0u64;
        for i in 0..1_000_000u64 {
            x = std::hint::black_box(x.wrapping_add(i));
        }
        assert!(super::thread() > t, "{x}");
        assert!(super::process() >= super::thread() - t);
        assert!(super::monotonic_ns() > 0);
        assert!(super::ticks_per_second() >= 1);
    }
}
