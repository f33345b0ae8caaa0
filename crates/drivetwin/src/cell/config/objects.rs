//! `[drive.objects]`: commissioning values, `"IIII:SS" = value`, encoded for the entry's
//! data type.

use od::{DataType, Value};

/// `"1017:00"` → (0x1017, 0).
pub fn parse_key(key: &str) -> Option<(u16, u8)> {
    let (i, s) = key.split_once(':')?;
    let i = i.trim().trim_start_matches("0x");
    let s = s.trim().trim_start_matches("0x");
    Some((
        u16::from_str_radix(i, 16).ok()?,
        u8::from_str_radix(s, 16).ok()?,
    ))
}

pub(super) fn encode_toml(t: DataType, v: &toml::Value) -> Result<Vec<u8>, String> {
    match (t, v) {
        (DataType::VisibleString, toml::Value::String(s)) => Ok(s.as_bytes().to_vec()),
        (DataType::OctetString | DataType::Domain, toml::Value::String(s)) => {
            crate::value_text::parse_hex(s).ok_or_else(|| "expected hex digits".into())
        }
        (_, toml::Value::Integer(i)) => encode_value(t, Value::Signed(*i)),
        (_, toml::Value::Float(f)) => encode_value(t, Value::Real(*f)),
        (_, toml::Value::Boolean(b)) => encode_value(t, Value::Bool(*b)),
        _ => Err(format!("value does not fit {}", t.name())),
    }
}

fn encode_value(t: DataType, v: Value) -> Result<Vec<u8>, String> {
    let mut b = [0u8; 8];
    let n = v
        .encode(t, &mut b)
        .ok_or_else(|| format!("{v} does not fit {}", t.name()))?;
    Ok(b.get(..n).unwrap_or(&[]).to_vec())
}
