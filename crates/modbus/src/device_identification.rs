//! Read Device Identification, function 0x2B with MEI type 0x0E (MODBUS Application
//! Protocol V1.1b3 §6.21).
//!
//! Objects are byte strings by id: 0x00–0x02 basic (VendorName, ProductCode,
//! MajorMinorRevision, mandatory), 0x03–0x7F regular (VendorUrl, ProductName, ModelName,
//! UserApplicationName, …), 0x80–0xFF extended (private). The map provides them through
//! [`RegisterMap::device_id`].
//!
//! Read device id codes 01/02/03 are *stream access*: the response carries the objects of
//! the category from the requested object id on, as many as fit in one PDU; when they do not
//! all fit, "more follows" is FFh and "next object id" names the first one left out, which the
//! client asks for next. An object id that is no object of the category restarts the stream at
//! object 0. A category above the device's conformity level is answered at its conformity
//! level. Code 04 is *individual access* to one object; an unknown object is exception 02,
//! and a device whose conformity level lacks bit 7 (no individual access) answers 03.
//!
//! The CMMO-ST (manual Tab. 4.3, Tab. 4.4) supports codes 01 and 02 with objects 00, 01,
//! 02 and 03, 04, 06, and reports as conformity level "0x01 basic / 0x02 regular", i.e. the
//! level of the request: vector FHPP-MB-06 answers a basic request with conformity 01. A map
//! gets that behaviour from [`RegisterMap::conformity_level`].

use crate::exception::{Exception, ExceptionResponse};
use crate::function_code::{ENCAPSULATED_INTERFACE_TRANSPORT, MEI_READ_DEVICE_IDENTIFICATION};
use crate::mbap::MAX_PDU_LEN;
use crate::server::RegisterMap;
use crate::writer::{Full, Writer};

/// The "read device id code" of a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum ReadDeviceIdCode {
    /// 01: basic identification, stream access (objects 0x00–0x02).
    Basic = 0x01,
    /// 02: regular identification, stream access (objects 0x00–0x7F).
    Regular = 0x02,
    /// 03: extended identification, stream access (objects 0x00–0xFF).
    Extended = 0x03,
    /// 04: one object, individual access.
    Individual = 0x04,
}

impl ReadDeviceIdCode {
    /// The code for a request byte; `None` outside 01…04 (exception 03).
    pub const fn from_code(code: u8) -> Option<ReadDeviceIdCode> {
        Some(match code {
            0x01 => ReadDeviceIdCode::Basic,
            0x02 => ReadDeviceIdCode::Regular,
            0x03 => ReadDeviceIdCode::Extended,
            0x04 => ReadDeviceIdCode::Individual,
            _ => return None,
        })
    }

    /// The code byte.
    pub const fn code(self) -> u8 {
        self as u8
    }
}

/// The conformity level byte of a response: the device's identification category (1 basic,
/// 2 regular, 3 extended) with bit 7 set when individual access (code 04) is supported.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ConformityLevel(pub u8);

impl ConformityLevel {
    /// 01h: basic, stream access only.
    pub const BASIC_STREAM: ConformityLevel = ConformityLevel(0x01);
    /// 02h: regular, stream access only.
    pub const REGULAR_STREAM: ConformityLevel = ConformityLevel(0x02);
    /// 03h: extended, stream access only.
    pub const EXTENDED_STREAM: ConformityLevel = ConformityLevel(0x03);
    /// 81h: basic, stream and individual access.
    pub const BASIC: ConformityLevel = ConformityLevel(0x81);
    /// 82h: regular, stream and individual access.
    pub const REGULAR: ConformityLevel = ConformityLevel(0x82);
    /// 83h: extended, stream and individual access.
    pub const EXTENDED: ConformityLevel = ConformityLevel(0x83);

    /// The category, 1…3 (other values count as the nearest).
    pub const fn category(self) -> u8 {
        match self.0 & 0x7F {
            0 | 1 => 1,
            2 => 2,
            _ => 3,
        }
    }

