//! The file behind a serial line: a pseudo-terminal the twin creates, with PATH a link to it
//! so that pyserial or any program opens PATH as a serial port, or a real device (a USB
//! adapter, `/dev/ttyUSB0`) the twin opens itself.
//!
//! - PATH does not exist, or is a link into `/dev/pts` (a pty is never a real port: a link a
//!   twin made before, stale or not): a new pty, PATH a link to its slave. The link is removed
//!   when the port is dropped, if it still points to this pty.
//! - PATH is a character device (itself or through a link, as `/dev/serial/by-id/...`): the
//!   device, raw 8N1 at the line's baud rate.
//! - Anything else (a file, a directory) is refused.
//!
//! The twin keeps the pty's slave open itself, in raw mode: the master then never reads a
//! hang-up while no program has the port open (no busy loop), and a program that does not
//! set the terminal mode (`cat`) still gets raw bytes, no echo, no line editing.

use std::io;
use std::os::fd::{AsFd, AsRawFd, OwnedFd, RawFd};
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};

use crate::sys::fd::Readiness;
use crate::sys::termios::Speed;

/// What is wrong with a serial port path.
#[derive(Debug, thiserror::Error)]
pub enum PortError {
    #[error("serial port {0}: exists and is neither a character device nor a pty link")]
    NotADevice(PathBuf),
    #[error("serial port {path}: {source}")]
    Io { path: PathBuf, source: io::Error },
    #[error("serial port {0}: {1} bit/s is not a rate a UART is set to")]
    Baud(PathBuf, u32),
}

/// An open serial port of the twin.
#[derive(Debug)]
pub struct Port {
    fd: OwnedFd,
    /// The pty's slave, kept open (none for a device).
    _slave: Option<OwnedFd>,
    /// The link made to the pty, and the pty's name.
    link: Option<(PathBuf, PathBuf)>,
}

fn err(path: &Path) -> impl Fn(io::Error) -> PortError + '_ {
    move |source| PortError::Io {
        path: path.to_path_buf(),
        source,
    }
}

impl Port {
    /// Opens `path` as the rules of the module doc say; a device is set to `baud` bit/s.
    pub fn open(path: &Path, baud: u32) -> Result<Port, PortError> {
        match std::fs::symlink_metadata(path) {
            Err(e) if e.kind() == io::ErrorKind::NotFound => Port::pty(path),
            Err(e) => Err(err(path)(e)),
            Ok(m) if m.file_type().is_symlink() => {
                let target = std::fs::read_link(path).map_err(err(path))?;
                if target.starts_with("/dev/pts") {
                    std::fs::remove_file(path).map_err(err(path))?;
                    return Port::pty(path);
                }
                match std::fs::metadata(path) {
                    Ok(m) if m.file_type().is_char_device() => Port::device(path, baud),
                    Ok(_) => Err(PortError::NotADevice(path.to_path_buf())),
                    // A dangling link: a new pty replaces it.
                    Err(_) => {
                        std::fs::remove_file(path).map_err(err(path))?;
                        Port::pty(path)
                    }
                }
            }
            Ok(m) if m.file_type().is_char_device() => Port::device(path, baud),
            Ok(_) => Err(PortError::NotADevice(path.to_path_buf())),
        }
    }

    /// A new pty, `path` a link to its slave.
    fn pty(path: &Path) -> Result<Port, PortError> {
        let e = err(path);
        let pty = crate::sys::pty::open().map_err(&e)?;
        crate::sys::termios::set_raw(pty.slave.as_fd(), None).map_err(&e)?;
        crate::sys::fd::set_nonblocking_cloexec(pty.master.as_fd()).map_err(&e)?;
        std::os::unix::fs::symlink(&pty.slave_name, path).map_err(&e)?;
        Ok(Port {
            fd: pty.master,
            _slave: Some(pty.slave),
            link: Some((path.to_path_buf(), pty.slave_name)),
        })
    }

