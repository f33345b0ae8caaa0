//! Serial devices and their terminal settings: raw 8N1, the UART's rates, exclusive use.

use std::ffi::CStr;
use std::io;
use std::os::fd::{AsRawFd, BorrowedFd, OwnedFd};

use super::fd::{cvt, owned};

/// A rate a UART is set to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Speed(libc::speed_t);

impl Speed {
    /// The termios speed of `baud` bit/s, if it is one of the rates the twin's lines use.
    pub fn from_baud(baud: u32) -> Option<Speed> {
        Some(Speed(match baud {
            9600 => libc::B9600,
            19_200 => libc::B19200,
            38_400 => libc::B38400,
            57_600 => libc::B57600,
            115_200 => libc::B115200,
            _ => return None,
        }))
    }
}

/// Opens the terminal device at `path`: read and write, not the controlling terminal,
/// non-blocking, close-on-exec.
pub fn open_device(path: &CStr) -> io::Result<OwnedFd> {
    // SAFETY: open returns a new descriptor, or -1 (`owned` checks).
    owned(unsafe {
        libc::open(
            path.as_ptr(),
            libc::O_RDWR | libc::O_NOCTTY | libc::O_NONBLOCK | libc::O_CLOEXEC,
        )
    })
}

/// Raw mode, 8N1, receiver on, no modem control; at `speed` when given.
pub fn set_raw(fd: BorrowedFd<'_>, speed: Option<Speed>) -> io::Result<()> {
    let fd = fd.as_raw_fd();
    // SAFETY: termios is plain data; tcgetattr fills it.
    let mut t: libc::termios = unsafe { std::mem::zeroed() };
    cvt(unsafe { libc::tcgetattr(fd, &mut t) })?;
    // SAFETY: cfmakeraw and cfset*speed only change the struct.
    unsafe { libc::cfmakeraw(&mut t) };
    t.c_cflag &= !(libc::CSTOPB | libc::PARENB | libc::CRTSCTS);
    t.c_cflag |= libc::CS8 | libc::CREAD | libc::CLOCAL;
    t.c_cc[libc::VMIN] = 0;
    t.c_cc[libc::VTIME] = 0;
    if let Some(Speed(s)) = speed {
        cvt(unsafe { libc::cfsetispeed(&mut t, s) })?;
        cvt(unsafe { libc::cfsetospeed(&mut t, s) })?;
    }
    // SAFETY: a valid descriptor and a filled struct.
    cvt(unsafe { libc::tcsetattr(fd, libc::TCSANOW, &t) })?;
    Ok(())
}

/// Exclusive use of the terminal (`TIOCEXCL`: no other open succeeds) or its end
/// (`TIOCNXCL`).
pub fn set_exclusive(fd: BorrowedFd<'_>, exclusive: bool) -> io::Result<()> {
    let request = if exclusive {
        libc::TIOCEXCL
    } else {
        libc::TIOCNXCL
    };
    // SAFETY: TIOCEXCL and TIOCNXCL take no argument.
    cvt(unsafe { libc::ioctl(fd.as_raw_fd(), request) })?;
    Ok(())
}
