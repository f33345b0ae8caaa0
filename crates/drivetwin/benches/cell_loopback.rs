//! The cell loop's latency against the kernel's floor, in one run.
//!
//! One plain blocking client (std `TcpStream`, `TCP_NODELAY`, blocking `read`) measures
//! sequential round trips against four servers, in interleaved rounds:
//!
//! - `floor socketcand`: a thread that blocks in `read` and answers every request at once
//!   with a fixed socketcand frame, no device (the lowest a sleeping server gets);
//! - `twin socketcand`: the cell loop ([`drivetwin::cell_loop`]) with a CMMP-AS, node 1,
//!   answering an expedited SDO upload of 1000h (`< send 601 8 40 00 10 00 … >` →
//!   `< frame 581 … 43 00 10 00 … >`) after the socketcand handshake;
//! - `floor modbus`: the same blocking thread answering a Modbus FC 17h request with a fixed
//!   17-byte response;
//! - `twin modbus`: the same cell loop's CMMO-ST answering FC 17h (read 4 registers at 0,
//!   write 4 at 0: the FHPP cyclic telegram).
//!
//! The twin's two drives are one cell on one loop and one clock: its CMMP-AS steps while the
//! CMMO-ST cycles every millisecond. Its CAN bus is the instant bus (a [`CanCell`] bus without a bit
//! rate, as `bitrate = "instant"` in a cell file): frames cross at once, so the figures are the
//! loop's and the kernel's, not a bus's bit time (about 2 ms a round trip at the default
//! cell's 125 kbit/s).
//!
//! Last, the realistic bus: the same SDO upload against a CMMP-AS alone on a bus at the default
//! cell's 125 kbit/s (`CELL_BENCH_BITRATE` another), client and loop on CPU 0,
//! `CELL_BENCH_BUS_COUNT` round trips (default 2000). It prints the p50 beside what the bus
//! alone costs: the request's and the answer's bit time (`canbus::frame_time`), plus the
//! drive's answer time, none (the answer leaves as the request has crossed; docs/decisions.md),
//! and the ratio (target: within 5 %).
//!
//! Two placements: `same CPU` (client and every server thread pinned to CPU 0; a round trip is
//! two context switches on one CPU) and `split CPUs` (servers on CPU 0, client on CPU 1: two
//! cross-CPU wake-ups). Pinning is `sched_setaffinity` on each thread. It prints p50 / p99 per
//! server and placement and the ratio of each twin path to its floor (target: p50 ≤ 1.2×).
//!
//! `cargo bench -p drivetwin --bench cell_loopback`; `CELL_BENCH_COUNT` sets the round trips
//! per server and placement (default 20000), `CELL_BENCH_ROUNDS` the interleaved rounds (default:
//! enough that a round sends at most 800 requests). A socketcand client may send no faster than
//! its bus carries frames after a burst of 1024 (`can::frame_budget`; an untimed bus counts as
//! 1 Mbit/s, about 21 000 frames/s), and a blocking client at 15 µs a round trip is three times
//! that: a round that fits the burst, with the other servers' rounds between, keeps every
//! request on the bus (longer rounds lose requests, as a flooding master would).
//!
//! It draws the figures into `docs/round-trip-latency.png` (`CELL_BENCH_PLOT` another path):
//! p50 and p99 of each path, floor beside twin, per placement. The machine the figures in
//! `docs/cell.md` come from is shared: a run measures the neighbours' load too.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use drivetwin::can::socketcand::ServerConfig;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::station::Station;
use drivetwin::cell_loop::{CanBus, CellLoop, FrontEnds, StopHandle};
use drivetwin::modbus_tcp::cell_drive::ModbusDrive;
use drivetwin::modbus_tcp::server::ModbusConfig;
use drivetwin::vendors::festo_cmmo_st::modbus_server::FhppModbus;

#[path = "../../drive/benches/support/mod.rs"]
mod support;

const WARM_UP: usize = 500;
/// Requests per server and round: within the socketcand client's burst of 1024 frames.
const MAX_PER_ROUND: usize = 800;
/// Longer than any round trip of a loaded machine: an answer not there by then is lost.
const READ_TIMEOUT: Duration = Duration::from_secs(5);
const SDO_UPLOAD_1000: &[u8] = b"< send 601 8 40 00 10 00 00 00 00 00 >";
const FLOOR_FRAME: &[u8] = b"< frame 581 1764000000.000000 4300100092010200 >";
/// FC 17h: read 4 registers at 0, write 4 registers at 0 (8 data bytes), unit 1.
const FC17_REQUEST: &[u8] = &[
    0, 1, 0, 0, 0, 19, 1, 0x17, 0, 0, 0, 4, 0, 0, 0, 4, 8, 0, 0, 0, 0, 0, 0, 0, 0,
];
const FC17_RESPONSE_LEN: usize = 17;

