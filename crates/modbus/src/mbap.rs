//! The MBAP header of Modbus TCP (Messaging on TCP/IP Implementation Guide V1.0b §3.1.3;
//! CMMO-ST manual Tab. 4.1).
//!
//! | Bytes | Field | Rule |
//! |---|---|---|
//! | 1–2 | transaction identifier | chosen by the client, echoed in the response |
//! | 3–4 | protocol identifier | always 0 |
//! | 5–6 | length | number of following bytes: unit id + PDU (manual: "n + 2") |
//! | 7 | unit identifier | may be ignored (e.g. 0); echoed |
//!
//! All fields are big-endian, high byte first.

/// Length of the MBAP header.
pub const MBAP_LEN: usize = 7;
/// Longest PDU (function code + data): 256 bytes of a serial ADU minus address and CRC.
pub const MAX_PDU_LEN: usize = 253;
/// Longest Modbus TCP ADU: MBAP + longest PDU = 260 bytes.
pub const MAX_ADU_LEN: usize = MBAP_LEN + MAX_PDU_LEN;
/// The only protocol identifier of Modbus.
pub const PROTOCOL_ID: u16 = 0;
/// Smallest length field: unit id + function code.
pub const MIN_LENGTH_FIELD: u16 = 2;
/// Largest length field: unit id + longest PDU.
pub const MAX_LENGTH_FIELD: u16 = 1 + MAX_PDU_LEN as u16;
/// Bytes before the counted part (transaction id, protocol id, length field).
pub const LENGTH_FIELD_END: usize = 6;

/// An MBAP header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Mbap {
    /// Transaction identifier, echoed in the response.
    pub transaction_id: u16,
    /// Protocol identifier, 0 for Modbus.
    pub protocol_id: u16,
    /// Number of bytes that follow the length field: unit id + PDU.
    pub length: u16,
    /// Unit identifier, echoed in the response.
    pub unit_id: u8,
}

impl Mbap {
    /// Reads the header from the first 7 bytes of `bytes`; `None` if there are fewer.
    /// Performs no checks: see [`Adu::parse`](crate::Adu::parse).
    pub fn parse(bytes: &[u8]) -> Option<Mbap> {
        match bytes {
            [t0, t1, p0, p1, l0, l1, unit, ..] => Some(Mbap {
                transaction_id: u16::from_be_bytes([*t0, *t1]),
                protocol_id: u16::from_be_bytes([*p0, *p1]),
                length: u16::from_be_bytes([*l0, *l1]),
                unit_id: *unit,
            }),
            _ => None,
        }
    }

    /// The 7 header bytes.
    pub fn to_bytes(&self) -> [u8; MBAP_LEN] {
        let [t0, t1] = self.transaction_id.to_be_bytes();
        let [p0, p1] = self.protocol_id.to_be_bytes();
        let [l0, l1] = self.length.to_be_bytes();
        [t0, t1, p0, p1, l0, l1, self.unit_id]
    }

    /// The header of the response to a request with this header, for a PDU of `pdu_len`
    /// bytes (at most [`MAX_PDU_LEN`]).
    pub fn response(&self, pdu_len: usize) -> Mbap {
        let pdu_len = pdu_len.min(MAX_PDU_LEN) as u16;
        Mbap {
            transaction_id: self.transaction_id,
            protocol_id: PROTOCOL_ID,
            length: 1 + pdu_len,
            unit_id: self.unit_id,
        }
    }

    /// Length of the whole ADU this header announces (6 + length field).
    pub fn adu_len(&self) -> usize {
        LENGTH_FIELD_END + usize::from(self.length)
    }
}
