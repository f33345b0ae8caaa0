//! The bus operations of FMI-LS-BUS 1.0 for CAN (the layered standard's Network Abstraction,
//! §4.3 "Layered Standard Bus Protocol" and §4.4.1 "CAN, CAN FD, CAN XL"): the bytes an FMU's
//! `Rx_Data` / `Tx_Data` binary variables carry, parsed into [`Operation`]s and emitted from
//! them.
//!
//! Every operation is an OP Code (4 bytes), a Length (4 bytes: the whole operation, OP Code and
//! Length included) and its arguments; numbers are little-endian; a binary value holds zero,
//! one or more operations back to back. An operation this module cannot read (an unknown OP
//! Code, a Length that does not fit the operation or the bytes left) is a [`Malformed`], whose
//! bytes go back in a Format Error operation (§4.3.1: "the complete binary data of the
//! operation that caused" it).

/// The MIME type of the CAN terminal's binary variables (§4.2.5).
pub const MIME_TYPE: &str = "application/org.fmi-standard.fmi-ls-bus.can; version=\"1.0.0\"";

/// OP Codes (§4.4.1.1, table "Overview of the available operations").
pub mod op_code {
    pub const FORMAT_ERROR: u32 = 0x01;
    pub const CAN_TRANSMIT: u32 = 0x10;
    pub const CAN_FD_TRANSMIT: u32 = 0x11;
    pub const CAN_XL_TRANSMIT: u32 = 0x12;
    pub const CONFIRM: u32 = 0x20;
    pub const ARBITRATION_LOST: u32 = 0x30;
    pub const BUS_ERROR: u32 = 0x31;
    pub const CONFIGURATION: u32 = 0x40;
    pub const STATUS: u32 = 0x41;
    pub const WAKEUP: u32 = 0x42;
}

/// OP Code and Length.
const HEADER: usize = 8;

/// The Bus Error's Error Code (§4.4.1.2.5, table "Overview of the available error codes").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum ErrorCode {
    BitError = 0x01,
    BitStuffingError = 0x02,
    FormError = 0x03,
    CrcError = 0x04,
    AckError = 0x05,
    BrokenErrorFrame = 0x06,
}

impl ErrorCode {
    fn from_u8(v: u8) -> Option<ErrorCode> {
        Some(match v {
            0x01 => ErrorCode::BitError,
            0x02 => ErrorCode::BitStuffingError,
            0x03 => ErrorCode::FormError,
            0x04 => ErrorCode::CrcError,
            0x05 => ErrorCode::AckError,
            0x06 => ErrorCode::BrokenErrorFrame,
            _ => return None,
        })
    }
}

/// The Bus Error's Error Flag: whether this participant detected the error first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum ErrorFlag {
    Primary = 0x01,
    Secondary = 0x02,
}

/// How a bus simulation treats a frame that lost arbitration (§4.4.1.2.6, `Arbitration Lost
/// Behavior`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum ArbitrationLostBehavior {
    /// Kept and sent as soon as the bus is free; no Arbitration Lost operation.
    BufferAndRetransmit = 0x01,
    /// Dropped, and the sender told with an Arbitration Lost operation.
    DiscardAndNotify = 0x02,
}

/// One parameter of a Configuration operation (§4.4.1.2.6: one per operation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Configuration {
    /// `CAN_BAUDRATE` (0x01), bit/s.
    CanBaudRate(u32),
    /// `CAN_FD_BAUDRATE` (0x02), bit/s.
    CanFdBaudRate(u32),
    /// `CAN_XL_BAUDRATE` (0x03), bit/s.
    CanXlBaudRate(u32),
    /// `ARBITRATION_LOST_BEHAVIOR` (0x04).
    ArbitrationLostBehavior(ArbitrationLostBehavior),
}

/// The node state a Status operation reports (§4.4.1.2.7).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Status {
    ErrorActive = 0x01,
    ErrorPassive = 0x02,
    BusOff = 0x03,
}

