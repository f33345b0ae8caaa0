//! What each sub-command does.

use std::path::PathBuf;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use canopen::{CanFrame, NmtCommand};
use drivetwin::bus::Bus;
use drivetwin::can_drive::{CanDrive, DriveError};
use drivetwin::cell::Cell;
use drivetwin::cell_config::{CellFile, ConfigError};
use drivetwin::master::link::{Link, LinkError};
use drivetwin::master::sdo_client::{SdoClient, SdoError};
use drivetwin::param_store::ParamStore;
use drivetwin::trace::{self, TraceWriter};
use drivetwin::{runtime, socketcand, value_text};
use od::DataType;

use crate::cli::{
    BusArgs, Cli, Command, DriveCommand, LssCommand, NmtArg, PdoCommand, RunArgs, SdoCommand,
};
use drivetwin::master::cia402::{self, Cia402Error};
use drivetwin::master::lss::{LssError, LssMaster};
use drivetwin::master::pdo_config::{self, Direction, Mapping, PdoSetting};

/// Writes a line to standard output; when the reader went away (`drivetwin monitor | head`)
/// the command ends quietly instead of panicking like `println!`.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let mut stdout = std::io::stdout().lock();
        if writeln!(stdout, $($arg)*).and_then(|_| stdout.flush()).is_err() {
            std::process::exit(0);
        }
    }};
}

/// As [`out!`] without the newline.
macro_rules! out_raw {
    ($text:expr) => {{
        use std::io::Write as _;
        let mut stdout = std::io::stdout().lock();
        if stdout
            .write_all($text.as_bytes())
            .and_then(|_| stdout.flush())
            .is_err()
        {
            std::process::exit(0);
        }
    }};
}

pub const EXIT_FAILURE: u8 = 1;
pub const EXIT_USAGE: u8 = 2;
pub const EXIT_LINK: u8 = 3;
pub const EXIT_TIMEOUT: u8 = 4;
pub const EXIT_ABORT: u8 = 5;
pub const EXIT_PROTOCOL: u8 = 6;

