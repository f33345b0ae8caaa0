//! What each sub-command does: one module per family of commands.

use std::path::PathBuf;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use canopen::{CanFrame, NmtCommand};
use drivetwin::cell::ci_console;
use drivetwin::cell::config::{CellFile, ConfigError, DriveSpec, FhppSpec};
use drivetwin::cell::param_store::ParamStore;
use drivetwin::cell::station::{Station, StationError};
use drivetwin::cell_loop::virtual_clock;
use drivetwin::master::link::{Link, LinkError};
use drivetwin::master::sdo_client::{SdoClient, SdoError};
use drivetwin::modbus_tcp::device_thread;
use drivetwin::trace::{self, TraceWriter};
use drivetwin::value_text;
use drivetwin::vendors::Failure;
use od::DataType;

use crate::cli::{
    BusArgs, Cli, Command, DriveCommand, LssCommand, NmtArg, PdoCommand, RunArgs, SdoCommand,
};
use crate::cli::{DiffArgs, RecordArgs};
use drivetwin::master::cia402::{self, Cia402Error};
use drivetwin::master::lss::{LssError, LssMaster};
use drivetwin::master::pdo_config::{self, Direction, Mapping, PdoSetting};

/// Writes a line to standard output; when the reader went away (`drivetwin monitor | head`)
/// the command ends quietly instead of panicking like `println!`.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let mut stdout = std::io::stdout().lock();
        if writeln!(stdout, $($arg)*).and_then(|_| stdout.flush()).is_err() {
            std::process::exit(0);
        }
    }};
}

/// As [`out!`] without the newline.
macro_rules! out_raw {
    ($text:expr) => {{
        use std::io::Write as _;
        let mut stdout = std::io::stdout().lock();
        if stdout
            .write_all($text.as_bytes())
            .and_then(|_| stdout.flush())
            .is_err()
        {
            std::process::exit(0);
        }
    }};
}

pub const EXIT_FAILURE: u8 = 1;
pub const EXIT_USAGE: u8 = 2;
pub const EXIT_LINK: u8 = 3;
pub const EXIT_TIMEOUT: u8 = 4;
pub const EXIT_ABORT: u8 = 5;
pub const EXIT_PROTOCOL: u8 = 6;
pub const EXIT_FAULT: u8 = 7;

