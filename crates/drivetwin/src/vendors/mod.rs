//! What the binary does for one vendor's devices only, one folder per device family, named
//! for the device as `drive::vendors` names it: the parts of a front end that follow one
//! manual (a device's own web pages, a vendor protocol's master). The other modules name no
//! vendor; they reach these folders through the seams this module lists, which the binary
//! hands them (`scripts/structure` checks it):
//!
//! - [`VENDORS`]: the seams of the runtime and of the front ends, as one value ([`Seams`]),
//!   which the commands and the tests' rigs hand on, each part to its layer;
//! - `VENDORS.runtime`: what the runtime takes from the vendors ([`crate::cell::Vendors`]):
//!   - `cell_sections`: each device's own keys of a cell file's `[[drive]]`
//!     ([`crate::cell::config::DeviceSection`]), read and checked against its drive;
//!   - `modbus_device`: the drives served over Modbus TCP with a register image of their own
//!     ([`crate::cell::modbus_device::ModbusDevice`]), as a cell file's drive makes them; the
//!     vendors' own APIs on them go through
//!     [`crate::cell::control::ControlHandle::with_modbus_device`];
//!   - `views`: what the runtime shows of a drive that only its vendor knows (the Kinco's LED
//!     panel as its display), [`crate::cell::control::DriveViews`]; the vendors' own APIs on
//!     a running drive go through [`crate::cell::control::ControlHandle::with_drive`];
//!   - `ci_terminal`: the terminal of a drive's `ci_terminal` port
//!     ([`crate::cell::terminal::Terminal`]);
//! - the front ends' seams, whose types are the front ends' own and so not in the runtime's
//!   part: `VENDORS.web_pages`, the devices' own pages of the web console
//!   ([`crate::web::DevicePages`]); `VENDORS.serial_lines`, the serial lines of a cell, each
//!   with its protocol ([`crate::serial::SerialLines`],
//!   [`crate::serial::line::LineProtocol`]);
//! - the sub-commands named for a device (`drivetwin kinco`, `fhpp`, `iodd`): their
//!   arguments are types of the vendor folder with a `run` method, failing with
//!   [`CommandError`], whose [`Failure`] the binary turns into its exit code.
//!
//! The vendors:
//!
//! - [`festo_cmmo_st`]: the CMMO-ST's FHPP register image on Modbus TCP, its FHPP side on
//!   the console, its web server pages, its FHPP master over Modbus TCP, its IODD and its
//!   cell file section;
//! - [`festo_cmmp_as`]: the CMMP-AS's CI terminal, its fieldbus switches' rules and its cell
//!   file section;
//! - [`kinco`]: the Kinco FD3 / CD3 serial lines (RS232 telegrams, Modbus RTU), its panel
//!   page, the RS232 telegram master and the cell file sections;
//! - [`nanotec`]: the Nanotec drives' cell file section.

#[cfg(test)]
mod cell_file_tests;
pub mod festo_cmmo_st;
pub mod festo_cmmp_as;
pub mod kinco;
pub mod nanotec;

use crate::cell::config::DeviceSections;
use crate::cell::control::{DisplayState, DriveViews};
use crate::cell::modbus_device::NewModbusDevice;
use crate::cell::terminal::NewTerminal;
use crate::cell::Vendors;
use crate::serial::SerialLines;
use crate::web::DevicePages;

/// Everything the binary takes from the vendor folders, as one value: what the runtime takes
/// ([`Vendors`], declared by the runtime), and what the front ends take, in their own types
/// (the runtime names no front end). Whoever builds a cell hands each part to its layer:
/// `runtime` to [`crate::cell::config::CellFile::drives`], the EtherCAT chains, the scenario
/// rig, the cell FMU and the loop's front ends; `web_pages` to [`crate::web::start`];
/// `serial_lines` to whoever opens the cell's serial lines.
#[derive(Debug, Clone, Copy)]
pub struct Seams {
    /// The runtime's seams: cell file sections, the Modbus TCP device, the drives' views and
    /// the CI terminal.
    pub runtime: Vendors,
    /// Every device's own web pages, in the order their OpenAPI documents join the console's.
    pub web_pages: &'static [DevicePages],
    /// The serial lines that drives' `rs232` / `rs485` ports (and `--rs232`, `--rs485`) ask
    /// for, each with its protocol: opened, and on the virtual clock.
    pub serial_lines: SerialLines,
}

