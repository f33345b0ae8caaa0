//! Scheduling of the calling thread: real time for the cell loop, batch for the work that
//! must not take the CPU from it.

use std::io;

/// `SCHED_FIFO` at `priority` for the calling thread (Linux; needs `CAP_SYS_NICE`).
#[cfg(target_os = "linux")]
pub fn set_fifo(priority: u8) -> io::Result<()> {
    let param = libc::sched_param {
        sched_priority: libc::c_int::from(priority),
    };
    // SAFETY: `param` is valid for the call; pid 0 is the calling thread.
    super::fd::cvt(unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) })?;
    Ok(())
}

/// `SCHED_FIFO` through `sched_setscheduler` is Linux's.
#[cfg(not(target_os = "linux"))]
pub fn set_fifo(_priority: u8) -> io::Result<()> {
    Err(io::Error::new(
        io::ErrorKind::Unsupported,
        "SCHED_FIFO for a thread is Linux's",
    ))
}

/// `SCHED_BATCH` for the calling thread (Linux; no privilege needed): the scheduler takes it
/// for throughput work, and its wake-ups do not preempt a running thread. The console's
/// threads run so: a WebSocket batch or a page load that wakes them does not push the cell
/// loop off its CPU, and the loop, waking, preempts them as before.
#[cfg(target_os = "linux")]
pub fn set_batch() -> io::Result<()> {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: `param` is valid for the call; pid 0 is the calling thread.
    super::fd::cvt(unsafe { libc::sched_setscheduler(0, libc::SCHED_BATCH, &param) })?;
    Ok(())
}

/// `SCHED_BATCH` is Linux's.
#[cfg(not(target_os = "linux"))]
pub fn set_batch() -> io::Result<()> {
    Err(io::Error::new(
        io::ErrorKind::Unsupported,
        "SCHED_BATCH for a thread is Linux's",
    ))
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    #[test]
    fn a_batch_thread_is_batch_and_the_others_are_not() {
        let policy = || {
            // SAFETY: no arguments but the calling thread's id 0.
            unsafe { libc::sched_getscheduler(0) }
        };
        let (was, now) = std::thread::spawn(move || {
            let was = policy();
            super::set_batch().unwrap();
            (was, policy())
        })
        .join()
        .unwrap();
        assert_eq!(was, libc::SCHED_OTHER);
        assert_eq!(now, libc::SCHED_BATCH);
        assert_eq!(policy(), libc::SCHED_OTHER, "only the calling thread");
    }
}
