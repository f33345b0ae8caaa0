//! Pseudo-terminals: a new master and its slave, both owned.

use std::ffi::CStr;
use std::io;
use std::os::fd::{AsRawFd, OwnedFd};
use std::path::PathBuf;

use super::fd::{cvt, owned};

/// A new pty: its master, its slave opened, and the slave's name (`/dev/pts/N`).
#[derive(Debug)]
pub struct Pty {
    pub master: OwnedFd,
    pub slave: OwnedFd,
    pub slave_name: PathBuf,
}

/// Opens a new pty (`posix_openpt`, `grantpt`, `unlockpt`) and its slave; neither becomes
/// the controlling terminal.
pub fn open() -> io::Result<Pty> {
    // SAFETY: posix_openpt returns a new descriptor, or -1 (`owned` checks).
    let master = owned(unsafe { libc::posix_openpt(libc::O_RDWR | libc::O_NOCTTY) })?;
    let m = master.as_raw_fd();
    // SAFETY: plain calls on a valid pty master.
    cvt(unsafe { libc::grantpt(m) })?;
    cvt(unsafe { libc::unlockpt(m) })?;
    let mut name = [0 as libc::c_char; 128];
    // SAFETY: the buffer is as long as we say.
    let r = unsafe { libc::ptsname_r(m, name.as_mut_ptr(), name.len()) };
    if r != 0 {
        return Err(io::Error::from_raw_os_error(r));
    }
    // SAFETY: ptsname_r wrote a NUL-terminated name into the buffer.
    let slave_name = unsafe { CStr::from_ptr(name.as_ptr()) };
    // SAFETY: open returns a new descriptor, or -1 (`owned` checks).
    let slave = owned(unsafe { libc::open(slave_name.as_ptr(), libc::O_RDWR | libc::O_NOCTTY) })?;
    Ok(Pty {
        master,
        slave,
        slave_name: PathBuf::from(slave_name.to_string_lossy().into_owned()),
    })
}