fn pin(cpu: usize) {
    if let Err(e) = platform::sched::pin(0, cpu) {
        eprintln!("cannot pin to CPU {cpu}: {e}");
    }
}

/// A blocking server thread on CPU `cpu` that answers each read with `reply`, at once.
fn floor(cpu: usize, reply: &'static [u8]) -> io::Result<SocketAddr> {
    let listener = TcpListener::bind("127.0.0.1:0")?;
    let addr = listener.local_addr()?;
    std::thread::spawn(move || {
        pin(cpu);
        for stream in listener.incoming() {
            let Ok(mut s) = stream else { continue };
            let _ = s.set_nodelay(true);
            std::thread::spawn(move || {
                pin(cpu);
                let mut buf = [0u8; 512];
                while let Ok(n) = s.read(&mut buf) {
                    if n == 0 || s.write_all(reply).is_err() {
                        break;
                    }
                }
            });
        }
    });
    Ok(addr)
}

/// The cell loop of `cell` and `front` on a thread of its own, pinned to CPU `cpu`.
fn spawn_loop(cell: CanCell, front: FrontEnds, cpu: usize) -> Result<StopHandle, String> {
    let cell_loop = CellLoop::new(cell, front).map_err(|e| e.to_string())?;
    let stop = cell_loop.stop_handle();
    std::thread::Builder::new()
        .name("cell".into())
        .spawn(move || {
            pin(cpu);
            if let Err(e) = cell_loop.run() {
                eprintln!("cell loop: {e}");
            }
        })
        .map_err(|e| e.to_string())?;
    Ok(stop)
}

/// A CMMP-AS alone on a bus at `bitrate` bit/s, served by socketcand from a cell loop on CPU
/// `cpu`.
fn twin_on_bus(cpu: usize, bitrate: u32) -> Result<(SocketAddr, StopHandle), String> {
    let cmmp = devices::by_name("cmmp-as").ok_or("no cmmp-as")?;
    let drive = Station::with_settings(cmmp, 1, None, vec![], Some(Default::default()))
        .map_err(|e| e.to_string())?;
    let listener = TcpListener::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    let addr = listener.local_addr().map_err(|e| e.to_string())?;
    let cell = CanCell::one_timed_bus(vec![drive], bitrate, Duration::from_millis(10));
    let front = FrontEnds {
        buses: vec![CanBus {
            socketcand: Some((listener, ServerConfig::new("vcan0"))),
            ..CanBus::default()
        }],
        ..FrontEnds::default()
    };
    let stop = spawn_loop(cell, front, cpu)?;
    Ok((addr, stop))
}

/// The SDO upload of 1000h on the realistic bus against the bit time of its two frames.
fn realistic_bus() -> Result<(), String> {
    let bitrate = env_usize("CELL_BENCH_BITRATE", 125_000) as u32;
    let count = env_usize("CELL_BENCH_BUS_COUNT", 2000);
    let (addr, stop) = twin_on_bus(0, bitrate)?;
    pin(0);
    let mut client = CanClient::connect(addr, true).map_err(|e| e.to_string())?;
    let mut samples = Vec::with_capacity(count);
    for i in 0..WARM_UP / 10 + count {
        let t = Instant::now();
        client
            .round_trip()
            .map_err(|e| format!("realistic bus: {e}"))?;
        if i >= WARM_UP / 10 {
            samples.push(t.elapsed());
        }
    }
    stop.stop();
    samples.sort_unstable();
    let bus = canbus::timed_bus::TimedBus::<1>::new(bitrate);
    let frame =
        |id: u16, data: &[u8]| canopen::CanFrame::new(id, data).map_err(|e| format!("{e:?}"));
    let request = frame(0x601, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0])?;
    let answer = frame(0x581, &[0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00])?;
    // CMMP-AS: the answer leaves as soon as the request has crossed (docs/decisions.md).
    let answer_time = Duration::ZERO;
    let bits = Duration::from_nanos(bus.frame_nanos(&request) + bus.frame_nanos(&answer));
    let p50 = percentile(&samples, 0.5);
    let p99 = percentile(&samples, 0.99);
    println!(
        "\nrealistic bus at {} kbit/s (client and loop on CPU 0), {count} SDO uploads of 1000h:",
        bitrate / 1000
    );
    println!(
        "  twin socketcand    p50 {:>8.2} us  p99 {:>8.2} us",
        p50.as_secs_f64() * 1e6,
        p99.as_secs_f64() * 1e6
    );
    println!(
        "  bit time of both frames {:.2} us + the drive's answer time {:.2} us: {:.3}x",
        bits.as_secs_f64() * 1e6,
        answer_time.as_secs_f64() * 1e6,
        p50.as_secs_f64() / (bits + answer_time).as_secs_f64().max(1e-9)
    );
    Ok(())
}

