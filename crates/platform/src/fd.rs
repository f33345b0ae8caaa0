//! A descriptor's blocking mode: a bench's floor server blocks in `recvfrom` on a socket the
//! runtime opened non-blocking.

use std::io;
use std::os::fd::{AsRawFd, BorrowedFd};

/// Switches `fd` to blocking reads and writes (clears `O_NONBLOCK`).
pub fn set_blocking(fd: BorrowedFd<'_>) -> io::Result<()> {
    let fd = fd.as_raw_fd();
    // SAFETY: fcntl's get of the flags of a descriptor open for the borrow.
    let flags = super::cvt(unsafe { libc::fcntl(fd, libc::F_GETFL) })?;
    // SAFETY: fcntl's set of the flags of a descriptor open for the borrow.
    super::cvt(unsafe { libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) })?;
    Ok(())
}
