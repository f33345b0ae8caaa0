//! An EtherCAT process-data cycle over a veth pair (1 kHz, one drive, unless told otherwise),
//! the twin beside the floor in one run.
//!
//! The veth pair's one end sits in a private network namespace, where the server under test
//! runs; this process is the master on the other end, with a raw socket and frames built with
//! `crates/ethercat`'s codecs. Servers, each its own process in the namespace:
//!
//! - `floor`: an `AF_PACKET` echo on the same interface (this bench binary again, with
//!   `--ecat-echo IF`): it blocks in `recvfrom` and sends each request back at once with the
//!   returned bit set, no slave behind it (the lowest a sleeping server gets);
//! - `floor, spinning`: the same echo reading without blocking in a loop (`--ecat-echo IF
//!   --spin`), the floor of a server that never sleeps;
//! - `twin`: the real `drivetwin run --ethercat IF`, one CMMP-AS, brought to Op as SOEM does
//!   it (station address, mailbox SMs, Pre-Op, SM2/SM3 and FMMUs for the default mapping
//!   1600h/1A00h — controlword out, statusword in — Safe-Op, Op);
//! - `twin --busy-poll`: the same with `--busy-poll`.
//!
//! Two masters: one that sleeps between cycles and waits for the reply in `poll(2)` (as a
//! normal-priority PLC task does), and one that spins (busy-waits for the reply and for the next
//! cycle, as a master on a core of its own does). One LRW frame per 1 ms cycle; the time from
//! `send` to the reply's `recv` is recorded; p50 / p99 / p99.9 / max are printed with the
//! count of late replies (after more than 1 ms), lost frames (no reply within 100 ms) and wrong
//! working counters, and each twin figure beside its floor with the ratio.
//!
//! Two placements (`sched_setaffinity` on the master's thread and on every thread of the
//! server's process): `one CPU` (master and server on CPU 0; a round trip is two context
//! switches on one CPU; the spinning master is not measured there, it would keep the server
//! from the CPU) and `split CPUs` (server on CPU 0, master on CPU 1).
//!
//! Targets: sleeping master, same placement: p50 ≤ 1.3×, p99 ≤ 1.5×, p99.9 ≤ 2× the floor, no
//! late cycle; spinning master with `--busy-poll`: p50 ≤ 1.2× the floor.
//!
//! `ECAT_ROUNDTRIP_SECONDS` sets each row's length (default 10 s: 10 000 cycles; a row ends
//! at three times its length on a machine too loaded to keep the cycle);
//! `ECAT_ROUNDTRIP_CYCLES` sets it in cycles instead (60000 for the targets' 60 000).
//! `ECAT_ROUNDTRIP_PLACEMENTS=one` (or `split`) runs that placement alone. `ECAT_ROUNDTRIP_FIFO=1` runs the master and every server under `SCHED_FIFO`
//! (priority 49), as a production EtherCAT master runs; `ECAT_ROUNDTRIP_NICE=-20` gives them
//! that nice value instead (a spinning task under `SCHED_FIFO` meets the kernel's real-time
//! throttling, 50 ms of every second). `DRIVETWIN_BIN=path` runs
//! another build of the twin; `ECAT_ROUNDTRIP_TWIN_ARGS` adds `drivetwin run` options.
//!
//! `ECAT_ROUNDTRIP_RT=N` schedules the server's frame path alone under `SCHED_FIFO` N: the
//! echo's thread, and the twin's cell loop through its own `--rt-priority N` (its other
//! threads stay at normal priority); the master keeps its own (a normal-priority PLC task,
//! or `ECAT_ROUNDTRIP_NICE`). `ECAT_ROUNDTRIP_SLICE_US=N` gives the same two threads an
//! EEVDF time slice of N µs instead (`--sched-slice-us N`, Linux 6.12+, no privilege).
//! `scripts/ecat-roundtrip` runs the targets' 60 000-cycle form in one command.
//!
//! A server that spins (the spinning echo, the twin with `--busy-poll`) never runs under
//! `SCHED_FIFO`, whichever of `ECAT_ROUNDTRIP_RT` and `ECAT_ROUNDTRIP_FIFO` is set: a task
//! that never sleeps there meets the kernel's real-time throttling (`sched_rt_runtime_us`, 50
//! ms of every second taken from it), and its p99.9 would measure the throttle. Both run at
//! normal priority (with `ECAT_ROUNDTRIP_NICE` when set, or `ECAT_ROUNDTRIP_SLICE_US`), so
//! the busy-poll row still stands beside a floor scheduled as it is.
//!
//! `ECAT_ROUNDTRIP_SLAVES=N` runs a chain of N CMMP-AS (a cell file of N drives on the
//! interface; each slave's 2 output and 2 input bytes in one LRW, working counter 3 × N) and
//! `ECAT_ROUNDTRIP_HZ=H` a cycle of H Hz; a reply later than one cycle is late. The echo then
//! returns a frame of the chain's size: the floor of one frame through the same path, which
//! the chain target is set against (4 kHz, 64 drives: p99 ≤ 2× the floor, no late cycle).
//!
//! `ECAT_ROUNDTRIP_MASTER=sleeps` runs the sleeping master's rows alone (no spinning master,
//! no spinning echo, no `--busy-poll` twin).
//!
//! `ECAT_ROUNDTRIP_TURNS=1` prints what each twin row's `drivetwin run` printed as it stopped:
//! its timers' lateness and its loop's longest turns, what each did and how many turns took
//! how long.
//!
//! `ECAT_ROUNDTRIP_LATE_LOG=path` appends each late reply to `path`: its row, the time it was
//! sent on `CLOCK_MONOTONIC` (ns, the clock `perf record -k CLOCK_MONOTONIC` stamps its
//! events with) and how long it took, so that a trace of the CPU's scheduling taken beside
//! the run shows what ran instead.
//!
//! Needs root (network namespace, raw sockets) and `ip`; otherwise prints why and exits 0.
//! `cargo bench -p drivetwin --bench ecat_veth_roundtrip`; without cargo bench's `--bench`
//! argument (e.g. `cargo test --benches`) each row runs 0.1 s, about 1 s in all, as a smoke
//! test.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

