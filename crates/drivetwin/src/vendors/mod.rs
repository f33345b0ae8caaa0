//! What the binary does for one vendor's devices only, one folder per device family, named
//! for the device as `drive::vendors` names it: the parts of a front end that follow one
//! manual (a device's own web pages, a vendor protocol's master). The other modules name no
//! vendor; they reach these folders through the seams this module lists, which the binary
//! hands them (`scripts/structure` checks it):
//!
//! - [`WEB_PAGES`]: the devices' own pages of the web console ([`crate::web::DevicePages`]);
//! - the sub-commands named for a device (`drivetwin kinco`, `fhpp`, `iodd`): their
//!   arguments are types of the vendor folder with a `run` method, failing with
//!   [`CommandError`], whose [`Failure`] the binary turns into its exit code.
//!
//! The vendors:
//!
//! - [`festo_cmmo_st`]: the CMMO-ST's web server pages, its FHPP master over Modbus TCP and
//!   its IODD;
//! - [`kinco`]: the Kinco FD3 / CD3 panel page and the RS232 telegram master.

pub mod festo_cmmo_st;
pub mod kinco;

use crate::web::DevicePages;

/// Every device's own web pages, in the order their OpenAPI documents join the console's.
pub const WEB_PAGES: &[DevicePages] = &[festo_cmmo_st::WEB_PAGES, kinco::WEB_PAGES];

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