    /// Whether individual access (code 04) is supported.
    pub const fn individual_access(self) -> bool {
        self.0 & 0x80 != 0
    }

    /// The standard's level for a device with these objects: the highest category that has
    /// an object, with individual access.
    pub fn from_objects<M: RegisterMap + ?Sized>(map: &M) -> ConformityLevel {
        if (0x80..=0xFF).any(|id| map.device_id(id).is_some()) {
            ConformityLevel::EXTENDED
        } else if (0x03..=0x7F).any(|id| map.device_id(id).is_some()) {
            ConformityLevel::REGULAR
        } else {
            ConformityLevel::BASIC
        }
    }
}

/// Highest object id of a stream category.
const fn last_object(category: u8) -> u8 {
    match category {
        1 => 0x02,
        2 => 0x7F,
        _ => 0xFF,
    }
}

/// Header bytes of a response before the object list: FC, MEI, code, conformity, more
/// follows, next object id, number of objects.
const HEADER_LEN: usize = 7;

/// Longest object value that fits into a response alone; longer values are cut to it.
pub const MAX_OBJECT_LEN: usize = MAX_PDU_LEN - HEADER_LEN - 2;

/// Writes the response PDU for a checked request into `w`.
pub(crate) fn respond<M: RegisterMap + ?Sized>(
    code: ReadDeviceIdCode,
    object_id: u8,
    map: &M,
    out: &mut [u8],
) -> Result<usize, ExceptionResponse> {
    let fail = |e| ExceptionResponse::new(ENCAPSULATED_INTERFACE_TRANSPORT, e);
    let level = map.conformity_level(code);
    let limit = out.len().min(MAX_PDU_LEN);
    let out = out
        .get_mut(..limit)
        .ok_or(fail(Exception::ServerDeviceFailure))?;
    let mut w = Writer::new(out);
    let header = |w: &mut Writer<'_>| -> Result<(), Full> {
        w.u8(ENCAPSULATED_INTERFACE_TRANSPORT)?;
        w.u8(MEI_READ_DEVICE_IDENTIFICATION)?;
        w.u8(code.code())?;
        w.u8(level.0)
    };
    let full = |_: Full| fail(Exception::ServerDeviceFailure);
    if code == ReadDeviceIdCode::Individual {
        if !level.individual_access() {
            return Err(fail(Exception::IllegalDataValue));
        }
        let value = map
            .device_id(object_id)
            .ok_or(fail(Exception::IllegalDataAddress))?;
        let value = value.get(..MAX_OBJECT_LEN).unwrap_or(value);
        header(&mut w).map_err(full)?;
        w.bytes(&[0x00, 0x00, 0x01, object_id, value.len() as u8])
            .map_err(full)?;
        w.bytes(value).map_err(full)?;
        return Ok(w.len());
    }
    let category = code.code().min(level.category());
    let last = last_object(category);
    let start = if object_id <= last && map.device_id(object_id).is_some() {
        object_id
    } else {
        0
    };
    header(&mut w).map_err(full)?;
    let more_at = w.len();
    w.bytes(&[0x00, 0x00, 0x00]).map_err(full)?;
    let mut count: u8 = 0;
    for id in start..=last {
        let Some(value) = map.device_id(id) else {
            continue;
        };
        let value = value.get(..MAX_OBJECT_LEN).unwrap_or(value);
        if w.remaining() < 2 + value.len() && count > 0 {
            w.patch(more_at, 0xFF).map_err(full)?;
            w.patch(more_at + 1, id).map_err(full)?;
            break;
        }
        w.bytes(&[id, value.len() as u8]).map_err(full)?;
        w.bytes(value).map_err(full)?;
        count += 1;
    }
    w.patch(more_at + 2, count).map_err(full)?;
    Ok(w.len())
}