#[path = "../tests/support/cmmp_as_chain.rs"]
mod cmmp_as_chain;
#[path = "../tests/support/ecat_veth.rs"]
mod ecat_veth;

use std::io::{self, BufRead, BufReader};
use std::os::fd::{AsFd, OwnedFd};
use std::path::PathBuf;
use std::process::{Child, Command as Process, Stdio};
use std::time::{Duration, Instant};

use cmmp_as_chain::{
    configure_process_data, mailboxes, INPUT_BYTES, MASTER_MAC, OUTPUT_BYTES, STATION,
    WKC_PER_SLAVE,
};
use drivetwin::sys::fd::{self, Readiness};
use drivetwin::sys::packet_socket::{self, Received};
use ecat_veth::{TwinProcess, Veth};
use ethercat::frame::{ETHERTYPE_ETHERCAT, SOURCE_MAC_RETURN_BIT};
use ethercat::register::RegisterAddress;
use ethercat::{Address, AlState, Command, EthernetFrame, Frame, FrameWriter};

/// The longest chain a frame of [`Master`]'s buffer holds (4 bytes of process data a slave).
const MOST_SLAVES: u16 = 256;
/// A reply later than this counts as lost.
const REPLY_TIMEOUT: Duration = Duration::from_millis(100);
/// How long a start-up datagram may take (a twin just started on a loaded machine).
const START_UP_TIMEOUT: Duration = Duration::from_secs(2);
/// Ratios to the floor the twin is to stay within: sleeping master p50, p99, p99.9; spinning
/// master with `--busy-poll` p50.
const TARGET_SLEEPS: [f64; 3] = [1.3, 1.5, 2.0];
const TARGET_BUSY_POLL_P50: f64 = 1.2;
/// A chain's p99 against the floor of its frame (the 4 kHz, 64-drive target).
const TARGET_CHAIN_P99: f64 = 2.0;
/// Real-time priority with `ECAT_ROUNDTRIP_FIFO=1`: just below the kernel's threaded
/// interrupt handlers (`SCHED_FIFO` 50), so they still run first.
const FIFO_PRIORITY: i32 = 49;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--ecat-echo") {
        let interface = args.get(i + 1).expect("--ecat-echo IF");
        let spin = args.iter().any(|a| a == "--spin");
        let value = |name: &str| {
            args.iter()
                .position(|a| a == name)
                .and_then(|i| args.get(i + 1))
                .map(|v| v.parse::<u32>().expect("a number"))
        };
        // The echo's thread scheduled as the twin's loop is (`ECAT_ROUNDTRIP_RT`, `_SLICE_US`).
        let scheduling = drivetwin::cell::realtime::LoopScheduling {
            rt_priority: value("--rt").map(|p| u8::try_from(p).expect("priority 1…99")),
            slice: value("--slice-us").map(|us| Duration::from_micros(u64::from(us))),
        };
        if let Err(e) = scheduling.apply() {
            eprintln!("echo: {e}");
            std::process::exit(2);
        }
        echo(interface, spin);
        return;
    }
    let smoke = !args.iter().any(|a| a == "--bench");
    let number = |name: &str, default: u32, range: std::ops::RangeInclusive<u32>| {
        match std::env::var(name) {
            Ok(v) => match v.parse::<u32>() {
                Ok(n) if range.contains(&n) => n,
                _ => {
                    eprintln!("{name}={v:?}: a number in {range:?}");
                    std::process::exit(2)
                }
            },
            Err(_) => default,
        }
    };
    let slaves = number("ECAT_ROUNDTRIP_SLAVES", 1, 1..=u32::from(MOST_SLAVES)) as u16;
    let hz = number("ECAT_ROUNDTRIP_HZ", 1000, 100..=20_000);
    let cycle = Duration::from_secs(1) / hz;
    let seconds: f64 = match std::env::var("ECAT_ROUNDTRIP_SECONDS") {
        Ok(s) => s.parse().unwrap_or_else(|_| {
            eprintln!("ECAT_ROUNDTRIP_SECONDS={s:?} is not a number of seconds");
            std::process::exit(2)
        }),
        Err(_) if smoke => 0.1,
        Err(_) => 10.0,
    };
    let cycles = match std::env::var("ECAT_ROUNDTRIP_CYCLES") {
        Ok(c) => c.parse::<usize>().unwrap_or_else(|_| {
            eprintln!("ECAT_ROUNDTRIP_CYCLES={c:?} is not a number of cycles");
            std::process::exit(2)
        }),
        Err(_) => (seconds * f64::from(hz)).round() as usize,
    }
    .max(1);
    let sleeping_only = match std::env::var("ECAT_ROUNDTRIP_MASTER").as_deref() {
        Ok("sleeps") => true,
        Ok("") | Err(_) => false,
        Ok(other) => {
            eprintln!("ECAT_ROUNDTRIP_MASTER={other:?}: sleeps, or unset for both masters");
            return;
        }
    };
    let placements = std::env::var("ECAT_ROUNDTRIP_PLACEMENTS").unwrap_or_default();
    let (one, split) = match placements.as_str() {
        "" => (true, true),
        "one" => (true, false),
        "split" => (false, true),
        other => {
            eprintln!("ECAT_ROUNDTRIP_PLACEMENTS={other:?}: one or split");
            std::process::exit(2)
        }
    };
    // DRIVETWIN_BIN (as for the pytest suite) benchmarks another build of the twin.
    let binary = std::env::var_os("DRIVETWIN_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_drivetwin")));
    // ECAT_ROUNDTRIP_TWIN_ARGS: more `drivetwin run` options.
    let mut extra: Vec<String> = std::env::var("ECAT_ROUNDTRIP_TWIN_ARGS")
        .map(|a| a.split_whitespace().map(str::to_owned).collect())
        .unwrap_or_default();
    // A chain: a cell file of `slaves` CMMP-AS on the interface, in the bench's temp dir.
    let chain_file = (slaves > 1).then(|| {
        let path = std::env::temp_dir().join(format!("ecat-roundtrip-{}.toml", std::process::id()));
        let drive = |k: u16| {
            format!("[[drive]]\ndevice = \"cmmp-as\"\nnode = {k}\ninterfaces = [\"ethercat\"]\n\n")
        };
        let text: String = (1..=slaves).map(drive).collect();
        std::fs::write(&path, text).expect("the chain's cell file");
        extra.extend(["--config".into(), path.to_string_lossy().into_owned()]);
        path
    });
    let fifo = std::env::var_os("ECAT_ROUNDTRIP_FIFO").is_some_and(|v| v != "0");
    let nice: Option<i32> = std::env::var("ECAT_ROUNDTRIP_NICE").ok().map(|n| {
        n.parse()
            .expect("ECAT_ROUNDTRIP_NICE is a nice value (-20..19)")
    });
    let server_rt: Option<u32> = std::env::var("ECAT_ROUNDTRIP_RT").ok().map(|n| {
        n.parse()
            .expect("ECAT_ROUNDTRIP_RT is a SCHED_FIFO priority (1..99)")
    });
    let server_slice_us: Option<u32> = std::env::var("ECAT_ROUNDTRIP_SLICE_US").ok().map(|n| {
        n.parse()
            .expect("ECAT_ROUNDTRIP_SLICE_US is a time slice in µs (100..100000)")
    });
    let veth = match Veth::create() {
        Ok(v) => v,
        Err(why) => {
            println!("ecat_veth_roundtrip skipped: {why}");
            return;
        }
    };
    let cpus = std::thread::available_parallelism().map_or(1, usize::from);
    println!(
        "ecat_veth_roundtrip: {cycles} LRW cycles at {hz} Hz per row, {slaves} slave(s), {} CPUs, \
         load average {}{}",
        cpus,
        load_average(),
        match (fifo, nice) {
            (true, _) => ", SCHED_FIFO 49".to_owned(),
            (false, Some(n)) => format!(", nice {n}"),
            (false, None) => String::new(),
        }
    );
    match (server_rt, server_slice_us) {
        (Some(p), _) => println!(
            "server's frame thread at SCHED_FIFO {p} (a spinning server at normal priority)"
        ),
        (None, Some(us)) => println!("server's frame thread with a {us} µs EEVDF slice"),
        (None, None) => {}
    }
    let bench = Bench {
        binary,
        extra,
        fifo,
        nice,
        cycles,
        veth,
        server_rt,
        server_slice_us,
        slaves,
        cycle,
        sleeping_only,
    };
    let mut all = Vec::new();
    if one {
        all.extend(bench.placement(Placement {
            label: "one CPU",
            server_cpu: 0,
            master_cpu: 0,
        }));
    }
    if split && cpus > 1 {
        all.extend(bench.placement(Placement {
            label: "split CPUs",
            server_cpu: 0,
            master_cpu: 1,
        }));
    } else if split {
        println!("\nsplit CPUs: skipped, one CPU only");
    }
    println!("\ntargets (each twin figure against the floor of its placement and master):");
    for row in &all {
        row.verdict();
    }
    println!("load average at the end {}", load_average());
    drop(bench);
    if let Some(path) = chain_file {
        let _ = std::fs::remove_file(path);
    }
}

