//! The serial ports of a drive: the Kinco FD3 / CD3 answer on RS232 (the 10-byte telegrams, Kinco
//! manual ch. 10) and on RS485 (Modbus RTU, ch. 12) at the same time as on CANopen, all three on
//! the same objects.
//!
//! - [`pty`]: the file behind a line, a pseudo-terminal the twin makes (PATH a link to it) or
//!   a real device;
//! - [`wire`]: the time bytes take on the line at its baud rate (pure);
//! - [`rs232_line`]: the telegram protocol on a line, point to point, a ring, or on RS485;
//! - [`rtu_line`]: Modbus RTU on an RS485 line, frames cut by the 3.5-character silence,
//!   several drives by station number;
//! - [`line`](mod@line): a line as the cell loop serves it: port, wire and protocol together.
//!
//! The cell loop ([`crate::cell_loop`]) owns the ports' descriptors with its other
//! sockets and calls [`line::SerialLine`] when one is readable or a line's deadline is due;
//! a line reaches its drives through [`LineDrives`], one object access at a time, on the
//! cell's clock.

pub mod line;
pub mod pty;
pub mod rs232_line;
pub mod rtu_line;
pub mod setup;
pub mod wire;

use od::{Instant, ObjectAccess};

use crate::cell::OnBus;

/// How a line reaches the drives of the cell.
pub trait LineDrives {
    /// Runs `f` on the objects of drive `at` at `now`, as a local interface of the drive
    /// writes them (the rules of an SDO download in its NMT state); what the drive sends
    /// meanwhile goes on its bus.
    fn access(&mut self, at: OnBus, now: Instant, f: &mut dyn FnMut(&mut dyn ObjectAccess));
}

/// The bit rate of a Kinco baud-rate code (2FE0h, 2FE1h, 2FE2h): the manual's table
/// ([`drive::vendors::kinco::bit_rates::SERIAL`], §2.1, KINCO-232-10); `None` for a code it
/// does not list.
pub fn baud_of_code(code: u64) -> Option<u32> {
    u16::try_from(code)
        .ok()
        .and_then(drive::vendors::kinco::bit_rates::serial_bit_rate)
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

    /// KINCO-232-10: the codes fit 10 368 000 / bit rate.
    #[test]
    fn kinco_232_10_baud_rate_codes() {
        assert_eq!(baud_of_code(540), Some(19_200));
        assert_eq!(baud_of_code(270), Some(38_400));
        assert_eq!(baud_of_code(90), Some(115_200));
        assert_eq!(baud_of_code(1080), Some(9600));
        assert_eq!(baud_of_code(0), None);
        // 180 would be 57600 by the formula, but the manual lists no such code.
        assert_eq!(baud_of_code(180), None);
        assert_eq!(baud_of_code(0x1_0000 + 270), None);
        assert!(has_port("kinco-fd3", Kind::Rs485));
        assert!(!has_port("kinco-cd3", Kind::Rs485));
        assert!(!has_port("cmmp-as", Kind::Rs232));
    }
}

/// Drives for the lines' tests: plain Kinco FD3 dictionaries, one per `OnBus::drive`.
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
        fn access(&mut self, at: OnBus, _now: Instant, f: &mut dyn FnMut(&mut dyn ObjectAccess)) {
            if let Some(od) = self.0.get_mut(at.drive) {
                f(od);
            }
        }
    }

    pub fn on(drive: usize) -> OnBus {
        OnBus { bus: 0, drive }
    }
}
