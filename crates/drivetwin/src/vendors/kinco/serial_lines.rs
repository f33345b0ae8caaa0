//! The serial lines of a cell, built from what the cell file and the command line ask for:
//! drives naming one path share a line. Each drive's settings are read from its objects at
//! power-up, as the firmware reads them after a reboot (§9.1 item 7: baud rates, node-ID and
//! RS232_Loop_Enable take effect after save and reboot):
//!
//! - station = node-ID (100Bh, §10.2 / §12.2);
//! - RS232 bit rate from RS232_Baudrate 2FE0h, then U2BRG 2FE1h when written (at once);
//! - RS485 bit rate from RS485_Baudrate 2FE2h; protocol from RS485_Protocol 6510h:0C
//!   (0 Modbus RTU, 1 the telegrams);
//! - several drives on one RS232 path: a ring in cell-file order (RS232_Loop_Enable 6510h:0B).
//!
//! Decision: a drive whose bit rate is not the line's (the first drive's) is left off the line
//! with a warning: on a real line it would read only framing errors.

use std::path::{Path, PathBuf};

use drive::vendors::kinco::rs232::KincoRs232;
use drive::vendors::kinco::rtu::RegisterMapping;

use super::baud_of_code;
use super::rs232_line::{TelegramLine, Topology, U2brg};
use super::rtu_line::{RtuDrive, RtuLine};
use crate::cell::can_cell::CanCell;
use crate::cell::station::Station;
use crate::cell::stations::StationId;
use crate::serial::line::{Protocol, SerialLine, VirtualLine};
use crate::serial::pty::PortError;
use crate::serial::{has_port, Kind, LineRequest, LinesError, SerialLines};

#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    #[error(
        "{device} has no {kind} port (Kinco §1.1: RS232 on the CD3 and FD3, RS485 on the FD3)"
    )]
    NoPort { device: String, kind: &'static str },
    #[error("{path}: both an RS232 and an RS485 line")]
    Mixed { path: PathBuf },
    #[error(
        "{kind} of node {node}: baud-rate code {code} is no bit rate (§2.1: 1080, 540, 270, 90)"
    )]
    Baud {
        kind: &'static str,
        node: u8,
        code: u64,
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

fn code(d: &Station, index: u16, sub: u8, default: u64) -> u64 {
    d.od().get_unsigned(index, sub).unwrap_or(default)
}

/// Whether drive `at` may have a port of `kind`.
pub fn check(cell: &CanCell, at: StationId, kind: Kind) -> Result<(), SetupError> {
    let Some(d) = drive(cell, at) else {
        return Ok(());
    };
    let name = d.od().description().name;
    if !has_port(name, kind) {
        return Err(SetupError::NoPort {
            device: name.into(),
            kind: kind.as_str(),
        });
    }
    Ok(())
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
        let rate_of = |d: &Station| -> Result<u32, SetupError> {
            let (index, default) = match kind {
                Kind::Rs232 => (0x2FE0, 270),
                Kind::Rs485 => (0x2FE2, 540),
            };
            let c = code(d, index, 0, default);
            let codes = d.od().description().serial_bit_rate.as_ref();
            codes
                .and_then(|codes| baud_of_code(codes, c))
                .ok_or(SetupError::Baud {
                    kind: kind.as_str(),
                    node: d.node_id(),
                    code: c,
                })
        };
        let Some(&(_, first)) = drives.first() else {
            continue;
        };
        let baud = rate_of(first)?;
        let mut on_line = Vec::new();
        for (at, d) in drives {
            let b = rate_of(d)?;
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
        let telegrams = kind == Kind::Rs232
            || on_line
                .first()
                .is_some_and(|(_, d)| code(d, 0x6510, 0x0C, 0) == 1);
        let protocol = if telegrams {
            let ring = kind == Kind::Rs232;
            if ring && on_line.len() > 1 {
                for (_, d) in &on_line {
                    if code(d, 0x6510, 0x0B, 0) != 1 {
                        tracing::warn!(
                            node = d.node_id(),
                            "several drives on one RS232 line, but RS232_Loop_Enable \
                             6510h:0B is 0: it passes nothing on (§2.1 multi-point)"
                        );
                    }
                }
            }
            let ports = on_line
                .iter()
                .map(|(at, d)| {
                    let loop_enable = kind == Kind::Rs232 && code(d, 0x6510, 0x0B, 0) == 1;
                    (*at, KincoRs232::new(d.node_id(), loop_enable))
                })
                .collect();
            let topology = if ring { Topology::Ring } else { Topology::Bus };
            let u2brg = (kind == Kind::Rs232)
                .then(|| {
                    on_line.first().and_then(|(_, d)| {
                        let codes = d.od().description().serial_bit_rate.as_ref()?;
                        Some(U2brg {
                            code: code(d, 0x2FE1, 0, 270),
                            codes,
                        })
                    })
                })
                .flatten();
            Box::new(TelegramLine::new(ports, topology, u2brg)) as Protocol
        } else {
            let drives = on_line
                .iter()
                .map(|(at, d)| RtuDrive {
                    at: *at,
                    station: d.node_id(),
                    map: register_map(d.od().description().name),
                })
                .collect();
            Box::new(RtuLine::new(baud, drives))
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