/// `/proc/loadavg`'s three averages: the figures of a shared machine measure its neighbours too.
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|l| l.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".into())
}

/// Where the master and the server run.
#[derive(Debug, Clone, Copy)]
struct Placement {
    label: &'static str,
    server_cpu: usize,
    master_cpu: usize,
}

/// How the master waits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MasterWait {
    /// Sleeps to the next cycle and blocks in `poll(2)` for the reply.
    Sleeps,
    /// Never sleeps: spins on the socket for the reply and on the clock to the next cycle.
    Spins,
}

impl MasterWait {
    fn label(self) -> &'static str {
        match self {
            MasterWait::Sleeps => "master sleeps",
            MasterWait::Spins => "master spins",
        }
    }
}

/// The server on the twin's end of the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Server {
    Echo,
    SpinningEcho,
    Twin,
    BusyPollTwin,
}

impl Server {
    fn label(self) -> &'static str {
        match self {
            Server::Echo => "floor (echo)",
            Server::SpinningEcho => "floor (spinning echo)",
            Server::Twin => "twin",
            Server::BusyPollTwin => "twin --busy-poll",
        }
    }
}

struct Bench {
    binary: PathBuf,
    extra: Vec<String>,
    fifo: bool,
    /// `ECAT_ROUNDTRIP_NICE`: the nice value of the master and the servers.
    nice: Option<i32>,
    cycles: usize,
    veth: Veth,
    /// `ECAT_ROUNDTRIP_RT`: `SCHED_FIFO` priority of the servers' frame thread.
    server_rt: Option<u32>,
    /// `ECAT_ROUNDTRIP_SLICE_US`: EEVDF slice of the servers' frame thread.
    server_slice_us: Option<u32>,
    /// `ECAT_ROUNDTRIP_SLAVES`: the drives on the chain.
    slaves: u16,
    /// `ECAT_ROUNDTRIP_HZ`: the process-data cycle; a reply later than it is late.
    cycle: Duration,
    /// `ECAT_ROUNDTRIP_MASTER=sleeps`: the sleeping master's rows alone.
    sleeping_only: bool,
}

