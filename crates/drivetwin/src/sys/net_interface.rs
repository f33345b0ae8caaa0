//! Network interfaces by name, for the raw-socket transports (SocketCAN, EtherCAT).

use std::ffi::CString;
use std::io;

/// The kernel's index of `interface`, as `bind(2)` on `AF_CAN` / `AF_PACKET` wants it.
pub fn index(interface: &str) -> io::Result<libc::c_int> {
    let name = CString::new(interface)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "interface name contains NUL"))?;
    // SAFETY: `name` is a valid NUL-terminated string that outlives the call.
    let index = unsafe { libc::if_nametoindex(name.as_ptr()) };
    if index == 0 {
        return Err(io::Error::new(
            io::ErrorKind::NotFound,
            format!("no network interface named {interface:?}"),
        ));
    }
    libc::c_int::try_from(index)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "interface index too large"))
}

/// Whether a network interface with this name exists.
pub fn exists(interface: &str) -> bool {
    match CString::new(interface) {
        // SAFETY: valid NUL-terminated string for the duration of the call.
        Ok(name) => unsafe { libc::if_nametoindex(name.as_ptr()) != 0 },
        Err(_) => false,
    }
}
