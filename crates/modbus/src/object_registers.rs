//! A Modbus RTU server whose holding registers are a mapping onto a device's objects, not a
//! second copy (MODBUS Application Protocol V1.1b3 §6.3, §6.6, §6.12; Modbus over Serial Line
//! V1.02 §2.2, §2.5.1). The table is data: [`RegisterMapping`] rows, from a device file's
//! `modbus` keys.
//!
//! - Frame `station, function, data, CRC-16` (low byte first, [`crate::rtu`]); station 0 is the
//!   broadcast: its writes are carried out, never answered (Serial Line §2.2). A bad CRC or
//!   another station: no answer, counted by the caller ([`Ignored`]).
//! - FC 03h read, 06h write one register, 10h write several.
//! - A 32-bit object takes two registers, the **low word first**, each word big-endian; an 8 or
//!   16-bit object one register.
//! - Errors: the function code + 80h with the standard exception byte (02 address, 03 value,
//!   04 device failure) that a client such as pymodbus needs to decode the reply. Some devices
//!   answer an FC 03h error with 81h instead ([`ErrorStyle::Read81h`]).
//!
//! Decisions:
//! - A read of more registers than the object at the start address has reads its sign
//!   extension (0000h, or FFFFh for a negative signed value) from the registers after it that
//!   map nothing, so that two registers read from any object are its 32-bit value, low word
//!   first; an 8-bit value's register is sign-extended the same way (−4 reads FFFCh, as FC 06h
//!   takes it). A read whose first register maps nothing is an error.
//! - FC 06h writes an object of one register (8 or 16 bit); an 8-bit object takes the
//!   register's low byte when the value fits 8 bits signed or unsigned (−4 may come as FFFCh).
//!   Half a 32-bit object is not written: an error.
//! - FC 10h must cover whole objects; the objects are written in address order and a failure
//!   stops there (the ones before stay written, as a sequential firmware does).

use od::{AbortCode, ObjectAccess};

use crate::exception::Exception;
use crate::function_code::{
    READ_HOLDING_REGISTERS, WRITE_MULTIPLE_REGISTERS, WRITE_SINGLE_REGISTER,
};
use crate::rtu::{self, MAX_FRAME};

/// One register of the map: `register` (and the next ones for a longer value) is object
/// `index`:`sub`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RegisterMapping {
    /// The register address.
    pub register: u16,
    /// The object's index.
    pub index: u16,
    /// The object's sub-index.
    pub sub: u8,
}

/// How an FC 03h error is answered (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ErrorStyle {
    /// 83h, as MODBUS Application Protocol §7 prescribes.
    #[default]
    Standard,
    /// 81h, as some device manuals print it.
    Read81h,
}

/// Why a frame got no answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ignored {
    /// Too short, or the CRC does not match.
    Crc,
    /// Addressed to another station.
    OtherStation,
    /// A broadcast (station 0): carried out, never answered.
    Broadcast,
}

/// The object register `register` starts, in `map`.
pub fn lookup(map: &[RegisterMapping], register: u16) -> Option<&RegisterMapping> {
    map.iter().find(|m| m.register == register)
}

/// Registers of an object of `len` bytes (1 or 2 bytes: one; 4 bytes: two).
pub const fn words(len: usize) -> usize {
    len.div_ceil(2)
}

/// An object's little-endian bytes as registers, low word first.
pub fn to_registers(bytes: &[u8], out: &mut [u16]) {
    for (w, chunk) in out.iter_mut().zip(bytes.chunks(2)) {
        let lo = chunk.first().copied().unwrap_or(0);
        let hi = chunk.get(1).copied().unwrap_or(0);
        *w = u16::from_le_bytes([lo, hi]);
    }
}

/// Registers, low word first, as an object's little-endian bytes (`out.len()` bytes).
pub fn from_registers(words: &[u16], out: &mut [u8]) {
    for (pair, w) in out.chunks_mut(2).zip(words) {
        for (b, v) in pair.iter_mut().zip(w.to_le_bytes()) {
            *b = v;
        }
    }
}

struct Failure {
    exception: Exception,
}