/// One measured row: a server, a master, a placement.
struct Row {
    /// The drives on the chain (the targets differ for one and for a chain).
    slaves: u16,
    placement: &'static str,
    wait: MasterWait,
    server: Server,
    stats: Stats,
    /// The floor's figures of the same placement and master, for a twin's row.
    floor: Option<[Duration; 4]>,
}

impl Bench {
    /// Every server against the masters that fit `p`; prints the rows as they come.
    fn placement(&self, p: Placement) -> Vec<Row> {
        println!(
            "\n{} (server on CPU {}, master on CPU {}):",
            p.label, p.server_cpu, p.master_cpu
        );
        pin_thread(p.master_cpu);
        let mut master = Master::open(&self.veth.master_if, self.slaves, self.cycle)
            .expect("master-side raw socket");
        let waits: &[MasterWait] = if p.server_cpu == p.master_cpu || self.sleeping_only {
            &[MasterWait::Sleeps]
        } else {
            &[MasterWait::Sleeps, MasterWait::Spins]
        };
        let mut rows: Vec<Row> = Vec::new();
        let servers = [
            (Server::Echo, waits),
            (Server::SpinningEcho, &[MasterWait::Spins][..]),
            (Server::Twin, waits),
            (Server::BusyPollTwin, &[MasterWait::Spins][..]),
        ];
        for (server, server_waits) in servers {
            let server_waits: Vec<MasterWait> = server_waits
                .iter()
                .copied()
                .filter(|w| waits.contains(w))
                .collect();
            if server_waits.is_empty() {
                continue;
            }
            let running = self.start(server, p.server_cpu);
            if matches!(server, Server::Twin | Server::BusyPollTwin) {
                master.start_up();
            }
            for wait in server_waits {
                let stats = master.measure(self.cycles, wait, server);
                let floor_server = if wait == MasterWait::Spins && server == Server::BusyPollTwin {
                    Server::SpinningEcho
                } else {
                    Server::Echo
                };
                let floor = matches!(server, Server::Twin | Server::BusyPollTwin)
                    .then(|| {
                        rows.iter()
                            .find(|r| r.server == floor_server && r.wait == wait)
                            .map(|r| r.stats.figures())
                    })
                    .flatten();
                let row = Row {
                    slaves: self.slaves,
                    placement: p.label,
                    wait,
                    server,
                    stats,
                    floor,
                };
                row.print();
                row.log_late();
                rows.push(row);
            }
            running.stop();
        }
        rows
    }

    /// Starts `server` in the namespace, every thread of it on `cpu`.
    fn start(&self, server: Server, cpu: usize) -> Running {
        let running = match server {
            Server::Echo | Server::SpinningEcho => Running::Echo(EchoProcess::start(
                &self.veth,
                server == Server::SpinningEcho,
                &self.echo_scheduling(server),
            )),
            Server::Twin | Server::BusyPollTwin => {
                let mut extra = self.extra.clone();
                if server == Server::BusyPollTwin && !extra.iter().any(|a| a == "--busy-poll") {
                    extra.push("--busy-poll".into());
                }
                if let Some(p) = self.server_rt.filter(|_| !server.spins()) {
                    extra.extend(["--rt-priority".into(), p.to_string()]);
                } else if let Some(us) = self.server_slice_us {
                    extra.extend(["--sched-slice-us".into(), us.to_string()]);
                }
                Running::Twin(
                    TwinProcess::start_chain(
                        &self.binary,
                        &self.veth,
                        &extra,
                        usize::from(self.slaves),
                    )
                    .unwrap_or_else(|e| panic!("{e}")),
                )
            }
        };
        let pid = running.pid();
        pin_process(pid, cpu).unwrap_or_else(|e| panic!("pin {pid} to CPU {cpu}: {e}"));
        if let Some(nice) = self.nice {
            for pid in [std::process::id(), pid] {
                set_nice(pid, nice).unwrap_or_else(|e| panic!("nice {nice} for {pid}: {e}"));
            }
        }
        if self.fifo {
            // A spinning server stays at normal priority (the module's doc: throttling).
            let pids = [Some(std::process::id()), (!server.spins()).then_some(pid)];
            for pid in pids.into_iter().flatten() {
                // A panic, not exit(): the guards still remove the servers and the veth pair.
                set_fifo(pid).unwrap_or_else(|e| panic!("SCHED_FIFO for {pid}: {e}"));
            }
        }
        running
    }
}