/// One bus operation, borrowing its variable-length data from the bytes it was parsed from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Operation<'a> {
    /// Format Error (0x01): `data` is the operation that could not be read.
    FormatError { data: &'a [u8] },
    /// CAN Transmit (0x10): a classic CAN frame; `id` is the numeric identifier, `ide` says
    /// 29-bit, `data` the actual bytes (not a DLC).
    CanTransmit {
        id: u32,
        ide: bool,
        rtr: bool,
        data: &'a [u8],
    },
    /// CAN FD Transmit (0x11).
    CanFdTransmit {
        id: u32,
        ide: bool,
        brs: bool,
        esi: bool,
        data: &'a [u8],
    },
    /// CAN XL Transmit (0x12).
    CanXlTransmit {
        id: u32,
        ide: bool,
        sec: bool,
        sdt: u8,
        vcid: u8,
        af: u32,
        data: &'a [u8],
    },
    /// Confirm (0x20): the frame with `id` was received by at least one other node.
    Confirm { id: u32 },
    /// Arbitration Lost (0x30): the frame with `id` was not sent (discarded).
    ArbitrationLost { id: u32 },
    /// Bus Error (0x31).
    BusError {
        id: u32,
        code: ErrorCode,
        flag: ErrorFlag,
        is_sender: bool,
    },
    /// Configuration (0x40).
    Configuration(Configuration),
    /// Status (0x41).
    Status(Status),
    /// Wakeup (0x42).
    Wakeup,
}

/// Bytes that are not an operation this module reads: an unknown OP Code, a Length that does
/// not fit the operation, an argument out of its range, or bytes too short for a header.
/// `bytes` is the operation as far as its Length (or the rest, when the Length cannot be
/// trusted); parsing goes on after it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Malformed<'a> {
    pub bytes: &'a [u8],
}

/// The operations of one binary value, in order.
pub fn parse(bytes: &[u8]) -> Operations<'_> {
    Operations { rest: bytes }
}

/// Iterator of [`parse`].
pub struct Operations<'a> {
    rest: &'a [u8],
}

impl<'a> Iterator for Operations<'a> {
    type Item = Result<Operation<'a>, Malformed<'a>>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.rest.is_empty() {
            return None;
        }
        let all = self.rest;
        let (Some(code), Some(length)) = (le32(all, 0), le32(all, 4)) else {
            self.rest = &[];
            return Some(Err(Malformed { bytes: all }));
        };
        let length = usize::try_from(length).unwrap_or(usize::MAX);
        let (Some(op), Some(rest)) = (all.get(..length), all.get(length..)) else {
            self.rest = &[];
            return Some(Err(Malformed { bytes: all }));
        };
        if length < HEADER {
            // A Length that does not even cover its header cannot be stepped over.
            self.rest = &[];
            return Some(Err(Malformed { bytes: all }));
        }
        self.rest = rest;
        Some(operation(code, op).ok_or(Malformed { bytes: op }))
    }
}

