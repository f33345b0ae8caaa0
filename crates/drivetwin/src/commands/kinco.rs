//! `drivetwin kinco read|write|status`: a Kinco drive over its RS232 telegrams
//! ([`drivetwin::master::kinco_rs232`]), values typed by the personality's dictionary.

use super::*;
use crate::cli::{KincoCommand, KincoPortArgs};
use drivetwin::master::kinco_rs232::{KincoError, KincoMaster};

pub(crate) fn exit_code(e: &KincoError) -> u8 {
    match e {
        KincoError::Port(_) | KincoError::Io(_) => EXIT_LINK,
        KincoError::Timeout { .. } => EXIT_TIMEOUT,
        KincoError::Abort { .. } => EXIT_ABORT,
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

pub(crate) fn kinco(cmd: KincoCommand, port: KincoPortArgs) -> Result<(), CommandError> {
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
            let index = parse_hex_u16(&index, "index")?;
            let sub = parse_hex_u8(&sub, "sub-index")?;
            let ty = type_of(desc, data_type.as_deref(), index, sub)?;
            let data = m.read(id, index, sub)?;
            out!("{}", text(ty, &data));
        }
        KincoCommand::Write {
            index,
            sub,
            value,
            data_type,
        } => {
            let index = parse_hex_u16(&index, "index")?;
            let sub = parse_hex_u8(&sub, "sub-index")?;
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
            out!("ok");
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
                    out!(
                        "{name:<14} {sw:#06x} {}",
                        drivetwin::master::cia402::state_name(sw)
                    );
                } else {
                    out!("{name:<14} {value}");
                }
            }
        }
    }
    Ok(())
}