impl Server {
    /// Whether the server never sleeps: it is kept out of `SCHED_FIFO` (the module's doc).
    fn spins(self) -> bool {
        matches!(self, Server::SpinningEcho | Server::BusyPollTwin)
    }
}

impl Bench {
    /// The echo's options that schedule its thread as the twin's loop is; a spinning echo
    /// is never put under `SCHED_FIFO` (the module's doc).
    fn echo_scheduling(&self, server: Server) -> Vec<String> {
        match (
            self.server_rt.filter(|_| !server.spins()),
            self.server_slice_us,
        ) {
            (Some(p), _) => vec!["--rt".into(), p.to_string()],
            (None, Some(us)) => vec!["--slice-us".into(), us.to_string()],
            (None, None) => Vec::new(),
        }
    }
}

/// A server process in the namespace.
enum Running {
    Echo(EchoProcess),
    Twin(TwinProcess),
}

impl Running {
    fn pid(&self) -> u32 {
        match self {
            Running::Echo(e) => e.child.id(),
            Running::Twin(t) => t.pid().expect("twin running"),
        }
    }

    fn stop(self) {
        match self {
            Running::Echo(e) => drop(e),
            Running::Twin(t) => {
                let report = t
                    .stop_reporting()
                    .expect("drivetwin stops cleanly on SIGTERM");
                // ECAT_ROUNDTRIP_TURNS=1: the twin's lateness and its loop's longest turns.
                if std::env::var_os("ECAT_ROUNDTRIP_TURNS").is_some_and(|v| v != "0") {
                    for line in report {
                        eprintln!("    twin: {line}");
                    }
                }
            }
        }
    }
}

/// This bench binary as the floor's echo (`--ecat-echo IF`) in the veth's namespace.
struct EchoProcess {
    child: Child,
}

impl EchoProcess {
    fn start(veth: &Veth, spin: bool, scheduling: &[String]) -> EchoProcess {
        let exe = std::env::current_exe().expect("the bench's own path");
        let mut cmd = Process::new("ip");
        cmd.args(["netns", "exec", &veth.ns])
            .arg(exe)
            .args(["--ecat-echo", &veth.twin_if])
            .stdin(Stdio::null())
            .stdout(Stdio::piped());
        if spin {
            cmd.arg("--spin");
        }
        cmd.args(scheduling);
        let mut child = cmd.spawn().expect("start the echo");
        let mut line = String::new();
        let stdout = child.stdout.take().expect("echo's stdout");
        BufReader::new(stdout)
            .read_line(&mut line)
            .expect("echo's ready line");
        assert_eq!(line.trim(), "ready", "echo did not start");
        EchoProcess { child }
    }
}

