//! `drivetwin kinco read|write|status`: a Kinco drive over its RS232 telegrams
//! ([`super::rs232_master`]), values typed by the personality's dictionary.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Subcommand};
use od::DataType;

use super::rs232_master::{KincoError, KincoMaster};
use crate::value_text;
use crate::vendors::{device, parse_hex, CommandError, Failure};

// `drivetwin kinco`'s arguments: what to do, and the serial port (no doc comment: the
// sub-command's help is the variant's in the binary's command list).
#[derive(Args, Debug)]
pub struct KincoArgs {
    #[command(subcommand)]
    pub command: KincoCommand,
    #[command(flatten)]
    pub port: KincoPortArgs,
}

/// The serial port of `drivetwin kinco`.
#[derive(Args, Debug, Clone)]
pub struct KincoPortArgs {
    /// The serial port: a device (/dev/ttyUSB0) or a twin's `--rs232` link.
    #[arg(long, global = true, default_value = "/dev/ttyUSB0")]
    pub port: PathBuf,
    /// The drive's station number (its node-ID, 100Bh).
    #[arg(long, global = true, default_value_t = 1)]
    pub id: u8,
    /// Bit rate (RS232_Baudrate 2FE0h: 270 = 38400, the default).
    #[arg(long, global = true, default_value_t = 38_400)]
    pub baud: u32,
    /// How long to wait for each answer, ms.
    #[arg(long, global = true, default_value_t = 200)]
    pub timeout_ms: u64,
    /// The personality whose dictionary types the values.
    #[arg(long, global = true, default_value = "kinco-fd3")]
    pub device: String,
}

#[derive(Subcommand, Debug)]
pub enum KincoCommand {
    /// Read an object (upload, 40h), decoded by its type.
    Read {
        /// Index, hex (0x6041 or 6041).
        index: String,
        /// Sub-index, hex.
        #[arg(default_value = "0")]
        sub: String,
        /// Type to decode as (u8 u16 u32 i8 i16 i32 hex); default the dictionary's.
        #[arg(long = "type", short = 't')]
        data_type: Option<String>,
    },
    /// Write an object (download, 23h / 2Bh / 2Fh by its size).
    Write {
        index: String,
        sub: String,
        #[arg(allow_negative_numbers = true)]
        value: String,
        /// Type to encode as; default the dictionary's.
        #[arg(long = "type", short = 't')]
        data_type: Option<String>,
    },
    /// The drive's state: statusword, controlword, mode, position, speed, errors.
    Status,
}

/// The port and the time-outs are the link; an error telegram is a refusal.
pub(crate) fn failure(e: &KincoError) -> Failure {
    match e {
        KincoError::Port(_) | KincoError::Io(_) => Failure::Link,
        KincoError::Timeout { .. } => Failure::Timeout,
        KincoError::Abort { .. } => Failure::Refused,
    }
}

/// What `status` reads, in order (objects the personality lacks are skipped).
const STATUS: &[(u16, u8, &str)] = &[
    (0x6041, 0, "statusword"),
    (0x6040, 0, "controlword"),
    (0x6061, 0, "mode"),
    (0x6063, 0, "position"),
    (0x606C, 0, "speed"),
    (0x2601, 0, "error state"),
    (0x2602, 0, "error state 2"),
];

fn type_of(
    desc: &'static od::DeviceDescription,
    explicit: Option<&str>,
    index: u16,
    sub: u8,
) -> Result<Option<DataType>, CommandError> {
    if let Some(t) = explicit {
        return value_text::parse_type(t)
            .map(Some)
            .ok_or_else(|| CommandError::Usage(format!("unknown type {t:?}")));
    }
    Ok(desc.entry(index, sub).map(|e| e.data_type))
}

fn text(ty: Option<DataType>, data: &[u8]) -> String {
    ty.and_then(|t| value_text::decode(t, data))
        .unwrap_or_else(|| value_text::hex(data))
}

impl KincoArgs {
    /// Carries the command out; each line of its answer goes to `out` as it is known.
    pub fn run(self, out: &mut dyn FnMut(&str)) -> Result<(), CommandError> {
        kinco(self.command, self.port, out)
    }
}

fn kinco(
    cmd: KincoCommand,
    port: KincoPortArgs,
    out: &mut dyn FnMut(&str),
) -> Result<(), CommandError> {
    let desc = device(&port.device)?;
    let mut m = KincoMaster::open(
        &port.port,
        port.baud,
        Duration::from_millis(port.timeout_ms),
    )?;
    let id = port.id;
    match cmd {
        KincoCommand::Read {
            index,
            sub,
            data_type,
        } => {
            let index = parse_hex(&index, "index", u16::from_str_radix)?;
            let sub = parse_hex(&sub, "sub-index", u8::from_str_radix)?;
            let ty = type_of(desc, data_type.as_deref(), index, sub)?;
            let data = m.read(id, index, sub)?;
            out(&text(ty, &data));
        }
        KincoCommand::Write {
            index,
            sub,
            value,
            data_type,
        } => {
            let index = parse_hex(&index, "index", u16::from_str_radix)?;
            let sub = parse_hex(&sub, "sub-index", u8::from_str_radix)?;
            let ty = type_of(desc, data_type.as_deref(), index, sub)?.ok_or_else(|| {
                CommandError::Usage(format!(
                    "{} has no entry {index:04X}:{sub:02X}: give --type",
                    desc.name
                ))
            })?;
            let data = value_text::encode(ty, &value).map_err(CommandError::Usage)?;
            if !matches!(data.len(), 1 | 2 | 4) {
                return Err(CommandError::Usage(format!(
                    "{} bytes: a telegram carries 1, 2 or 4",
                    data.len()
                )));
            }
            m.write(id, index, sub, &data)?;
            out("ok");
        }
        KincoCommand::Status => {
            for &(index, sub, name) in STATUS {
                let Some(e) = desc.entry(index, sub) else {
                    continue;
                };
                let data = m.read(id, index, sub)?;
                let value = text(Some(e.data_type), &data);
                if index == 0x6041 {
                    let sw = data
                        .iter()
                        .take(2)
                        .enumerate()
                        .fold(0u16, |acc, (i, b)| acc | (u16::from(*b) << (8 * i)));
                    out(&format!(
                        "{name:<14} {sw:#06x} {}",
                        crate::master::cia402::state_name(sw)
                    ));
                } else {
                    out(&format!("{name:<14} {value}"));
                }
            }
        }
    }
    Ok(())
}
