//! The serial lines of a cell, built from what the cell file and the command line ask for:
//! drives naming one path share a line. Each drive's port is read from the objects its device
//! file names (`[device.serial_ports]`: the Kinco's RS232_Baudrate 2FE0h, U2BRG 2FE1h,
//! RS232_Loop_Enable 6510h:0B, RS485_Baudrate 2FE2h, RS485_Protocol 6510h:0C) at power-up, as
//! the firmware reads them after a reboot (§9.1 item 7: baud rates, node-ID and
//! RS232_Loop_Enable take effect after save and reboot):
//!
//! - station = node-ID (100Bh, §10.2 / §12.2);
//! - the bit rate from the port's `bit_rate` object, then its `bit_rate_now` when written (at
//!   once);
//! - the protocol from the port's `protocol` object (Modbus RTU or the telegrams), the
//!   telegrams alone on a port without one;
//! - several drives on one path of a port with `loop_enable`: a ring in cell-file order, each
//!   passing on what it receives while its object reads 1; on a port without it, a bus.
//!
//! Decision: a drive whose bit rate is not the line's (the first drive's) is left off the line
//! with a warning: on a real line it would read only framing errors.

use std::path::{Path, PathBuf};

use drive::vendors::kinco::rs232::KincoRs232;
use drive::vendors::kinco::rtu::RegisterMapping;
use od::{SerialPort, SerialProtocol};

use super::baud_of_code;
use super::rs232_line::{TelegramLine, Topology, U2brg};
use super::rtu_line::{RtuDrive, RtuLine};
use crate::cell::can_cell::CanCell;
use crate::cell::station::Station;
use crate::cell::stations::StationId;
use crate::serial::line::{Protocol, SerialLine, VirtualLine};
use crate::serial::pty::PortError;
use crate::serial::{Kind, LineRequest, LinesError, SerialLines};

#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    #[error(
        "{device} has no {kind} port (Kinco §1.1: RS232 on the CD3 and FD3, RS485 on the FD3)"
    )]
    NoPort { device: String, kind: &'static str },
    #[error("{path}: both an RS232 and an RS485 line")]
    Mixed { path: PathBuf },
    #[error(
        "{kind} of node {node}: baud-rate code {code} in {object:04X}h is no bit rate of its \
         device file's serial_bit_rate (§2.1: {known})"
    )]
    Baud {
        kind: &'static str,
        node: u8,
        object: u16,
        code: u64,
        /// The codes the device file lists.
        known: String,
    },
    #[error("{kind} of node {node}: its object {index:04X}h sub {sub} cannot be read")]
    Unreadable {
        kind: &'static str,
        node: u8,
        index: u16,
        sub: u8,
    },
    #[error(transparent)]
    Port(#[from] PortError),
}

impl From<SetupError> for LinesError {
    fn from(e: SetupError) -> Self {
        match e {
            SetupError::Port(p) => LinesError::Port(p),
            refused => LinesError::Refused(refused.to_string()),
        }
    }
}

/// The serial lines of a cell as the runtime's front end takes them
/// ([`crate::serial::SerialLines`]).
pub const SERIAL_LINES: SerialLines = SerialLines {
    open_lines: |requests, cell| Ok(open_lines(requests, cell)?),
    virtual_lines: |requests, cell| Ok(virtual_lines(requests, cell)?),
};

fn drive(cell: &CanCell, at: StationId) -> Option<&Station> {
    cell.stations.station(at)
}

/// The value of object `index:sub` of drive `d`; `None` where it cannot be read.
fn code(d: &Station, (index, sub): (u16, u8)) -> Option<u64> {
    d.od().get_unsigned(index, sub)
}

/// The port of drive `d` that is interface `kind` (its device file's `[device.serial_ports]`).
fn port(d: &Station, kind: Kind) -> Option<&'static SerialPort> {
    SerialPort::find(d.od().description().serial_ports, kind.as_str())
}

/// Whether drive `at` has a port of `kind`.
pub fn check(cell: &CanCell, at: StationId, kind: Kind) -> Result<(), SetupError> {
    let Some(d) = drive(cell, at) else {
        return Ok(());
    };
    if port(d, kind).is_none() {
        return Err(SetupError::NoPort {
            device: d.od().description().name.into(),
            kind: kind.as_str(),
        });
    }
    Ok(())
}

