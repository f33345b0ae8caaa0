use super::*;

pub(crate) fn resolve_type(
    typing: &crate::cli::TypeArgs,
    index: u16,
    sub: u8,
) -> Result<Option<DataType>, CommandError> {
    if let Some(t) = typing.data_type.as_deref() {
        return value_text::parse_type(t)
            .map(Some)
            .ok_or_else(|| CommandError::Usage(format!("unknown type {t:?}")));
    }
    if let Some(name) = typing.device.as_deref() {
        let desc = device(name)?;
        let e = desc.entry(index, sub).ok_or_else(|| {
            CommandError::Usage(format!("{name} has no entry {index:04X}:{sub:02X}"))
        })?;
        return Ok(Some(e.data_type));
    }
    Ok(None)
}

pub(crate) async fn sdo(cmd: SdoCommand) -> Result<(), CommandError> {
    match cmd {
        SdoCommand::Read {
            node,
            index,
            sub,
            typing,
            timeout_ms,
            bus,
        } => {
            check_node(node)?;
            let index = parse_hex_u16(&index, "index")?;
            let sub = parse_hex_u8(&sub, "sub-index")?;
            let ty = resolve_type(&typing, index, sub)?;
            let mut link = connect(&bus).await?;
            let result = SdoClient::new(&mut link, node, Duration::from_millis(timeout_ms))
                .upload(index, sub)
                .await;
            let data = match result {
                Ok(d) => d,
                Err(e) => return Err(report_sdo_error(&bus, node, index, sub, e)),
            };
            print_upload(
                ty,
                &data,
                bus.json.then(|| {
                    serde_json::json!({"node": node, "index": format!("0x{index:04X}"), "sub": sub})
                }),
            );
            Ok(())
        }
        SdoCommand::Write {
            node,
            index,
            sub,
            value,
            typing,
            timeout_ms,
            bus,
        } => {
            check_node(node)?;
            let index = parse_hex_u16(&index, "index")?;
            let sub = parse_hex_u8(&sub, "sub-index")?;
            let ty = resolve_type(&typing, index, sub)?.ok_or_else(|| {
                CommandError::Usage("sdo write needs --type or --device to encode the value".into())
            })?;
            let data = value_text::encode(ty, &value).map_err(CommandError::Usage)?;
            let mut link = connect(&bus).await?;
            let result = SdoClient::new(&mut link, node, Duration::from_millis(timeout_ms))
                .download(index, sub, &data)
                .await;
            if let Err(e) = result {
                return Err(report_sdo_error(&bus, node, index, sub, e));
            }
            if bus.json {
                out!(
                    "{}",
                    serde_json::json!({"node": node, "index": format!("0x{index:04X}"), "sub": sub, "written": value_text::hex(&data)})
                );
            }
            Ok(())
        }
    }
}

/// In JSON mode an SDO failure is also a JSON object on standard output.
fn report_sdo_error(bus: &BusArgs, node: u8, index: u16, sub: u8, e: SdoError) -> CommandError {
    if bus.json {
        let mut j = serde_json::json!({
            "node": node, "index": format!("0x{index:04X}"), "sub": sub, "error": e.to_string(),
        });
        if let (SdoError::Abort(code), Some(o)) = (&e, j.as_object_mut()) {
            o.insert(
                "abort_code".into(),
                serde_json::json!(format!("0x{:08X}", code.0)),
            );
            o.insert("abort_text".into(), serde_json::json!(code.description()));
        }
        out!("{j}");
    }
    CommandError::Sdo(e)
}

/// Prints an uploaded value as `ty` (without one, guessed from the length: 1, 2, 4 bytes are
/// unsigned), or hex; in JSON mode as `head` plus `data` and `value`.
pub(crate) fn print_upload(ty: Option<DataType>, data: &[u8], head: Option<serde_json::Value>) {
    let ty = ty.or(match data.len() {
        1 => Some(DataType::Unsigned8),
        2 => Some(DataType::Unsigned16),
        4 => Some(DataType::Unsigned32),
        _ => None,
    });
    let value = ty.and_then(|t| value_text::decode(t, data));
    if let Some(mut j) = head {
        // Numbers stay numbers in JSON; strings and octets stay strings.
        let json_value = match (ty, &value) {
            (Some(t), Some(v)) if t.is_numeric() => serde_json::from_str::<serde_json::Value>(v)
                .unwrap_or_else(|_| serde_json::Value::String(v.clone())),
            (_, Some(v)) => serde_json::Value::String(v.clone()),
            _ => serde_json::Value::Null,
        };
        if let Some(o) = j.as_object_mut() {
            o.insert("data".into(), serde_json::json!(value_text::hex(data)));
            o.insert("value".into(), json_value);
        }
        out!("{j}");
    } else {
        match value {
            Some(v) => out!("{v}"),
            None => out!("{}", value_text::hex(data)),
        }
    }
}
