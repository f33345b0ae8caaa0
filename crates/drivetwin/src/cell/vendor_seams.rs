//! The seams through which the runtime reaches what only a drive's vendor knows, as one value.
//! The binary's `drivetwin::vendors::VENDORS.runtime` fills it from the vendor folders;
//! whoever builds a cell (the run and scenario commands, the scenario rig, the cell FMU, the
//! tests) hands it on, and the runtime names no vendor. Each field's type is declared beside
//! what calls it.
//!
//! The front ends' own seams are beside it in `drivetwin::vendors::VENDORS`, not in it, since
//! the runtime never depends on its front ends: the web console's device pages
//! (`web::DevicePages`, `VENDORS.web_pages`) and the serial lines with their protocols
//! (`serial::SerialLines`, `VENDORS.serial_lines`) go to the front end that serves them.

use super::config::DeviceSections;
use super::control::DriveViews;
use super::modbus_device::NewModbusDevice;
use super::terminal::{NewTerminal, Terminal, Typed};

/// What the runtime takes from the drives' vendors.
#[derive(Debug, Clone, Copy)]
pub struct Vendors {
    /// Each device's own keys of a cell file's `[[drive]]`, read and checked against its
    /// drive ([`CellFile::drives`](super::config::CellFile::drives)).
    pub cell_sections: DeviceSections,
    /// The device of a cell file's drive served over Modbus TCP with a register image of its
    /// own (a [`ModbusDevice`](super::modbus_device::ModbusDevice)).
    pub modbus_device: NewModbusDevice,
    /// What the runtime shows of a drive that only its vendor knows (its display).
    pub views: DriveViews,
    /// The terminal a drive's `ci_terminal` port serves.
    pub ci_terminal: NewTerminal,
}

impl Vendors {
    /// No vendor: no device has keys of its own, none is served over Modbus TCP with a
    /// register image of its own, the engine's display, a terminal that answers nothing. The
    /// runtime's own tests run on it, as do drives whose device needs no vendor (a drive from
    /// its EDS).
    pub const NONE: Vendors = Vendors {
        cell_sections: &[],
        modbus_device: |_, _| None,
        views: DriveViews::ENGINE,
        ci_terminal: || Box::new(Silent),
    };
}

/// The terminal of [`Vendors::NONE`]: it takes every byte and completes no line.
struct Silent;

impl Terminal for Silent {
    fn push(&mut self, _byte: u8) -> Option<Typed> {
        None
    }

    fn answer(&mut self, _line: &[u8], _od: &mut dyn od::ObjectAccess, _answer: &mut Vec<u8>) {}

    fn refuse(&mut self, _answer: &mut Vec<u8>) {}
}