/// The value of `object` of drive `d` on its `kind` port, or why not.
fn read(d: &Station, kind: Kind, object: (u16, u8)) -> Result<u64, SetupError> {
    code(d, object).ok_or(SetupError::Unreadable {
        kind: kind.as_str(),
        node: d.node_id(),
        index: object.0,
        sub: object.1,
    })
}

/// The bit rate of drive `d`'s `kind` port: its `bit_rate` object's code in the device file's
/// `serial_bit_rate`.
fn bit_rate(d: &Station, kind: Kind) -> Result<u32, SetupError> {
    let p = port(d, kind).ok_or_else(|| SetupError::NoPort {
        device: d.od().description().name.into(),
        kind: kind.as_str(),
    })?;
    let c = read(d, kind, (p.bit_rate, 0))?;
    let codes = d.od().description().serial_bit_rate.as_ref();
    codes
        .and_then(|codes| baud_of_code(codes, c))
        .ok_or_else(|| SetupError::Baud {
            kind: kind.as_str(),
            node: d.node_id(),
            object: p.bit_rate,
            code: c,
            known: codes.map_or_else(String::new, |codes| {
                let list: Vec<String> = codes.codes.iter().map(|(c, _)| c.to_string()).collect();
                list.join(", ")
            }),
        })
}

/// Drive `d` passes on what it receives: its port's `loop_enable` object reads 1.
fn loop_enabled(d: &Station, kind: Kind) -> bool {
    port(d, kind)
        .and_then(|p| p.loop_enable)
        .is_some_and(|o| code(d, o) == Some(1))
}

/// Opens one line per path of `requests` (in order of first mention).
pub fn open_lines(requests: &[LineRequest], cell: &CanCell) -> Result<Vec<SerialLine>, SetupError> {
    let mut lines = Vec::new();
    for (kind, path, baud, protocol) in line_protocols(requests, cell)? {
        lines.push(SerialLine::open(kind, path, baud, protocol)?);
    }
    Ok(lines)
}

/// The lines of `requests` for the virtual clock ([`crate::cell_loop::virtual_clock::run_virtual_lines`]):
/// as [`open_lines`] builds them, without ports (a path only names the line its drives share).
pub fn virtual_lines(
    requests: &[LineRequest],
    cell: &CanCell,
) -> Result<Vec<VirtualLine>, SetupError> {
    Ok(line_protocols(requests, cell)?
        .into_iter()
        .map(|(kind, _, baud, protocol)| VirtualLine::new(kind, baud, protocol))
        .collect())
}

/// One line per path of `requests`: its kind, path, bit rate and protocol with its drives.
fn line_protocols<'a>(
    requests: &'a [LineRequest],
    cell: &CanCell,
) -> Result<Vec<(Kind, &'a Path, u32, Protocol)>, SetupError> {
    let mut paths: Vec<&Path> = Vec::new();
    for r in requests {
        check(cell, r.drive, r.kind)?;
        if !paths.contains(&r.path.as_path()) {
            paths.push(&r.path);
        }
    }
    let mut lines = Vec::new();
    for path in paths {
        let on: Vec<&LineRequest> = requests.iter().filter(|r| r.path == path).collect();
        let kind = on.first().map_or(Kind::Rs232, |r| r.kind);
        if on.iter().any(|r| r.kind != kind) {
            return Err(SetupError::Mixed { path: path.into() });
        }
        let drives: Vec<(StationId, &Station)> = on
            .iter()
            .filter_map(|r| drive(cell, r.drive).map(|d| (r.drive, d)))
            .collect();
        let Some(&(_, first)) = drives.first() else {
            continue;
        };
        let baud = bit_rate(first, kind)?;
        let mut on_line = Vec::new();
        for (at, d) in drives {
            let b = bit_rate(d, kind)?;
            if b != baud {
                tracing::warn!(
                    node = d.node_id(),
                    path = %path.display(),
                    "its {b} bit/s is not the line's {baud} bit/s: off the line"
                );
                continue;
            }
            on_line.push((at, d));
        }
        // The first drive's port decides the line's protocol and wiring.
        let Some((first_port, &(_, first))) = on_line
            .first()
            .and_then(|f| port(f.1, kind).map(|p| (p, f)))
        else {
            continue;
        };
        let selected = first_port.protocol.map(|p| code(first, p.object));
        let protocol = match first_port.protocol(selected.flatten()) {
            SerialProtocol::Telegrams => {
                let ring = first_port.loop_enable;
                if let Some((index, sub)) = ring.filter(|_| on_line.len() > 1) {
                    for (_, d) in &on_line {
                        if !loop_enabled(d, kind) {
                            tracing::warn!(
                                node = d.node_id(),
                                "several drives on one line, but its loop enable \
                                 {index:04X}h:{sub:02X}h is not 1: it passes nothing on \
                                 (§2.1 multi-point)"
                            );
                        }
                    }
                }
                let ports = on_line
                    .iter()
                    .map(|(at, d)| (*at, KincoRs232::new(d.node_id(), loop_enabled(d, kind))))
                    .collect();
                let topology = if ring.is_some() {
                    Topology::Ring
                } else {
                    Topology::Bus
                };
                let u2brg = match (
                    first_port.bit_rate_now,
                    &first.od().description().serial_bit_rate,
                ) {
                    (Some(object), Some(codes)) => Some(U2brg {
                        object,
                        code: read(first, kind, (object, 0))?,
                        codes,
                    }),
                    _ => None,
                };
                Box::new(TelegramLine::new(ports, topology, u2brg)) as Protocol
            }
            SerialProtocol::ModbusRtu => {
                let drives = on_line
                    .iter()
                    .map(|(at, d)| RtuDrive {
                        at: *at,
                        station: d.node_id(),
                        map: register_map(d.od().description().name),
                    })
                    .collect();
                Box::new(RtuLine::new(baud, drives))
            }
        };
        lines.push((kind, path, baud, protocol));
    }
    Ok(lines)
}