/// The operation `op` (header included) with OP Code `code`, if its length and arguments
/// are as the standard defines them.
fn operation(code: u32, op: &[u8]) -> Option<Operation<'_>> {
    let args = op.get(HEADER..)?;
    let exact = |n: usize| (args.len() == n).then_some(());
    let boolean = |i: usize| match args.get(i)? {
        0x00 => Some(false),
        0x01 => Some(true),
        _ => None,
    };
    // Data Length (2 bytes) at `at`, then exactly that many bytes to the end.
    let data = |at: usize| {
        let n = usize::from(le16(args, at)?);
        let d = args.get(at + 2..)?;
        (d.len() == n).then_some(d)
    };
    Some(match code {
        op_code::FORMAT_ERROR => Operation::FormatError { data: data(0)? },
        op_code::CAN_TRANSMIT => Operation::CanTransmit {
            id: le32(args, 0)?,
            ide: boolean(4)?,
            rtr: boolean(5)?,
            data: data(6)?,
        },
        op_code::CAN_FD_TRANSMIT => Operation::CanFdTransmit {
            id: le32(args, 0)?,
            ide: boolean(4)?,
            brs: boolean(5)?,
            esi: boolean(6)?,
            data: data(7)?,
        },
        op_code::CAN_XL_TRANSMIT => Operation::CanXlTransmit {
            id: le32(args, 0)?,
            ide: boolean(4)?,
            sec: boolean(5)?,
            sdt: *args.get(6)?,
            vcid: *args.get(7)?,
            af: le32(args, 8)?,
            data: data(12)?,
        },
        op_code::CONFIRM => {
            exact(4)?;
            Operation::Confirm { id: le32(args, 0)? }
        }
        op_code::ARBITRATION_LOST => {
            exact(4)?;
            Operation::ArbitrationLost { id: le32(args, 0)? }
        }
        op_code::BUS_ERROR => {
            exact(7)?;
            Operation::BusError {
                id: le32(args, 0)?,
                code: ErrorCode::from_u8(*args.get(4)?)?,
                flag: match args.get(5)? {
                    0x01 => ErrorFlag::Primary,
                    0x02 => ErrorFlag::Secondary,
                    _ => return None,
                },
                is_sender: boolean(6)?,
            }
        }
        op_code::CONFIGURATION => {
            let kind = *args.first()?;
            let value = args.get(1..)?;
            let rate = || (value.len() == 4).then(|| le32(value, 0)).flatten();
            Operation::Configuration(match kind {
                0x01 => Configuration::CanBaudRate(rate()?),
                0x02 => Configuration::CanFdBaudRate(rate()?),
                0x03 => Configuration::CanXlBaudRate(rate()?),
                0x04 => Configuration::ArbitrationLostBehavior(match value {
                    [0x01] => ArbitrationLostBehavior::BufferAndRetransmit,
                    [0x02] => ArbitrationLostBehavior::DiscardAndNotify,
                    _ => return None,
                }),
                _ => return None,
            })
        }
        op_code::STATUS => {
            exact(1)?;
            Operation::Status(match args.first()? {
                0x01 => Status::ErrorActive,
                0x02 => Status::ErrorPassive,
                0x03 => Status::BusOff,
                _ => return None,
            })
        }
        op_code::WAKEUP => {
            exact(0)?;
            Operation::Wakeup
        }
        _ => return None,
    })
}

/// Why an operation could not be emitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum EmitError {
    #[error("{0} data bytes do not fit the operation's 2-byte Data Length")]
    DataTooLong(usize),
}

