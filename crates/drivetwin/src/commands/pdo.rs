use super::*;

fn parse_pdo_name(s: &str) -> Result<(Direction, u16), CommandError> {
    let lower = s.to_ascii_lowercase();
    let (dir, n) = if let Some(n) = lower.strip_prefix("rpdo") {
        (Direction::Rpdo, n)
    } else if let Some(n) = lower.strip_prefix("tpdo") {
        (Direction::Tpdo, n)
    } else {
        return Err(CommandError::Usage(format!(
            "{s:?}: expected rpdoN or tpdoN"
        )));
    };
    match n.parse::<u16>() {
        Ok(n) if (1..=512).contains(&n) => Ok((dir, n)),
        _ => Err(CommandError::Usage(format!("{s:?}: PDO number 1…512"))),
    }
}

pub(crate) async fn pdo(cmd: PdoCommand) -> Result<(), CommandError> {
    match cmd {
        PdoCommand::Show {
            node,
            timeout_ms,
            bus,
        } => {
            check_node(node)?;
            let mut link = connect(&bus).await?;
            let mut client = SdoClient::new(&mut link, node, Duration::from_millis(timeout_ms));
            let mut all = Vec::new();
            for dir in [Direction::Rpdo, Direction::Tpdo] {
                for n in 1..=512u16 {
                    match pdo_config::read_pdo(&mut client, dir, n).await? {
                        Some(p) => all.push(p),
                        None => break,
                    }
                }
            }
            if bus.json {
                out!("{}", serde_json::to_string(&all).unwrap_or_default());
            } else {
                for p in &all {
                    let name = match p.direction {
                        Direction::Rpdo => "RPDO",
                        Direction::Tpdo => "TPDO",
                    };
                    let map: Vec<String> = p
                        .mapping
                        .iter()
                        .map(|m| format!("{:04X}:{:02X}/{}", m.index, m.sub, m.bits))
                        .collect();
                    out!(
                        "{name}{} cob-id {:08X} {} type {} inhibit {} event {}  [{}]",
                        p.number,
                        p.cob_id,
                        if p.valid { "enabled " } else { "disabled" },
                        p.transmission_type,
                        p.inhibit_time_100us
                            .map(|v| v.to_string())
                            .unwrap_or_else(|| "-".into()),
                        p.event_timer_ms
                            .map(|v| v.to_string())
                            .unwrap_or_else(|| "-".into()),
                        map.join(", ")
                    );
                }
            }
            Ok(())
        }
        PdoCommand::Map {
            node,
            pdo,
            cob_id,
            transmission_type,
            inhibit,
            event_timer,
            map,
            disabled,
            timeout_ms,
            bus,
        } => {
            check_node(node)?;
            let (dir, n) = parse_pdo_name(&pdo)?;
            let cob_id = match cob_id {
                Some(c) => parse_hex_u16(&c, "COB-ID")?,
                None if n <= 4 => {
                    let base = match dir {
                        Direction::Tpdo => 0x180,
                        Direction::Rpdo => 0x200,
                    };
                    base + 0x100 * (n - 1) + u16::from(node)
                }
                None => return Err(CommandError::Usage("PDOs above 4 need --cob-id".into())),
            };
            let mapping = map
                .iter()
                .map(|m| {
                    Mapping::parse(m).ok_or_else(|| {
                        CommandError::Usage(format!("mapping {m:?}: expected INDEX:SUB:BITS"))
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            let setting = PdoSetting {
                cob_id,
                transmission_type,
                inhibit_time_100us: inhibit,
                event_timer_ms: event_timer,
                mapping,
                enable: !disabled,
            };
            let mut link = connect(&bus).await?;
            let mut client = SdoClient::new(&mut link, node, Duration::from_millis(timeout_ms));
            pdo_config::write_pdo(&mut client, dir, n, &setting).await?;
            if bus.json {
                out!(
                    "{}",
                    serde_json::json!({"node": node, "pdo": pdo, "cob_id": cob_id, "entries": setting.mapping.len()})
                );
            }
            Ok(())
        }
    }
}
