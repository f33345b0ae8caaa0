//! Platform calls the benches and tests of the workspace share, behind safe functions: the
//! CPU time a thread or the process has used, where threads run and at which priority, the
//! threads of another process, and a global allocator that counts. The binary's own platform
//! code is `drivetwin::sys`; this crate holds what only a measurement or a test rig needs, so
//! that `drive`'s benches (which may not depend on drivetwin) and drivetwin's benches and tests
//! use one copy. Every `unsafe` block of a bench or a test is here; the workspace denies
//! `unsafe_code` everywhere else (`[workspace.lints]`, `scripts/structure`).
//!
//! What only Linux has (`CLOCK_THREAD_CPUTIME_ID` beside the others, `sched_setaffinity`,
//! `SCHED_FIFO` on another thread, `/proc`) is switched here with `cfg(target_os)`: elsewhere
//! the same functions refuse with [`std::io::ErrorKind::Unsupported`].
//!
//! One file per concern:
//! - [`cpu_time`]: the CPU time of the calling thread and of the process, the monotonic clock;
//! - [`sched`]: CPU placement, real-time and nice scheduling of a thread;
//! - [`process`]: the threads of a process, the effective user, a polite stop;
//! - [`fd`]: a descriptor's blocking mode;
//! - [`alloc`]: a global allocator that counts the calling thread's allocations.
#![allow(unsafe_code)]

pub mod alloc;
pub mod cpu_time;
pub mod fd;
pub mod process;
pub mod sched;

/// A C call's `int` result: negative is the error in `errno`.
fn cvt(r: libc::c_int) -> std::io::Result<libc::c_int> {
    if r < 0 {
        Err(std::io::Error::last_os_error())
    } else {
        Ok(r)
    }
}
