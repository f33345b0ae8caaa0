//! Requests per second and p99 latency of a 4-register FC 0x17 read/write cycle over loopback,
//! the drivetwin CMMO-ST server side by side with pymodbus's own server on the same machine
//! (target: at least 10× pymodbus).
//!
//! Every server runs as its own process: `drivetwin run --device cmmo-st --bitrate instant
//! --modbus …` (the binary Cargo builds for this bench; the instant bus stated, so that no
//! bus's bit time is ever measured) and `tests/bench/pymodbus_server.py` (a plain
//! holding-register datastore). The same Rust client drives each on one connection with
//! sequential cycles: read 4 registers from 0, write 4 registers at 0, in one request. It is
//! the `no_std` codec of `modbus::client` on a blocking std socket, the leanest client there is,
//! so that the numbers are the servers' rather than the client's. It measures every cycle after
//! a warm-up and prints requests/s, p50 and p99.
//!
//! Two figures: **sequential** cycles (one request, wait for its answer: what one PLC does; on
//! loopback the kernel's own round trip, 6…7 µs on one CPU of a small VM, bounds every server
//! from below) and **pipelined** cycles (`PIPELINE_DEPTH` requests written at once, then their
//! answers, as Modbus TCP allows with transaction identifiers: the server's own cost per
//! request).
//!
//! Placement: by default the client and every server run on CPU 0 alone (the servers inherit
//! the client's affinity), the client blocking while it waits. A round trip then costs two
//! context switches on one CPU instead of two wake-ups across CPUs; on a small VM such a cross-CPU wake-up (an
//! inter-processor interrupt through the hypervisor) costs more than a whole round trip on
//! one CPU and belongs to neither server. Each server gets the same placement.
//! `MODBUS_BENCH_CPU=N` picks another CPU; `MODBUS_BENCH_CPU=any` leaves placement to the
//! scheduler, the client then spinning while it waits (as a PLC's fieldbus task would).
//!
//! Three servers: `drivetwin` as it runs by default (the device's cycle thread serves its
//! connection), `dt async` (the same twin with `--modbus-io async`: its server a tokio task),
//! and pymodbus, the reference of the ratios.
//!
//! `cargo bench -p drivetwin --bench modbus_loopback`; `MODBUS_BENCH_COUNT` sets the cycles per
//! server (default 10000). Without python3 or pymodbus it says so and exits 0.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::net::TcpListener as StdListener;
use std::path::PathBuf;
use std::process::{Child, Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

use std::io::{self, Read, Write};
use std::net::TcpStream;

use modbus::client::{self, Response};
use modbus::{Mbap, MAX_ADU_LEN, MBAP_LEN};

const WARM_UP: usize = 500;
/// Interleaved rounds (`MODBUS_BENCH_ROUNDS`).
const DEFAULT_ROUNDS: usize = 10;
const DEFAULT_COUNT: usize = 10_000;
/// Requests in flight in the pipelined measurement.
const PIPELINE_DEPTH: usize = 16;
const START_TIMEOUT: Duration = Duration::from_secs(15);

/// A server process, killed when dropped.
struct Server {
    name: &'static str,
    child: Child,
    addr: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

struct Measurement {
    requests_per_second: f64,
    p50: Duration,
    p99: Duration,
}

fn free_port() -> Result<u16, String> {
    let l = StdListener::bind("127.0.0.1:0").map_err(|e| format!("bind: {e}"))?;
    l.local_addr()
        .map(|a| a.port())
        .map_err(|e| format!("local_addr: {e}"))
}

/// `MODBUS_BENCH_CPU`: the one CPU for the client and every server (default 0), or `any`.
fn pinned_cpu() -> Option<usize> {
    match std::env::var("MODBUS_BENCH_CPU") {
        Err(_) => Some(0),
        Ok(v) => v.parse().ok(),
    }
}

/// Pins the calling thread (the client) to `cpu`; the servers it starts afterwards inherit
/// the affinity (no `taskset` needed).
fn pin_self(cpu: usize) -> Result<(), String> {
    platform::sched::pin(0, cpu).map_err(|e| format!("CPU {cpu}: {e}"))
}

fn pymodbus_available() -> bool {
    Command::new("python3")
        .args(["-c", "import pymodbus"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

fn spawn(name: &'static str, mut command: Command, port: u16) -> Result<Server, String> {
    let child = command
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("cannot start {name}: {e}"))?;
    Ok(Server {
        name,
        child,
        addr: format!("127.0.0.1:{port}"),
    })
}

/// A blocking Modbus TCP client doing FC 0x17 cycles with the `modbus::client` codec.
struct Client {
    stream: TcpStream,
    transaction: u16,
    tx: [u8; MAX_ADU_LEN],
    rx: [u8; MAX_ADU_LEN],
}

impl Client {
    fn connect(addr: &str) -> io::Result<Client> {
        let stream = TcpStream::connect(addr)?;
        stream.set_nodelay(true)?;
        if pinned_cpu().is_some() {
            stream.set_read_timeout(Some(Duration::from_secs(2)))?;
        } else {
            stream.set_nonblocking(true)?;
        }
        Ok(Client {
            stream,
            transaction: 0,
            tx: [0; MAX_ADU_LEN],
            rx: [0; MAX_ADU_LEN],
        })
    }

    /// The next FC 0x17 request (read 4 from 0, write `values` at 0) in `tx`; its length.
    fn request(&mut self, values: &[u16; 4]) -> Result<usize, String> {
        self.transaction = self.transaction.wrapping_add(1);
        client::read_write_multiple_registers(&mut self.tx, self.transaction, 1, 0, 4, 0, values)
            .map_err(|e| e.to_string())
    }

    /// Reads one response ADU; its transaction identifier and the FC 0x17 registers.
    fn response(&mut self) -> Result<(u16, [u16; 4]), String> {
        let io = |e: io::Error| e.to_string();
        let (head, body) = self.rx.split_at_mut(MBAP_LEN);
        spin_read_exact(&mut self.stream, head).map_err(io)?;
        let mbap = Mbap::parse(head).ok_or("short header")?;
        let len = usize::from(mbap.length).saturating_sub(1).min(body.len());
        spin_read_exact(&mut self.stream, &mut body[..len]).map_err(io)?;
        match Response::parse(&body[..len]) {
            Ok(Response::ReadWriteMultipleRegisters(r)) if r.len() == 4 => {
                let mut out = [0u16; 4];
                r.decode_into(&mut out);
                Ok((mbap.transaction_id, out))
            }
            other => Err(format!("unexpected response {other:?}")),
        }
    }

    /// `depth` cycles written at once, then their answers read in order.
    fn burst(&mut self, depth: usize, values: &[u16; 4]) -> Result<(), String> {
        let mut batch = Vec::with_capacity(depth * 32);
        let first = self.transaction.wrapping_add(1);
        for _ in 0..depth {
            let n = self.request(values)?;
            batch.extend_from_slice(&self.tx[..n]);
        }
        self.stream.write_all(&batch).map_err(|e| e.to_string())?;
        for k in 0..depth {
            let (transaction, _) = self.response()?;
            if transaction != first.wrapping_add(k as u16) {
                return Err("transaction identifier out of order".into());
            }
        }
        Ok(())
    }

    /// One cycle: write `values` at 0, read `out.len()` registers from 0.
    fn cycle(&mut self, out: &mut [u16; 4], values: &[u16; 4]) -> Result<(), String> {
        let n = self.request(values)?;
        self.stream
            .write_all(&self.tx[..n])
            .map_err(|e| e.to_string())?;
        let (transaction, registers) = self.response()?;
        if transaction != self.transaction {
            return Err("transaction identifier mismatch".into());
        }
        *out = registers;
        Ok(())
    }
}

/// `read_exact` on a non-blocking socket, spinning while nothing has come: the client never
/// sleeps, so its own wake-up is not part of the round trip and the figures are the server's
/// (as an EtherCAT master like SOEM spins while it waits for its frame). Gives up after 2 s.
fn spin_read_exact(stream: &mut TcpStream, mut buf: &mut [u8]) -> io::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(2);
    while !buf.is_empty() {
        match stream.read(buf) {
            Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
            Ok(n) => buf = &mut buf[n..],
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                if Instant::now() > deadline {
                    return Err(io::ErrorKind::TimedOut.into());
                }
                std::hint::spin_loop();
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// A connection once the server takes one (the CMMO-ST refuses a client while it still
/// holds the previous connection, closed only a moment ago).
fn connect_when_free(server: &Server) -> Result<Client, String> {
    let deadline = Instant::now() + Duration::from_secs(2);
    loop {
        let attempt = Client::connect(&server.addr)
            .map_err(|e| e.to_string())
            .and_then(|mut c| {
                c.cycle(&mut [0; 4], &[0; 4])?;
                Ok(c)
            });
        match attempt {
            Ok(c) => return Ok(c),
            Err(e) if Instant::now() > deadline => return Err(format!("{}: {e}", server.name)),
            Err(_) => std::thread::sleep(Duration::from_millis(5)),
        }
    }
}

/// Waits until the server accepts a connection and answers one cycle (a probe connection,
/// closed again: the CMMO-ST takes one client at a time).
fn wait_ready(server: &mut Server) -> Result<(), String> {
    let deadline = Instant::now() + START_TIMEOUT;
    loop {
        if let Ok(Some(status)) = server.child.try_wait() {
            return Err(format!("{} exited at start: {status}", server.name));
        }
        if let Ok(mut c) = Client::connect(&server.addr) {
            if c.cycle(&mut [0; 4], &[0; 4]).is_ok() {
                drop(c);
                std::thread::sleep(Duration::from_millis(200));
                return Ok(());
            }
        }
        if Instant::now() > deadline {
            return Err(format!(
                "{} did not answer within {START_TIMEOUT:?}",
                server.name
            ));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The cycles of one server: every latency and the time they took together.
struct Samples {
    latencies: Vec<Duration>,
    total: Duration,
}

impl Samples {
    fn new(count: usize) -> Samples {
        Samples {
            latencies: Vec::with_capacity(count),
            total: Duration::ZERO,
        }
    }

    /// `count` cycles on `c`.
    fn run(&mut self, c: &mut Client, count: usize) -> Result<(), String> {
        let mut out = [0u16; 4];
        // CCON, CPOS, … all 0: a valid FHPP telegram that leaves the CMMO-ST disabled.
        let values = [0u16; 4];
        let start = Instant::now();
        for _ in 0..count {
            let t = Instant::now();
            c.cycle(&mut out, &values)?;
            self.latencies.push(t.elapsed());
        }
        self.total += start.elapsed();
        Ok(())
    }

    fn result(mut self) -> Measurement {
        self.latencies.sort_unstable();
        let at = |q: f64| {
            let i = ((self.latencies.len() as f64 * q).ceil() as usize).saturating_sub(1);
            self.latencies.get(i).copied().unwrap_or_default()
        };
        Measurement {
            requests_per_second: self.latencies.len() as f64 / self.total.as_secs_f64(),
            p50: at(0.50),
            p99: at(0.99),
        }
    }
}

/// `drivetwin run --device cmmo-st` on a free port, with `--modbus-io io`.
fn spawn_twin(name: &'static str, io: &str) -> Result<Server, String> {
    let port = free_port()?;
    let mut twin = Command::new(env!("CARGO_BIN_EXE_drivetwin"));
    // The instant bus, stated: a latency benchmark measures the loop, never a bus's bit time
    // (the CMMO-ST itself has no CAN bus).
    twin.args(["run", "--device", "cmmo-st", "--bitrate", "instant"])
        .args(["--modbus-io", io, "--modbus"])
        .arg(format!("127.0.0.1:{port}"));
    // MODBUS_BENCH_TWIN_ARGS: more `drivetwin run` options, e.g. "--busy-poll".
    if let Ok(extra) = std::env::var("MODBUS_BENCH_TWIN_ARGS") {
        twin.args(extra.split_whitespace());
    }
    spawn(name, twin, port)
}

fn run(count: usize, rounds: usize) -> Result<(), String> {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let script = repo.join("tests/bench/pymodbus_server.py");

    // The CMMO-ST twin as it runs by default (its cycle thread serves the connection), the
    // same twin with its server as a tokio task, and pymodbus (always last: the reference).
    let mut servers = vec![
        spawn_twin("drivetwin", "thread")?,
        spawn_twin("dt async", "async")?,
    ];
    let port = free_port()?;
    let mut py = Command::new("python3");
    py.arg(&script).arg(port.to_string());
    servers.push(spawn("pymodbus", py, port)?);
    for server in &mut servers {
        wait_ready(server)?;
    }

    println!(
        "Modbus TCP loopback, FC 0x17 read 4 / write 4 registers, one connection per server, \
         {count} sequential cycles each in {rounds} interleaved rounds"
    );
    let mut samples: Vec<Samples> = servers.iter().map(|_| Samples::new(count)).collect();
    // Interleaved rounds: a busy machine slows every server alike. Each round opens its own
    // connection (after the CMMO-ST has seen the last one close) and warms it up untimed, so
    // that a server waiting for its next client is idle while another one is measured.
    // The requests/s ratio of each round: its median shrugs off a burst of load in one round.
    let mut round_ratios: Vec<Vec<f64>> = servers.iter().map(|_| Vec::new()).collect();
    for round in 0..rounds {
        let n = count / rounds + usize::from(round < count % rounds);
        let mut times = Vec::with_capacity(servers.len());
        for (server, s) in servers.iter().zip(samples.iter_mut()) {
            let mut c = connect_when_free(server)?;
            for _ in 0..WARM_UP {
                c.cycle(&mut [0; 4], &[0; 4])?;
            }
            let before = s.total;
            s.run(&mut c, n)?;
            times.push((s.total - before).as_secs_f64().max(1e-9));
        }
        let reference = times.last().copied().unwrap_or_default();
        for (ratios, t) in round_ratios.iter_mut().zip(&times) {
            ratios.push(reference / t);
        }
    }
    let results: Vec<Measurement> = samples.into_iter().map(Samples::result).collect();
    let Some(reference) = results.last() else {
        return Ok(());
    };
    for ((server, m), ratios) in servers.iter().zip(&results).zip(&mut round_ratios) {
        print!(
            "  {:<10} {:>10.0} requests/s   p50 {:>7.1} µs   p99 {:>7.1} µs",
            server.name,
            m.requests_per_second,
            m.p50.as_secs_f64() * 1e6,
            m.p99.as_secs_f64() * 1e6
        );
        if std::ptr::eq(m, reference) {
            println!();
            continue;
        }
        ratios.sort_by(f64::total_cmp);
        let median = ratios.get(ratios.len() / 2).copied().unwrap_or_default();
        println!(
            "   {:.1}× pymodbus (median of the rounds {median:.1}×), p99 {:.1}× lower",
            m.requests_per_second / reference.requests_per_second,
            reference.p99.as_secs_f64() / m.p99.as_secs_f64().max(1e-9),
        );
    }
    // Pipelined: the server's own cost per request. A server that does not answer every
    // request of a burst (pymodbus 3.16 answers the first one of a read only) gets no figure.
    println!("pipelined, {PIPELINE_DEPTH} requests in flight, {count} cycles each:");
    for server in &servers {
        let mut c = connect_when_free(server)?;
        let c = &mut c;
        let bursts = (count / PIPELINE_DEPTH).max(1);
        let start = Instant::now();
        let mut failed = None;
        for _ in 0..bursts {
            if let Err(e) = c.burst(PIPELINE_DEPTH, &[0; 4]) {
                failed = Some(e);
                break;
            }
        }
        match failed {
            None => {
                let rate = (bursts * PIPELINE_DEPTH) as f64 / start.elapsed().as_secs_f64();
                println!("  {:<10} {:>10.0} requests/s", server.name, rate);
            }
            Some(e) => println!("  {:<10} does not answer a pipeline: {e}", server.name),
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    // `cargo bench` passes `--bench`; `cargo test --benches` passes nothing of ours either.
    if !pymodbus_available() {
        println!("modbus_loopback: skipped, python3 with pymodbus is not available");
        return ExitCode::SUCCESS;
    }
    if let Some(cpu) = pinned_cpu() {
        if let Err(e) = pin_self(cpu) {
            eprintln!("modbus_loopback: MODBUS_BENCH_CPU: {e}");
            return ExitCode::FAILURE;
        }
        println!("client and servers on CPU {cpu} (MODBUS_BENCH_CPU=any: unpinned)");
    } else {
        println!("client and servers placed by the scheduler, the client spinning");
    }
    let env = |name: &str, default: usize| {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse().ok())
            .filter(|n| *n > 0)
            .unwrap_or(default)
    };
    let count = env("MODBUS_BENCH_COUNT", DEFAULT_COUNT);
    let rounds = env("MODBUS_BENCH_ROUNDS", DEFAULT_ROUNDS).min(count);
    match run(count, rounds) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("modbus_loopback: {e}");
            ExitCode::FAILURE
        }
    }
}
