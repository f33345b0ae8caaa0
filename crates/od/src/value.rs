//! Typed views of the little-endian bytes an entry holds.

use crate::{DataType, Limit};

/// A decoded numeric value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    Bool(bool),
    Signed(i64),
    Unsigned(u64),
    Real(f64),
}

impl Value {
    /// Decodes `bytes` (exactly the type's size) as `ty`; `None` for non-numeric types or a
    /// wrong length.
    pub fn decode(ty: DataType, bytes: &[u8]) -> Option<Value> {
        let mut buf = [0u8; 8];
        let n = ty.fixed_size()?;
        if bytes.len() != n {
            return None;
        }
        buf.get_mut(..n)?.copy_from_slice(bytes);
        let raw = u64::from_le_bytes(buf);
        Some(match ty {
            DataType::Boolean => Value::Bool(raw != 0),
            DataType::Integer8 => Value::Signed(raw as u8 as i8 as i64),
            DataType::Integer16 => Value::Signed(raw as u16 as i16 as i64),
            DataType::Integer32 => Value::Signed(raw as u32 as i32 as i64),
            DataType::Integer64 => Value::Signed(raw as i64),
            DataType::Unsigned8 | DataType::Unsigned16 | DataType::Unsigned32 => {
                Value::Unsigned(raw)
            }
            DataType::Unsigned64 => Value::Unsigned(raw),
            DataType::Real32 => Value::Real(f32::from_bits(raw as u32) as f64),
            DataType::Real64 => Value::Real(f64::from_bits(raw)),
            _ => return None,
        })
    }

    /// Encodes into `out` (which must be the type's size) as `ty`. Returns the length written,
    /// or `None` when the value does not fit the type.
    pub fn encode(self, ty: DataType, out: &mut [u8]) -> Option<usize> {
        let n = ty.fixed_size()?;
        let raw: u64 = match (ty, self) {
            (DataType::Boolean, Value::Bool(b)) => b as u64,
            (DataType::Boolean, Value::Unsigned(u)) if u <= 1 => u,
            (DataType::Real32, v) => (v.as_f64()? as f32).to_bits() as u64,
            (DataType::Real64, v) => v.as_f64()?.to_bits(),
            (t, v) if t.is_signed() => {
                let s = v.as_i128()?;
                let bits = n as u32 * 8;
                let lo = -(1i128 << (bits - 1));
                let hi = (1i128 << (bits - 1)) - 1;
                if s < lo || s > hi {
                    return None;
                }
                s as i64 as u64
            }
            (_, v) => {
                let u = v.as_i128()?;
                let bits = n as u32 * 8;
                if u < 0 || (bits < 64 && u >= (1i128 << bits)) || u > u64::MAX as i128 {
                    return None;
                }
                u as u64
            }
        };
        out.get_mut(..n)?
            .copy_from_slice(raw.to_le_bytes().get(..n)?);
        Some(n)
    }

    /// The value a limit stands for.
    pub fn from_limit(l: Limit) -> Value {
        match l {
            Limit::Signed(s) => Value::Signed(s),
            Limit::Unsigned(u) => Value::Unsigned(u),
            Limit::Real(r) => Value::Real(r),
        }
    }

    fn as_i128(self) -> Option<i128> {
        match self {
            Value::Bool(b) => Some(b as i128),
            Value::Signed(s) => Some(s as i128),
            Value::Unsigned(u) => Some(u as i128),
            Value::Real(_) => None,
        }
    }

    pub fn as_f64(self) -> Option<f64> {
        Some(match self {
            Value::Bool(b) => b as u8 as f64,
            Value::Signed(s) => s as f64,
            Value::Unsigned(u) => u as f64,
            Value::Real(r) => r,
        })
    }

    /// Ordering against a limit of the description; `None` when they cannot be compared.
    pub fn compare(self, limit: Limit) -> Option<core::cmp::Ordering> {
        match (self, limit) {
            (Value::Real(a), l) => a.partial_cmp(&limit_f64(l)),
            (v, Limit::Real(b)) => v.as_f64()?.partial_cmp(&b),
            (v, Limit::Signed(b)) => Some(v.as_i128()?.cmp(&(b as i128))),
            (v, Limit::Unsigned(b)) => Some(v.as_i128()?.cmp(&(b as i128))),
        }
    }
}

fn limit_f64(l: Limit) -> f64 {
    match l {
        Limit::Signed(s) => s as f64,
        Limit::Unsigned(u) => u as f64,
        Limit::Real(r) => r,
    }
}

impl core::fmt::Display for Value {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Value::Bool(b) => write!(f, "{}", *b as u8),
            Value::Signed(s) => write!(f, "{s}"),
            Value::Unsigned(u) => write!(f, "{u}"),
            Value::Real(r) => write!(f, "{r}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signed_values_round_trip_and_refuse_overflow() {
        let mut b = [0u8; 2];
        assert_eq!(
            Value::Signed(-2).encode(DataType::Integer16, &mut b),
            Some(2)
        );
        assert_eq!(b, [0xFE, 0xFF]);
        assert_eq!(
            Value::decode(DataType::Integer16, &b),
            Some(Value::Signed(-2))
        );
        assert_eq!(
            Value::Signed(40000).encode(DataType::Integer16, &mut b),
            None
        );
        assert_eq!(
            Value::Unsigned(256).encode(DataType::Unsigned8, &mut b[..1]),
            None
        );
    }

    #[test]
    fn limits_compare_across_kinds() {
        use core::cmp::Ordering::*;
        assert_eq!(Value::Unsigned(5).compare(Limit::Signed(-1)), Some(Greater));
        assert_eq!(Value::Signed(-5).compare(Limit::Unsigned(0)), Some(Less));
        assert_eq!(Value::Real(1.5).compare(Limit::Unsigned(2)), Some(Less));
    }
}
