//! Reads, writes and waits on a descriptor, for the transports that hold a raw one (a pty, a
//! raw socket): the results are the system calls' own, errors as [`io::Error`].

use std::io;
use std::os::fd::{AsRawFd, BorrowedFd, FromRawFd, OwnedFd};
use std::time::Duration;

use tokio::io::unix::AsyncFd;

/// A C call's `int` result: negative is the error in `errno`.
pub(super) fn cvt(r: libc::c_int) -> io::Result<libc::c_int> {
    if r < 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(r)
    }
}

/// A C call's `ssize_t` result: negative is the error in `errno`.
pub(super) fn cvt_size(n: libc::ssize_t) -> io::Result<usize> {
    usize::try_from(n).map_err(|_| io::Error::last_os_error())
}

/// The descriptor a call just returned, owned, or its error.
pub(super) fn owned(raw: libc::c_int) -> io::Result<OwnedFd> {
    let raw = cvt(raw)?;
    // SAFETY: `raw` is a fresh, valid descriptor the call returned to us and nobody else owns.
    Ok(unsafe { OwnedFd::from_raw_fd(raw) })
}

/// `read(2)`: the bytes read into `buf`; `WouldBlock` on a non-blocking descriptor with
/// nothing waiting.
#[inline]
pub fn read(fd: BorrowedFd<'_>, buf: &mut [u8]) -> io::Result<usize> {
    // SAFETY: `buf` is valid for writes of `buf.len()` bytes; `fd` is open for the borrow.
    cvt_size(unsafe { libc::read(fd.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) })
}

/// `write(2)`: the bytes the descriptor took.
#[inline]
pub fn write(fd: BorrowedFd<'_>, bytes: &[u8]) -> io::Result<usize> {
    // SAFETY: `bytes` is valid for reads of `bytes.len()` bytes; `fd` is open for the borrow.
    cvt_size(unsafe { libc::write(fd.as_raw_fd(), bytes.as_ptr().cast(), bytes.len()) })
}

/// What [`wait`] waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Readiness {
    Readable,
    Writable,
}

/// `poll(2)` on one descriptor for up to `timeout` (in whole milliseconds, rounded down):
/// whether it became ready.
pub fn wait(fd: BorrowedFd<'_>, readiness: Readiness, timeout: Duration) -> io::Result<bool> {
    let mut p = libc::pollfd {
        fd: fd.as_raw_fd(),
        events: match readiness {
            Readiness::Readable => libc::POLLIN,
            Readiness::Writable => libc::POLLOUT,
        },
        revents: 0,
    };
    let ms = libc::c_int::try_from(timeout.as_millis()).unwrap_or(libc::c_int::MAX);
    // SAFETY: one valid pollfd, as many as we say.
    let n = cvt(unsafe { libc::poll(&mut p, 1, ms) })?;
    Ok(n > 0)
}

/// Switches `fd` to non-blocking and close-on-exec.
pub fn set_nonblocking_cloexec(fd: BorrowedFd<'_>) -> io::Result<()> {
    let fd = fd.as_raw_fd();
    // SAFETY: fcntl's get and set of flags on a descriptor open for the borrow.
    let flags = cvt(unsafe { libc::fcntl(fd, libc::F_GETFL) })?;
    cvt(unsafe { libc::fcntl(fd, libc::F_SETFL, flags | libc::O_NONBLOCK) })?;
    // SAFETY: as above.
    let fdflags = cvt(unsafe { libc::fcntl(fd, libc::F_GETFD) })?;
    cvt(unsafe { libc::fcntl(fd, libc::F_SETFD, fdflags | libc::FD_CLOEXEC) })?;
    Ok(())
}

/// `fd` registered with the current tokio runtime (readable and writable). Must be called
/// inside a tokio runtime.
pub fn register_async(fd: OwnedFd) -> io::Result<AsyncFd<OwnedFd>> {
    // SAFETY: the `OwnedFd` moves into the `AsyncFd`, which owns it until dropped, so the
    // descriptor stays open and the same for the registration's whole lifetime.
    Ok(unsafe { AsyncFd::register(fd) }?)
}

/// The interface's TX queue is full (`ENOBUFS`): the frame is lost, as a controller drops it.
pub fn is_queue_full(e: &io::Error) -> bool {
    e.raw_os_error() == Some(libc::ENOBUFS)
}
