//! Values as people type and read them on the command line: typed numbers, strings, hex.

use od::{DataType, Value};

/// A type name for the command line (`u16`, `i32`, `str`, `hex`, …) or a CiA 301 name.
pub fn parse_type(s: &str) -> Option<DataType> {
    Some(match s.to_ascii_lowercase().as_str() {
        "bool" => DataType::Boolean,
        "i8" => DataType::Integer8,
        "i16" => DataType::Integer16,
        "i32" => DataType::Integer32,
        "i64" => DataType::Integer64,
        "u8" => DataType::Unsigned8,
        "u16" => DataType::Unsigned16,
        "u32" => DataType::Unsigned32,
        "u64" => DataType::Unsigned64,
        "f32" => DataType::Real32,
        "f64" => DataType::Real64,
        "str" | "string" => DataType::VisibleString,
        "hex" | "octets" => DataType::OctetString,
        "domain" => DataType::Domain,
        _ => return DataType::from_name(&s.to_ascii_uppercase()),
    })
}

pub fn parse_hex(s: &str) -> Option<Vec<u8>> {
    let s: String = s.chars().filter(|c| !c.is_whitespace()).collect();
    let s = s.strip_prefix("0x").unwrap_or(&s);
    if !s.len().is_multiple_of(2) {
        return None;
    }
    (0..s.len())
        .step_by(2)
        .map(|i| s.get(i..i + 2).and_then(|p| u8::from_str_radix(p, 16).ok()))
        .collect()
}

/// Parses a number: decimal, `0x` hex, negative, or a float for REAL types.
pub fn parse_number(s: &str) -> Option<Value> {
    let t = s.trim();
    if let Some(h) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        return u64::from_str_radix(&h.replace('_', ""), 16)
            .ok()
            .map(Value::Unsigned);
    }
    if let Ok(i) = t.parse::<i64>() {
        return Some(Value::Signed(i));
    }
    if let Ok(u) = t.parse::<u64>() {
        return Some(Value::Unsigned(u));
    }
    t.parse::<f64>()
        .ok()
        .filter(|f| f.is_finite())
        .map(Value::Real)
}

/// The bytes to write for `text` as type `t`.
pub fn encode(t: DataType, text: &str) -> Result<Vec<u8>, String> {
    match t {
        DataType::VisibleString => Ok(text.as_bytes().to_vec()),
        DataType::OctetString | DataType::Domain => {
            parse_hex(text).ok_or_else(|| format!("{text:?} is not hex"))
        }
        _ => {
            let v = parse_number(text).ok_or_else(|| format!("{text:?} is not a number"))?;
            let mut b = [0u8; 8];
            let n = v
                .encode(t, &mut b)
                .ok_or_else(|| format!("{text} does not fit {}", t.name()))?;
            Ok(b.get(..n).unwrap_or(&[]).to_vec())
        }
    }
}

/// A readable form of `data` as type `t`, or `None` when it does not decode.
pub fn decode(t: DataType, data: &[u8]) -> Option<String> {
    match t {
        DataType::VisibleString => Some(String::from_utf8_lossy(data).into_owned()),
        DataType::OctetString | DataType::Domain => Some(hex(data)),
        _ => Value::decode(t, data).map(|v| v.to_string()),
    }
}

pub fn hex(data: &[u8]) -> String {
    data.iter().map(|b| format!("{b:02X}")).collect()
}

/// A value in a file (a scenario's step, a record script's write): a number or a text (a
/// string, a hex number).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(untagged)]
pub enum Number {
    Int(i64),
    Float(f64),
    Text(String),
}

impl Number {
    /// As the command line types it, for [`encode`].
    pub fn text(&self) -> String {
        match self {
            Number::Int(i) => i.to_string(),
            Number::Float(f) => f.to_string(),
            Number::Text(t) => t.clone(),
        }
    }

    /// The value as an integer, when it is one (`0x` hex in a text too).
    pub fn integer(&self) -> Option<i64> {
        match self {
            Number::Int(i) => Some(*i),
            Number::Float(_) => None,
            Number::Text(t) => match parse_number(t)? {
                od::Value::Signed(i) => Some(i),
                od::Value::Unsigned(u) => i64::try_from(u).ok(),
                _ => None,
            },
        }
    }
}

/// `text` (`0x6041` or `6041`) as a hexadecimal number of the type `parse` reads; the error
/// names `what` is not hex.
pub fn parse_hex_number<T>(
    text: &str,
    what: &str,
    parse: fn(&str, u32) -> Result<T, std::num::ParseIntError>,
) -> Result<T, String> {
    let t = text.trim_start_matches("0x").trim_start_matches("0X");
    parse(t, 16).map_err(|_| format!("{what} {text:?} is not hex"))
}

/// The built-in device named `name` (`--device`), or an error listing the known ones.
pub fn device_named(name: &str) -> Result<&'static od::DeviceDescription, String> {
    devices::by_name(name).ok_or_else(|| {
        let known: Vec<&str> = devices::ALL.iter().map(|d| d.name).collect();
        format!("unknown device {name:?} (known: {})", known.join(", "))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_numbers_and_device_names_as_typed() {
        assert_eq!(
            parse_hex_number("0x6041", "index", u16::from_str_radix),
            Ok(0x6041)
        );
        assert_eq!(
            parse_hex_number("1A", "sub-index", u8::from_str_radix),
            Ok(0x1A)
        );
        assert_eq!(
            parse_hex_number("1FF", "sub-index", u8::from_str_radix),
            Err("sub-index \"1FF\" is not hex".to_owned())
        );
        assert_eq!(device_named("kinco-fd3").map(|d| d.name), Ok("kinco-fd3"));
        let err = device_named("acme").unwrap_err();
        assert!(
            err.starts_with("unknown device \"acme\" (known: ") && err.contains("cmmp-as"),
            "{err}"
        );
    }

    #[test]
    fn typed_values_encode_and_refuse_overflow() {
        assert_eq!(encode(DataType::Unsigned16, "1000"), Ok(vec![0xE8, 0x03]));
        assert_eq!(encode(DataType::Integer8, "-2"), Ok(vec![0xFE]));
        assert_eq!(
            encode(DataType::Unsigned32, "0x65766173"),
            Ok(vec![0x73, 0x61, 0x76, 0x65])
        );
        assert!(encode(DataType::Unsigned8, "256").is_err());
        assert!(encode(DataType::Unsigned8, "abc").is_err());
        assert_eq!(
            encode(DataType::OctetString, "DEAD beef"),
            Ok(vec![0xDE, 0xAD, 0xBE, 0xEF])
        );
        assert_eq!(
            decode(DataType::Integer16, &[0xFE, 0xFF]).as_deref(),
            Some("-2")
        );
        assert_eq!(parse_type("u16"), Some(DataType::Unsigned16));
        assert_eq!(parse_type("UNSIGNED32"), Some(DataType::Unsigned32));
    }
}