#[derive(Debug, thiserror::Error)]
pub enum CommandError {
    #[error("{0}")]
    Usage(String),
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Drive(#[from] StationError),
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error(transparent)]
    Sdo(#[from] SdoError),
    #[error(transparent)]
    Lss(#[from] LssError),
    #[error(transparent)]
    Cia402(#[from] Cia402Error),
    #[error(transparent)]
    Ecat(#[from] drivetwin::master::ecat::EcatError),
    /// A sub-command named for a device (`kinco`, `fhpp`, `iodd`), in its vendor folder.
    #[error(transparent)]
    Vendor(#[from] drivetwin::vendors::CommandError),
    #[error("{what}: {source}")]
    Io {
        what: String,
        source: std::io::Error,
    },
    /// A scenario ran and an expectation was not met (the report has been printed).
    #[error("{0}")]
    ScenarioFailed(String),
    /// A script or a recording that cannot be read, at a line.
    #[error("{}:{line}: {what}", path.display())]
    Script {
        path: PathBuf,
        line: usize,
        what: String,
    },
    /// A replay's answers differ from the recording (the report has been printed).
    #[error("{0}")]
    Differs(String),
    /// `drivetwin diff` could not compare: exit code 2 whatever the cause, as `diff`.
    #[error(transparent)]
    Unusable(Box<CommandError>),
}

impl CommandError {
    pub fn exit_code(&self) -> u8 {
        match self {
            CommandError::Usage(_) | CommandError::Config(_) => EXIT_USAGE,
            CommandError::Link(_) | CommandError::Sdo(SdoError::Link(_)) => EXIT_LINK,
            CommandError::Sdo(SdoError::Timeout { .. }) => EXIT_TIMEOUT,
            CommandError::Sdo(SdoError::Abort(_)) => EXIT_ABORT,
            CommandError::Sdo(SdoError::Protocol(_)) => EXIT_PROTOCOL,
            CommandError::Lss(LssError::Link(_)) => EXIT_LINK,
            CommandError::Lss(LssError::NoResponse(_)) => EXIT_TIMEOUT,
            CommandError::Lss(LssError::Refused { .. }) => EXIT_PROTOCOL,
            CommandError::Cia402(Cia402Error::Timeout { .. }) => EXIT_TIMEOUT,
            CommandError::Cia402(
                Cia402Error::Missing { .. }
                | Cia402Error::NoMode(..)
                | Cia402Error::ModeRefused { .. },
            ) => EXIT_ABORT,
            CommandError::Cia402(Cia402Error::OutOfRange { .. }) => EXIT_USAGE,
            CommandError::Cia402(Cia402Error::Sdo(e)) => match e {
                SdoError::Abort(_) => EXIT_ABORT,
                SdoError::Timeout { .. } => EXIT_TIMEOUT,
                SdoError::Protocol(_) => EXIT_PROTOCOL,
                SdoError::Link(_) => EXIT_LINK,
            },
            CommandError::Drive(drivetwin::cell::station::StationError::NodeId(_)) => EXIT_USAGE,
            CommandError::Drive(_) | CommandError::Io { .. } => EXIT_FAILURE,
            CommandError::Ecat(e) => ecat::exit_code(e),
            CommandError::Vendor(e) => match e.failure() {
                Failure::Usage => EXIT_USAGE,
                Failure::Link => EXIT_LINK,
                Failure::Timeout => EXIT_TIMEOUT,
                Failure::Refused => EXIT_ABORT,
                Failure::Protocol => EXIT_PROTOCOL,
                Failure::Fault => EXIT_FAULT,
                Failure::Other => EXIT_FAILURE,
            },
            CommandError::ScenarioFailed(_) | CommandError::Differs(_) => EXIT_FAILURE,
            CommandError::Script { .. } | CommandError::Unusable(_) => EXIT_USAGE,
        }
    }
}

mod diff;
mod drive;
mod ecat;
mod fmu;
mod lss;
mod network;
mod pdo;
pub(crate) mod progress;
mod record;
mod run;
mod scenario;
mod sdo;

pub(crate) fn io(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> CommandError {
    let what = what.into();
    move |source| CommandError::Io { what, source }
}

pub async fn dispatch(cli: Cli) -> Result<(), CommandError> {
    match cli.command {
        Command::Run(args) => run::run(*args).await,
        Command::Eds { device, output } => run::eds(&device, output),
        Command::Esi {
            device,
            eds,
            output,
        } => run::esi(&device, eds.as_deref(), output),
        Command::Devices => {
            let width = devices::ALL.iter().map(|d| d.name.len()).max().unwrap_or(0);
            for d in devices::ALL {
                out!(
                    "{:<width$} {} ({}), {} objects",
                    d.name,
                    d.product_name,
                    d.vendor_name,
                    d.objects.len()
                );
            }
            Ok(())
        }
        Command::Sdo(cmd) => sdo::sdo(cmd).await,
        Command::Nmt { command, node, bus } => network::nmt(command, node, bus).await,
        Command::Pdo(cmd) => pdo::pdo(cmd).await,
        Command::Sync {
            period_ms,
            count,
            counter,
            cob_id,
            bus,
        } => network::sync(period_ms, count, counter, &cob_id, bus).await,
        Command::Lss(cmd) => lss::lss(cmd).await,
        Command::Scan { timeout_ms, bus } => network::scan(timeout_ms, bus).await,
        Command::Drive {
            node,
            command,
            wait,
            timeout_ms,
            bus,
        } => drive::drive_command(node, command, wait, timeout_ms, bus).await,
        Command::Fhpp(args) => Ok(args.run(&mut print).await?),
        Command::Monitor {
            count,
            seconds,
            bitrate,
            bus,
        } => network::monitor(count, seconds, bitrate, bus).await,
        Command::Ecat(cmd) => ecat::ecat(cmd).await,
        Command::Kinco(args) => Ok(args.run(&mut print)?),
        Command::Scenario(args) => scenario::scenario(args),
        Command::Fmu(args) => fmu::fmu(args),
        Command::Record(args) => record::record(args).await,
        Command::Diff(args) => diff::diff(args).await.map_err(|e| match e {
            CommandError::Differs(_) => e,
            other => CommandError::Unusable(Box::new(other)),
        }),
        Command::Iodd(args) => Ok(args.run(&mut print)?),
    }
}

/// A line of a command's answer on standard output (as [`out!`]).
fn print(line: &str) {
    out!("{line}");
}

pub(crate) fn device(name: &str) -> Result<&'static od::DeviceDescription, CommandError> {
    drivetwin::value_text::device_named(name).map_err(CommandError::Usage)
}

pub(crate) async fn connect(bus: &BusArgs) -> Result<Link, CommandError> {
    if let Some(ifname) = &bus.can {
        // Elsewhere than on Linux, the socket refuses with its reason (`sys::socketcan`).
        return Ok(Link::socketcan(ifname)?);
    }
    Ok(Link::socketcand(&bus.socketcand, &bus.channel).await?)
}

pub(crate) fn parse_hex_u16(s: &str, what: &str) -> Result<u16, CommandError> {
    drivetwin::value_text::parse_hex_number(s, what, u16::from_str_radix)
        .map_err(CommandError::Usage)
}

pub(crate) fn parse_hex_u8(s: &str, what: &str) -> Result<u8, CommandError> {
    drivetwin::value_text::parse_hex_number(s, what, u8::from_str_radix)
        .map_err(CommandError::Usage)
}

pub(crate) fn check_node(node: u8) -> Result<(), CommandError> {
    if (1..=127).contains(&node) {
        Ok(())
    } else {
        Err(CommandError::Usage(format!(
            "node-ID {node} is outside 1…127"
        )))
    }
}

/// Ctrl-C (SIGINT) or SIGTERM: both stop the cell cleanly, flushing the trace.
///
/// The handlers are installed when this is called, not when the future is first polled: a
/// supervisor (a test fixture) that sends SIGTERM as soon as the cell prints that it runs
/// finds them in place, instead of the default action ending the process without "stopped".
#[cfg(unix)]
pub(crate) fn shutdown_signal() -> impl std::future::Future<Output = ()> + Send + 'static {
    use tokio::signal::unix::{signal, SignalKind};
    let interrupt = signal(SignalKind::interrupt()).ok();
    let terminate = signal(SignalKind::terminate()).ok();
    async move {
        match (interrupt, terminate) {
            (Some(mut interrupt), Some(mut terminate)) => {
                tokio::select! {
                    _ = interrupt.recv() => {}
                    _ = terminate.recv() => {}
                }
            }
            _ => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
}

/// Ctrl-C: stops the cell cleanly, flushing the trace.
#[cfg(not(unix))]
pub(crate) fn shutdown_signal() -> impl std::future::Future<Output = ()> + Send + 'static {
    async {
        let _ = tokio::signal::ctrl_c().await;
    }
}
