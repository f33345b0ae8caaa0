//! What the calling thread has used so far (`getrusage(2)`, `RUSAGE_THREAD`): its CPU time,
//! its page faults and the times the scheduler took the CPU from it, as the cell loop records
//! them for its longest turns. Elsewhere nothing is read (zeros).

use std::time::Duration;

/// The calling thread's use of the machine since it started.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ThreadUsage {
    /// CPU time (`CLOCK_THREAD_CPUTIME_ID`, exact where `getrusage` is as of the last tick;
    /// Linux counts it without the time the host stole from a virtual CPU,
    /// `CONFIG_PARAVIRT_TIME_ACCOUNTING`).
    pub cpu: Duration,
    /// Page faults served without I/O (a page first touched, a copy on write).
    pub minor_faults: u64,
    /// Page faults that waited for I/O.
    pub major_faults: u64,
    /// Times the scheduler switched the thread out while it could run (a task of higher
    /// priority, or its time slice ended).
    pub involuntary_switches: u64,
}

/// The calling thread's [`ThreadUsage`]; zeros where it cannot be read.
#[cfg(target_os = "linux")]
pub fn thread_usage() -> ThreadUsage {
    // SAFETY: `rusage` is plain old data; all-zero is a valid value.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `usage` is valid for writes for the duration of the call.
    if unsafe { libc::getrusage(libc::RUSAGE_THREAD, &mut usage) } != 0 {
        return ThreadUsage::default();
    }
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is valid for writes for the duration of the call.
    let cpu = if unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) } == 0 {
        Duration::new(
            u64::try_from(ts.tv_sec).unwrap_or(0),
            u32::try_from(ts.tv_nsec).unwrap_or(0),
        )
    } else {
        Duration::ZERO
    };
    ThreadUsage {
        cpu,
        minor_faults: u64::try_from(usage.ru_minflt).unwrap_or(0),
        major_faults: u64::try_from(usage.ru_majflt).unwrap_or(0),
        involuntary_switches: u64::try_from(usage.ru_nivcsw).unwrap_or(0),
    }
}

/// `RUSAGE_THREAD` is Linux's.
#[cfg(not(target_os = "linux"))]
pub fn thread_usage() -> ThreadUsage {
    ThreadUsage::default()
}