impl Operation<'_> {
    /// The operation's OP Code.
    pub fn op_code(&self) -> u32 {
        match self {
            Operation::FormatError { .. } => op_code::FORMAT_ERROR,
            Operation::CanTransmit { .. } => op_code::CAN_TRANSMIT,
            Operation::CanFdTransmit { .. } => op_code::CAN_FD_TRANSMIT,
            Operation::CanXlTransmit { .. } => op_code::CAN_XL_TRANSMIT,
            Operation::Confirm { .. } => op_code::CONFIRM,
            Operation::ArbitrationLost { .. } => op_code::ARBITRATION_LOST,
            Operation::BusError { .. } => op_code::BUS_ERROR,
            Operation::Configuration(_) => op_code::CONFIGURATION,
            Operation::Status(_) => op_code::STATUS,
            Operation::Wakeup => op_code::WAKEUP,
        }
    }

    /// Appends the operation's bytes to `out`.
    pub fn emit(&self, out: &mut Vec<u8>) -> Result<(), EmitError> {
        let start = out.len();
        out.extend_from_slice(&self.op_code().to_le_bytes());
        out.extend_from_slice(&[0; 4]); // the Length, once the arguments are in
        if let Err(e) = self.emit_arguments(out) {
            out.truncate(start);
            return Err(e);
        }
        let length = u32::try_from(out.len() - start).unwrap_or(u32::MAX);
        if let Some(slot) = out.get_mut(start + 4..start + HEADER) {
            slot.copy_from_slice(&length.to_le_bytes());
        }
        Ok(())
    }

    fn emit_arguments(&self, out: &mut Vec<u8>) -> Result<(), EmitError> {
        let data_len =
            |d: &[u8]| u16::try_from(d.len()).map_err(|_| EmitError::DataTooLong(d.len()));
        match *self {
            Operation::FormatError { data } => {
                out.extend_from_slice(&data_len(data)?.to_le_bytes());
                out.extend_from_slice(data);
            }
            Operation::CanTransmit { id, ide, rtr, data } => {
                out.extend_from_slice(&id.to_le_bytes());
                out.extend_from_slice(&[u8::from(ide), u8::from(rtr)]);
                out.extend_from_slice(&data_len(data)?.to_le_bytes());
                out.extend_from_slice(data);
            }
            Operation::CanFdTransmit {
                id,
                ide,
                brs,
                esi,
                data,
            } => {
                out.extend_from_slice(&id.to_le_bytes());
                out.extend_from_slice(&[u8::from(ide), u8::from(brs), u8::from(esi)]);
                out.extend_from_slice(&data_len(data)?.to_le_bytes());
                out.extend_from_slice(data);
            }
            Operation::CanXlTransmit {
                id,
                ide,
                sec,
                sdt,
                vcid,
                af,
                data,
            } => {
                out.extend_from_slice(&id.to_le_bytes());
                out.extend_from_slice(&[u8::from(ide), u8::from(sec), sdt, vcid]);
                out.extend_from_slice(&af.to_le_bytes());
                out.extend_from_slice(&data_len(data)?.to_le_bytes());
                out.extend_from_slice(data);
            }
            Operation::Confirm { id } | Operation::ArbitrationLost { id } => {
                out.extend_from_slice(&id.to_le_bytes());
            }
            Operation::BusError {
                id,
                code,
                flag,
                is_sender,
            } => {
                out.extend_from_slice(&id.to_le_bytes());
                out.extend_from_slice(&[code as u8, flag as u8, u8::from(is_sender)]);
            }
            Operation::Configuration(c) => match c {
                Configuration::CanBaudRate(r) => {
                    out.push(0x01);
                    out.extend_from_slice(&r.to_le_bytes());
                }
                Configuration::CanFdBaudRate(r) => {
                    out.push(0x02);
                    out.extend_from_slice(&r.to_le_bytes());
                }
                Configuration::CanXlBaudRate(r) => {
                    out.push(0x03);
                    out.extend_from_slice(&r.to_le_bytes());
                }
                Configuration::ArbitrationLostBehavior(b) => {
                    out.extend_from_slice(&[0x04, b as u8]);
                }
            },
            Operation::Status(s) => out.push(s as u8),
            Operation::Wakeup => {}
        }
        Ok(())
    }
}

fn le32(b: &[u8], at: usize) -> Option<u32> {
    let s = b.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes(s.try_into().ok()?))
}

