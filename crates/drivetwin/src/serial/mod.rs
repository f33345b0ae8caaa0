//! The serial ports of a drive (RS232, RS485), served at the same time as its other front
//! ends, on the same objects. The protocols on them are the vendors' (the Kinco FD3 / CD3's
//! 10-byte telegrams and its Modbus RTU, `crate::vendors`), each a [`line::LineProtocol`] of
//! a line the vendor builds: the binary hands the vendors' builders in as [`SerialLines`]
//! (`drivetwin::vendors::VENDORS.serial_lines`).
//!
//! - [`pty`]: the file behind a line, a pseudo-terminal the twin makes (PATH a link to it) or
//!   a real device;
//! - [`wire`]: the time bytes take on the line at its baud rate (pure);
//! - [`line`](mod@line): a line as the cell loop serves it: port, wire and protocol together.
//!
//! The cell loop ([`crate::cell_loop`]) owns the ports' descriptors with its other
//! sockets and calls [`line::SerialLine`] when one is readable or a line's deadline is due;
//! a line reaches its drives through [`LineDrives`], one object access at a time, on the
//! cell's clock.

pub mod line;
pub mod pty;
pub mod wire;

use od::{Instant, ObjectAccess};

use crate::cell::can_cell::CanCell;
use crate::cell::stations::StationId;

/// How the lines of a cell are built from its drives' ports: one line per path of the
/// requests, with the protocol and the bit rate of its drives, which only the drives' vendor
/// knows. The binary's `drivetwin::vendors::VENDORS.serial_lines` fills it from the vendor
/// folders.
#[derive(Debug, Clone, Copy)]
pub struct SerialLines {
    /// The lines, opened: a pty the twin makes (its path a link to it) or a real device.
    pub open_lines: BuildLines<line::SerialLine>,
    /// The same lines on the virtual clock, without ports
    /// ([`crate::cell_loop::virtual_clock::run_virtual_lines`]): a path only names the line its
    /// drives share.
    pub virtual_lines: BuildLines<line::VirtualLine>,
}

/// Builds one line `L` per path of the requests, for the stations of the cell.
pub type BuildLines<L> = fn(&[LineRequest], &CanCell) -> Result<Vec<L>, LinesError>;

/// Why the lines of a cell could not be built.
#[derive(Debug, thiserror::Error)]
pub enum LinesError {
    /// The drive's vendor refuses the request (a port the device does not have, a speed code
    /// that is no bit rate); the text cites its manual.
    #[error("{0}")]
    Refused(String),
    #[error(transparent)]
    Port(#[from] pty::PortError),
}

/// How a line reaches the drives of the cell.
pub trait LineDrives {
    /// Runs `f` on the objects of drive `at` at `now`, as a local interface of the drive
    /// writes them (the rules of an SDO download in its NMT state); what the drive sends
    /// meanwhile goes on its bus.
    fn access(&mut self, at: StationId, now: Instant, f: &mut dyn FnMut(&mut dyn ObjectAccess));
}

/// A drive's port on a path: drives that name one path share its line.
#[derive(Debug, Clone)]
pub struct LineRequest {
    pub kind: Kind,
    pub path: std::path::PathBuf,
    /// The drive's station in the cell.
    pub drive: StationId,
}

/// A serial port of a drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Rs232,
    Rs485,
}

impl Kind {
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Rs232 => "rs232",
            Kind::Rs485 => "rs485",
        }
    }
}

/// Whether personality `device` has a port of `kind`: its device file lists it among its
/// `interfaces` (`rs232`, `rs485`; the manual's connector table).
pub fn has_port(device: &str, kind: Kind) -> bool {
    devices::by_name(device).is_some_and(|d| d.interfaces.has.contains(&kind.as_str()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ports are the device files' `interfaces` (Kinco §1.1, Tab. 3-7).
    #[test]
    fn ports_are_the_device_files_interfaces() {
        assert!(has_port("kinco-fd3", Kind::Rs485));
        assert!(!has_port("kinco-cd3", Kind::Rs485));
        assert!(!has_port("cmmp-as", Kind::Rs232));
    }
}

/// Drives for the lines' tests: plain Kinco FD3 dictionaries, one per station id.
#[cfg(test)]
pub(crate) mod test_drives {
    use super::*;
    use od::ObjectDictionary;

    pub struct Dictionaries(pub Vec<ObjectDictionary<Vec<u8>>>);

    impl Dictionaries {
        /// `n` FD3s with node-IDs 1…n.
        pub fn fd3(n: u8) -> Self {
            let d = &devices::KINCO_FD3;
            Dictionaries(
                (1..=n)
                    .filter_map(|id| ObjectDictionary::new(d, id, vec![0; d.storage_size]).ok())
                    .collect(),
            )
        }
    }

    impl LineDrives for Dictionaries {
        fn access(
            &mut self,
            at: StationId,
            _now: Instant,
            f: &mut dyn FnMut(&mut dyn ObjectAccess),
        ) {
            if let Some(od) = self.0.get_mut(at.index()) {
                f(od);
            }
        }
    }

    pub fn on(drive: usize) -> StationId {
        StationId::from_index(drive)
    }
}
