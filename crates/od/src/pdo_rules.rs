//! CiA 301 §7.5.2.35–38: the rules for writing PDO communication and mapping parameters, so
//! every front end that reaches 1400h–1BFFh gets the same answers (CCT PDO 22–33).

use crate::{
    AbortCode, Behaviour, DataType, DeviceDescription, Entry, ObjectAccess, ObjectDictionary,
};

/// Largest PDO payload in bits.
pub const MAX_PDO_BITS: u32 = 64;

/// Which PDO a communication or mapping index belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PdoRef {
    pub transmit: bool,
    /// The communication parameter index (1400h… or 1800h…).
    pub comm: u16,
}

impl PdoRef {
    pub fn of(index: u16) -> Option<Self> {
        match index {
            0x1400..=0x15FF => Some(PdoRef {
                transmit: false,
                comm: index,
            }),
            0x1600..=0x17FF => Some(PdoRef {
                transmit: false,
                comm: index - 0x200,
            }),
            0x1800..=0x19FF => Some(PdoRef {
                transmit: true,
                comm: index,
            }),
            0x1A00..=0x1BFF => Some(PdoRef {
                transmit: true,
                comm: index - 0x200,
            }),
            _ => None,
        }
    }
    pub fn mapping(self) -> u16 {
        self.comm + 0x200
    }
}

pub use crate::cob_id::restricted_can_id;

/// A decoded mapping entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MapEntry {
    pub index: u16,
    pub sub: u8,
    pub bits: u8,
}

impl MapEntry {
    pub fn from_u32(v: u32) -> Self {
        MapEntry {
            index: (v >> 16) as u16,
            sub: (v >> 8) as u8,
            bits: v as u8,
        }
    }
    /// Dummy entries map a data type index (0001h–0007h) to skip bytes in an RPDO.
    pub fn is_dummy(&self) -> bool {
        (0x0001..=0x0007).contains(&self.index) && self.sub == 0
    }
}

/// Checks one mapping entry against the dictionary (CiA 301 §7.5.2.38; CMMP-AS §3.3.1: the
/// length must be the object's whole length).
pub fn check_map_entry(desc: &DeviceDescription, transmit: bool, v: u32) -> Result<(), AbortCode> {
    if v == 0 {
        return Ok(());
    }
    let m = MapEntry::from_u32(v);
    if u32::from(m.bits) > MAX_PDO_BITS {
        return Err(AbortCode::PDO_LENGTH);
    }
    if m.is_dummy() {
        // Dummies only make sense where bytes are skipped: in RPDOs. An EDS says which may be
        // mapped in [DummyUsage] (CiA 306); a device file that lists the dummy objects says
        // it by their mapping flag (Nanotec §9.44: 0001h may not).
        let allowed = match desc.cia301.dummy_usage {
            Some(usage) => usage & (1 << m.index) != 0,
            None => desc.entry(m.index, 0).map(|e| e.pdo_mappable) != Some(false),
        };
        let size = dummy_type(m.index)
            .and_then(|t| t.fixed_size())
            .unwrap_or(0) as u32;
        return if !transmit && allowed && u32::from(m.bits) == size * 8 {
            Ok(())
        } else {
            Err(AbortCode::NOT_MAPPABLE)
        };
    }
    let obj = desc.object(m.index).ok_or(AbortCode::NO_OBJECT)?;
    let e = obj.entry(m.sub).ok_or(AbortCode::NO_SUB_INDEX)?;
    let direction_ok = if transmit {
        e.access.readable()
    } else {
        e.access.writable()
    };
    if !e.pdo_mappable || !direction_ok || e.is_variable() || u32::from(m.bits) != e.bit_len() {
        return Err(AbortCode::NOT_MAPPABLE);
    }
    Ok(())
}

fn dummy_type(index: u16) -> Option<DataType> {
    Some(match index {
        0x0001 => DataType::Boolean,
        0x0002 => DataType::Integer8,
        0x0003 => DataType::Integer16,
        0x0004 => DataType::Integer32,
        0x0005 => DataType::Unsigned8,
        0x0006 => DataType::Unsigned16,
        0x0007 => DataType::Unsigned32,
        _ => return None,
    })
}

/// The entry as it is stored: where the personality fills in the length (Nanotec §12.2, "bits
/// 7–0 need not be set, the firmware does it"), an entry with length 0 gets the mapped object's
/// length. Anything else is kept as written.
pub fn fill_map_length(desc: &DeviceDescription, v: u32) -> u32 {
    let m = MapEntry::from_u32(v);
    if v == 0 || m.bits != 0 || !desc.cia301.pdo_map_length_filled {
        return v;
    }
    let bits = if m.is_dummy() {
        dummy_type(m.index)
            .and_then(|t| t.fixed_size())
            .map(|n| n as u32 * 8)
    } else {
        desc.entry(m.index, m.sub)
            .filter(|e| !e.is_variable())
            .map(|e| e.bit_len())
    };
    match bits {
        Some(b) if b <= MAX_PDO_BITS => v | b,
        _ => v,
    }
}

