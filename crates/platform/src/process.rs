//! Other processes as a test rig meets them: the threads of a server it started (to pin or
//! prioritise each), whether it runs as root (network namespaces, raw sockets), and the polite
//! stop (`SIGTERM`) that lets a server save before it ends.

use std::io;

/// The thread ids of process `pid`, from `/proc/PID/task`.
pub fn threads(pid: u32) -> io::Result<Vec<u32>> {
    let mut tids = Vec::new();
    for task in std::fs::read_dir(format!("/proc/{pid}/task"))? {
        if let Some(tid) = task?.file_name().to_str().and_then(|t| t.parse().ok()) {
            tids.push(tid);
        }
    }
    Ok(tids)
}

/// This process runs as root (effective user id 0).
pub fn is_root() -> bool {
    // SAFETY: geteuid has no preconditions and cannot fail.
    unsafe { libc::geteuid() == 0 }
}

/// Sends `SIGTERM` to process `pid`. For a child, call it before the child is reaped
/// (`Child::try_wait` or `wait` returned it), so that the pid cannot have been reused.
pub fn terminate(pid: u32) -> io::Result<()> {
    let pid = libc::pid_t::try_from(pid).map_err(|_| io::ErrorKind::InvalidInput)?;
    // SAFETY: kill(2) passes no memory.
    super::cvt(unsafe { libc::kill(pid, libc::SIGTERM) })?;
    Ok(())
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    #[test]
    fn this_process_has_this_thread() {
        let threads = super::threads(std::process::id()).unwrap();
        assert!(!threads.is_empty());
    }
}
