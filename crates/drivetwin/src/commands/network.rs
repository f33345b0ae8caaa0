use super::*;

pub(crate) async fn nmt(command: NmtArg, node: u8, bus: BusArgs) -> Result<(), CommandError> {
    if node > 127 {
        return Err(CommandError::Usage(format!(
            "node-ID {node} is outside 0…127"
        )));
    }
    let cmd = match command {
        NmtArg::Start => NmtCommand::Start,
        NmtArg::Stop => NmtCommand::Stop,
        NmtArg::PreOperational => NmtCommand::EnterPreOperational,
        NmtArg::ResetNode => NmtCommand::ResetNode,
        NmtArg::ResetCommunication => NmtCommand::ResetCommunication,
    };
    let mut link = connect(&bus).await?;
    let frame =
        CanFrame::new(0x000, &[cmd.cs(), node]).map_err(|e| CommandError::Usage(e.to_string()))?;
    link.send(&frame).await?;
    // Give the server a moment to put the frame on the bus before the connection closes.
    tokio::time::sleep(Duration::from_millis(50)).await;
    if bus.json {
        out!("{}", serde_json::json!({"nmt": cmd.name(), "node": node}));
    }
    Ok(())
}

pub(crate) async fn monitor(
    count: Option<u64>,
    seconds: Option<f64>,
    bitrate: Option<u32>,
    bus: BusArgs,
) -> Result<(), CommandError> {
    if bitrate == Some(0) {
        return Err(CommandError::Usage("--bitrate must be above 0".into()));
    }
    let mut link = connect(&bus).await?;
    let started = tokio::time::Instant::now();
    let since_start = || od::Instant::from_nanos(started.elapsed().as_nanos() as u64);
    let window = drivetwin::cell::bus_timing::LOAD_WINDOW.as_nanos() as u64;
    let mut load = bitrate.map(|b| (b, canbus::bus_load::LoadWindow::new(window, since_start())));
    let deadline = match seconds {
        Some(s) if s.is_finite() && s >= 0.0 => {
            Some(tokio::time::Instant::now() + Duration::from_secs_f64(s))
        }
        Some(_) => {
            return Err(CommandError::Usage(
                "--seconds must be a positive number".into(),
            ))
        }
        None => None,
    };
    let mut seen = 0u64;
    while count.is_none_or(|c| seen < c) {
        let frame = match deadline {
            Some(d) => match tokio::time::timeout_at(d, link.recv()).await {
                Ok(f) => f?,
                Err(_) => break,
            },
            None => link.recv().await?,
        };
        seen += 1;
        if let Some((bitrate, window)) = load.as_mut() {
            let nanos =
                canbus::frame_time::bits_to_nanos(canbus::frame_time::frame_bits(&frame), *bitrate);
            if let Some(closed) = window.add(since_start(), nanos) {
                print_load(bus.json, *bitrate, closed.load_percent, closed.frames, 1);
                if closed.quiet > 0 {
                    print_load(bus.json, *bitrate, 0.0, 0, closed.quiet);
                }
            }
        }
        let mut text = String::new();
        let _ = canopen::decode::describe(&frame, &mut text);
        let t = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        if bus.json {
            let (function, node) = match frame.cob_id() {
                Some(c) => {
                    let (f, n) = canopen::decode::classify(c);
                    (format!("{f:?}"), n)
                }
                None => ("Extended".to_string(), 0),
            };
            out!(
                "{}",
                serde_json::json!({
                    "time": t.as_secs_f64(), "id": frame.id, "extended": frame.extended, "rtr": frame.rtr,
                    "data": value_text::hex(frame.payload()), "function": function, "node": node, "text": text,
                })
            );
        } else {
            let id = if frame.extended {
                format!("{:08X}", frame.id)
            } else {
                format!("{:03X}", frame.id)
            };
            out!(
                "{:.6}  {id}  [{}] {:<24} {text}",
                t.as_secs_f64(),
                frame.len,
                canopen::decode::Hex(frame.payload()).to_string()
            );
        }
    }
    Ok(())
}