/// Every seam of the vendor folders, as one value.
pub const VENDORS: Seams = Seams {
    runtime: Vendors {
        cell_sections: CELL_SECTIONS,
        modbus_device: MODBUS_DEVICE,
        views: DRIVE_VIEWS,
        ci_terminal: CI_TERMINAL,
    },
    web_pages: WEB_PAGES,
    serial_lines: SERIAL_LINES,
};

/// Every device's own web pages, in the order their OpenAPI documents join the console's.
const WEB_PAGES: &[DevicePages] = &[festo_cmmo_st::WEB_PAGES, kinco::WEB_PAGES];

/// What the drives' vendors tell the runtime: the Kinco's display is its LED panel, the
/// other CiA 402 drives' the engine's (the CMMP-AS's 7-segment display; none for the rest).
const DRIVE_VIEWS: DriveViews = DriveViews { display };

fn display(d: &drive::vendors::AnyDrive<Vec<u8>>) -> Option<DisplayState> {
    kinco::panel_page::display(d).or_else(|| (DriveViews::default().display)(d))
}

/// The device of a cell file's drive served over Modbus TCP: the CMMO-ST's FHPP register
/// image, the only drive served so.
const MODBUS_DEVICE: NewModbusDevice = festo_cmmo_st::modbus_server::new_device;

/// Each device's own section of a cell file's `[[drive]]`, by the device files it serves.
const CELL_SECTIONS: DeviceSections = &[
    festo_cmmp_as::cell_section::SECTION,
    nanotec::cell_section::SECTION,
    kinco::cell_section::FD3,
    kinco::cell_section::CD3,
    festo_cmmo_st::cell_section::SECTION,
];

/// The terminal a drive's `ci_terminal` port (and `--ci-terminal`) serves: the CMMP-AS's CI
/// terminal, the only drive with one.
const CI_TERMINAL: NewTerminal = festo_cmmp_as::ci_terminal::new;

/// The serial lines that drives' `rs232` / `rs485` ports ask for: the Kinco FD3 / CD3 are
/// the drives with serial ports.
const SERIAL_LINES: SerialLines = kinco::serial_lines::SERIAL_LINES;

/// Why a vendor's sub-command (`drivetwin kinco`, `drivetwin fhpp`, `drivetwin iodd`)
/// failed; [`CommandError::failure`] is the class the binary turns into its exit code.
#[derive(Debug, thiserror::Error)]
pub enum CommandError {
    #[error("{0}")]
    Usage(String),
    #[error(transparent)]
    Kinco(#[from] kinco::rs232_master::KincoError),
    #[error(transparent)]
    Fhpp(#[from] festo_cmmo_st::fhpp_master::FhppError),
    #[error("{what}: {source}")]
    Io {
        what: String,
        source: std::io::Error,
    },
}

/// What kind of failure a sub-command had, as the binary's exit codes tell them apart (the
/// CANopen commands' codes: a refusal is like an SDO abort).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Failure {
    Usage,
    Link,
    Timeout,
    Refused,
    Protocol,
    Fault,
    Other,
}

impl CommandError {
    pub fn failure(&self) -> Failure {
        match self {
            CommandError::Usage(_) => Failure::Usage,
            CommandError::Kinco(e) => kinco::rs232_commands::failure(e),
            CommandError::Fhpp(e) => festo_cmmo_st::fhpp_commands::failure(e),
            CommandError::Io { .. } => Failure::Other,
        }
    }
}

/// The device file named `name`, or a usage error that lists the known ones.
fn device(name: &str) -> Result<&'static od::DeviceDescription, CommandError> {
    crate::value_text::device_named(name).map_err(CommandError::Usage)
}

/// `text` (`0x6041` or `6041`) as a hexadecimal number, or a usage error naming `what`.
fn parse_hex<T>(
    text: &str,
    what: &str,
    parse: fn(&str, u32) -> Result<T, std::num::ParseIntError>,
) -> Result<T, CommandError> {
    crate::value_text::parse_hex_number(text, what, parse).map_err(CommandError::Usage)
}
