//! Linux SocketCAN: a `CAN_RAW` socket bound to one interface, with the kernel defaults (no
//! own frames received, no CAN FD, no error frames). Elsewhere opening one is unsupported.

use std::io;
use std::os::fd::OwnedFd;

/// A non-blocking, close-on-exec `CAN_RAW` socket bound to `interface`.
#[cfg(target_os = "linux")]
pub fn open(interface: &str) -> io::Result<OwnedFd> {
    use std::mem;
    use std::os::fd::AsRawFd;

    let ifindex = super::net_interface::index(interface)?;
    // SAFETY: plain socket(2) call; `owned` checks the result before taking it.
    let fd = super::fd::owned(unsafe {
        libc::socket(
            libc::PF_CAN,
            libc::SOCK_RAW | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
            libc::CAN_RAW,
        )
    })?;
    // SAFETY: `sockaddr_can` is plain old data; all-zero is a valid value.
    let mut addr: libc::sockaddr_can = unsafe { mem::zeroed() };
    addr.can_family = libc::AF_CAN as libc::sa_family_t;
    addr.can_ifindex = ifindex;
    // SAFETY: `addr` is a properly initialised `sockaddr_can` and the length matches it.
    let rc = unsafe {
        libc::bind(
            fd.as_raw_fd(),
            (&addr as *const libc::sockaddr_can).cast::<libc::sockaddr>(),
            mem::size_of::<libc::sockaddr_can>() as libc::socklen_t,
        )
    };
    super::fd::cvt(rc)?;
    Ok(fd)
}

/// SocketCAN is Linux's.
#[cfg(not(target_os = "linux"))]
pub fn open(interface: &str) -> io::Result<OwnedFd> {
    Err(io::Error::new(
        io::ErrorKind::Unsupported,
        format!("SocketCAN interface {interface:?}: SocketCAN is Linux's"),
    ))
}