/// The bus load of one window, or of `windows` quiet ones in a row, as a line between the
/// frames.
fn print_load(json: bool, bitrate: u32, percent: f64, frames: u32, windows: u64) {
    let window_ms = u64::try_from(drivetwin::cell::bus_timing::LOAD_WINDOW.as_millis())
        .unwrap_or(u64::MAX)
        .saturating_mul(windows);
    if json {
        out!(
            "{}",
            serde_json::json!({"bus_load_percent": percent, "bitrate": bitrate, "window_ms": window_ms, "frames": frames})
        );
    } else {
        out!("-- bus load {percent:.1} % at {bitrate} bit/s ({frames} frames in {window_ms} ms)");
    }
}

pub(crate) async fn sync(
    period_ms: f64,
    count: Option<u64>,
    counter: u8,
    cob_id: &str,
    bus: BusArgs,
) -> Result<(), CommandError> {
    if !(period_ms.is_finite() && period_ms > 0.0) {
        return Err(CommandError::Usage("--period-ms must be positive".into()));
    }
    if counter == 1 || counter > 240 {
        return Err(CommandError::Usage(
            "--counter is 0 or 2…240 (CiA 301 1019h)".into(),
        ));
    }
    let cob = parse_hex_u16(cob_id, "COB-ID")?;
    let mut link = connect(&bus).await?;
    let mut interval = tokio::time::interval(Duration::from_secs_f64(period_ms / 1000.0));
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut sent = 0u64;
    let mut value = 0u8;
    let stop = shutdown_signal();
    tokio::pin!(stop);
    while count.is_none_or(|c| sent < c) {
        tokio::select! {
            _ = &mut stop => break,
            _ = interval.tick() => {}
        }
        let frame = if counter == 0 {
            CanFrame::new(cob, &[])
        } else {
            value = if value >= counter { 1 } else { value + 1 };
            CanFrame::new(cob, &[value])
        }
        .map_err(|e| CommandError::Usage(e.to_string()))?;
        link.send(&frame).await?;
        sent += 1;
    }
    tokio::time::sleep(Duration::from_millis(50)).await;
    if bus.json {
        out!("{}", serde_json::json!({"sync": sent}));
    } else {
        out!("{sent} SYNC sent");
    }
    Ok(())
}

pub(crate) async fn scan(timeout_ms: u64, bus: BusArgs) -> Result<(), CommandError> {
    let mut link = connect(&bus).await?;
    // As python-canopen's NodeScanner: read 1000h from every node-ID, collect the answers.
    for node in 1..=127u16 {
        let frame = CanFrame::full(0x600 + node, [0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
        link.send(&frame).await?;
    }
    let deadline = tokio::time::Instant::now() + Duration::from_millis(timeout_ms);
    let mut found = std::collections::BTreeMap::new();
    let spinner = super::progress::spinner("scan: 0 nodes answered");
    while let Ok(f) = tokio::time::timeout_at(deadline, link.recv()).await {
        let f = f?;
        if let Some(cob) = f.cob_id() {
            if (0x581..=0x5FF).contains(&cob) {
                let p = f.payload();
                let device_type = match p {
                    [0x43, 0x00, 0x10, 0x00, a, b, c, d] => {
                        Some(u32::from_le_bytes([*a, *b, *c, *d]))
                    }
                    _ => None,
                };
                found.insert((cob - 0x580) as u8, device_type);
                spinner.set_message(format!("scan: {} nodes answered", found.len()));
            }
        }
    }
    spinner.finish_and_clear();
    if bus.json {
        let nodes: Vec<_> = found
            .iter()
            .map(|(n, t)| serde_json::json!({"node": n, "device_type": t}))
            .collect();
        out!("{}", serde_json::json!(nodes));
    } else {
        for (n, t) in &found {
            match t {
                Some(t) => out!("node {n}: device type {t:08X}"),
                None => out!("node {n}: answers (1000h not readable)"),
            }
        }
        if found.is_empty() {
            out!("no node answered");
        }
    }
    Ok(())
}
