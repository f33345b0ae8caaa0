//! What a frame means on a CiA 301 bus with the pre-defined connection set, for monitors
//! and traces. Decoding never fails: anything unknown is reported as such.

use od::AbortCode;

use crate::{CanFrame, NmtCommand, NmtState};

/// The pre-defined connection set's function of a COB-ID (CiA 301 §7.3.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Function {
    Nmt,
    Sync,
    Time,
    Emcy,
    Tpdo(u8),
    Rpdo(u8),
    /// Server → client (580h + node).
    SdoTx,
    /// Client → server (600h + node).
    SdoRx,
    /// Boot-up, heartbeat or guarding (700h + node).
    ErrorControl,
    LssMaster,
    LssSlave,
    Unknown,
}

/// Splits a standard COB-ID into function and node-ID.
pub fn classify(cob: u16) -> (Function, u8) {
    let node = (cob & 0x7F) as u8;
    let f = match cob {
        0x000 => return (Function::Nmt, 0),
        0x080 => return (Function::Sync, 0),
        0x100 => return (Function::Time, 0),
        0x7E4 => return (Function::LssSlave, 0),
        0x7E5 => return (Function::LssMaster, 0),
        _ if node == 0 => Function::Unknown,
        0x081..=0x0FF => Function::Emcy,
        0x181..=0x1FF => Function::Tpdo(1),
        0x201..=0x27F => Function::Rpdo(1),
        0x281..=0x2FF => Function::Tpdo(2),
        0x301..=0x37F => Function::Rpdo(2),
        0x381..=0x3FF => Function::Tpdo(3),
        0x401..=0x47F => Function::Rpdo(3),
        0x481..=0x4FF => Function::Tpdo(4),
        0x501..=0x57F => Function::Rpdo(4),
        0x581..=0x5FF => Function::SdoTx,
        0x601..=0x67F => Function::SdoRx,
        0x701..=0x77F => Function::ErrorControl,
        _ => Function::Unknown,
    };
    (f, node)
}

/// Writes a one-line description of `frame`.
pub fn describe(frame: &CanFrame, w: &mut impl core::fmt::Write) -> core::fmt::Result {
    let Some(cob) = frame.cob_id() else {
        return write!(w, "extended frame {:08X}", frame.id);
    };
    let d = frame.payload();
    let (f, node) = classify(cob);
    if frame.rtr {
        return match f {
            Function::ErrorControl => write!(w, "node guarding request, node {node}"),
            _ => write!(w, "remote request {cob:03X}"),
        };
    }
    match f {
        Function::Nmt => match d {
            [cs, target] => {
                let name = NmtCommand::from_cs(*cs)
                    .map(|c| c.name())
                    .unwrap_or("unknown command");
                if *target == 0 {
                    write!(w, "NMT {name}, all nodes")
                } else {
                    write!(w, "NMT {name}, node {target}")
                }
            }
            _ => write!(w, "NMT, bad length {}", d.len()),
        },
        Function::Sync => match d {
            [] => write!(w, "SYNC"),
            [c] => write!(w, "SYNC counter {c}"),
            _ => write!(w, "SYNC, bad length {}", d.len()),
        },
        Function::Time => write!(w, "TIME"),
        Function::Emcy => match d {
            [c0, c1, reg, rest @ ..] => {
                let code = u16::from_le_bytes([*c0, *c1]);
                write!(
                    w,
                    "EMCY node {node}: error {code:04X}h, register {reg:02X}h"
                )?;
                if code == 0 {
                    write!(w, " (error reset)")?;
                }
                if rest.iter().any(|b| *b != 0) {
                    write!(w, ", vendor {rest:02X?}")?;
                }
                Ok(())
            }
            _ => write!(w, "EMCY node {node}, bad length {}", d.len()),
        },
        Function::Tpdo(n) => write!(w, "TPDO{n} node {node}: {}", Hex(d)),
        Function::Rpdo(n) => write!(w, "RPDO{n} node {node}: {}", Hex(d)),
        Function::SdoRx | Function::SdoTx => {
            let dir = if f == Function::SdoRx {
                "request"
            } else {
                "response"
            };
            write!(w, "SDO {dir} node {node}: ")?;
            describe_sdo(f == Function::SdoRx, d, w)
        }
        Function::ErrorControl => match d {
            [0] => write!(w, "boot-up node {node}"),
            [s] => {
                let state = NmtState::from_code(s & 0x7F)
                    .map(|s| s.name())
                    .unwrap_or("unknown state");
                if s & 0x80 != 0 {
                    write!(w, "node guarding node {node}: {state}, toggle 1")
                } else {
                    write!(w, "heartbeat node {node}: {state}")
                }
            }
            _ => write!(w, "error control node {node}, bad length {}", d.len()),
        },
        Function::LssMaster => write!(w, "LSS master: {}", Hex(d)),
        Function::LssSlave => write!(w, "LSS slave: {}", Hex(d)),
        Function::Unknown => write!(w, "{cob:03X}: {}", Hex(d)),
    }
}