fn le16(b: &[u8], at: usize) -> Option<u16> {
    let s = b.get(at..at.checked_add(2)?)?;
    Some(u16::from_le_bytes(s.try_into().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn emitted(op: Operation<'_>) -> Vec<u8> {
        let mut v = Vec::new();
        op.emit(&mut v).unwrap();
        v
    }

    /// §4.4.1.2.1: `Length = 16 + Data Length`, every number little-endian: an SDO upload
    /// request of 1018h:01 to node 1 (CiA 301 §7.2.4.3.6) as CAN Transmit.
    #[test]
    fn can_transmit_is_op_code_length_id_ide_rtr_data_length_data() {
        let sdo = [0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0];
        let bytes = emitted(Operation::CanTransmit {
            id: 0x601,
            ide: false,
            rtr: false,
            data: &sdo,
        });
        assert_eq!(
            bytes,
            [
                0x10, 0, 0, 0, // OP Code
                24, 0, 0, 0, // Length = 16 + 8
                0x01, 0x06, 0, 0,    // ID
                0x00, // Ide: FALSE
                0x00, // Rtr: FALSE
                8, 0, // Data Length
                0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0,
            ]
        );
        let ops: Vec<_> = parse(&bytes).collect();
        assert_eq!(
            ops,
            [Ok(Operation::CanTransmit {
                id: 0x601,
                ide: false,
                rtr: false,
                data: &sdo
            })]
        );
    }

    /// The fixed lengths of the standard's table: Confirm 12, Arbitration Lost 12, Bus Error
    /// 15, Status 9, Wakeup 8, a baud rate Configuration 9 + 4, CAN FD Transmit 17 + DL,
    /// CAN XL Transmit 22 + DL, Format Error 10 + n.
    #[test]
    fn every_operation_has_the_length_the_table_gives() {
        let cases: [(Operation<'_>, usize); 11] = [
            (Operation::Confirm { id: 0x581 }, 12),
            (Operation::ArbitrationLost { id: 0x581 }, 12),
            (
                Operation::BusError {
                    id: 0x601,
                    code: ErrorCode::BitError,
                    flag: ErrorFlag::Primary,
                    is_sender: true,
                },
                15,
            ),
            (Operation::Status(Status::ErrorPassive), 9),
            (Operation::Wakeup, 8),
            (
                Operation::Configuration(Configuration::CanBaudRate(125_000)),
                13,
            ),
            (
                Operation::Configuration(Configuration::CanFdBaudRate(2_000_000)),
                13,
            ),
            (
                Operation::Configuration(Configuration::ArbitrationLostBehavior(
                    ArbitrationLostBehavior::DiscardAndNotify,
                )),
                10,
            ),
            (
                Operation::CanFdTransmit {
                    id: 0x1234_5678,
                    ide: true,
                    brs: true,
                    esi: false,
                    data: &[1, 2, 3],
                },
                20,
            ),
            (
                Operation::CanXlTransmit {
                    id: 0x42,
                    ide: false,
                    sec: true,
                    sdt: 3,
                    vcid: 7,
                    af: 0xDEAD_BEEF,
                    data: &[9; 5],
                },
                27,
            ),
            (Operation::FormatError { data: &[0xFF; 3] }, 13),
        ];
        for (op, len) in cases {
            let bytes = emitted(op);
            assert_eq!(bytes.len(), len, "{op:?}");
            assert_eq!(le32(&bytes, 0), Some(op.op_code()));
            assert_eq!(le32(&bytes, 4), Some(len as u32), "{op:?}");
            assert_eq!(parse(&bytes).collect::<Vec<_>>(), [Ok(op)]);
        }
    }

    #[test]
    fn bus_error_and_configuration_bytes_are_the_tables_values() {
        let bytes = emitted(Operation::BusError {
            id: 0x12,
            code: ErrorCode::CrcError,
            flag: ErrorFlag::Secondary,
            is_sender: false,
        });
        assert_eq!(
            bytes,
            [0x31, 0, 0, 0, 15, 0, 0, 0, 0x12, 0, 0, 0, 0x04, 0x02, 0x00]
        );
        let bytes = emitted(Operation::Configuration(Configuration::CanBaudRate(
            500_000,
        )));
        // 500000 = 0x0007A120
        assert_eq!(
            bytes,
            [0x40, 0, 0, 0, 13, 0, 0, 0, 0x01, 0x20, 0xA1, 0x07, 0x00]
        );
        let bytes = emitted(Operation::Configuration(
            Configuration::ArbitrationLostBehavior(ArbitrationLostBehavior::BufferAndRetransmit),
        ));
        assert_eq!(bytes, [0x40, 0, 0, 0, 10, 0, 0, 0, 0x04, 0x01]);
    }

    /// §4.2.4: a binary value may hold several operations back to back.
    #[test]
    fn operations_back_to_back_parse_in_order() {
        let mut bytes = Vec::new();
        Operation::Configuration(Configuration::CanBaudRate(125_000))
            .emit(&mut bytes)
            .unwrap();
        Operation::CanTransmit {
            id: 0x1FFF_FFFF,
            ide: true,
            rtr: true,
            data: &[],
        }
        .emit(&mut bytes)
        .unwrap();
        Operation::Confirm { id: 7 }.emit(&mut bytes).unwrap();
        let ops: Vec<_> = parse(&bytes).map(Result::unwrap).collect();
        assert_eq!(
            ops,
            [
                Operation::Configuration(Configuration::CanBaudRate(125_000)),
                Operation::CanTransmit {
                    id: 0x1FFF_FFFF,
                    ide: true,
                    rtr: true,
                    data: &[]
                },
                Operation::Confirm { id: 7 },
            ]
        );
    }

    /// §4.3.1: an unknown OP Code or an invalid length is a Format Error carrying the
    /// operation's bytes; the operations after it still parse.
    #[test]
    fn an_unknown_op_code_or_a_wrong_length_is_malformed_and_parsing_goes_on() {
        let unknown = [0x99, 0, 0, 0, 9, 0, 0, 0, 0xAA];
        let short_confirm = [0x20, 0, 0, 0, 11, 0, 0, 0, 1, 2, 3];
        let bad_bool = [0x10, 0, 0, 0, 16, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0];
        let data_len_wrong = [0x10, 0, 0, 0, 17, 0, 0, 0, 1, 0, 0, 0, 0, 0, 2, 0, 0xAB];
        let mut bytes = Vec::new();
        for op in [&unknown[..], &short_confirm, &bad_bool, &data_len_wrong] {
            bytes.extend_from_slice(op);
        }
        Operation::Wakeup.emit(&mut bytes).unwrap();
        let ops: Vec<_> = parse(&bytes).collect();
        assert_eq!(
            ops,
            [
                Err(Malformed { bytes: &unknown }),
                Err(Malformed {
                    bytes: &short_confirm
                }),
                Err(Malformed { bytes: &bad_bool }),
                Err(Malformed {
                    bytes: &data_len_wrong
                }),
                Ok(Operation::Wakeup),
            ]
        );
        // The answer to one of them.
        let reply = emitted(Operation::FormatError { data: &unknown });
        assert_eq!(&reply[..10], [0x01, 0, 0, 0, 19, 0, 0, 0, 9, 0]);
        assert_eq!(&reply[10..], unknown);
    }

    #[test]
    fn a_length_past_the_end_or_under_a_header_takes_the_rest() {
        let past = [0x20, 0, 0, 0, 40, 0, 0, 0, 1, 2, 3, 4];
        assert_eq!(
            parse(&past).collect::<Vec<_>>(),
            [Err(Malformed { bytes: &past })]
        );
        let under = [0x42, 0, 0, 0, 4, 0, 0, 0, 0x42, 0, 0, 0, 8, 0, 0, 0];
        assert_eq!(
            parse(&under).collect::<Vec<_>>(),
            [Err(Malformed { bytes: &under })]
        );
        let stub = [0x10, 0, 0];
        assert_eq!(
            parse(&stub).collect::<Vec<_>>(),
            [Err(Malformed { bytes: &stub })]
        );
        assert_eq!(parse(&[]).count(), 0);
    }

    #[test]
    fn data_longer_than_the_data_length_field_is_refused_and_nothing_is_written() {
        let big = vec![0u8; 70_000];
        let mut out = vec![1, 2];
        assert_eq!(
            Operation::CanXlTransmit {
                id: 0,
                ide: false,
                sec: false,
                sdt: 0,
                vcid: 0,
                af: 0,
                data: &big
            }
            .emit(&mut out),
            Err(EmitError::DataTooLong(70_000))
        );
        assert_eq!(out, [1, 2]);
    }
}
