//! Does the web console move the cell loop's jitter?
//!
//! A cell of 16 CMMP-AS (CiA 402, each with its simulated drive and motor, nodes 1…16 on one
//! CAN bus) runs in real time on its loop thread, enabled in profile velocity mode, each
//! target velocity reversed every second so that the plant accelerates and draws current. The
//! same cell runs twice for `CONSOLE_JITTER_SECS` seconds (default 10):
//!
//! - `floor`: no console;
//! - `console`: the web console ([`drivetwin::web::start`], its own thread and runtime as in
//!   the binary) serving two WebSocket clients ("tabs"), each subscribed to all 16 drives at
//!   1 kHz with four signals: position, velocity, current (the plant) and the following error
//!   (`objects=60F4:0`), batched every 50 ms as the page asks.
//!
//! For each run it prints the loop's lateness ([`CellLoop::lateness`]: how late the loop
//! served its due timers; p50 / p99 / p99.9 as power-of-two bucket bounds, max exact), and for
//! the console run the console's CPU share and the samples each tab received per second.
//!
//! CPU time is read from `/proc/self/task/*/stat` (utime + stime of each thread, in clock
//! ticks) at the start and end of the measured window, grouped by thread name: the loop
//! (`cell-loop`), the console (`web`, `web-worker`: its server thread, runtime workers and
//! blocking pool) and the clients (`tab-*`); the process total is `getrusage(RUSAGE_SELF)`.
//! The console's share is printed both ways: its own threads, and the process minus the loop
//! and the clients (which also counts threads that ended within the window).
//!
//! Placement: the loop thread is pinned to the last CPU; the console and the clients are left
//! to the scheduler, or with `CONSOLE_JITTER_SPLIT=1` pinned to CPU 0 (they inherit the main
//! thread's affinity). `CONSOLE_JITTER_FIFO=1` runs the loop at `SCHED_FIFO` 80 (the binary's
//! `--rt-priority 80`; needs root or `CAP_SYS_NICE`).
//!
//! `cargo bench -p drivetwin --bench console_jitter`; `CONSOLE_JITTER_ROUNDS` repeats the pair
//! of runs (default 1), each round printing its own figures (the machine may be shared).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::collections::BTreeMap;
use std::io;
use std::process::ExitCode;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::control::ControlHandle;
use drivetwin::cell::lateness::LatenessFigures;
use drivetwin::cell::station::Station;
use drivetwin::cell_loop::{CellLoop, FrontEnds};
use drivetwin::web::{self, HttpSetting};

const DRIVES: usize = 16;
const TABS: usize = 2;
/// Warm-up before the measured window: enabling, first subscriptions.
const SETTLE: Duration = Duration::from_millis(500);

fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn pin(cpu: usize) -> bool {
    if let Err(e) = platform::sched::pin(0, cpu) {
        eprintln!("cannot pin to CPU {cpu}: {e}");
        return false;
    }
    true
}

/// CPU time per thread name (`comm`), from `/proc/self/task/*/stat`.
fn thread_cpu() -> BTreeMap<String, Duration> {
    let hz = platform::cpu_time::ticks_per_second();
    let mut by_name = BTreeMap::new();
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return by_name;
    };
    for task in dir.flatten() {
        let Ok(stat) = std::fs::read_to_string(task.path().join("stat")) else {
            continue;
        };
        // `pid (comm) state … utime stime …`: comm may hold spaces, so split at the last ')'.
        let (Some(open), Some(close)) = (stat.find('('), stat.rfind(')')) else {
            continue;
        };
        let name = stat.get(open + 1..close).unwrap_or("").to_owned();
        let rest: Vec<&str> = stat
            .get(close + 1..)
            .unwrap_or("")
            .split_whitespace()
            .collect();
        // Fields 14 and 15 of proc(5); `rest` starts at field 3.
        let ticks: u64 = [11, 12]
            .iter()
            .filter_map(|&i| rest.get(i).and_then(|v| v.parse::<u64>().ok()))
            .sum();
        *by_name.entry(name).or_insert(Duration::ZERO) +=
            Duration::from_nanos(ticks * 1_000_000_000 / hz);
    }
    by_name
}