impl Drop for EchoProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The floor: every request on `interface` goes back at once with the returned bit set (as a
/// slave that touches nothing). Blocks in `recvfrom`, or with `spin` reads without blocking in
/// a loop. Runs until killed.
fn echo(interface: &str, spin: bool) {
    let fd = drivetwin::ecat::link::open_raw(interface).expect("echo's raw socket");
    if !spin {
        platform::fd::set_blocking(fd.as_fd()).expect("a blocking raw socket");
    }
    println!("ready");
    let _ = std::io::Write::flush(&mut std::io::stdout());
    let mut buf = [0u8; 1536];
    loop {
        let Ok(Received {
            len: n, outgoing, ..
        }) = packet_socket::recv(fd.as_fd(), &mut buf)
        else {
            std::hint::spin_loop();
            continue;
        };
        if outgoing || n <= 6 || buf[6] & SOURCE_MAC_RETURN_BIT != 0 || n > buf.len() {
            continue;
        }
        buf[6] |= SOURCE_MAC_RETURN_BIT;
        let _ = packet_socket::send(fd.as_fd(), &buf[..n]);
    }
}

/// Pins the calling thread to `cpu`.
fn pin_thread(cpu: usize) {
    if let Err(e) = platform::sched::pin(0, cpu) {
        eprintln!("cannot pin the master to CPU {cpu}: {e}");
    }
}

/// Pins every thread of process `pid` to `cpu`.
fn pin_process(pid: u32, cpu: usize) -> io::Result<()> {
    for tid in platform::process::threads(pid)? {
        platform::sched::pin(tid, cpu)?;
    }
    Ok(())
}

/// A blocking raw socket on the master-side interface, bound to EtherType 0x88A4.
struct Master {
    fd: OwnedFd,
    tx: [u8; 1536],
    rx: [u8; 1536],
    index: u8,
    /// How it waits for a reply.
    wait: MasterWait,
    /// The slaves on the chain: station addresses `STATION + k`, slave k's outputs at logical
    /// address `k × OUTPUT_BYTES`, its inputs after every slave's outputs.
    slaves: u16,
    /// The process-data cycle.
    cycle: Duration,
    /// The LRW's process data (every slave's outputs, then inputs): zeros, kept so the cyclic
    /// loop does not allocate.
    io: Vec<u8>,
}

/// One returned datagram: its first bytes (as many as the start-up reads) and working
/// counter; a plain array, so the cyclic loop does not allocate.
struct Reply {
    data: [u8; 8],
    wkc: u16,
}

impl Master {
    fn open(interface: &str, slaves: u16, cycle: Duration) -> io::Result<Master> {
        // The twin's own socket set-up (non-blocking: the master spins on `recvfrom`).
        let fd = drivetwin::ecat::link::open_raw(interface)?;
        Ok(Master {
            fd,
            tx: [0; 1536],
            rx: [0; 1536],
            index: 0,
            wait: MasterWait::Spins,
            slaves,
            cycle,
            io: vec![0; usize::from(slaves) * usize::from(OUTPUT_BYTES + INPUT_BYTES)],
        })
    }

    /// Build a one-datagram frame in `self.tx`; returns its length.
    fn build(&mut self, command: Command, address: Address, data: &[u8]) -> usize {
        self.index = self.index.wrapping_add(1);
        let mut w = FrameWriter::ethernet(&mut self.tx, MASTER_MAC).expect("frame buffer");
        w.push(command, self.index, address, data)
            .expect("datagram fits");
        w.finish()
    }

    fn send(&self, len: usize) -> io::Result<()> {
        packet_socket::send(self.fd.as_fd(), &self.tx[..len])?;
        Ok(())
    }

    /// Wait for the returned frame carrying the datagram index just sent; `None` when it does
    /// not come back within `timeout`. Frames with another index (late replies to an earlier
    /// cycle) are skipped.
    /// A spinning master polls the socket in a loop until the frame is back or the timeout
    /// passes (as SOEM's `ecx_waitinframe` does); a sleeping one waits in `poll(2)`.
    fn recv_reply(&mut self, timeout: Duration) -> Option<Reply> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.checked_duration_since(Instant::now())?;
            // The socket is non-blocking (`open_raw`): `WouldBlock` when nothing waits.
            let Ok(Received {
                len: n, outgoing, ..
            }) = packet_socket::recv(self.fd.as_fd(), &mut self.rx)
            else {
                match self.wait {
                    MasterWait::Spins => std::hint::spin_loop(),
                    MasterWait::Sleeps => {
                        let wait = left.clamp(Duration::from_millis(1), Duration::from_secs(1));
                        let _ = fd::wait(self.fd.as_fd(), Readiness::Readable, wait);
                    }
                }
                continue;
            };
            if outgoing || n > self.rx.len() {
                continue;
            }
            if let Some(reply) = self.parse(n) {
                return Some(reply);
            }
        }
    }

    /// The first datagram of a returned frame with the current index.
    fn parse(&self, len: usize) -> Option<Reply> {
        let eth = EthernetFrame::new_checked(self.rx.get(..len)?).ok()?;
        if eth.ethertype() != ETHERTYPE_ETHERCAT || eth.source()[0] & SOURCE_MAC_RETURN_BIT == 0 {
            return None;
        }
        let frame = Frame::new_checked(eth.payload()).ok()?;
        let dg = frame.datagrams().next()?.ok()?;
        if dg.index() != self.index {
            return None;
        }
        let mut data = [0; 8];
        for (d, s) in data.iter_mut().zip(dg.data()) {
            *d = *s;
        }
        Some(Reply {
            data,
            wkc: dg.wkc(),
        })
    }

    /// One datagram out and back (start-up).
    fn exchange(&mut self, command: Command, address: Address, data: &[u8]) -> Reply {
        let len = self.build(command, address, data);
        self.send(len).expect("send");
        self.recv_reply(START_UP_TIMEOUT)
            .unwrap_or_else(|| panic!("no reply to {command:?} {address:?}"))
    }

    fn fpwr(&mut self, station: u16, register: u16, data: &[u8]) {
        let r = self.exchange(Command::Fpwr, phys(station, register), data);
        assert_eq!(r.wkc, 1, "FPWR {station:#06x} {register:#06x}");
    }

    /// AL status and AL status code of the slave at `station`.
    fn al_status(&mut self, station: u16) -> (u16, u16) {
        let r = self.exchange(
            Command::Fprd,
            phys(station, RegisterAddress::AlStatus.addr()),
            &[0; 6],
        );
        assert_eq!(r.wkc, 1, "FPRD AL status of {station:#06x}");
        (
            u16::from_le_bytes([r.data[0], r.data[1]]),
            u16::from_le_bytes([r.data[4], r.data[5]]),
        )
    }

    /// Every slave's AL status is `state` with no status code.
    fn all_in(&mut self, state: AlState) -> bool {
        (0..self.slaves).all(|k| self.al_status(STATION + k) == (state as u16, 0))
    }

    /// Requests `state` of every slave at once (a broadcast write of AL control).
    fn request(&mut self, state: AlState) {
        let r = self.exchange(
            Command::Bwr,
            phys(0, RegisterAddress::AlControl.addr()),
            &[state as u8, 0],
        );
        assert_eq!(r.wkc, self.slaves, "every slave takes the AL control write");
    }

    fn lrw(&mut self) -> Reply {
        let io = std::mem::take(&mut self.io);
        let reply = self.exchange(Command::Lrw, Address::Logical(0), &io);
        self.io = io;
        reply
    }

    /// The LRW's working counter when every slave reads and writes.
    fn expected_wkc(&self) -> u16 {
        WKC_PER_SLAVE * self.slaves
    }

    /// Init → Pre-Op → Safe-Op → Op with the default mapping (the ESC reference kept beside the
    /// project, §9.1).
    fn start_up(&mut self) {
        let r = self.exchange(
            Command::Bwr,
            phys(0, RegisterAddress::AlControl.addr()),
            &[AlState::Init as u8 | 0x10, 0],
        );
        assert_eq!(r.wkc, self.slaves, "every slave answers the broadcast");
        let mailboxes = mailboxes();
        for k in 0..self.slaves {
            // Auto-increment address: the k-th slave on the wire is at -k.
            let r = self.exchange(
                Command::Apwr,
                phys(
                    0u16.wrapping_sub(k),
                    RegisterAddress::ConfiguredStationAddress.addr(),
                ),
                &(STATION + k).to_le_bytes(),
            );
            assert_eq!(r.wkc, 1, "station address of slave {k} set");
            self.fpwr(STATION + k, RegisterAddress::Sm0.addr(), &mailboxes);
        }
        self.request(AlState::PreOp);
        assert!(self.all_in(AlState::PreOp), "Pre-Op");

        let slaves = self.slaves;
        for k in 0..slaves {
            configure_process_data(k, slaves, |station, register, data| {
                self.fpwr(station, register, data)
            });
        }
        self.request(AlState::SafeOp);
        assert!(self.all_in(AlState::SafeOp), "Safe-Op");

        // Outputs before and while Op is requested, as SOEM does.
        self.lrw();
        self.request(AlState::Op);
        for _ in 0..200 {
            self.lrw();
            if self.all_in(AlState::Op) {
                return;
            }
            std::thread::sleep(self.cycle);
        }
        panic!("no Op: AL status {:?}", self.al_status(STATION));
    }

    /// `cycles` LRW frames, one a cycle, to `server`; the hot loop does not allocate.
    fn measure(&mut self, cycles: usize, wait: MasterWait, server: Server) -> Stats {
        self.wait = wait;
        let check_wkc = matches!(server, Server::Twin | Server::BusyPollTwin);
        let expected_wkc = self.expected_wkc();
        let cycle = self.cycle;
        let mut round_trips = Vec::with_capacity(cycles);
        let mut stats = Stats::default();
        let io = std::mem::take(&mut self.io);
        let late_log = std::env::var_os("ECAT_ROUNDTRIP_LATE_LOG").is_some();
        stats.late_at = Vec::with_capacity(if late_log { cycles.min(100_000) } else { 0 });
        let began = Instant::now();
        let mut next = began;
        // A machine too loaded to keep the cycle ends the row at three times its length.
        let give_up = cycle * u32::try_from(cycles).unwrap_or(u32::MAX) * 3;
        for _ in 0..cycles {
            if began.elapsed() > give_up {
                stats.cut_short = true;
                break;
            }
            let len = self.build(Command::Lrw, Address::Logical(0), &io);
            let sent = Instant::now();
            let sent_ns = if late_log { monotonic_ns() } else { 0 };
            if self.send(len).is_err() {
                stats.lost += 1;
            } else {
                match self.recv_reply(REPLY_TIMEOUT) {
                    Some(reply) => {
                        let took = sent.elapsed();
                        round_trips.push(took);
                        stats.late += u32::from(took > cycle);
                        if took > cycle && stats.late_at.len() < stats.late_at.capacity() {
                            stats.late_at.push((sent_ns, took));
                        }
                        stats.wrong_wkc += u32::from(check_wkc && reply.wkc != expected_wkc);
                    }
                    None => stats.lost += 1,
                }
            }
            // Absolute schedule; a cycle that overran starts the next one at once.
            next += cycle;
            let now = Instant::now();
            if next > now {
                match wait {
                    MasterWait::Sleeps => std::thread::sleep(next - now),
                    MasterWait::Spins => {
                        while Instant::now() < next {
                            std::hint::spin_loop();
                        }
                    }
                }
            } else {
                stats.overruns += 1;
                next = now;
            }
        }
        stats.elapsed = began.elapsed();
        round_trips.sort_unstable();
        stats.round_trips = round_trips;
        stats.load = load_average();
        self.wait = MasterWait::Spins;
        self.io = io;
        stats
    }
}