/// Total bits of the first `n` mapping entries, checking each.
fn mapped_bits<A: ObjectAccess + ?Sized>(
    od: &A,
    desc: &DeviceDescription,
    pdo: PdoRef,
    n: u8,
) -> Result<u32, AbortCode> {
    let mut total = 0u32;
    for sub in 1..=n {
        let v = od
            .read_u32(pdo.mapping(), sub)
            .ok_or(AbortCode::PDO_LENGTH)?;
        if v == 0 {
            return Err(AbortCode::NOT_MAPPABLE);
        }
        check_map_entry(desc, pdo.transmit, v).map_err(|_| AbortCode::NOT_MAPPABLE)?;
        total += u32::from(MapEntry::from_u32(v).bits);
    }
    Ok(total)
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> ObjectDictionary<S> {
    fn pdo_valid(&self, pdo: PdoRef) -> bool {
        self.read_u32(pdo.comm, 1)
            .is_some_and(|c| c & 0x8000_0000 == 0)
    }

    /// Checks a write to a PDO parameter; returns the value to store when it differs from
    /// what was written (COB-IDs always carry bit 30, "no RTR").
    pub(crate) fn check_pdo_write(&self, e: &Entry, data: &[u8]) -> Result<Option<u32>, AbortCode> {
        let pdo = PdoRef::of(e.index).ok_or(AbortCode::GENERAL)?;
        let valid = self.pdo_valid(pdo);
        let opts = self.description().cia301;
        let v = match data {
            [a] => u32::from(*a),
            [a, b] => u32::from(u16::from_le_bytes([*a, *b])),
            [a, b, c, d] => u32::from_le_bytes([*a, *b, *c, *d]),
            _ => return Err(AbortCode::LENGTH_MISMATCH),
        };
        let locked = valid && opts.pdo_params_locked_while_valid;
        match e.behaviour {
            Behaviour::PdoCobId => {
                // Only 11-bit identifiers; bit 30 (RTR) is not evaluated on write.
                if v & 0x3FFF_F800 != 0 {
                    return Err(AbortCode::INVALID_VALUE);
                }
                let new_valid = v & 0x8000_0000 == 0;
                let id = v & 0x7FF;
                let current = self.read_u32(pdo.comm, 1).unwrap_or(0x8000_0000);
                if valid && new_valid && id != current & 0x7FF {
                    return Err(AbortCode::INVALID_VALUE);
                }
                if new_valid && restricted_can_id(id) {
                    return Err(AbortCode::INVALID_VALUE);
                }
                if new_valid
                    && !valid
                    && !opts.pdo_valid_without_mapping
                    && self.read_u8(pdo.mapping(), 0).unwrap_or(0) == 0
                {
                    return Err(AbortCode::INVALID_VALUE);
                }
                // CMMP-AS §3.3.2: bit 30 is ignored on write and always reads 1 (no RTR).
                Ok(Some(v | 0x4000_0000))
            }
            Behaviour::PdoTransmissionType => {
                // CMMP-AS: the OD table allows 0…8Ch, FEh, FFh, Tab. 3.7 01h–F0h, FEh, FFh.
                // Decided by CiA 301: 0…240 (synchronous), 254, 255; 252/253 need RTR, which
                // this device does not answer.
                if locked {
                    return Err(AbortCode::INVALID_VALUE);
                }
                match v {
                    0..=240 | 255 => Ok(None),
                    // Nanotec §9.10–9.21 list 0…240 and 255 only.
                    254 if !opts.pdo_refuses_type_254 => Ok(None),
                    _ => Err(AbortCode::INVALID_VALUE),
                }
            }
            Behaviour::PdoInhibitTime => {
                if valid {
                    return Err(AbortCode::INVALID_VALUE);
                }
                Ok(None)
            }
            Behaviour::PdoSyncStart => {
                if valid || v > 240 {
                    return Err(AbortCode::INVALID_VALUE);
                }
                Ok(None)
            }
            Behaviour::PdoEventTimer => {
                if locked {
                    return Err(AbortCode::INVALID_VALUE);
                }
                Ok(None)
            }
            Behaviour::PdoMapCount => {
                // CCT PDO 23/24 accept 0601 0000h for a mapping change of a valid PDO.
                if valid {
                    return Err(AbortCode::UNSUPPORTED_ACCESS);
                }
                let entries = self
                    .description()
                    .object(pdo.mapping())
                    .map(|o| o.entries.len().saturating_sub(1))
                    .unwrap_or(0);
                if v as usize > entries {
                    return Err(AbortCode::PDO_LENGTH);
                }
                if v > 0 {
                    let bits = mapped_bits(self, self.description(), pdo, v as u8)?;
                    if bits > MAX_PDO_BITS {
                        return Err(AbortCode::PDO_LENGTH);
                    }
                }
                Ok(None)
            }
            Behaviour::PdoMapEntry => {
                if valid || self.read_u8(pdo.mapping(), 0).unwrap_or(0) != 0 {
                    return Err(AbortCode::UNSUPPORTED_ACCESS);
                }
                let filled = fill_map_length(self.description(), v);
                check_map_entry(self.description(), pdo.transmit, filled)?;
                Ok((filled != v).then_some(filled))
            }
            _ => Ok(None),
        }
    }
}
