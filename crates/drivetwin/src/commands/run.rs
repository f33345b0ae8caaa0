use super::*;
use drivetwin::can::socketcand::ServerConfig;
use drivetwin::cell::bus_rate::BusRate;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::config::{BusSection, Ports};
use drivetwin::cell::stations::StationId;
use drivetwin::cell_loop::{CanBus, CellLoop, EthercatChain, FrontEnds, TerminalPort};
use drivetwin::cosim::FmuLoadError;
use drivetwin::modbus_tcp::cell_drive::ModbusDrive;

pub(crate) fn eds(name: &str, output: Option<PathBuf>) -> Result<(), CommandError> {
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

/// The ESI of the device `name`, or of the generic drive of the EDS / DCF `eds` on EtherCAT
/// (its description there: [`drivetwin::cell::eds_drive::on_ethercat`]).
pub(crate) fn esi(
    name: &str,
    eds: Option<&std::path::Path>,
    output: Option<PathBuf>,
) -> Result<(), CommandError> {
    let desc = match eds {
        Some(path) => {
            let desc = drivetwin::cell::eds_drive::load(path)
                .map_err(|e| CommandError::Usage(e.to_string()))?;
            drivetwin::cell::eds_drive::on_ethercat(desc)
                .map_err(|e| CommandError::Usage(e.to_string()))?
        }
        None => {
            let desc = device(name)?;
            // An ESI describes an EtherCAT slave: a device without one has none to give, and a
            // file that a configurator imported would offer a slave that does not exist.
            if !desc.interfaces.has.contains(&"ethercat") {
                return Err(CommandError::Usage(format!(
                    "{} ({}) has no EtherCAT interface (its interfaces: {}): no ESI to write",
                    desc.name,
                    desc.product_name,
                    desc.interfaces.has.join(", ")
                )));
            }
            desc
        }
    };
    let mut text = String::new();
    drivetwin::export::esi::write_esi(desc, &mut text)
        .map_err(|_| CommandError::Usage("ESI formatting failed".into()))?;
    match output {
        Some(path) => std::fs::write(&path, text).map_err(io(path.display().to_string())),
        None => {
            out_raw!(text);
            Ok(())
        }
    }
}

/// A drive's planned changes: its `[[drive.diagnostic]]` and its plant's (`[drive.thermal]`,
/// `[[drive.plant]]`: ms on the cell's clock, the change).
type Planned = (
    Vec<drivetwin::cell::diagnostics::PlannedDiagnostic>,
    Vec<(u64, drivetwin::cell::control::PhysicsChange)>,
);

/// The cell of the stations that are on CAN, one bus per bus of the cell file (`buses` of
/// them, running at `rates`; the stations in bus order), and for each drive of `specs` (the
/// cell file's, in order) its station (`None`: a CMMO-ST, an EtherCAT-only drive, or its
/// switches keep it off the bus); the stations' planned changes on the cell's timeline.
pub(crate) fn build_cell(
    specs: Vec<DriveSpec>,
    buses: &[BusSection],
    rates: &[BusRate],
    state_dir: Option<&PathBuf>,
) -> Result<(CanCell, Vec<Option<StationId>>), CommandError> {
    // Each bus's stations, in segment order, each with its drive's place among `specs` and
    // its planned changes (`[[drive.diagnostic]]`, `[[drive.plant]]`).
    let mut drives: Vec<Vec<(Station, usize, Planned)>> =
        buses.iter().map(|_| Vec::new()).collect();
    let mut in_cell = Vec::new();
    for mut spec in specs {
        in_cell.push(None);
        if spec.fhpp.is_some() || !spec.canopen {
            // The CMMO-ST runs beside the bus (Modbus TCP); an EtherCAT-only drive is its
            // chain's (`ethercat_chains`).
            continue;
        }
        if !spec.on_can()? {
            out!(
                "drive {} node {}: CANopen deactivated by its switches, silent on the bus",
                spec.desc.name,
                spec.node
            );
            continue;
        }
        // A node set to another rate than the bus's sees only error frames and never sends
        // (ISO 11898-1; CMMP-AS §2.3); only a named `bitrate` can differ from the nodes'.
        if let (Some(rate), Some(bus)) = (&spec.bit_rate, rates.get(spec.bus)) {
            out!(
                "drive {} node {}: {} kbit/s, set by {}",
                spec.desc.name,
                spec.node,
                rate.kbit,
                rate.set_by
            );
            if !bus.carries(rate) {
                out!(
                    "drive {} node {}: its {} kbit/s is not the bus's {bus}, silent on the bus",
                    spec.desc.name,
                    spec.node,
                    rate.kbit
                );
                continue;
            }
        }
        let planned = std::mem::take(&mut spec.diagnostics);
        let physics = std::mem::take(&mut spec.physics);
        let store = state_dir.map(|d| ParamStore::new(d, spec.desc.name, spec.node));
        let bus = spec.bus;
        let Some(on_bus) = drives.get_mut(bus) else {
            continue;
        };
        let shared = spec.ethercat.is_some();
        let settings = spec.settings.map(|mut s| {
            // Served over EtherCAT too: CSP (6060h = 8) exists.
            s.ethercat |= shared;
            s
        });
        let mut drive =
            Station::with_settings(spec.desc, spec.node, store, spec.commissioning, settings)?;
        drive.couple_load(spec.load.as_ref(), spec.node)?;
        if shared {
            drive.serve_coe();
        }
        on_bus.push((drive, in_cell.len() - 1, (planned, physics)));
    }
    let mut cell = CanCell::new();
    for (d, (section, rate)) in drives.into_iter().zip(buses.iter().zip(rates)) {
        let mut stations = Vec::with_capacity(d.len());
        let mut places = Vec::with_capacity(d.len());
        for (station, spec, plans) in d {
            stations.push(station);
            places.push((spec, plans));
        }
        let ids = cell.push_stations(stations);
        for (id, (spec, (diagnostics, physics))) in ids.iter().zip(places) {
            if let Some(slot) = in_cell.get_mut(spec) {
                *slot = Some(*id);
            }
            cell.plan_drive(*id, diagnostics, physics);
        }
        cell.buses
            .push(drivetwin::cell::can_segment::SegmentBus::new(ids));
        let b = cell.buses.len() - 1;
        let Some(segment) = cell.bus_mut(b) else {
            continue;
        };
        if let Some(bitrate) = rate.bitrate() {
            segment.set_bitrate(bitrate, section.late_after());
        }
        for p in &section.disturb {
            segment.plan_disturbance(od::Instant::from_millis(p.at_ms), p.node, p.frames);
        }
    }
    Ok((cell, in_cell))
}

pub(crate) async fn run(args: RunArgs) -> Result<(), CommandError> {
    let mut files = Vec::new();
    for path in &args.config {
        files.push(CellFile::load(path)?);
    }
    if files.is_empty() {
        files.push(match &args.eds {
            Some(eds) => CellFile::single_eds(eds, args.node)?,
            None => CellFile::single(&args.device, args.node.unwrap_or(1)),
        });
    }
    if files.len() > 1
        && (args.virtual_seconds.is_some() || args.modbus_io != crate::cli::ModbusIo::Cell)
    {
        return Err(CommandError::Usage(
            "several --config run several cell loops: not with --virtual-seconds or \
             --modbus-io thread|async"
                .into(),
        ));
    }
    if let Some(b) = args.bitrate {
        for file in &mut files {
            file.set_bitrate(b);
        }
    }
    if let Some(first) = files.first_mut() {
        if let Some(s) = &args.socketcand {
            first.bus.first_mut().socketcand = s.clone();
        }
        if let Some(c) = &args.channel {
            first.bus.first_mut().channel = c.clone();
        }
        if let Some(c) = &args.socketcan {
            first.bus.first_mut().socketcan = Some(c.clone());
        }
        if let Some(j) = &args.socketcand_join {
            first.bus.first_mut().join = Some(j.clone());
        }
    }
    let mut loops = Vec::new();
    let mut fhpp_tasks = Vec::new();
    let mut pcap_writers = Vec::new();
    for (i, file) in files.iter().enumerate() {
        match prepare_cell(file, &args, i == 0).await? {
            Prepared::Done => return Ok(()),
            Prepared::Fhpp(tasks) => fhpp_tasks.extend(tasks),
            Prepared::Loop {
                cell_loop,
                fhpp,
                pcap,
            } => {
                loops.push(cell_loop);
                fhpp_tasks.extend(fhpp);
                pcap_writers.extend(pcap);
            }
        }
    }
    if loops.is_empty() {
        // Only CMMO-STs on threads of their own: no bus, no socketcand server.
        out!("running; Ctrl-C stops");
        for t in fhpp_tasks {
            let _ = t.await;
        }
        out!("stopped");
        return Ok(());
    }
    let _console = match loops.first() {
        Some(l) => web_console(args.http.as_deref(), l.control_handle())?,
        None => None,
    };
    // A scheduling that is asked for and refused is told before the cell says it runs.
    drivetwin::cell::realtime::LoopScheduling {
        rt_priority: args.rt_priority,
        slice: args
            .sched_slice_us
            .map(|us| std::time::Duration::from_micros(u64::from(us))),
    }
    .probe()
    .map_err(|e| CommandError::Usage(e.to_string()))?;
    let mut stops = Vec::new();
    let mut threads = Vec::new();
    let mut lateness = Vec::new();
    for (i, cell_loop) in loops.into_iter().enumerate() {
        stops.push(cell_loop.stop_handle());
        let name = if i == 0 {
            "cell".into()
        } else {
            format!("cell-{i}")
        };
        lateness.push((name.clone(), cell_loop.lateness(), cell_loop.turn_report()));
        threads.push(
            std::thread::Builder::new()
                .name(name)
                .spawn(move || (*cell_loop).run())
                .map_err(io("cell thread"))?,
        );
    }
    // Listening before the line that tells a supervisor the cell runs.
    let stop = shutdown_signal();
    out!("running; Ctrl-C stops");
    let finished = tokio::task::spawn_blocking(move || {
        threads.into_iter().map(|t| t.join()).collect::<Vec<_>>()
    });
    tokio::pin!(finished);
    let stop_all = || stops.iter().for_each(|s| s.stop());
    let results = tokio::select! {
        _ = stop => {
            stop_all();
            finished.await
        }
        done = &mut finished => {
            // One loop ended (failed): the others stop with it.
            stop_all();
            done
        }
    };
    for t in fhpp_tasks {
        let _ = t.await;
    }
    // The taps went with the chains: each writer drains its queue and ends.
    for w in pcap_writers {
        let _ = w.join();
    }
    let failed = |what: &str| CommandError::Io {
        what: "cell loop".into(),
        source: std::io::Error::other(what.to_owned()),
    };
    for result in results.map_err(|e| failed(&e.to_string()))? {
        result.map_err(|_| failed("panicked"))?.map_err(|e| {
            // A load FMU that failed ends the run with its own error.
            match e.get_ref().and_then(|e| e.downcast_ref::<FmuLoadError>()) {
                Some(load) => CommandError::Drive(StationError::Load(load.clone())),
                None => io("cell loop")(e),
            }
        })?;
    }
    for (name, l, turns) in &lateness {
        out!("{name} loop: {}", l.figures());
        out!(
            "{name} turns: {}",
            turns.lock().unwrap_or_else(|e| e.into_inner())
        );
    }
    out!("stopped");
    Ok(())
}

/// One cell made ready to run.
enum Prepared {
    /// A virtual-clock run, finished.
    Done,
    /// Only CMMO-STs on threads of their own (`--modbus-io thread|async`).
    Fhpp(Vec<tokio::task::JoinHandle<()>>),
    Loop {
        cell_loop: Box<CellLoop>,
        fhpp: Vec<tokio::task::JoinHandle<()>>,
        pcap: Vec<std::thread::JoinHandle<()>>,
    },
}

/// Builds the cell of `file` with every socket bound; `first`: the command line's per-cell
/// options (`--ci-terminal`, `--trace`, `--ethercat`) are its.
async fn prepare_cell(
    file: &CellFile,
    args: &RunArgs,
    first: bool,
) -> Result<Prepared, CommandError> {
    let mut specs = file.drives(drivetwin::vendors::VENDORS.runtime)?;
    // `--ethercat IF`: the chain of the drives that name none, or of every drive of a cell
    // file that names no interfaces (as the cell FMU resolves them).
    let ethercat_if = args.ethercat.as_deref().filter(|_| first);
    drivetwin::cell::interfaces::resolve_ethercat_chains(file, &mut specs, ethercat_if)
        .map_err(|e| CommandError::Usage(e.to_string()))?;
    let any_ethercat = specs.iter().any(|s| s.ethercat.is_some());
    let ci_terminal = args.ci_terminal.as_deref().filter(|_| first);
    let trace_path = args.trace.as_ref().filter(|_| first);
    if ci_terminal.is_some() && specs.first().is_some_and(|s| s.fhpp.is_some()) {
        return Err(CommandError::Usage(
            "--ci-terminal is the CMMP-AS debug console; the CMMO-ST has none".into(),
        ));
    }
    // Refused before anything opens: the console writes without authentication.
    for addr in ci_terminal
        .iter()
        .copied()
        .chain(specs.iter().filter_map(|s| s.ports.ci_terminal.as_deref()))
    {
        ci_console::check_address(addr).map_err(|e| CommandError::Usage(e.to_string()))?;
    }
    // The CMMO-ST has Modbus TCP, no CANopen and no EtherCAT: it runs beside the bus.
    let fhpp_drives = specs.iter().filter(|s| s.fhpp.is_some()).count();
    let any_fhpp = fhpp_drives > 0;
    if any_fhpp && args.virtual_seconds.is_some() {
        return Err(CommandError::Usage(
            "--virtual-seconds runs CANopen drives; the CMMO-ST runs on the real clock".into(),
        ));
    }
    if args.busy_poll && !any_ethercat && !any_fhpp {
        return Err(CommandError::Usage(
            "--busy-poll applies to EtherCAT chains and to the CMMO-ST's Modbus server".into(),
        ));
    }
    if any_ethercat && args.virtual_seconds.is_some() {
        return Err(CommandError::Usage(
            "--virtual-seconds runs CANopen drives; EtherCAT chains run on the real clock".into(),
        ));
    }
    let in_loop = args.modbus_io == crate::cli::ModbusIo::Cell;
    let fhpp_tasks = if in_loop {
        Vec::new()
    } else {
        start_fhpp_drives(&specs, args).await?
    };
    if fhpp_drives == specs.len() && !in_loop {
        return Ok(Prepared::Fhpp(fhpp_tasks));
    }
    let modbus = if in_loop {
        cell_modbus_drives(&specs, args)?
    } else {
        Vec::new()
    };
    let buses = file.bus.all().to_vec();
    let chain_specs: Vec<(usize, DriveSpec)> = specs
        .iter()
        .enumerate()
        .filter(|(_, s)| s.ethercat.is_some())
        .map(|(i, s)| (i, s.clone()))
        .collect();
    // `[[drive.diagnostic]]` / `[[drive.plant]]` of the drives outside the CAN segments.
    let outside = drivetwin::cell::planned::outside_plans(&specs, in_loop);
    // A rate object the node saved wins over the cell file's, as at power-on.
    if let Some(dir) = &args.state_dir {
        for spec in specs.iter_mut().filter(|s| s.rate_object.is_some()) {
            let store = ParamStore::new(dir, spec.desc.name, spec.node);
            let stored = store.load().map_err(StationError::from)?;
            spec.load_stored_rate(&stored, store.path());
        }
    }
    let rates = file.bus_rates(&specs)?;
    // Each drive's CI terminal and serial ports, as its section names them.
    let ports: Vec<Ports> = specs.iter().map(|s| s.ports.clone()).collect();
    let (cell, in_cell) = build_cell(specs, &buses, &rates, args.state_dir.as_ref())?;
    for d in cell.stations.iter() {
        out!(
            "drive {} node {} ({})",
            d.od().description().name,
            d.node_id(),
            d.od().description().product_name
        );
    }
    for (section, rate) in buses.iter().zip(&rates) {
        out!("bus {}: {rate}", section.label());
    }

    if let Some(seconds) = args.virtual_seconds {
        let mut cell = cell;
        if cell.buses.len() != 1 {
            return Err(CommandError::Usage(
                "--virtual-seconds runs a cell of one CAN bus".into(),
            ));
        }
        let channel = buses.first().map_or("vcan0", |b| b.channel.as_str());
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
        let mut writer = match trace_path {
            Some(p) => Some(
                TraceWriter::create_for_bus(
                    p,
                    channel,
                    cell.bus(0).and_then(|b| b.timed_bitrate()),
                )
                .map_err(io(p.display().to_string()))?,
            ),
            None => None,
        };
        let mut count = 0u64;
        let mut failed = None;
        virtual_clock::run_virtual(
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
        if let Some(e) = cell.load_failure() {
            return Err(StationError::Load(e.clone()).into());
        }
        out!("virtual run of {seconds} s: {count} frames");
        return Ok(Prepared::Done);
    }

    let (ethercat, pcap_writers) = ethercat_chains(
        chain_specs,
        &in_cell,
        &cell,
        args,
        ethercat_if,
        trace_path.map(|p| p.as_path()),
        cell.stations.is_empty(),
    )?;
    let serial = serial_lines(&ports, &in_cell, args, first, &cell)?;
    let mut front = FrontEnds {
        modbus,
        ethercat,
        serial,
        rt_priority: args.rt_priority,
        sched_slice: args
            .sched_slice_us
            .map(|us| std::time::Duration::from_micros(u64::from(us))),
        busy_poll: args.busy_poll,
        views: drivetwin::vendors::VENDORS.runtime.views,
        plans: outside,
        line_plans: file.ethercat_line.clone(),
        ..FrontEnds::default()
    };
    for (b, (section, rate)) in buses.iter().zip(&rates).enumerate() {
        let mut bus = CanBus::default();
        let has_drives = cell.bus(b).is_some_and(|s| !s.members().is_empty());
        // A bus without drives (a cell of CMMO-STs only) has no socketcand server.
        if has_drives && !section.socketcand.is_empty() {
            let listener = std::net::TcpListener::bind(&section.socketcand)
                .map_err(io(format!("socketcand listen on {}", section.socketcand)))?;
            let addr = listener.local_addr().map_err(io("socketcand address"))?;
            out!("socketcand server on {addr}, channel {}", section.channel);
            let mut config = ServerConfig::new(section.channel.clone());
            if let Some(max) = section.max_clients {
                config.max_clients = max;
            }
            bus.socketcand = Some((listener, config));
        }
        if let Some(ifname) = &section.socketcan {
            if let Some(why) = drivetwin::sys::platform::socketcan_missing() {
                return Err(CommandError::Usage(format!("SocketCAN {ifname}: {why}")));
            }
            let socket = drivetwin::can::socketcan::RawCanSocket::open(ifname)
                .map_err(io(format!("SocketCAN {ifname}")))?;
            out!("SocketCAN bridge on {ifname}");
            bus.socketcan = Some(socket);
        }
        if let Some(addr) = &section.join {
            let stream = drivetwin::can::socketcand::join::join(addr, &section.channel)
                .map_err(|e| CommandError::Usage(e.to_string()))?;
            out!(
                "joined socketcand server {addr}, channel {}",
                section.channel
            );
            bus.upstream = Some(stream);
        }
        // `--trace` records the first bus (unless it is an EtherCAT chain's pcap); `trace` on a
        // `[[bus]]` its bus.
        let first_bus_trace = trace_path.filter(|_| b == 0 && pcap_writers.is_empty());
        if let Some(p) = section.trace.as_ref().or(first_bus_trace) {
            let writer = TraceWriter::create_for_bus(p, &section.channel, rate.bitrate())
                .map_err(io(p.display().to_string()))?;
            out!("tracing to {}", p.display());
            bus.trace = Some(writer);
        }
        front.buses.push(bus);
    }
    front.ci_terminals = ci_consoles(&ports, &in_cell, ci_terminal)?;
    let cell_loop = CellLoop::new(cell, front).map_err(io("cell loop"))?;
    if fhpp_drives > 0 && !in_loop && specs_had_fhpp_plans(file) {
        tracing::warn!(
            "planned changes of a CMMO-ST run with --modbus-io cell only (the cell loop carries \
             them out on its clock; its own thread has none)"
        );
    }
    Ok(Prepared::Loop {
        cell_loop: Box::new(cell_loop),
        fhpp: fhpp_tasks,
        pcap: pcap_writers,
    })
}

/// Whether an FHPP drive of `file` (the CMMO-ST) plans a diagnostic message or a plant change.
fn specs_had_fhpp_plans(file: &CellFile) -> bool {
    file.drive.iter().any(|d| {
        devices::by_name(&d.device).is_some_and(drivetwin::cell::device_model::is_fhpp)
            && (!d.diagnostic.is_empty() || !d.plant.is_empty() || d.thermal.is_some())
    })
}

/// The web console of a cell loop (`--http`), on a thread of its own.
fn web_console(
    http: Option<&str>,
    handle: drivetwin::cell::control::ControlHandle,
) -> Result<Option<drivetwin::web::WebConsole>, CommandError> {
    use drivetwin::web::{self, HttpSetting};
    let console = web::start(
        &HttpSetting::parse(http),
        handle,
        drivetwin::vendors::VENDORS.web_pages,
    )
    .map_err(|e| CommandError::Usage(e.to_string()))?;
    if let Some(c) = &console {
        match &c.token {
            None => out!("web console on http://{}/", c.addr),
            Some(t) => {
                out!("web console on http://{}/?token={t}", c.addr);
                out!(
                    "web console token: {t} (header {})",
                    web::auth::TOKEN_HEADER
                );
            }
        }
    }
    Ok(console)
}

/// The CI terminals the cell file (or `--ci-terminal`, for the first drive) asks for, each a
/// listener and the index of its drive in the cell; the cell loop answers their lines.
fn ci_consoles(
    ports: &[Ports],
    in_cell: &[Option<StationId>],
    first: Option<&str>,
) -> Result<Vec<TerminalPort>, CommandError> {
    let mut consoles = Vec::new();
    for (i, d) in ports.iter().enumerate() {
        let cli = if i == 0 { first } else { None };
        let Some(addr) = cli.or(d.ci_terminal.as_deref()) else {
            continue;
        };
        // The console is the drive's own RS232, but a drive the switches keep off the bus is
        // not simulated at all here.
        let Some(Some(drive)) = in_cell.get(i).copied() else {
            tracing::warn!(
                drive = i + 1,
                "no CI terminal: the drive is not in the cell"
            );
            continue;
        };
        let listener = ci_console::bind(addr).map_err(|e| CommandError::Usage(e.to_string()))?;
        let local = listener.local_addr().map_err(io("CI terminal address"))?;
        out!("CI terminal of drive {} on {local}", i + 1);
        consoles.push(TerminalPort {
            listener,
            drive,
            terminal: drivetwin::vendors::VENDORS.runtime.ci_terminal,
        });
    }
    Ok(consoles)
}

/// The serial lines the cell file (or `--rs232` / `--rs485`, for the first drive) asks for,
/// opened: links to the twin's ptys, or real devices.
fn serial_lines(
    ports: &[Ports],
    in_cell: &[Option<StationId>],
    args: &RunArgs,
    first_cell: bool,
    cell: &CanCell,
) -> Result<Vec<drivetwin::serial::line::SerialLine>, CommandError> {
    use drivetwin::serial::{Kind, LineRequest};
    let mut requests = Vec::new();
    for (i, d) in ports.iter().enumerate() {
        // The command line's ports are the first drive's of the first cell.
        let first = |p: &Option<PathBuf>| {
            if i == 0 && first_cell {
                p.clone()
            } else {
                None
            }
        };
        for (kind, path) in [
            (
                Kind::Rs232,
                first(&args.rs232).or(d.rs232.as_ref().map(PathBuf::from)),
            ),
            (
                Kind::Rs485,
                first(&args.rs485).or(d.rs485.as_ref().map(PathBuf::from)),
            ),
        ] {
            let Some(path) = path else {
                continue;
            };
            let Some(Some(drive)) = in_cell.get(i).copied() else {
                tracing::warn!(
                    drive = i + 1,
                    "no {} port: the drive is not in the cell",
                    kind.as_str()
                );
                continue;
            };
            requests.push(LineRequest { kind, path, drive });
        }
    }
    let lines = (drivetwin::vendors::VENDORS.serial_lines.open_lines)(&requests, cell)
        .map_err(|e| CommandError::Usage(e.to_string()))?;
    for l in &lines {
        match l.port().pty_name() {
            Some(pty) => out!(
                "{} line on {} (pty {})",
                l.kind().as_str().to_uppercase(),
                l.path().display(),
                pty.display()
            ),
            None => out!(
                "{} line on device {}",
                l.kind().as_str().to_uppercase(),
                l.path().display()
            ),
        }
    }
    Ok(lines)
}

/// The cell's CMMO-STs for the cell loop, each with its Modbus listener bound.
fn cell_modbus_drives(
    specs: &[DriveSpec],
    args: &RunArgs,
) -> Result<Vec<ModbusDrive>, CommandError> {
    let mut drives = Vec::new();
    for (spec, fhpp, addr) in fhpp_addresses(specs, args)? {
        let dev = modbus_device(spec, args)?;
        let listener =
            std::net::TcpListener::bind(addr).map_err(io(format!("Modbus listen on {addr}")))?;
        let local = listener.local_addr().map_err(io("Modbus address"))?;
        out!("modbus server on {local}");
        let config = modbus_config(fhpp, args);
        drives.push(ModbusDrive::new(listener, dev, config));
    }
    Ok(drives)
}

/// The cell's CMMO-STs, each with the address its Modbus TCP server listens on: `--modbus`
/// (allowed for one CMMO-ST only), else the drive's `modbus` key, else the default.
fn fhpp_addresses<'a>(
    specs: &'a [DriveSpec],
    args: &'a RunArgs,
) -> Result<Vec<(&'a DriveSpec, &'a FhppSpec, &'a str)>, CommandError> {
    use drivetwin::modbus_tcp::server::DEFAULT_ADDR;
    let fhpp: Vec<_> = specs
        .iter()
        .filter_map(|spec| Some((spec, spec.fhpp.as_ref()?)))
        .collect();
    if args.modbus.is_some() && fhpp.len() > 1 {
        return Err(CommandError::Usage(
            "--modbus: the cell has several CMMO-STs; give each its `modbus` address in the \
             cell file"
                .into(),
        ));
    }
    Ok(fhpp
        .into_iter()
        .map(|(spec, fhpp)| {
            let addr = args
                .modbus
                .as_deref()
                .or(fhpp.modbus.as_deref())
                .unwrap_or(DEFAULT_ADDR);
            (spec, fhpp, addr)
        })
        .collect())
}

/// The cell's EtherCAT chains, one per network interface in order of first mention, each
/// with its slaves in cell-file order, and the pcap writers of `--trace` (the first chain's,
/// when the path is not a candump `.log` or the cell has no CAN drive).
fn ethercat_chains(
    specs: Vec<(usize, DriveSpec)>,
    in_cell: &[Option<StationId>],
    cell: &CanCell,
    args: &RunArgs,
    ethercat_if: Option<&str>,
    trace_path: Option<&std::path::Path>,
    no_can: bool,
) -> Result<(Vec<EthercatChain>, Vec<std::thread::JoinHandle<()>>), CommandError> {
    use drivetwin::ecat::chain::{own_drive, SlaveChain, SlaveDrive};
    let mut chains: Vec<(String, SlaveChain)> = Vec::new();
    for (i, mut spec) in specs {
        let Some(chain) = spec.ethercat.clone() else {
            continue;
        };
        if !spec.canopen {
            // A drive from an EDS has a description of its own there.
            spec.desc = drivetwin::cell::eds_drive::on_ethercat(spec.desc)
                .map_err(|e| CommandError::Usage(e.to_string()))?;
        }
        let Some(ifname) = chain.or_else(|| ethercat_if.map(str::to_owned)) else {
            return Err(CommandError::Usage(format!(
                "drive {} (node {}): \"ethercat\" in its interfaces needs a chain: \
                 `ethercat = \"IFNAME\"` in the cell file or --ethercat IFNAME",
                i + 1,
                spec.node
            )));
        };
        if let Some(why) = drivetwin::sys::platform::raw_ethernet_missing() {
            return Err(CommandError::Usage(format!("EtherCAT on {ifname}: {why}")));
        }
        let desc = spec.desc;
        let drive = if spec.canopen {
            match in_cell.get(i).copied().flatten() {
                Some(id) => SlaveDrive::Station {
                    id,
                    bus: cell.bus_of(id),
                },
                None => {
                    return Err(CommandError::Usage(format!(
                        "drive {} (node {}): on CANopen and EtherCAT, but its switches keep \
                         it off the bus",
                        i + 1,
                        spec.node
                    )))
                }
            }
        } else {
            own_drive(spec, args.state_dir.as_deref())
                .map_err(|e| CommandError::Usage(e.to_string()))?
        };
        let at = match chains.iter().position(|(n, _)| *n == ifname) {
            Some(at) => at,
            None => {
                chains.push((ifname, SlaveChain::empty()));
                chains.len() - 1
            }
        };
        if let Some((_, c)) = chains.get_mut(at) {
            c.push(desc, drive)
                .map_err(|e| CommandError::Usage(e.to_string()))?;
        }
    }
    let mut out_chains = Vec::new();
    let mut writers = Vec::new();
    for (n, (ifname, cell)) in chains.into_iter().enumerate() {
        for i in 0..cell.len() {
            let Some(desc) = cell.device(i).map(|d| d.description()) else {
                continue;
            };
            out!(
                "slave {} {} ({}), vendor {:#x} product {:#010x} revision {:#x}",
                i + 1,
                desc.name,
                desc.product_name,
                desc.vendor_id,
                desc.product_code,
                desc.revision
            );
        }
        let socket = drivetwin::ecat::link::SlaveSocket::open(&ifname)
            .map_err(io(format!("EtherCAT on {ifname}")))?;
        out!("EtherCAT on {ifname}: {} slave(s)", cell.len());
        let mut trace = None;
        if let (0, Some(path)) = (n, trace_path) {
            if no_can || path.extension().is_none_or(|e| e != "log") {
                let (tap, writer) = ethercat_trace(path)?;
                out!("tracing to {}", path.display());
                trace = Some(tap);
                writers.push(writer);
            }
        }
        out_chains.push(EthercatChain {
            chain: cell,
            socket,
            trace,
        });
    }
    Ok((out_chains, writers))
}

/// The `--trace` writer of an EtherCAT run: a pcap of Ethernet frames (tshark decodes
/// EtherCAT and CoE from it), written on its own thread so the frame loop never waits on the
/// disk.
fn ethercat_trace(
    path: &std::path::Path,
) -> Result<
    (
        drivetwin::ecat::chain::FrameTap,
        std::thread::JoinHandle<()>,
    ),
    CommandError,
> {
    use drivetwin::trace::pcap::PcapWriter;
    if path.extension().is_some_and(|e| e == "log") {
        return Err(CommandError::Usage(format!(
            "--trace {}: an EtherCAT trace is a pcap file (candump .log is for CAN)",
            path.display()
        )));
    }
    let file = std::fs::File::create(path).map_err(io(path.display().to_string()))?;
    let mut pcap = PcapWriter::ethernet(std::io::BufWriter::new(file))
        .map_err(io(path.display().to_string()))?;
    let (tap, rx) = std::sync::mpsc::sync_channel::<drivetwin::ecat::chain::TracedFrame>(4096);
    let writer = std::thread::spawn(move || {
        while let Ok(first) = rx.recv() {
            let mut next = Some(first);
            while let Some(f) = next {
                let t = f.at.duration_since(UNIX_EPOCH).unwrap_or_default();
                if let Err(e) = pcap.write_packet_at(t, &f.frame) {
                    tracing::error!(error = %e, "writing the trace failed");
                    return;
                }
                next = rx.try_recv().ok();
            }
            if let Err(e) = pcap.flush() {
                tracing::error!(error = %e, "writing the trace failed");
                return;
            }
        }
    });
    Ok((tap, writer))
}

/// Starts the cell's CMMO-STs (FHPP over Modbus TCP), each on its own thread with its own
/// server, stopped by the shutdown signal; their tasks end when they have stopped.
async fn start_fhpp_drives(
    specs: &[DriveSpec],
    args: &RunArgs,
) -> Result<Vec<tokio::task::JoinHandle<()>>, CommandError> {
    let mut tasks = Vec::new();
    for (spec, fhpp, addr) in fhpp_addresses(specs, args)? {
        let (listener, dev, options) = prepare_modbus_device(spec, fhpp, addr, args).await?;
        tasks.push(tokio::spawn(device_thread::run(
            listener,
            dev,
            options,
            shutdown_signal(),
        )));
    }
    Ok(tasks)
}

/// One CMMO-ST at power-on: defaults, the cell's commissioning values, then its permanent
/// memory (`--state-dir`).
fn modbus_device(
    spec: &DriveSpec,
    args: &RunArgs,
) -> Result<Box<dyn drivetwin::cell::modbus_device::ModbusDevice>, CommandError> {
    let desc = spec.desc;
    let store = args
        .state_dir
        .as_ref()
        .map(|dir| ParamStore::new(dir, desc.name, spec.node));
    let path = store.as_ref().map(|s| s.memory_path().to_path_buf());
    let powered = (drivetwin::vendors::VENDORS.runtime.modbus_device)(spec, store)
        .ok_or_else(|| {
            CommandError::Usage(format!("drive {}: not served over Modbus TCP", desc.name))
        })?
        .map_err(|e| CommandError::Usage(e.to_string()))?;
    out!("drive {} ({})", desc.name, desc.product_name);
    if let Some(path) = path {
        match powered.memory_error {
            None => out!("permanent memory in {}", path.display()),
            Some(e) => tracing::warn!("{e}"),
        }
    }
    Ok(powered.device)
}

fn modbus_config(fhpp: &FhppSpec, args: &RunArgs) -> drivetwin::modbus_tcp::server::ModbusConfig {
    use drivetwin::modbus_tcp::server::ModbusConfig;
    ModbusConfig {
        busy_poll: args.busy_poll,
        ..ModbusConfig::with_watchdog_ms(fhpp.watchdog_ms.unwrap_or(args.modbus_timeout_ms))
    }
}

/// One CMMO-ST at power-on: defaults, the cell's commissioning values, then its permanent
/// memory (`--state-dir`), and its Modbus listener bound.
async fn prepare_modbus_device(
    spec: &DriveSpec,
    fhpp: &FhppSpec,
    addr: &str,
    args: &RunArgs,
) -> Result<
    (
        tokio::net::TcpListener,
        Box<dyn drivetwin::cell::modbus_device::ModbusDevice>,
        device_thread::ServeOptions,
    ),
    CommandError,
> {
    let dev = modbus_device(spec, args)?;
    let listener = tokio::net::TcpListener::bind(addr)
        .await
        .map_err(io(format!("Modbus listen on {addr}")))?;
    let local = listener.local_addr().map_err(io("Modbus address"))?;
    out!("modbus server on {local}");
    let config = modbus_config(fhpp, args);
    let io = match args.modbus_io {
        crate::cli::ModbusIo::Async => device_thread::ServerIo::Async,
        crate::cli::ModbusIo::Thread | crate::cli::ModbusIo::Cell => {
            device_thread::ServerIo::CycleThread
        }
    };
    let options = device_thread::ServeOptions { config, io };
    Ok((listener, dev, options))
}