/// The process's CPU time (every thread, ended ones too).
fn process_cpu() -> Duration {
    platform::cpu_time::process()
}

struct CpuSnapshot {
    threads: BTreeMap<String, Duration>,
    process: Duration,
}

impl CpuSnapshot {
    fn now() -> CpuSnapshot {
        CpuSnapshot {
            threads: thread_cpu(),
            process: process_cpu(),
        }
    }

    /// CPU time of the threads whose name `matches`, since `before`.
    fn group_since(&self, before: &CpuSnapshot, matches: impl Fn(&str) -> bool) -> Duration {
        let sum = |s: &CpuSnapshot| -> Duration {
            s.threads
                .iter()
                .filter(|(n, _)| matches(n))
                .map(|(_, d)| *d)
                .sum()
        };
        sum(self).saturating_sub(sum(before))
    }
}

/// 16 CMMP-AS with motors on one bus, nodes 1…16.
fn cell() -> Result<CanCell, String> {
    let cmmp = devices::by_name("cmmp-as").ok_or("no cmmp-as")?;
    let drives = (1..=DRIVES as u8)
        .map(|node| {
            Station::with_settings(cmmp, node, None, vec![], Some(Default::default()))
                .map_err(|e| e.to_string())
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(CanCell::one_bus(drives))
}

/// Profile velocity mode, a target velocity, then the controlword steps to OPERATION ENABLED
/// (CMMP-AS §6.1.3 Tab. 6.4), as the console's enable does.
fn enable_all(h: &ControlHandle) -> Result<(), String> {
    let e = |e: drivetwin::cell::control::ControlError| e.to_string();
    for d in 0..DRIVES {
        h.write(d, 0x6060, 0, &[3]).map_err(e)?;
        h.write(d, 0x60FF, 0, &velocity(d, false).to_le_bytes())
            .map_err(e)?;
        for cw in [0x0006u16, 0x0007, 0x000F] {
            h.write(d, 0x6040, 0, &cw.to_le_bytes()).map_err(e)?;
            std::thread::sleep(Duration::from_millis(3));
        }
    }
    let sw = h.read(0, 0x6041, 0).map_err(e)?;
    let sw = u16::from_le_bytes([*sw.first().unwrap_or(&0), *sw.get(1).unwrap_or(&0)]);
    if sw & 0x006F != 0x0027 {
        return Err(format!("drive 0 not enabled: statusword {sw:04X}h"));
    }
    Ok(())
}

/// Drive `d`'s target velocity (user units per second), reversed when `back`.
fn velocity(d: usize, back: bool) -> i32 {
    let v = 1000 + 100 * d as i32;
    if back {
        -v
    } else {
        v
    }
}

/// A browser tab: 16 WebSockets on a runtime of its own thread, counting the samples received.
fn tab(addr: std::net::SocketAddr, n: usize, samples: Arc<AtomicU64>) -> io::Result<()> {
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    std::thread::Builder::new()
        .name(format!("tab-{n}"))
        .spawn(move || {
            let rt = match tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
            {
                Ok(rt) => rt,
                Err(e) => {
                    let _ = ready_tx.send(Err(e.to_string()));
                    return;
                }
            };
            rt.block_on(async move {
                use futures_util::StreamExt;
                let mut tasks = Vec::new();
                for d in 0..DRIVES {
                    let url = format!(
                        "ws://{addr}/api/drives/{d}/samples?rate_hz=1000&batch_ms=50&objects=60F4:0"
                    );
                    let ws = match tokio_tungstenite::connect_async(url).await {
                        Ok((ws, _)) => ws,
                        Err(e) => {
                            let _ = ready_tx.send(Err(format!("drive {d}: {e}")));
                            return;
                        }
                    };
                    let samples = Arc::clone(&samples);
                    tasks.push(tokio::spawn(async move {
                        let (_, mut rx) = ws.split();
                        while let Some(Ok(m)) = rx.next().await {
                            let Ok(text) = m.to_text() else { continue };
                            let Ok(v) = serde_json::from_str::<serde_json::Value>(text) else {
                                continue;
                            };
                            // Four signals per sample, as the page draws them.
                            let full = v["samples"].as_array().map_or(0, |s| {
                                s.iter()
                                    .filter(|p| {
                                        p["position"].is_number()
                                            && p["velocity"].is_number()
                                            && p["current"].is_number()
                                            && p["objects"]["60F4:00"].is_number()
                                    })
                                    .count()
                            });
                            samples.fetch_add(full as u64, Ordering::Relaxed);
                        }
                    }));
                }
                let _ = ready_tx.send(Ok(()));
                for t in tasks {
                    let _ = t.await;
                }
            });
        })?;
    ready_rx
        .recv()
        .map_err(|_| io::Error::other("tab thread ended"))?
        .map_err(io::Error::other)
}

struct Run {
    lateness: LatenessFigures,
    secs: f64,
    loop_cpu: Duration,
    console_threads: Duration,
    console_rest: Duration,
    tab_samples: Vec<u64>,
}

fn run(with_console: bool, secs: u64, loop_cpu_no: usize, fifo: bool) -> Result<Run, String> {
    let cell_loop = CellLoop::new(
        cell()?,
        FrontEnds {
            rt_priority: fifo.then_some(80),
            ..FrontEnds::default()
        },
    )
    .map_err(|e| e.to_string())?;
    let handle = cell_loop.control_handle();
    let stop = cell_loop.stop_handle();
    let lateness = cell_loop.lateness();
    let thread = std::thread::Builder::new()
        .name("cell-loop".into())
        .spawn(move || {
            pin(loop_cpu_no);
            cell_loop.run().map(|_| ()).map_err(|e| e.to_string())
        })
        .map_err(|e| e.to_string())?;
    enable_all(&handle)?;
    let counters: Vec<Arc<AtomicU64>> = (0..TABS).map(|_| Arc::default()).collect();
    let _console = if with_console {
        let console = web::start(
            &HttpSetting::At("127.0.0.1:0".into()),
            handle.clone(),
            drivetwin::vendors::VENDORS.web_pages,
        )
        .map_err(|e| e.to_string())?
        .ok_or("no console")?;
        for (n, c) in counters.iter().enumerate() {
            tab(console.addr, n, Arc::clone(c)).map_err(|e| e.to_string())?;
        }
        Some(console)
    } else {
        None
    };
    std::thread::sleep(SETTLE);
    let position_before = handle.read(0, 0x6064, 0).map_err(|e| e.to_string())?;
    let before = CpuSnapshot::now();
    let counted: Vec<u64> = counters.iter().map(|c| c.load(Ordering::Relaxed)).collect();
    let t0 = Instant::now();
    let mut back = false;
    while t0.elapsed() < Duration::from_secs(secs) {
        std::thread::sleep(Duration::from_secs(1));
        back = !back;
        for d in 0..DRIVES {
            handle
                .write(d, 0x60FF, 0, &velocity(d, back).to_le_bytes())
                .map_err(|e| e.to_string())?;
        }
    }
    let elapsed = t0.elapsed().as_secs_f64();
    let after = CpuSnapshot::now();
    let tab_samples = counters
        .iter()
        .zip(&counted)
        .map(|(c, b)| c.load(Ordering::Relaxed) - b)
        .collect();
    let position_after = handle.read(0, 0x6064, 0).map_err(|e| e.to_string())?;
    let figures = lateness.figures();
    stop.stop();
    thread
        .join()
        .map_err(|_| "the loop panicked".to_string())??;
    if position_after == position_before {
        return Err("drive 0 did not move".into());
    }
    let loop_cpu = after.group_since(&before, |n| n == "cell-loop");
    let console_threads = after.group_since(&before, |n| n.starts_with("web"));
    let tabs = after.group_since(&before, |n| n.starts_with("tab-"));
    let process = after.process.saturating_sub(before.process);
    Ok(Run {
        lateness: figures,
        secs: elapsed,
        loop_cpu,
        console_threads,
        console_rest: process.saturating_sub(loop_cpu + tabs),
        tab_samples,
    })
}

fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

fn print(label: &str, r: &Run) {
    let f = &r.lateness;
    println!(
        "{label:<8} lateness p50 ≤ {:.0} µs  p99 ≤ {:.0} µs  p99.9 ≤ {:.0} µs  max {:.0} µs  \
         ({} timers served, {:.1} s); loop thread {:.1} % of a CPU",
        us(f.p50),
        us(f.p99),
        us(f.p999),
        us(f.max),
        f.served,
        r.secs,
        r.loop_cpu.as_secs_f64() / r.secs * 100.0
    );
}

/// The floor run, then the console run; whether the console's p99 bucket is above the floor's.
fn one_round(secs: u64, loop_cpu: usize, fifo: bool) -> Result<bool, String> {
    let floor = match run(false, secs, loop_cpu, fifo) {
        Ok(r) => r,
        Err(e) => return Err(format!("floor: {e}")),
    };
    print("floor", &floor);
    let console = match run(true, secs, loop_cpu, fifo) {
        Ok(r) => r,
        Err(e) => return Err(format!("console: {e}")),
    };
    print("console", &console);
    println!(
        "console CPU: its threads {:.1} % of a CPU; process minus loop and clients {:.1} %",
        console.console_threads.as_secs_f64() / console.secs * 100.0,
        console.console_rest.as_secs_f64() / console.secs * 100.0
    );
    for (n, s) in console.tab_samples.iter().enumerate() {
        println!(
            "tab {n}: {:.0} samples/s of 4 signals ({DRIVES} drives × 1 kHz = {} wanted)",
            *s as f64 / console.secs,
            DRIVES * 1000
        );
    }
    let moved = console.lateness.p99 > floor.lateness.p99;
    println!(
        "p99: floor ≤ {:.0} µs, console ≤ {:.0} µs: {}",
        us(floor.lateness.p99),
        us(console.lateness.p99),
        if moved { "MOVED" } else { "not moved" }
    );
    Ok(moved)
}

fn main() -> ExitCode {
    let secs = env_u64("CONSOLE_JITTER_SECS", 10).max(1);
    let rounds = env_u64("CONSOLE_JITTER_ROUNDS", 1).max(1);
    let fifo = std::env::var("CONSOLE_JITTER_FIFO").is_ok_and(|v| v == "1");
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let loop_cpu = cpus - 1;
    let split = cpus > 1 && std::env::var("CONSOLE_JITTER_SPLIT").is_ok_and(|v| v == "1");
    // The loop thread pins itself after it is spawned; the console's and the clients' threads
    // inherit this thread's affinity.
    let others = if split && pin(0) {
        "console and clients pinned to CPU 0"
    } else {
        "console and clients unpinned"
    };
    println!(
        "{cpus} CPUs; loop pinned to CPU {loop_cpu}{}; {others}; \
         {DRIVES} CMMP-AS with motors, {secs} s per run",
        if fifo {
            ", SCHED_FIFO 80"
        } else {
            ", SCHED_OTHER"
        }
    );
    let mut moved_rounds = 0;
    for round in 1..=rounds {
        if rounds > 1 {
            println!("round {round} of {rounds}:");
        }
        match one_round(secs, loop_cpu, fifo) {
            Ok(true) => moved_rounds += 1,
            Ok(false) => {}
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    if rounds > 1 {
        println!("p99 moved in {moved_rounds} of {rounds} rounds");
    }
    ExitCode::SUCCESS
}
