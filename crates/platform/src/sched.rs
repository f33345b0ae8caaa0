//! Where a thread runs and at which priority: a bench pins the master and the server under
//! test to CPUs of its choosing, and runs them under `SCHED_FIFO` or at a nice value, as a
//! production master runs. A thread is named by its id (`0`: the calling thread), as
//! [`crate::process::threads`] lists them.

use std::io;

/// Pins thread `tid` (`0`: the calling thread) to CPU `cpu` alone; threads it starts
/// afterwards inherit the placement.
#[cfg(target_os = "linux")]
pub fn pin(tid: u32, cpu: usize) -> io::Result<()> {
    let tid = libc::pid_t::try_from(tid).map_err(|_| io::ErrorKind::InvalidInput)?;
    // SAFETY: `cpu_set_t` is plain old data; all-zero is the empty set.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    if cpu >= libc::CPU_SETSIZE as usize {
        return Err(io::ErrorKind::InvalidInput.into());
    }
    // SAFETY: `cpu` is inside the set (checked above); `set` is valid for the call.
    unsafe { libc::CPU_SET(cpu, &mut set) };
    // SAFETY: `set` is a valid `cpu_set_t` of the size given, for the duration of the call.
    super::cvt(unsafe {
        libc::sched_setaffinity(tid, std::mem::size_of::<libc::cpu_set_t>(), &set)
    })?;
    Ok(())
}

/// The scheduling of the calling thread, to put back later ([`Scheduling::restore`]).
#[cfg(target_os = "linux")]
#[derive(Debug, Clone, Copy)]
pub struct Scheduling {
    policy: libc::c_int,
    priority: libc::c_int,
}

#[cfg(target_os = "linux")]
impl Scheduling {
    /// The calling thread's policy and priority now.
    pub fn of_this_thread() -> io::Result<Scheduling> {
        // SAFETY: no arguments but the calling thread's id 0.
        let policy = super::cvt(unsafe { libc::sched_getscheduler(0) })?;
        let mut param = libc::sched_param { sched_priority: 0 };
        // SAFETY: `param` is valid for writes for the duration of the call.
        super::cvt(unsafe { libc::sched_getparam(0, &mut param) })?;
        Ok(Scheduling {
            policy,
            priority: param.sched_priority,
        })
    }

    /// Puts the calling thread back to this policy and priority.
    pub fn restore(&self) -> io::Result<()> {
        let param = libc::sched_param {
            sched_priority: self.priority,
        };
        // SAFETY: `param` is valid for the duration of the call; pid 0 is the calling thread.
        super::cvt(unsafe { libc::sched_setscheduler(0, self.policy, &param) })?;
        Ok(())
    }
}

/// Thread `tid` (`0`: the calling thread) under `SCHED_FIFO` at `priority`; threads it
/// starts afterwards inherit it. Needs `CAP_SYS_NICE`.
#[cfg(target_os = "linux")]
pub fn set_fifo(tid: u32, priority: i32) -> io::Result<()> {
    let tid = libc::pid_t::try_from(tid).map_err(|_| io::ErrorKind::InvalidInput)?;
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: `param` is a valid sched_param for the duration of the call.
    super::cvt(unsafe { libc::sched_setscheduler(tid, libc::SCHED_FIFO, &param) })?;
    Ok(())
}

/// Thread `tid` (`0`: the calling thread) at nice value `nice` (negative needs
/// `CAP_SYS_NICE`).
#[cfg(target_os = "linux")]
pub fn set_nice(tid: u32, nice: i32) -> io::Result<()> {
    // SAFETY: setpriority(2) on a thread id; no memory is passed.
    super::cvt(unsafe { libc::setpriority(libc::PRIO_PROCESS, tid, nice) })?;
    Ok(())
}

/// CPU placement of a thread is Linux's here.
#[cfg(not(target_os = "linux"))]
pub fn pin(_tid: u32, _cpu: usize) -> io::Result<()> {
    Err(io::ErrorKind::Unsupported.into())
}

/// The scheduling of a thread is Linux's here.
#[cfg(not(target_os = "linux"))]
#[derive(Debug, Clone, Copy)]
pub struct Scheduling;

#[cfg(not(target_os = "linux"))]
impl Scheduling {
    pub fn of_this_thread() -> io::Result<Scheduling> {
        Err(io::ErrorKind::Unsupported.into())
    }

    pub fn restore(&self) -> io::Result<()> {
        Err(io::ErrorKind::Unsupported.into())
    }
}

/// `SCHED_FIFO` on a thread is Linux's here.
#[cfg(not(target_os = "linux"))]
pub fn set_fifo(_tid: u32, _priority: i32) -> io::Result<()> {
    Err(io::ErrorKind::Unsupported.into())
}

/// The nice value of a thread is Linux's here.
#[cfg(not(target_os = "linux"))]
pub fn set_nice(_tid: u32, _nice: i32) -> io::Result<()> {
    Err(io::ErrorKind::Unsupported.into())
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    #[test]
    fn a_thread_pinned_to_cpu_0_and_back_keeps_its_scheduling() {
        std::thread::spawn(|| {
            let was = super::Scheduling::of_this_thread().unwrap();
            super::pin(0, 0).unwrap();
            assert!(super::pin(0, usize::MAX).is_err());
            super::set_nice(0, 1).unwrap();
            was.restore().unwrap();
        })
        .join()
        .unwrap();
    }
}
