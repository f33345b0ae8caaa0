//! Real-time scheduling of the calling thread.

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
