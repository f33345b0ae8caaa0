//! Real-time scheduling for the threads that play a drive's fieldbus task.

use std::io;

/// `SCHED_FIFO` at `priority` (1…99) for the calling thread. Needs `CAP_SYS_NICE` (root).
#[cfg(target_os = "linux")]
pub fn set_fifo_priority(priority: u8) -> io::Result<()> {
    if !(1..=99).contains(&priority) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("real-time priority {priority}: must be 1…99"),
        ));
    }
    let param = libc::sched_param {
        sched_priority: libc::c_int::from(priority),
    };
    // SAFETY: `param` is valid for the call; pid 0 is the calling thread.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_of_range_priority_is_refused() {
        assert_eq!(
            set_fifo_priority(0).unwrap_err().kind(),
            io::ErrorKind::InvalidInput
        );
        assert_eq!(
            set_fifo_priority(100).unwrap_err().kind(),
            io::ErrorKind::InvalidInput
        );
    }
}