/// The Modbus registers of personality `name` (its device file's `modbus` keys).
pub fn register_map(name: &str) -> Vec<RegisterMapping> {
    devices::addresses(name)
        .map(|a| {
            a.modbus
                .iter()
                .map(|r| RegisterMapping {
                    register: r.register,
                    index: r.index,
                    sub: r.sub,
                })
                .collect()
        })
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell::station::Commissioning;

    /// A Kinco of `desc` at node `node` with `index`:00 (UNSIGNED16) commissioned to `value`.
    fn station(desc: &'static od::DeviceDescription, node: u8, set: &[(u16, u16)]) -> Station {
        let commissioning = set
            .iter()
            .map(|&(index, value)| Commissioning {
                index,
                sub: 0,
                bytes: value.to_le_bytes().to_vec(),
            })
            .collect();
        Station::with_settings(desc, node, None, commissioning, None).expect("station")
    }

    fn refusal(cell: &CanCell, kind: Kind) -> String {
        let request = [LineRequest {
            kind,
            path: "line".into(),
            drive: StationId::from_index(0),
        }];
        match virtual_lines(&request, cell) {
            Ok(_) => String::new(),
            Err(e) => e.to_string(),
        }
    }

    /// The rate is the code of the object the device file names for the port (RS232_Baudrate
    /// 2FE0h, RS485_Baudrate 2FE2h): a code outside `serial_bit_rate` refuses the line, naming
    /// the object and the codes the file lists; a port the file has no table for is refused.
    #[test]
    fn the_ports_objects_are_the_device_files() {
        let fd3 = &devices::KINCO_FD3;
        let factory = CanCell::one_bus(vec![station(fd3, 2, &[])]);
        assert_eq!(refusal(&factory, Kind::Rs232), "");
        assert_eq!(refusal(&factory, Kind::Rs485), "");
        let rs232_180 = CanCell::one_bus(vec![station(fd3, 2, &[(0x2FE0, 180)])]);
        assert_eq!(
            refusal(&rs232_180, Kind::Rs232),
            "rs232 of node 2: baud-rate code 180 in 2FE0h is no bit rate of its device file's \
             serial_bit_rate (§2.1: 1080, 540, 270, 90)"
        );
        assert_eq!(refusal(&rs232_180, Kind::Rs485), "", "RS485 reads 2FE2h");
        let rs485_7 = CanCell::one_bus(vec![station(fd3, 3, &[(0x2FE2, 7)])]);
        assert!(refusal(&rs485_7, Kind::Rs485).contains("code 7 in 2FE2h"));
        let cd3 = CanCell::one_bus(vec![station(&devices::KINCO_CD3, 1, &[])]);
        assert_eq!(
            refusal(&cd3, Kind::Rs485),
            "kinco-cd3 has no rs485 port (Kinco §1.1: RS232 on the CD3 and FD3, RS485 on the FD3)"
        );
    }
}