/// The twin: one cell loop with a CMMP-AS on socketcand and a CMMO-ST on Modbus TCP.
fn twin(cpu: usize) -> Result<(SocketAddr, SocketAddr, StopHandle), String> {
    let cmmp = devices::by_name("cmmp-as").ok_or("no cmmp-as")?;
    let drive = Station::with_settings(cmmp, 1, None, vec![], Some(Default::default()))
        .map_err(|e| e.to_string())?;
    let cmmo = devices::by_name("cmmo-st").ok_or("no cmmo-st")?;
    let od = od::ObjectDictionary::new(cmmo, 1, vec![0u8; cmmo.storage_size])
        .map_err(|_| "CMMO-ST storage")?;
    let dev = drive::vendors::festo_cmmo_st::device::FhppDevice::new(od, Default::default());
    let can_listener = TcpListener::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    let can_addr = can_listener.local_addr().map_err(|e| e.to_string())?;
    let mb_listener = TcpListener::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    let mb_addr = mb_listener.local_addr().map_err(|e| e.to_string())?;
    let front = FrontEnds {
        buses: vec![CanBus {
            socketcand: Some((can_listener, ServerConfig::new("vcan0"))),
            ..CanBus::default()
        }],
        modbus: vec![ModbusDrive::new(
            mb_listener,
            Box::new(FhppModbus::new(dev, None)),
            ModbusConfig::default(),
        )],
        ..FrontEnds::default()
    };
    // The instant bus: no bit rate.
    let stop = spawn_loop(CanCell::one_bus(vec![drive]), front, cpu)?;
    Ok((can_addr, mb_addr, stop))
}

/// A client of one server: one request, its answer, timed.
trait Client {
    fn round_trip(&mut self) -> io::Result<()>;
}

/// socketcand: reads until a `< frame 581 … >` has come.
struct CanClient {
    s: TcpStream,
    buf: Vec<u8>,
}

impl CanClient {
    fn connect(addr: SocketAddr, handshake: bool) -> io::Result<CanClient> {
        let s = TcpStream::connect(addr)?;
        s.set_nodelay(true)?;
        // A lost answer ends the run with an error instead of a hang.
        s.set_read_timeout(Some(READ_TIMEOUT))?;
        let mut c = CanClient {
            s,
            buf: Vec::with_capacity(4096),
        };
        if handshake {
            c.expect(b"< hi >")?;
            c.s.write_all(b"< open vcan0 >")?;
            c.expect(b"< ok >")?;
            c.s.write_all(b"< rawmode >")?;
            c.expect(b"< ok >")?;
            // The stream starts after the server's stream delay.
            std::thread::sleep(Duration::from_millis(150));
            let _ = c.s.set_nonblocking(true);
            let mut junk = [0u8; 4096];
            while matches!(c.s.read(&mut junk), Ok(n) if n > 0) {}
            c.s.set_nonblocking(false)?;
        }
        Ok(c)
    }

    fn expect(&mut self, what: &[u8]) -> io::Result<()> {
        let mut buf = [0u8; 256];
        let n = self.s.read(&mut buf)?;
        if buf.get(..n) != Some(what) {
            return Err(io::Error::other(format!(
                "expected {:?}, got {:?}",
                String::from_utf8_lossy(what),
                String::from_utf8_lossy(buf.get(..n).unwrap_or(&[]))
            )));
        }
        Ok(())
    }
}

impl Client for CanClient {
    fn round_trip(&mut self) -> io::Result<()> {
        self.s.write_all(SDO_UPLOAD_1000)?;
        self.buf.clear();
        let mut chunk = [0u8; 1024];
        loop {
            let n = self.s.read(&mut chunk)?;
            if n == 0 {
                return Err(io::ErrorKind::UnexpectedEof.into());
            }
            self.buf.extend_from_slice(chunk.get(..n).unwrap_or(&[]));
            // Other frames (boot-up, heartbeats) may come first.
            if self.buf.windows(11).any(|w| w == b"< frame 581") && self.buf.ends_with(b">") {
                return Ok(());
            }
        }
    }
}

struct ModbusClient {
    s: TcpStream,
}