/// `CLOCK_MONOTONIC` now, in ns.
fn monotonic_ns() -> u64 {
    platform::cpu_time::monotonic_ns()
}

/// Every thread of process `pid` at nice value `nice` (a weight a loaded machine's builds
/// cannot outnumber, without the real-time throttling a spinning `SCHED_FIFO` task meets).
fn set_nice(pid: u32, nice: i32) -> io::Result<()> {
    for tid in platform::process::threads(pid)? {
        platform::sched::set_nice(tid, nice)?;
    }
    Ok(())
}

/// Put every thread of process `pid` under `SCHED_FIFO` at [`FIFO_PRIORITY`].
fn set_fifo(pid: u32) -> io::Result<()> {
    for tid in platform::process::threads(pid)? {
        platform::sched::set_fifo(tid, FIFO_PRIORITY)?;
    }
    Ok(())
}

fn phys(adp: u16, ado: u16) -> Address {
    Address::Physical { adp, ado }
}

#[derive(Debug, Default)]
struct Stats {
    /// Sorted send → receive times of the frames that came back.
    round_trips: Vec<Duration>,
    lost: u32,
    /// Replies after more than one cycle.
    late: u32,
    wrong_wkc: u32,
    /// Cycles that took longer than the cycle time (the next one started late).
    overruns: u32,
    elapsed: Duration,
    /// The load average when the row ended.
    load: String,
    /// Ended at three times its length, before all its cycles.
    cut_short: bool,
    /// With `ECAT_ROUNDTRIP_LATE_LOG`: each late reply's send time on `CLOCK_MONOTONIC` (ns)
    /// and how long it took.
    late_at: Vec<(u64, Duration)>,
}

