//! Issue 12's latency point: the cell loop against the kernel's floor, in one run.
//!
//! One plain blocking client (std `TcpStream`, `TCP_NODELAY`, blocking `read`) measures
//! sequential round trips against four servers, in interleaved rounds:
//!
//! - `floor socketcand`: a thread that blocks in `read` and answers every request at once
//!   with a fixed socketcand frame, no device (the lowest a sleeping server gets);
//! - `twin socketcand`: the cell loop ([`drivetwin::cell::poll_loop`]) with a CMMP-AS, node 1,
//!   answering an expedited SDO upload of 1000h (`< send 601 8 40 00 10 00 … >` →
//!   `< frame 581 … 43 00 10 00 … >`) after the socketcand handshake;
//! - `floor modbus`: the same blocking thread answering a Modbus FC 17h request with a fixed
//!   17-byte response;
//! - `twin modbus`: the same cell loop's CMMO-ST answering FC 17h (read 4 registers at 0,
//!   write 4 at 0: the FHPP cyclic telegram).
//!
//! The twin's two drives are one cell on one loop and one clock: its CMMP-AS steps while the
//! CMMO-ST cycles every millisecond.
//!
//! Two placements: `same CPU` (client and every server thread pinned to CPU 0; a round trip is
//! two context switches on one CPU) and `split CPUs` (servers on CPU 0, client on CPU 1: two
//! cross-CPU wake-ups). Pinning is `sched_setaffinity` on each thread. It prints p50 / p99 per
//! server and placement and the ratio of each twin path to its floor (target: p50 ≤ 1.2×).
//!
//! `cargo bench -p drivetwin --bench cell_loopback`; `CELL_BENCH_COUNT` sets the round trips
//! per server and placement (default 20000), `CELL_BENCH_ROUNDS` the interleaved rounds (10).

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::process::ExitCode;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use drivetwin::can::drive::CanDrive;
use drivetwin::can::socketcand::ServerConfig;
use drivetwin::cell::poll_loop::{CanBus, CellLoop, FrontEnds, StopHandle};
use drivetwin::cell::Cell;
use drivetwin::modbus_tcp::cell_drive::ModbusDrive;
use drivetwin::modbus_tcp::server::ModbusConfig;

const WARM_UP: usize = 500;
const SDO_UPLOAD_1000: &[u8] = b"< send 601 8 40 00 10 00 00 00 00 00 >";
const FLOOR_FRAME: &[u8] = b"< frame 581 1764000000.000000 4300100092010200 >";
/// FC 17h: read 4 registers at 0, write 4 registers at 0 (8 data bytes), unit 1.
const FC17_REQUEST: &[u8] = &[
    0, 1, 0, 0, 0, 19, 1, 0x17, 0, 0, 0, 4, 0, 0, 0, 4, 8, 0, 0, 0, 0, 0, 0, 0, 0,
];
const FC17_RESPONSE_LEN: usize = 17;

fn pin(cpu: usize) {
    // SAFETY: `cpu_set_t` is plain data; all-zero is the empty set; pid 0 is this thread.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) != 0 {
            eprintln!("cannot pin to CPU {cpu}: {}", io::Error::last_os_error());
        }
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

/// The twin: one cell loop with a CMMP-AS on socketcand and a CMMO-ST on Modbus TCP.
fn twin(cpu: usize) -> Result<(SocketAddr, SocketAddr, StopHandle), String> {
    let cmmp = devices::by_name("cmmp-as").ok_or("no cmmp-as")?;
    let drive = CanDrive::with_settings(cmmp, 1, None, vec![], Some(Default::default()))
        .map_err(|e| e.to_string())?;
    let cmmo = devices::by_name("cmmo-st").ok_or("no cmmo-st")?;
    let od = od::ObjectDictionary::new(cmmo, 1, vec![0u8; cmmo.storage_size])
        .map_err(|_| "CMMO-ST storage")?;
    let dev = drive::fhpp::device::FhppDevice::new(od, Default::default());
    let can_listener = TcpListener::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    let can_addr = can_listener.local_addr().map_err(|e| e.to_string())?;
    let mb_listener = TcpListener::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    let mb_addr = mb_listener.local_addr().map_err(|e| e.to_string())?;
    let front = FrontEnds {
        buses: vec![CanBus {
            socketcand: Some((can_listener, ServerConfig::new("vcan0"))),
            ..CanBus::new(Cell::new(vec![drive]))
        }],
        modbus: vec![ModbusDrive::new(
            mb_listener,
            Arc::new(Mutex::new(dev)),
            ModbusConfig::default(),
            None,
        )],
        ..FrontEnds::default()
    };
    let cell_loop = CellLoop::with_buses(front).map_err(|e| e.to_string())?;
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

/// One placement: servers on CPU `server_cpu`, the client on `client_cpu`.
fn placement(label: &str, server_cpu: usize, client_cpu: usize) -> Result<(), String> {
    let count = env_usize("CELL_BENCH_COUNT", 20_000);
    let rounds = env_usize("CELL_BENCH_ROUNDS", 10).max(1);
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
    }
    Ok(())
}

fn main() -> ExitCode {
    // `cargo bench` passes `--bench`; a filter argument is ignored.
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    if let Err(e) = placement("same CPU", 0, 0) {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    if cpus < 2 {
        println!("\nsplit CPUs: skipped, one CPU only");
        return ExitCode::SUCCESS;
    }
    if let Err(e) = placement("split CPUs", 0, 1) {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    ExitCode::SUCCESS
}