impl Client for ModbusClient {
    fn round_trip(&mut self) -> io::Result<()> {
        self.s.write_all(FC17_REQUEST)?;
        let mut answer = [0u8; FC17_RESPONSE_LEN];
        self.s.read_exact(&mut answer)
    }
}

fn modbus_client(addr: SocketAddr) -> io::Result<ModbusClient> {
    let s = TcpStream::connect(addr)?;
    s.set_nodelay(true)?;
    s.set_read_timeout(Some(READ_TIMEOUT))?;
    Ok(ModbusClient { s })
}

struct Series {
    name: &'static str,
    client: Box<dyn Client>,
    samples: Vec<Duration>,
}

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    if sorted.is_empty() {
        return Duration::ZERO;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted.get(i).copied().unwrap_or_default()
}

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The figures of one placement: its label and (path, p50, p99) of each server.
struct Placement {
    label: String,
    figures: Vec<(&'static str, Duration, Duration)>,
}

/// One placement: servers on CPU `server_cpu`, the client on `client_cpu`.
fn placement(label: &str, server_cpu: usize, client_cpu: usize) -> Result<Placement, String> {
    let count = env_usize("CELL_BENCH_COUNT", 20_000);
    let rounds = env_usize("CELL_BENCH_ROUNDS", count.div_ceil(MAX_PER_ROUND).max(10)).max(1);
    let floor_can = floor(server_cpu, FLOOR_FRAME).map_err(|e| e.to_string())?;
    let floor_mb = floor(server_cpu, &[0u8; FC17_RESPONSE_LEN]).map_err(|e| e.to_string())?;
    let (twin_can, twin_mb, stop) = twin(server_cpu)?;
    pin(client_cpu);
    let err = |e: io::Error| e.to_string();
    let mut series = vec![
        Series {
            name: "floor socketcand",
            client: Box::new(CanClient::connect(floor_can, false).map_err(err)?),
            samples: Vec::new(),
        },
        Series {
            name: "twin socketcand",
            client: Box::new(CanClient::connect(twin_can, true).map_err(err)?),
            samples: Vec::new(),
        },
        Series {
            name: "floor modbus",
            client: Box::new(modbus_client(floor_mb).map_err(err)?),
            samples: Vec::new(),
        },
        Series {
            name: "twin modbus",
            client: Box::new(modbus_client(twin_mb).map_err(err)?),
            samples: Vec::new(),
        },
    ];
    for s in &mut series {
        for _ in 0..WARM_UP {
            s.client
                .round_trip()
                .map_err(|e| format!("{}: {e}", s.name))?;
        }
    }
    let per_round = count / rounds;
    for _ in 0..rounds {
        for s in &mut series {
            for _ in 0..per_round {
                let t = Instant::now();
                s.client
                    .round_trip()
                    .map_err(|e| format!("{}: {e}", s.name))?;
                s.samples.push(t.elapsed());
            }
        }
    }
    stop.stop();
    println!("\n{label} (servers on CPU {server_cpu}, client on CPU {client_cpu}), {count} round trips each:");
    let mut p50s = Vec::new();
    let mut figures = Vec::new();
    for s in &mut series {
        s.samples.sort_unstable();
        p50s.push(percentile(&s.samples, 0.5));
    }
    for (i, s) in series.iter().enumerate() {
        let p50 = percentile(&s.samples, 0.5);
        let p99 = percentile(&s.samples, 0.99);
        // Each twin path against the floor before it.
        let floor = if i % 2 == 1 { p50s.get(i - 1) } else { None };
        let ratio = floor
            .map(|f| {
                format!(
                    "  {:.2}x floor",
                    p50.as_secs_f64() / f.as_secs_f64().max(1e-9)
                )
            })
            .unwrap_or_default();
        println!(
            "  {:<18} p50 {:>6.2} us  p99 {:>7.2} us{ratio}",
            s.name,
            p50.as_secs_f64() * 1e6,
            p99.as_secs_f64() * 1e6
        );
        figures.push((s.name, p50, p99));
    }
    Ok(Placement {
        label: label.to_string(),
        figures,
    })
}

/// Draws the placements into `docs/round-trip-latency.png` (or `CELL_BENCH_PLOT`).
fn draw(placements: &[Placement]) {
    let path = std::env::var_os("CELL_BENCH_PLOT")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../../docs/round-trip-latency.png")
        });
    match plot::round_trips(&path, placements) {
        Ok(()) => println!("\nplot: {}", path.display()),
        Err(e) => println!("\nplot not drawn: {e}"),
    }
}