impl Stats {
    /// Nearest-rank percentile `p` (0..=1) of the sorted round trips.
    fn percentile(&self, p: f64) -> Duration {
        let n = self.round_trips.len();
        if n == 0 {
            return Duration::ZERO;
        }
        let rank = ((p * n as f64).ceil() as usize).clamp(1, n);
        self.round_trips[rank - 1]
    }

    /// p50, p99, p99.9, max.
    fn figures(&self) -> [Duration; 4] {
        [
            self.percentile(0.50),
            self.percentile(0.99),
            self.percentile(0.999),
            self.round_trips.last().copied().unwrap_or_default(),
        ]
    }
}

fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

fn ratio(twin: Duration, floor: Duration) -> f64 {
    twin.as_secs_f64() / floor.as_secs_f64().max(1e-9)
}

impl Row {
    /// Appends the row's late replies to `ECAT_ROUNDTRIP_LATE_LOG`, one a line: placement,
    /// master, server, send time on `CLOCK_MONOTONIC` (ns), round trip (µs).
    fn log_late(&self) {
        let Some(path) = std::env::var_os("ECAT_ROUNDTRIP_LATE_LOG") else {
            return;
        };
        let mut text = String::new();
        for (at, took) in &self.stats.late_at {
            text.push_str(&format!(
                "{}\t{}\t{}\t{at}\t{}\n",
                self.placement,
                self.wait.label(),
                self.server.label(),
                took.as_micros()
            ));
        }
        let written = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .and_then(|mut f| std::io::Write::write_all(&mut f, text.as_bytes()));
        if let Err(e) = written {
            eprintln!(
                "cannot write the late replies to {}: {e}",
                path.to_string_lossy()
            );
        }
    }

    fn print(&self) {
        let s = &self.stats;
        let names = ["p50", "p99", "p99.9", "max"];
        let mut line = format!("  {:<14} {:<22}", self.wait.label(), self.server.label());
        for (k, (name, value)) in names.iter().zip(s.figures()).enumerate() {
            line.push_str(&format!(" {name} {:>6.1} µs", us(value)));
            if let Some(floor) = self.floor {
                line.push_str(&format!(" ({:.2}×)", ratio(value, floor[k])));
            }
        }
        line.push_str(&format!(
            ", {} late, {} lost, {} wrong WKC, {} overran, {:.1} s{}, load {}",
            s.late,
            s.lost,
            s.wrong_wkc,
            s.overruns,
            s.elapsed.as_secs_f64(),
            if s.cut_short { " (cut short)" } else { "" },
            s.load
        ));
        println!("{line}");
    }

    /// The targets that apply to this row, met or not.
    fn verdict(&self) {
        let Some(floor) = self.floor else {
            return;
        };
        let f = self.stats.figures();
        let met = |ok: bool| if ok { "met" } else { "NOT met" };
        let prefix = format!(
            "  {}, {}, {}:",
            self.placement,
            self.wait.label(),
            self.server.label()
        );
        match (self.wait, self.server) {
            (MasterWait::Sleeps, Server::Twin) if self.slaves > 1 => {
                let r = ratio(f[1], floor[1]);
                println!(
                    "{prefix} {} slaves: p99 {r:.2}× the floor of its frame (≤ {TARGET_CHAIN_P99}: \
                     {}), {} late (0: {})",
                    self.slaves,
                    met(r <= TARGET_CHAIN_P99),
                    self.stats.late,
                    met(self.stats.late == 0 && self.stats.lost == 0)
                );
            }
            (MasterWait::Sleeps, Server::Twin) => {
                let [p50, p99, p999] = TARGET_SLEEPS;
                let r = [
                    ratio(f[0], floor[0]),
                    ratio(f[1], floor[1]),
                    ratio(f[2], floor[2]),
                ];
                println!(
                    "{prefix} p50 {:.2}× (≤ {p50}: {}), p99 {:.2}× (≤ {p99}: {}), \
                     p99.9 {:.2}× (≤ {p999}: {}), {} late (0: {})",
                    r[0],
                    met(r[0] <= p50),
                    r[1],
                    met(r[1] <= p99),
                    r[2],
                    met(r[2] <= p999),
                    self.stats.late,
                    met(self.stats.late == 0 && self.stats.lost == 0)
                );
            }
            (MasterWait::Spins, Server::BusyPollTwin) => {
                let r = ratio(f[0], floor[0]);
                println!(
                    "{prefix} p50 {r:.2}× the spinning echo (≤ {TARGET_BUSY_POLL_P50}: {})",
                    met(r <= TARGET_BUSY_POLL_P50)
                );
            }
            _ => {}
        }
    }
}