    /// A real device (or a twin's pty link, from the host's side), raw 8N1 at `baud`,
    /// opened exclusively.
    pub fn device(path: &Path, baud: u32) -> Result<Port, PortError> {
        let e = err(path);
        let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes())
            .map_err(|_| PortError::NotADevice(path.to_path_buf()))?;
        let fd = crate::sys::termios::open_device(&c).map_err(&e)?;
        let speed =
            Speed::from_baud(baud).ok_or_else(|| PortError::Baud(path.to_path_buf(), baud))?;
        crate::sys::termios::set_raw(fd.as_fd(), Some(speed)).map_err(&e)?;
        crate::sys::termios::set_exclusive(fd.as_fd(), true).map_err(&e)?;
        Ok(Port {
            fd,
            _slave: None,
            link: None,
        })
    }

    /// The pty's slave (`/dev/pts/N`), none for a device.
    pub fn pty_name(&self) -> Option<&Path> {
        self.link.as_ref().map(|(_, p)| p.as_path())
    }

    /// Whether this is a pty the twin made (its timing is the twin's).
    pub fn is_pty(&self) -> bool {
        self.link.is_some()
    }

    pub fn raw_fd(&self) -> RawFd {
        self.fd.as_raw_fd()
    }

    /// Reads what waits; `Ok(0)` when nothing does (non-blocking).
    pub fn read(&self, buf: &mut [u8]) -> io::Result<usize> {
        match crate::sys::fd::read(self.fd.as_fd(), buf) {
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
                ) =>
            {
                Ok(0)
            }
            r => r,
        }
    }

    /// Waits up to `timeout` for bytes to read; whether some wait.
    pub fn wait_readable(&self, timeout: std::time::Duration) -> io::Result<bool> {
        crate::sys::fd::wait(self.fd.as_fd(), Readiness::Readable, timeout)
    }

    /// Writes what the port takes now; 0 when it is full.
    pub fn write(&self, bytes: &[u8]) -> usize {
        crate::sys::fd::write(self.fd.as_fd(), bytes).unwrap_or(0)
    }
}

impl Drop for Port {
    fn drop(&mut self) {
        if self.link.is_none() {
            // TIOCEXCL outlives the descriptor while another keeps the terminal open (a twin
            // holds its pty's slave): give the port back.
            let _ = crate::sys::termios::set_exclusive(self.fd.as_fd(), false);
        }
        if let Some((link, pts)) = &self.link {
            // Only the link to this pty: another twin may have taken the path since.
            if std::fs::read_link(link).is_ok_and(|t| t == *pts) {
                let _ = std::fs::remove_file(link);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pty_behind_a_link_that_goes_with_the_port() {
        let dir = std::env::temp_dir().join(format!("drivetwin-pty-{}", std::process::id()));
        let _ = std::fs::create_dir_all(&dir);
        let path = dir.join("ttyKINCO");
        let port = Port::open(&path, 38_400).expect("pty");
        assert!(port.is_pty());
        let target = std::fs::read_link(&path).expect("link");
        assert!(target.starts_with("/dev/pts"), "{target:?}");
        // A host writes through the link; the twin reads it raw.
        let mut host = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&path)
            .expect("open link");
        std::io::Write::write_all(&mut host, &[0x01, 0x0D, 0x0A, 0x7F]).expect("write");
        std::thread::sleep(std::time::Duration::from_millis(20));
        let mut buf = [0u8; 16];
        let n = port.read(&mut buf).expect("read");
        assert_eq!(buf.get(..n), Some(&[0x01, 0x0D, 0x0A, 0x7F][..]));
        assert_eq!(port.write(&[0x55, 0x0A]), 2);
        std::thread::sleep(std::time::Duration::from_millis(20));
        let mut got = [0u8; 2];
        std::io::Read::read_exact(&mut host, &mut got).expect("read back");
        assert_eq!(got, [0x55, 0x0A], "raw: no echo, no CR/LF translation");
        // A stale link is replaced; the link goes when the port does.
        drop(port);
        assert!(std::fs::symlink_metadata(&path).is_err());
        std::os::unix::fs::symlink("/dev/pts/999999", &path).expect("stale link");
        let port = Port::open(&path, 38_400).expect("over a stale link");
        assert_ne!(
            std::fs::read_link(&path).ok(),
            Some("/dev/pts/999999".into())
        );
        drop(port);
        // A regular file is not a port.
        std::fs::write(&path, b"x").expect("file");
        assert!(matches!(
            Port::open(&path, 38_400),
            Err(PortError::NotADevice(_))
        ));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
