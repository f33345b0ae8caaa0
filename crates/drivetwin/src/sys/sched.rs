//! Scheduling of the calling thread: real time or a short time slice for the cell loop,
//! batch for the work that must not take the CPU from it.
//!
//! The loop's settings carry `SCHED_RESET_ON_FORK` (`sched(7)`): a thread the loop starts
//! (a parameter save's file writer) begins at normal priority with the default slice, not
//! at the loop's, so work off the frame's path never competes with it on its terms.

use std::io;
use std::time::Duration;

/// `SCHED_FIFO` at `priority` for the calling thread, its children reset to normal
/// priority (Linux; needs `CAP_SYS_NICE` or an `RLIMIT_RTPRIO` of at least `priority`).
#[cfg(target_os = "linux")]
pub fn set_fifo(priority: u8) -> io::Result<()> {
    let param = libc::sched_param {
        sched_priority: libc::c_int::from(priority),
    };
    // SAFETY: `param` is valid for the call; pid 0 is the calling thread.
    super::fd::cvt(unsafe {
        libc::sched_setscheduler(0, libc::SCHED_FIFO | libc::SCHED_RESET_ON_FORK, &param)
    })?;
    Ok(())
}

/// The calling thread's `sched_attr` (`sched_getattr(2)`).
#[cfg(target_os = "linux")]
fn attributes() -> io::Result<libc::sched_attr> {
    // SAFETY: `sched_attr` is plain old data; all-zero is a valid value.
    let mut attr: libc::sched_attr = unsafe { std::mem::zeroed() };
    let size = std::mem::size_of::<libc::sched_attr>() as libc::c_uint;
    // SAFETY: `attr` is valid for writes of `size` bytes; pid 0 is the calling thread.
    let r = unsafe {
        libc::syscall(
            libc::SYS_sched_getattr,
            0,
            &mut attr as *mut libc::sched_attr,
            size,
            0,
        )
    };
    if r < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(attr)
}

/// A time slice of `slice` for the calling thread under the fair scheduler (EEVDF, Linux
/// 6.12 and later: `sched_attr.sched_runtime` of a `SCHED_OTHER` thread, 0.1–100 ms), its
/// nice value kept, its children reset to the default slice. EEVDF orders runnable threads
/// by virtual deadline, a thread's eligible time plus its slice: a thread that asks for a
/// short slice runs sooner after it wakes, and preempts a neighbour that asked for none,
/// in exchange for shorter turns. No privilege is needed. Returns the slice the kernel
/// keeps: zero where the kernel has no slice of a thread's own (before 6.12), which takes
/// the call and ignores it.
#[cfg(target_os = "linux")]
pub fn set_slice(slice: Duration) -> io::Result<Duration> {
    let mut attr = attributes()?;
    attr.size = std::mem::size_of::<libc::sched_attr>() as u32;
    attr.sched_policy = libc::SCHED_OTHER as u32;
    attr.sched_flags = libc::SCHED_FLAG_RESET_ON_FORK as u64;
    attr.sched_priority = 0;
    attr.sched_runtime = u64::try_from(slice.as_nanos()).unwrap_or(u64::MAX);
    attr.sched_deadline = 0;
    attr.sched_period = 0;
    // SAFETY: `attr` is a valid `sched_attr` of the size it names for the duration of the
    // call; pid 0 is the calling thread.
    let r = unsafe {
        libc::syscall(
            libc::SYS_sched_setattr,
            0,
            &attr as *const libc::sched_attr,
            0,
        )
    };
    if r < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(Duration::from_nanos(attributes()?.sched_runtime))
}

/// A slice of a thread's own is Linux's.
#[cfg(not(target_os = "linux"))]
pub fn set_slice(_slice: Duration) -> io::Result<Duration> {
    Err(io::Error::new(
        io::ErrorKind::Unsupported,
        "a time slice for a thread is Linux's",
    ))
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

    /// The policy and slice of the calling thread.
    fn policy_and_slice() -> (libc::c_int, u64) {
        super::attributes().map_or((-1, 0), |attr| {
            (attr.sched_policy as libc::c_int, attr.sched_runtime)
        })
    }

    #[test]
    fn a_slice_is_the_thread_s_own_and_its_children_start_with_the_default() {
        let (own, child) = std::thread::spawn(|| {
            let kept = super::set_slice(std::time::Duration::from_micros(150)).unwrap();
            let own = policy_and_slice();
            assert_eq!(own.1, u64::try_from(kept.as_nanos()).unwrap());
            let child = std::thread::spawn(policy_and_slice).join().unwrap();
            (own, child)
        })
        .join()
        .unwrap();
        assert_eq!(own.0, libc::SCHED_OTHER);
        assert_eq!(child.0, libc::SCHED_OTHER);
        if own.1 != 0 {
            // A kernel with slices of a thread's own (6.12+): 150 µs taken as asked, the
            // child at the default (a base slice of its own, never the parent's).
            assert_eq!(own.1, 150_000);
            assert_ne!(child.1, 150_000, "the child has the default slice");
        }
    }

    #[test]
    fn a_fifo_thread_s_children_start_at_normal_priority() {
        let r = std::thread::spawn(|| {
            super::set_fifo(10)?;
            let own = policy_and_slice().0;
            let child = std::thread::spawn(|| policy_and_slice().0).join().unwrap();
            Ok::<_, std::io::Error>((own, child))
        })
        .join()
        .unwrap();
        match r {
            Ok((own, child)) => {
                assert_eq!(own, libc::SCHED_FIFO);
                assert_eq!(child, libc::SCHED_OTHER, "reset on fork");
            }
            // Not permitted here (no CAP_SYS_NICE, no RLIMIT_RTPRIO): nothing to look at.
            Err(e) => assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied, "{e}"),
        }
    }
}