fn describe_sdo(request: bool, d: &[u8], w: &mut impl core::fmt::Write) -> core::fmt::Result {
    let Some(&cs) = d.first() else {
        return write!(w, "empty");
    };
    let mux = match d {
        [_, i0, i1, s, ..] => Some((u16::from_le_bytes([*i0, *i1]), *s)),
        _ => None,
    };
    let data = d.get(4..).unwrap_or(&[]);
    let (idx, sub) = mux.unwrap_or((0, 0));
    if cs == 0x80 {
        let code = match data {
            [a, b, c, e, ..] => u32::from_le_bytes([*a, *b, *c, *e]),
            _ => 0,
        };
        return write!(w, "abort {idx:04X}:{sub:02X}, {}", AbortCode(code));
    }
    let ccs = cs >> 5;
    match (request, ccs) {
        (true, 1) if cs & 0x02 != 0 => {
            let n = if cs & 0x01 != 0 {
                4 - usize::from((cs >> 2) & 3)
            } else {
                4
            };
            write!(
                w,
                "write {idx:04X}:{sub:02X} = {}",
                Hex(data.get(..n).unwrap_or(data))
            )
        }
        (true, 1) => write!(w, "write {idx:04X}:{sub:02X}, segmented"),
        (true, 2) => write!(w, "read {idx:04X}:{sub:02X}"),
        (true, 0) => write!(w, "download segment, toggle {}", (cs >> 4) & 1),
        (true, 3) => write!(w, "upload segment request, toggle {}", (cs >> 4) & 1),
        (true, 5) => write!(w, "block upload {idx:04X}:{sub:02X}"),
        (true, 6) => write!(w, "block download {idx:04X}:{sub:02X}"),
        (false, 3) => write!(w, "write {idx:04X}:{sub:02X} ok"),
        (false, 2) if cs & 0x02 != 0 => {
            let n = if cs & 0x01 != 0 {
                4 - usize::from((cs >> 2) & 3)
            } else {
                4
            };
            write!(
                w,
                "read {idx:04X}:{sub:02X} = {}",
                Hex(data.get(..n).unwrap_or(data))
            )
        }
        (false, 2) => write!(w, "read {idx:04X}:{sub:02X}, segmented"),
        (false, 0) => write!(w, "upload segment, toggle {}", (cs >> 4) & 1),
        (false, 1) => write!(w, "download segment ok, toggle {}", (cs >> 4) & 1),
        (false, 5) => write!(w, "block download response"),
        (false, 6) => write!(w, "block upload response"),
        _ => write!(w, "block segment / unknown {}", Hex(d)),
    }
}

/// Bytes as spaced upper-case hex.
pub struct Hex<'a>(pub &'a [u8]);

impl core::fmt::Display for Hex<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for (i, b) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(" ")?;
            }
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}