mod plot {
    //! Grouped bars on a logarithmic axis (p50 is tens of µs, p99 on a loaded machine up to
    //! milliseconds): per placement and path (socketcand, Modbus) the floor and the twin, each
    //! a p50 bar with its p99 as a thin bar on top, in µs.

    use std::path::Path;

    use plotters::prelude::*;

    use super::Placement;

    /// Bars per placement: floor / twin socketcand, floor / twin Modbus.
    const BARS: f64 = 4.0;
    /// The bars' foot, µs (the logarithmic axis has no 0).
    const FOOT: f64 = 1.0;

    pub fn round_trips(path: &Path, placements: &[Placement]) -> Result<(), String> {
        crate::support::load_font()?;
        let us = |d: std::time::Duration| (d.as_secs_f64() * 1e6).max(FOOT);
        let top = placements
            .iter()
            .flat_map(|p| p.figures.iter().map(|f| us(f.2)))
            .fold(100.0, f64::max)
            * 12.0;
        let width = placements.len().max(1) as f64 * (BARS + 1.0);
        let root = BitMapBackend::new(path, (1000, 600)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Round trip over loopback TCP: the twin against the floor (p50 bar, p99 on top)",
                ("sans-serif", 22),
            )
            .margin(16)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..width, (FOOT..top).log_scale())
            .map_err(|e| e.to_string())?;
        // Group centres lie on the 0.5 grid: 2.5, 7.5, …
        let labels: Vec<(f64, String)> = placements
            .iter()
            .enumerate()
            .map(|(g, p)| (g as f64 * (BARS + 1.0) + 0.5 + BARS / 2.0, p.label.clone()))
            .collect();
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels((width * 2.0) as usize + 1)
            .x_label_formatter(&|x: &f64| {
                labels
                    .iter()
                    .find(|(at, _)| (at - x).abs() < 0.01)
                    .map_or(String::new(), |(_, l)| l.clone())
            })
            .y_label_formatter(&|y: &f64| format!("{y:.0}"))
            .y_desc("round trip, µs (log scale)")
            .label_style(("sans-serif", 16))
            .draw()
            .map_err(|e| e.to_string())?;
        let floor = RGBColor(170, 170, 170);
        let twin = RGBColor(40, 90, 170);
        let p99 = RGBColor(230, 120, 40);
        for (g, p) in placements.iter().enumerate() {
            for (i, (name, p50v, p99v)) in p.figures.iter().enumerate() {
                let x0 = g as f64 * (BARS + 1.0) + 0.5 + i as f64;
                let color = if name.starts_with("floor") {
                    floor
                } else {
                    twin
                };
                let (a, b) = (us(*p50v), us(*p99v).max(us(*p50v)));
                chart
                    .draw_series([
                        Rectangle::new([(x0 + 0.1, FOOT), (x0 + 0.9, a)], color.filled()),
                        Rectangle::new([(x0 + 0.4, a), (x0 + 0.6, b)], p99.filled()),
                    ])
                    .map_err(|e| e.to_string())?;
                // Text hangs from its point: the p50 inside its bar, the p99 and the path's
                // two words above the p99 bar.
                let (who, what) = name.split_once(' ').unwrap_or((name, ""));
                let label = |t: String, y: f64, color: &RGBColor| {
                    Text::new(
                        t,
                        (x0 + 0.12, y),
                        ("sans-serif", 13).into_font().color(color),
                    )
                };
                chart
                    .draw_series([
                        label(format!("{a:.1}"), a / 1.25, &WHITE),
                        label(format!("{b:.0}"), b * 1.45, &BLACK),
                        label(what.to_string(), b * 2.1, &BLACK),
                        label(who.to_string(), b * 3.0, &BLACK),
                    ])
                    .map_err(|e| e.to_string())?;
            }
        }
        for (label, color) in [
            ("floor: a blocking thread answering at once (p50)", floor),
            ("twin: the cell loop with its drives (p50)", twin),
            ("p99", p99),
        ] {
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(0.0, FOOT), (0.0, FOOT)],
                    color.filled(),
                )))
                .map_err(|e| e.to_string())?
                .label(label)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 6), (x + 20, y + 6)], color.filled())
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())
    }
}

fn main() -> ExitCode {
    // `cargo bench` passes `--bench`; a filter argument is ignored.
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut placements = Vec::new();
    match placement("same CPU", 0, 0) {
        Ok(p) => placements.push(p),
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    }
    if cpus < 2 {
        println!("\nsplit CPUs: skipped, one CPU only");
    } else {
        match placement("split CPUs", 0, 1) {
            Ok(p) => placements.push(p),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    draw(&placements);
    if let Err(e) = realistic_bus() {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    ExitCode::SUCCESS
}