impl From<AbortCode> for Failure {
    fn from(code: AbortCode) -> Self {
        let exception = match code {
            AbortCode::NO_OBJECT
            | AbortCode::NO_SUB_INDEX
            | AbortCode::READ_ONLY
            | AbortCode::WRITE_ONLY
            | AbortCode::UNSUPPORTED_ACCESS => Exception::IllegalDataAddress,
            AbortCode::VALUE_TOO_HIGH
            | AbortCode::VALUE_TOO_LOW
            | AbortCode::INVALID_VALUE
            | AbortCode::LENGTH_MISMATCH
            | AbortCode::LENGTH_TOO_HIGH
            | AbortCode::LENGTH_TOO_LOW => Exception::IllegalDataValue,
            _ => Exception::ServerDeviceFailure,
        };
        Failure { exception }
    }
}

const fn fail(exception: Exception) -> Failure {
    Failure { exception }
}

fn be16(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_be_bytes([*b.get(at)?, *b.get(at + 1)?]))
}

/// The RTU server of one device: its station and its register map.
#[derive(Debug, Clone, Copy)]
pub struct ObjectRegisters<'a> {
    /// The device's station number.
    pub station: u8,
    /// The register map (the device file's `modbus` keys).
    pub map: &'a [RegisterMapping],
    /// How an FC 03h error is answered.
    pub errors: ErrorStyle,
}

