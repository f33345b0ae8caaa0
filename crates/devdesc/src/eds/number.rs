//! Values as CiA 306 §4.6.3 writes them: decimal, `0x` hexadecimal or `0` octal integers,
//! `$NODEID` plus a constant, hexadecimal octet strings, and REAL defaults either as a decimal
//! number or as their IEEE 754 bit pattern (the form `drivetwin eds` writes).

use od::{DataType, Limit, Value};

/// An integer as CiA 306 writes it; `None` if it is not one.
pub fn integer(text: &str) -> Option<i128> {
    let t = text.trim();
    let (negative, t) = match t.strip_prefix('-') {
        Some(rest) => (true, rest.trim_start()),
        None => (false, t.strip_prefix('+').unwrap_or(t)),
    };
    let magnitude = if let Some(hex) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        u128::from_str_radix(hex, 16).ok()?
    } else if t.len() > 1 && t.starts_with('0') {
        u128::from_str_radix(t.get(1..)?, 8).ok()?
    } else {
        t.parse::<u128>().ok()?
    };
    let m = i128::try_from(magnitude).ok()?;
    Some(if negative { -m } else { m })
}

/// Whether `text` is a hexadecimal literal (`0x…`), which for a signed type is the two's
/// complement bit pattern (python-canopen reads `LowLimit=0x80000000` of an INTEGER32 so).
fn is_hex(text: &str) -> bool {
    let t = text.trim();
    t.starts_with("0x") || t.starts_with("0X")
}

/// `text` as a value of the numeric type `t`, encoded little-endian.
pub fn encode(t: DataType, text: &str) -> Result<Vec<u8>, String> {
    let value = value(t, text)?;
    let mut buf = [0u8; 8];
    let n = value
        .encode(t, &mut buf)
        .ok_or_else(|| format!("{text:?} does not fit {}", t.name()))?;
    Ok(buf.get(..n).unwrap_or(&[]).to_vec())
}

/// `text` as a value of the numeric type `t`.
pub fn value(t: DataType, text: &str) -> Result<Value, String> {
    let bad = || format!("{text:?} is not a {} value", t.name());
    if t.is_real() {
        if is_hex(text) {
            let bits = integer(text).ok_or_else(bad)?;
            return Ok(Value::Real(match t {
                DataType::Real32 => {
                    f64::from(f32::from_bits(u32::try_from(bits).map_err(|_| bad())?))
                }
                _ => f64::from_bits(u64::try_from(bits).map_err(|_| bad())?),
            }));
        }
        return text
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|r| r.is_finite())
            .map(Value::Real)
            .ok_or_else(bad);
    }
    let i = integer(text).ok_or_else(bad)?;
    if t.is_signed() && is_hex(text) {
        let bits = t.fixed_size().unwrap_or(8) as u32 * 8;
        if i < 0 || i >= 1i128 << bits {
            return Err(format!("{text:?} does not fit {}", t.name()));
        }
        // Sign-extend the pattern of `bits` bits.
        let shift = 128 - bits;
        return Ok(Value::Signed(((i << shift) >> shift) as i64));
    }
    if t == DataType::Boolean {
        return match i {
            0 => Ok(Value::Bool(false)),
            1 => Ok(Value::Bool(true)),
            _ => Err(format!("{text:?}: a BOOLEAN is 0 or 1")),
        };
    }
    if i < 0 {
        i64::try_from(i).map(Value::Signed).map_err(|_| bad())
    } else {
        u64::try_from(i).map(Value::Unsigned).map_err(|_| bad())
    }
}

/// A limit (`LowLimit`, `HighLimit`) of the numeric type `t`.
pub fn limit(t: DataType, text: &str) -> Result<Limit, String> {
    if text.to_ascii_uppercase().contains("$NODEID") {
        return Err("a limit relative to $NODEID".into());
    }
    let v = value(t, text)?;
    let mut buf = [0u8; 8];
    v.encode(t, &mut buf)
        .ok_or_else(|| format!("{text:?} does not fit {}", t.name()))?;
    Ok(match v {
        Value::Real(r) => Limit::Real(r),
        Value::Signed(s) if s < 0 => Limit::Signed(s),
        Value::Signed(s) => Limit::Unsigned(s as u64),
        Value::Unsigned(u) => Limit::Unsigned(u),
        Value::Bool(b) => Limit::Unsigned(u64::from(b)),
    })
}