#[derive(Debug, thiserror::Error)]
pub enum CommandError {
    #[error("{0}")]
    Usage(String),
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Drive(#[from] DriveError),
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error(transparent)]
    Sdo(#[from] SdoError),
    #[error(transparent)]
    Lss(#[from] LssError),
    #[error(transparent)]
    Cia402(#[from] Cia402Error),
    #[error("{what}: {source}")]
    Io {
        what: String,
        source: std::io::Error,
    },
}

impl CommandError {
    pub fn exit_code(&self) -> u8 {
        match self {
            CommandError::Usage(_) | CommandError::Config(_) => EXIT_USAGE,
            CommandError::Link(_) | CommandError::Sdo(SdoError::Link(_)) => EXIT_LINK,
            CommandError::Sdo(SdoError::Timeout { .. }) => EXIT_TIMEOUT,
            CommandError::Sdo(SdoError::Abort(_)) => EXIT_ABORT,
            CommandError::Sdo(SdoError::Protocol(_)) => EXIT_PROTOCOL,
            CommandError::Lss(LssError::Link(_)) => EXIT_LINK,
            CommandError::Lss(LssError::NoResponse(_)) => EXIT_TIMEOUT,
            CommandError::Lss(LssError::Refused { .. }) => EXIT_PROTOCOL,
            CommandError::Cia402(Cia402Error::Timeout { .. }) => EXIT_TIMEOUT,
            CommandError::Cia402(Cia402Error::Sdo(e)) => match e {
                SdoError::Abort(_) => EXIT_ABORT,
                SdoError::Timeout { .. } => EXIT_TIMEOUT,
                SdoError::Protocol(_) => EXIT_PROTOCOL,
                SdoError::Link(_) => EXIT_LINK,
            },
            CommandError::Drive(drivetwin::can_drive::DriveError::NodeId(_)) => EXIT_USAGE,
            CommandError::Drive(_) | CommandError::Io { .. } => EXIT_FAILURE,
        }
    }
}

fn io(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> CommandError {
    let what = what.into();
    move |source| CommandError::Io { what, source }
}

pub async fn dispatch(cli: Cli) -> Result<(), CommandError> {
    match cli.command {
        Command::Run(args) => run(args).await,
        Command::Eds { device, output } => eds(&device, output),
        Command::Esi { device, output } => esi(&device, output),
        Command::Devices => {
            for d in devices::ALL {
                out!(
                    "{:<10} {} ({}), {} objects",
                    d.name,
                    d.product_name,
                    d.vendor_name,
                    d.objects.len()
                );
            }
            Ok(())
        }
        Command::Sdo(cmd) => sdo(cmd).await,
        Command::Nmt { command, node, bus } => nmt(command, node, bus).await,
        Command::Pdo(cmd) => pdo(cmd).await,
        Command::Sync {
            period_ms,
            count,
            counter,
            cob_id,
            bus,
        } => sync(period_ms, count, counter, &cob_id, bus).await,
        Command::Lss(cmd) => lss(cmd).await,
        Command::Scan { timeout_ms, bus } => scan(timeout_ms, bus).await,
        Command::Drive {
            node,
            command,
            wait,
            timeout_ms,
            bus,
        } => drive_command(node, command, wait, timeout_ms, bus).await,
        Command::Monitor {
            count,
            seconds,
            bus,
        } => monitor(count, seconds, bus).await,
    }
}

fn device(name: &str) -> Result<&'static od::DeviceDescription, CommandError> {
    devices::by_name(name).ok_or_else(|| {
        let known: Vec<&str> = devices::ALL.iter().map(|d| d.name).collect();
        CommandError::Usage(format!(
            "unknown device {name:?} (known: {})",
            known.join(", ")
        ))
    })
}

fn eds(name: &str, output: Option<PathBuf>) -> Result<(), CommandError> {
    let desc = device(name)?;
    let mut text = String::new();
    od::eds::write_eds(&mut text, desc, "01-01-2026")
        .map_err(|_| CommandError::Usage("EDS formatting failed".into()))?;
    match output {
        Some(path) => std::fs::write(&path, text).map_err(io(path.display().to_string())),
        None => {
            out_raw!(text);
            Ok(())
        }
    }
}

fn esi(name: &str, output: Option<PathBuf>) -> Result<(), CommandError> {
    let desc = device(name)?;
    let mut text = String::new();
    drivetwin::esi::write_esi(desc, &mut text)
        .map_err(|_| CommandError::Usage("ESI formatting failed".into()))?;
    match output {
        Some(path) => std::fs::write(&path, text).map_err(io(path.display().to_string())),
        None => {
            out_raw!(text);
            Ok(())
        }
    }
}

fn build_cell(file: &CellFile, state_dir: Option<&PathBuf>) -> Result<Cell, CommandError> {
    let mut drives = Vec::new();
    for spec in file.drives()? {
        let store = state_dir.map(|d| ParamStore::new(d, spec.desc.name, spec.node));
        drives.push(CanDrive::with_settings(
            spec.desc,
            spec.node,
            store,
            spec.commissioning,
            spec.settings,
        )?);
    }
    Ok(Cell::new(drives))
}

async fn run(args: RunArgs) -> Result<(), CommandError> {
    let mut file = match &args.config {
        Some(path) => CellFile::load(path)?,
        None => CellFile::single(&args.device, args.node),
    };
    if let Some(s) = &args.socketcand {
        file.bus.socketcand = s.clone();
    }
    if let Some(c) = &args.channel {
        file.bus.channel = c.clone();
    }
    if let Some(c) = &args.socketcan {
        file.bus.socketcan = Some(c.clone());
    }
    let mut cell = build_cell(&file, args.state_dir.as_ref())?;
    for d in &cell.drives {
        out!(
            "drive {} node {} ({})",
            d.od().description().name,
            d.node_id(),
            d.od().description().product_name
        );
    }

    if let Some(seconds) = args.virtual_seconds {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(CommandError::Usage(
                "--virtual-seconds must be a positive number".into(),
            ));
        }
        let inputs = match &args.inject {
            Some(p) => {
                let text = std::fs::read_to_string(p).map_err(io(p.display().to_string()))?;
                let mut frames = trace::parse_candump(&text)
                    .map_err(|e| CommandError::Usage(format!("{}: {e}", p.display())))?;
                frames.sort_by_key(|(t, _)| *t);
                frames
            }
            None => Vec::new(),
        };
        let mut writer = match &args.trace {
            Some(p) => Some(
                TraceWriter::create(p, &file.bus.channel).map_err(io(p.display().to_string()))?,
            ),
            None => None,
        };
        let mut count = 0u64;
        let mut failed = None;
        runtime::run_virtual(
            &mut cell,
            &inputs,
            Duration::from_secs_f64(seconds),
            &mut |t, f| {
                count += 1;
                if let Some(w) = writer.as_mut() {
                    if let Err(e) = w.write(t, f) {
                        failed.get_or_insert(e);
                    }
                }
            },
        );
        if let Some(w) = writer.as_mut() {
            w.flush().map_err(io("trace"))?;
        }
        if let Some(e) = failed {
            return Err(io("trace")(e));
        }
        out!("virtual run of {seconds} s: {count} frames");
        return Ok(());
    }

    let bus = Bus::new(drivetwin::bus::DEFAULT_CAPACITY);
    let mut tasks = Vec::new();
    if !file.bus.socketcand.is_empty() {
        let listener = tokio::net::TcpListener::bind(&file.bus.socketcand)
            .await
            .map_err(io(format!("socketcand listen on {}", file.bus.socketcand)))?;
        let addr = listener.local_addr().map_err(io("socketcand address"))?;
        out!("socketcand server on {addr}, channel {}", file.bus.channel);
        tasks.push(tokio::spawn(socketcand::serve(
            listener,
            bus.clone(),
            file.bus.channel.clone(),
        )));
    }
    #[cfg(target_os = "linux")]
    if let Some(ifname) = &file.bus.socketcan {
        let socket = drivetwin::socketcan::CanSocket::open(ifname)
            .map_err(io(format!("SocketCAN {ifname}")))?;
        out!("SocketCAN bridge on {ifname}");
        let port = bus.port();
        tasks.push(tokio::spawn(async move {
            if let Err(e) = drivetwin::socketcan::bridge(socket, port).await {
                tracing::error!(error = %e, "SocketCAN bridge stopped");
            }
        }));
    }
    let trace_task = match &args.trace {
        Some(p) => {
            let mut writer =
                TraceWriter::create(p, &file.bus.channel).map_err(io(p.display().to_string()))?;
            out!("tracing to {}", p.display());
            let mut tap = bus.tap();
            Some(tokio::spawn(async move {
                'outer: while let Some(first) = tap.recv().await {
                    // Write what is queued, then flush once the tap runs dry.
                    let mut next = Some(first);
                    while let Some(bf) = next {
                        let t = bf.timestamp.duration_since(UNIX_EPOCH).unwrap_or_default();
                        if let Err(e) = writer.write(t, &bf.frame) {
                            tracing::error!(error = %e, "writing the trace failed");
                            break 'outer;
                        }
                        next = tap.try_recv();
                    }
                    trace::flush_quietly(&mut writer);
                }
                trace::flush_quietly(&mut writer);
            }))
        }
        None => None,
    };
    let shutdown = shutdown_signal();
    out!("running; Ctrl-C stops");
    runtime::run_realtime(cell, bus.clone(), shutdown).await;
    for t in tasks {
        t.abort();
    }
    if let Some(t) = trace_task {
        // Let the tap drain what is queued, then stop it.
        tokio::time::sleep(Duration::from_millis(50)).await;
        t.abort();
        let _ = t.await;
    }
    out!("stopped");
    Ok(())
}

/// Ctrl-C (SIGINT) or SIGTERM: both stop the cell cleanly, flushing the trace.
async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

async fn connect(bus: &BusArgs) -> Result<Link, CommandError> {
    if let Some(ifname) = &bus.can {
        #[cfg(target_os = "linux")]
        return Ok(Link::socketcan(ifname)?);
        #[cfg(not(target_os = "linux"))]
        return Err(CommandError::Usage(format!(
            "--can {ifname}: SocketCAN needs Linux"
        )));
    }
    Ok(Link::socketcand(&bus.socketcand, &bus.channel).await?)
}

fn parse_hex_u16(s: &str, what: &str) -> Result<u16, CommandError> {
    let t = s.trim_start_matches("0x").trim_start_matches("0X");
    u16::from_str_radix(t, 16).map_err(|_| CommandError::Usage(format!("{what} {s:?} is not hex")))
}

fn parse_hex_u8(s: &str, what: &str) -> Result<u8, CommandError> {
    let t = s.trim_start_matches("0x").trim_start_matches("0X");
    u8::from_str_radix(t, 16).map_err(|_| CommandError::Usage(format!("{what} {s:?} is not hex")))
}

fn check_node(node: u8) -> Result<(), CommandError> {
    if (1..=127).contains(&node) {
        Ok(())
    } else {
        Err(CommandError::Usage(format!(
            "node-ID {node} is outside 1…127"
        )))
    }
}

fn resolve_type(
    data_type: Option<&str>,
    device_name: Option<&str>,
    index: u16,
    sub: u8,
) -> Result<Option<DataType>, CommandError> {
    if let Some(t) = data_type {
        return value_text::parse_type(t)
            .map(Some)
            .ok_or_else(|| CommandError::Usage(format!("unknown type {t:?}")));
    }
    if let Some(name) = device_name {
        let desc = device(name)?;
        let e = desc.entry(index, sub).ok_or_else(|| {
            CommandError::Usage(format!("{name} has no entry {index:04X}:{sub:02X}"))
        })?;
        return Ok(Some(e.data_type));
    }
    Ok(None)
}

async fn sdo(cmd: SdoCommand) -> Result<(), CommandError> {
    match cmd {
        SdoCommand::Read {
            node,
            index,
            sub,
            data_type,
            device,
            timeout_ms,
            bus,
        } => {
            check_node(node)?;
            let index = parse_hex_u16(&index, "index")?;
            let sub = parse_hex_u8(&sub, "sub-index")?;
            let ty = resolve_type(data_type.as_deref(), device.as_deref(), index, sub)?;
            let mut link = connect(&bus).await?;
            let result = SdoClient::new(&mut link, node, Duration::from_millis(timeout_ms))
                .upload(index, sub)
                .await;
            let data = match result {
                Ok(d) => d,
                Err(e) => return Err(report_sdo_error(&bus, node, index, sub, e)),
            };
            let ty = ty.or(match data.len() {
                1 => Some(DataType::Unsigned8),
                2 => Some(DataType::Unsigned16),
                4 => Some(DataType::Unsigned32),
                _ => None,
            });
            let value = ty.and_then(|t| value_text::decode(t, &data));
            if bus.json {
                // Numbers stay numbers in JSON; strings and octets stay strings.
                let json_value = match (ty, &value) {
                    (Some(t), Some(v)) if t.is_numeric() => {
                        serde_json::from_str::<serde_json::Value>(v)
                            .unwrap_or_else(|_| serde_json::Value::String(v.clone()))
                    }
                    (_, Some(v)) => serde_json::Value::String(v.clone()),
                    _ => serde_json::Value::Null,
                };
                let j = serde_json::json!({
                    "node": node, "index": format!("0x{index:04X}"), "sub": sub,
                    "data": value_text::hex(&data), "value": json_value,
                });
                out!("{j}");
            } else {
                match value {
                    Some(v) => out!("{v}"),
                    None => out!("{}", value_text::hex(&data)),
                }
            }
            Ok(())
        }
        SdoCommand::Write {
            node,
            index,
            sub,
            value,
            data_type,
            device,
            timeout_ms,
            bus,
        } => {
            check_node(node)?;
            let index = parse_hex_u16(&index, "index")?;
            let sub = parse_hex_u8(&sub, "sub-index")?;
            let ty = resolve_type(data_type.as_deref(), device.as_deref(), index, sub)?
                .ok_or_else(|| {
                    CommandError::Usage(
                        "sdo write needs --type or --device to encode the value".into(),
                    )
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
        if let SdoError::Abort(code) = &e {
            j["abort_code"] = serde_json::json!(format!("0x{:08X}", code.0));
            j["abort_text"] = serde_json::json!(code.description());
        }
        out!("{j}");
    }
    CommandError::Sdo(e)
}

async fn nmt(command: NmtArg, node: u8, bus: BusArgs) -> Result<(), CommandError> {
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

async fn monitor(
    count: Option<u64>,
    seconds: Option<f64>,
    bus: BusArgs,
) -> Result<(), CommandError> {
    let mut link = connect(&bus).await?;
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

async fn pdo(cmd: PdoCommand) -> Result<(), CommandError> {
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

async fn sync(
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

async fn lss(cmd: LssCommand) -> Result<(), CommandError> {
    match cmd {
        LssCommand::Fastscan {
            node,
            timeout_ms,
            bus,
        } => {
            if let Some(n) = node {
                check_node(n)?;
            }
            let mut link = connect(&bus).await?;
            let mut m = LssMaster::new(&mut link, Duration::from_millis(timeout_ms));
            let Some(addr) = m.fast_scan().await? else {
                if bus.json {
                    out!("{}", serde_json::json!({"found": false}));
                } else {
                    out!("no unconfigured node answered");
                }
                return Err(CommandError::Lss(LssError::NoResponse(
                    Duration::from_millis(timeout_ms),
                )));
            };
            if let Some(n) = node {
                m.timeout = Duration::from_millis(timeout_ms.max(200));
                m.configure_node_id(n).await?;
                m.store_configuration().await?;
                m.switch_global(false).await?;
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
            if bus.json {
                out!(
                    "{}",
                    serde_json::json!({"found": true, "vendor_id": addr[0], "product_code": addr[1], "revision": addr[2], "serial": addr[3], "node": node})
                );
            } else {
                out!(
                    "found vendor {:08X} product {:08X} revision {:08X} serial {:08X}{}",
                    addr[0],
                    addr[1],
                    addr[2],
                    addr[3],
                    node.map(|n| format!(", now node {n}")).unwrap_or_default()
                );
            }
            Ok(())
        }
        LssCommand::SetNode {
            node,
            timeout_ms,
            bus,
        } => {
            check_node(node)?;
            let mut link = connect(&bus).await?;
            let mut m = LssMaster::new(&mut link, Duration::from_millis(timeout_ms));
            m.switch_global(true).await?;
            m.configure_node_id(node).await?;
            m.store_configuration().await?;
            m.switch_global(false).await?;
            tokio::time::sleep(Duration::from_millis(50)).await;
            Ok(())
        }
    }
}

async fn scan(timeout_ms: u64, bus: BusArgs) -> Result<(), CommandError> {
    let mut link = connect(&bus).await?;
    // As python-canopen's NodeScanner: read 1000h from every node-ID, collect the answers.
    for node in 1..=127u16 {
        let frame = CanFrame::full(0x600 + node, [0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
        link.send(&frame).await?;
    }
    let deadline = tokio::time::Instant::now() + Duration::from_millis(timeout_ms);
    let mut found = std::collections::BTreeMap::new();
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
            }
        }
    }
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

async fn drive_command(
    node: u8,
    command: DriveCommand,
    wait: bool,
    timeout_ms: u64,
    bus: BusArgs,
) -> Result<(), CommandError> {
    check_node(node)?;
    let timeout = Duration::from_millis(timeout_ms);
    let mut link = connect(&bus).await?;
    let mut c = SdoClient::new(&mut link, node, Duration::from_millis(1000));
    match command {
        DriveCommand::State => {}
        DriveCommand::Enable => cia402::enable(&mut c, timeout).await?,
        DriveCommand::Disable => cia402::disable(&mut c, timeout).await?,
        DriveCommand::Move {
            target,
            relative,
            velocity,
            accel,
            decel,
        } => {
            cia402::move_to(&mut c, target, relative, (velocity, accel, decel), timeout).await?;
        }
        DriveCommand::Velocity { velocity } => {
            cia402::set_mode(&mut c, 3, timeout).await?;
            c.download(0x60FF, 0, &velocity.to_le_bytes())
                .await
                .map_err(Cia402Error::from)?;
        }
        DriveCommand::Torque { torque, slope } => {
            cia402::set_mode(&mut c, 4, timeout).await?;
            if let Some(s) = slope {
                c.download(0x6087, 0, &s.to_le_bytes())
                    .await
                    .map_err(Cia402Error::from)?;
            }
            c.download(0x6071, 0, &torque.to_le_bytes())
                .await
                .map_err(Cia402Error::from)?;
        }
    }
    let moving = !matches!(
        command,
        DriveCommand::State | DriveCommand::Enable | DriveCommand::Disable
    );
    if wait && moving {
        // Target reached in OPERATION ENABLED (bit 10 with the state bits).
        cia402::wait_for(&mut c, "target reached", timeout, |sw| {
            sw & 0x0400 != 0 && sw & 0x6F == 0x27
        })
        .await?;
    }
    let s = cia402::snapshot(&mut c).await.map_err(Cia402Error::from)?;
    if bus.json {
        out!("{}", serde_json::to_string(&s).unwrap_or_default());
    } else {
        out!(
            "{} (statusword {:04X}h) mode {} position {} velocity {} current {}‰ torque {}‰{}{}",
            s.state,
            s.statusword,
            s.mode,
            s.position,
            s.velocity,
            s.current_permille,
            s.torque_permille,
            if s.target_reached {
                ", target reached"
            } else {
                ""
            },
            if s.following_error {
                ", FOLLOWING ERROR"
            } else {
                ""
            }
        );
    }
    Ok(())
}