impl ObjectRegisters<'_> {
    /// Handles one frame (station, PDU, CRC): the reply is written to `out` (at least
    /// [`MAX_FRAME`] bytes) and its length returned, or why there is none.
    pub fn handle_frame(
        &self,
        frame: &[u8],
        od: &mut dyn ObjectAccess,
        out: &mut [u8],
    ) -> Result<usize, Ignored> {
        let body = rtu::strip_crc(frame).ok_or(Ignored::Crc)?;
        let (&station, pdu) = body.split_first().ok_or(Ignored::Crc)?;
        if station != self.station && station != 0 {
            return Err(Ignored::OtherStation);
        }
        let (&function, data) = pdu.split_first().ok_or(Ignored::Crc)?;
        let mut reply = [0u8; MAX_FRAME];
        let result = match function {
            READ_HOLDING_REGISTERS => self.read(data, od, &mut reply),
            WRITE_SINGLE_REGISTER => self.write_single(data, od, &mut reply),
            WRITE_MULTIPLE_REGISTERS => self.write_multiple(data, od, &mut reply),
            _ => Err(fail(Exception::IllegalFunction)),
        };
        if station == 0 {
            return Err(Ignored::Broadcast);
        }
        let (code, n) = match result {
            Ok(n) => (function, n),
            Err(f) => {
                if let Some(first) = reply.first_mut() {
                    *first = f.exception.code();
                }
                let code = match (function, self.errors) {
                    (READ_HOLDING_REGISTERS, ErrorStyle::Read81h) => 0x81,
                    _ => function | 0x80,
                };
                (code, 1)
            }
        };
        let mut len = 0;
        for &b in [self.station, code]
            .iter()
            .chain(reply.get(..n).unwrap_or(&[]))
        {
            if let Some(slot) = out.get_mut(len) {
                *slot = b;
                len += 1;
            }
        }
        let crc = rtu::crc_bytes(out.get(..len).unwrap_or(&[]));
        for b in crc {
            if let Some(slot) = out.get_mut(len) {
                *slot = b;
                len += 1;
            }
        }
        Ok(len)
    }

    /// FC 03h: `address, quantity` → `byte count, registers…` (the PDU after the function).
    fn read(
        &self,
        data: &[u8],
        od: &mut dyn ObjectAccess,
        reply: &mut [u8],
    ) -> Result<usize, Failure> {
        let (Some(address), Some(quantity), 4) = (be16(data, 0), be16(data, 2), data.len()) else {
            return Err(fail(Exception::IllegalDataValue));
        };
        let quantity = usize::from(quantity);
        if !(1..=125).contains(&quantity) {
            return Err(fail(Exception::IllegalDataValue));
        }
        let mut words = [0u16; 125];
        let mut fill = 0u16;
        let mut at = 0usize;
        while at < quantity {
            let register = address.wrapping_add(at as u16);
            match lookup(self.map, register) {
                Some(m) => {
                    let e = od.entry(m.index, m.sub)?;
                    if !matches!(e.data_type.fixed_size(), Some(1 | 2 | 4)) {
                        return Err(fail(Exception::IllegalDataAddress));
                    }
                    let mut bytes = [0u8; 4];
                    let n = od.read(m.index, m.sub, &mut bytes)?;
                    let negative = e.data_type.is_signed()
                        && bytes
                            .get(n.saturating_sub(1))
                            .is_some_and(|b| b & 0x80 != 0);
                    fill = if negative { 0xFFFF } else { 0 };
                    // An 8-bit value fills its register's high byte with its sign.
                    let len = self::words(n).max(1) * 2;
                    for b in bytes.iter_mut().take(len).skip(n) {
                        *b = fill as u8;
                    }
                    let w = words.get_mut(at..).unwrap_or(&mut []);
                    to_registers(bytes.get(..len).unwrap_or(&[]), w);
                    at += self::words(n).max(1);
                }
                None if at == 0 => return Err(fail(Exception::IllegalDataAddress)),
                None => {
                    if let Some(w) = words.get_mut(at) {
                        *w = fill;
                    }
                    at += 1;
                }
            }
        }
        let count = 2 * quantity;
        let dst = reply
            .get_mut(..1 + count)
            .ok_or(fail(Exception::ServerDeviceFailure))?;
        let (head, rest) = dst.split_at_mut(1);
        head.copy_from_slice(&[count as u8]);
        for (pair, w) in rest.chunks_mut(2).zip(words.iter()) {
            pair.copy_from_slice(&w.to_be_bytes());
        }
        Ok(1 + count)
    }

    /// FC 06h: `register, value` → the echo.
    fn write_single(
        &self,
        data: &[u8],
        od: &mut dyn ObjectAccess,
        reply: &mut [u8],
    ) -> Result<usize, Failure> {
        let (Some(register), Some(value), 4) = (be16(data, 0), be16(data, 2), data.len()) else {
            return Err(fail(Exception::IllegalDataValue));
        };
        let m = lookup(self.map, register).ok_or(fail(Exception::IllegalDataAddress))?;
        let e = od.entry(m.index, m.sub)?;
        match e.data_type.fixed_size() {
            Some(2) => od.write(m.index, m.sub, &value.to_le_bytes())?,
            Some(1) => {
                let fits = value <= 0xFF || (value as i16) >= -128 && (value as i16) < 0;
                if !fits {
                    return Err(fail(Exception::IllegalDataValue));
                }
                od.write(m.index, m.sub, &[value as u8])?
            }
            _ => return Err(fail(Exception::IllegalDataAddress)),
        }
        let dst = reply
            .get_mut(..4)
            .ok_or(fail(Exception::ServerDeviceFailure))?;
        dst.copy_from_slice(data.get(..4).unwrap_or(&[0; 4]));
        Ok(4)
    }

    /// FC 10h: `address, quantity, byte count, registers…` → `address, quantity`.
    fn write_multiple(
        &self,
        data: &[u8],
        od: &mut dyn ObjectAccess,
        reply: &mut [u8],
    ) -> Result<usize, Failure> {
        let (Some(address), Some(quantity), Some(&count)) =
            (be16(data, 0), be16(data, 2), data.get(4))
        else {
            return Err(fail(Exception::IllegalDataValue));
        };
        let quantity = usize::from(quantity);
        let values = data.get(5..).unwrap_or(&[]);
        if !(1..=123).contains(&quantity)
            || usize::from(count) != 2 * quantity
            || values.len() != 2 * quantity
        {
            return Err(fail(Exception::IllegalDataValue));
        }
        let mut words = [0u16; 123];
        for (w, pair) in words.iter_mut().zip(values.chunks(2)) {
            *w = be16(pair, 0).unwrap_or(0);
        }
        let mut at = 0usize;
        while at < quantity {
            let register = address.wrapping_add(at as u16);
            let m = lookup(self.map, register).ok_or(fail(Exception::IllegalDataAddress))?;
            let e = od.entry(m.index, m.sub)?;
            let len = match e.data_type.fixed_size() {
                Some(n @ (1 | 2 | 4)) => n,
                _ => return Err(fail(Exception::IllegalDataAddress)),
            };
            let n = self::words(len);
            let src = words
                .get(at..at + n)
                .filter(|_| at + n <= quantity)
                .ok_or(fail(Exception::IllegalDataAddress))?;
            let mut bytes = [0u8; 4];
            let dst = bytes.get_mut(..len).unwrap_or(&mut []);
            from_registers(src, dst);
            od.write(m.index, m.sub, dst)?;
            at += n;
        }
        let dst = reply
            .get_mut(..4)
            .ok_or(fail(Exception::ServerDeviceFailure))?;
        dst.copy_from_slice(data.get(..4).unwrap_or(&[0; 4]));
        Ok(4)
    }
}