/// Splits a `$NODEID` expression (CiA 306 §4.6.3: `$NODEID+0x180`; also `0x180+$NODEID` and
/// `$NODEID` alone) into its constant: `Ok(Some(c))`, or `Ok(None)` when `text` does not name
/// `$NODEID`. Any other arithmetic is refused.
pub fn node_relative(text: &str) -> Result<Option<&str>, String> {
    let t = text.trim();
    let upper = t.to_ascii_uppercase();
    let Some(at) = upper.find("$NODEID") else {
        return Ok(None);
    };
    let before = t.get(..at).unwrap_or("").trim();
    let after = t.get(at + "$NODEID".len()..).unwrap_or("").trim();
    let constant = match (before, after) {
        ("", "") => "0",
        ("", rest) => rest.strip_prefix('+').map(str::trim).unwrap_or(""),
        (rest, "") => rest.strip_suffix('+').map(str::trim).unwrap_or(""),
        _ => "",
    };
    if constant.is_empty() || constant.to_ascii_uppercase().contains("$NODEID") {
        return Err(format!(
            "{t:?}: only $NODEID, $NODEID+constant and constant+$NODEID are understood"
        ));
    }
    Ok(Some(constant))
}

/// Bytes from hexadecimal digits (white space between them allowed), as python-canopen's
/// `bytes.fromhex` reads an OCTET_STRING or DOMAIN default.
pub fn hex_bytes(text: &str) -> Result<Vec<u8>, String> {
    let digits: Vec<u8> = text.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
    if !digits.len().is_multiple_of(2) {
        return Err(format!("{text:?}: an odd number of hex digits"));
    }
    digits
        .chunks(2)
        .map(|pair| {
            std::str::from_utf8(pair)
                .ok()
                .and_then(|s| u8::from_str_radix(s, 16).ok())
                .ok_or_else(|| format!("{text:?} is not hexadecimal"))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers_as_cia_306_writes_them() {
        assert_eq!(integer("0x1A"), Some(26));
        assert_eq!(integer("017"), Some(15), "leading 0: octal");
        assert_eq!(integer("0"), Some(0));
        assert_eq!(integer("-5"), Some(-5));
        assert_eq!(integer("09"), None, "not octal");
        assert_eq!(integer("ten"), None);
    }

    #[test]
    fn signed_hex_is_a_bit_pattern_and_reals_take_both_forms() {
        assert_eq!(
            value(DataType::Integer32, "0x80000000"),
            Ok(Value::Signed(i64::from(i32::MIN)))
        );
        assert_eq!(value(DataType::Integer16, "-1"), Ok(Value::Signed(-1)));
        assert!(encode(DataType::Integer8, "0x100").is_err());
        assert!(encode(DataType::Unsigned8, "256").is_err());
        assert!(encode(DataType::Unsigned8, "-1").is_err());
        assert_eq!(value(DataType::Real32, "0x3FC00000"), Ok(Value::Real(1.5)));
        assert_eq!(value(DataType::Real32, "1.5"), Ok(Value::Real(1.5)));
        assert!(value(DataType::Boolean, "2").is_err());
    }

    #[test]
    fn node_id_expressions() {
        assert_eq!(node_relative("$NODEID+0x180"), Ok(Some("0x180")));
        assert_eq!(node_relative("0x600 + $nodeid"), Ok(Some("0x600")));
        assert_eq!(node_relative("$NODEID"), Ok(Some("0")));
        assert_eq!(node_relative("0x180"), Ok(None));
        assert!(node_relative("$NODEID*2").is_err());
        assert!(node_relative("$NODEID+$NODEID").is_err());
        assert!(limit(DataType::Unsigned32, "$NODEID+1").is_err());
    }

    #[test]
    fn octet_strings() {
        assert_eq!(hex_bytes("01 ab"), Ok(vec![1, 0xAB]));
        assert!(hex_bytes("abc").is_err());
        assert!(hex_bytes("zz").is_err());
    }
}
