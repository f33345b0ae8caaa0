//! Linux packet sockets: an `AF_PACKET` raw socket bound to one interface and one EtherType,
//! as a device on the wire sees its frames. Elsewhere opening one is unsupported.

use std::io;
use std::os::fd::{BorrowedFd, OwnedFd};

/// `linux/if_packet.h`: packet type of a copy of a frame this host sent.
#[cfg(target_os = "linux")]
const PACKET_OUTGOING: u8 = 4;
/// `linux/if_packet.h`: socket option that stops delivery of outgoing copies (Linux 4.20+).
#[cfg(target_os = "linux")]
const PACKET_IGNORE_OUTGOING: libc::c_int = 23;

/// A frame [`recv`] read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Received {
    /// The frame's real length, longer than the buffer when it did not fit.
    pub len: usize,
    /// A copy of a frame this host sent.
    pub outgoing: bool,
}

/// A non-blocking, close-on-exec `AF_PACKET` socket for `ethertype` bound to `interface`,
/// with the outgoing copies switched off where the kernel can (older kernels refuse the
/// option, `ENOPROTOOPT`: [`Received::outgoing`] tells them then). Needs `CAP_NET_RAW`.
#[cfg(target_os = "linux")]
pub fn open(interface: &str, ethertype: u16) -> io::Result<OwnedFd> {
    use std::mem;
    use std::os::fd::AsRawFd;

    let ifindex = super::net_interface::index(interface)?;
    let protocol = ethertype.to_be();
    // SAFETY: plain socket(2) call; `owned` checks the result before taking it.
    let fd = super::fd::owned(unsafe {
        libc::socket(
            libc::AF_PACKET,
            libc::SOCK_RAW | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
            libc::c_int::from(protocol),
        )
    })?;
    // SAFETY: `sockaddr_ll` is plain old data; all-zero is a valid value.
    let mut addr: libc::sockaddr_ll = unsafe { mem::zeroed() };
    addr.sll_family = libc::AF_PACKET as libc::c_ushort;
    addr.sll_protocol = protocol;
    addr.sll_ifindex = ifindex;
    // SAFETY: `addr` is a properly initialised `sockaddr_ll` and the length matches it.
    let rc = unsafe {
        libc::bind(
            fd.as_raw_fd(),
            (&addr as *const libc::sockaddr_ll).cast::<libc::sockaddr>(),
            mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
        )
    };
    super::fd::cvt(rc)?;
    let one: libc::c_int = 1;
    // SAFETY: `one` is a valid c_int for the duration of the call and the length matches.
    let _ = unsafe {
        libc::setsockopt(
            fd.as_raw_fd(),
            libc::SOL_PACKET,
            PACKET_IGNORE_OUTGOING,
            (&one as *const libc::c_int).cast(),
            mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    Ok(fd)
}

/// One `recvfrom(2)` into `buf`; `WouldBlock` when nothing waits.
#[cfg(target_os = "linux")]
#[inline]
pub fn recv(fd: BorrowedFd<'_>, buf: &mut [u8]) -> io::Result<Received> {
    use std::mem;
    use std::os::fd::AsRawFd;

    // SAFETY: `sockaddr_ll` is plain old data; all-zero is a valid value.
    let mut from: libc::sockaddr_ll = unsafe { mem::zeroed() };
    let mut from_len = mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t;
    // SAFETY: `buf` is valid for writes of `buf.len()` bytes, `from` for `from_len` bytes.
    // MSG_TRUNC makes the call return the real length of a frame longer than `buf`.
    let n = unsafe {
        libc::recvfrom(
            fd.as_raw_fd(),
            buf.as_mut_ptr().cast(),
            buf.len(),
            libc::MSG_TRUNC,
            (&mut from as *mut libc::sockaddr_ll).cast::<libc::sockaddr>(),
            &mut from_len,
        )
    };
    let len = super::fd::cvt_size(n)?;
    Ok(Received {
        len,
        outgoing: from.sll_pkttype == PACKET_OUTGOING,
    })
}

/// One `send(2)` on the bound interface (no destination address needed); the bytes taken.
#[cfg(target_os = "linux")]
#[inline]
pub fn send(fd: BorrowedFd<'_>, frame: &[u8]) -> io::Result<usize> {
    use std::os::fd::AsRawFd;

    // SAFETY: `frame` is valid for reads of `frame.len()` bytes; `fd` is open for the borrow.
    super::fd::cvt_size(unsafe {
        libc::send(fd.as_raw_fd(), frame.as_ptr().cast(), frame.len(), 0)
    })
}

/// Packet sockets are Linux's.
#[cfg(not(target_os = "linux"))]
pub fn open(interface: &str, _ethertype: u16) -> io::Result<OwnedFd> {
    Err(io::Error::new(
        io::ErrorKind::Unsupported,
        format!("network interface {interface:?}: raw Ethernet sockets are Linux's"),
    ))
}

/// Packet sockets are Linux's (no socket is ever open to read).
#[cfg(not(target_os = "linux"))]
pub fn recv(_fd: BorrowedFd<'_>, _buf: &mut [u8]) -> io::Result<Received> {
    Err(io::ErrorKind::Unsupported.into())
}

/// Packet sockets are Linux's (no socket is ever open to write).
#[cfg(not(target_os = "linux"))]
pub fn send(_fd: BorrowedFd<'_>, _frame: &[u8]) -> io::Result<usize> {
    Err(io::ErrorKind::Unsupported.into())
}
