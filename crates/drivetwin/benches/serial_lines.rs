//! The serial front ends, timed.
//!
//! - `serial_lines/*` (criterion): one telegram or RTU frame through a line, sans-IO: the
//!   wire's timing, the cutter or the 3.5-character framer, the codec and the drive's object
//!   access (a plain FD3 dictionary). The codecs alone are `cargo bench -p drive --bench
//!   kinco_rs232` and `cargo bench -p drive --bench kinco_rtu`.
//! - Then, printed: the round trip of a 10-byte telegram and its 10-byte answer over the pty
//!   of a running cell loop at 38400 and 115200 bit/s, against the wire time of the 20 bytes
//!   (target: the twin adds under 10 %). `SERIAL_BENCH_COUNT` round trips per rate (200).
//!
//! `cargo bench -p drivetwin --bench serial_lines`.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::{Duration, Instant as StdInstant};

use criterion::{black_box, Criterion};
use drive::vendors::kinco::rs232::{KincoRs232, Request};
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::station::{Commissioning, Station};
use drivetwin::cell::stations::StationId;
use drivetwin::cell_loop::{CellLoop, FrontEnds};
use drivetwin::serial::pty::Port;
use drivetwin::serial::wire::Wire;
use drivetwin::serial::LineRequest;
use drivetwin::serial::{Kind, LineDrives};
use drivetwin::vendors::kinco::rs232_line::{TelegramLine, Topology};
use drivetwin::vendors::kinco::rtu_line::{RtuDrive, RtuLine};
use drivetwin::vendors::kinco::serial_lines::{open_lines, register_map};
use od::{Instant, ObjectAccess, ObjectDictionary};

struct Plain(ObjectDictionary<Vec<u8>>);

impl LineDrives for Plain {
    fn access(&mut self, _at: StationId, _now: Instant, f: &mut dyn FnMut(&mut dyn ObjectAccess)) {
        f(&mut self.0);
    }
}

const AT: StationId = StationId::from_index(0);

fn fd3() -> Plain {
    let d = &devices::KINCO_FD3;
    Plain(ObjectDictionary::new(d, 1, vec![0; d.storage_size]).expect("storage"))
}

fn sans_io(c: &mut Criterion) {
    let mut g = c.benchmark_group("serial_lines");
    let read = Request::Read {
        index: 0x6041,
        sub: 0,
    }
    .emit(1);
    let mut drives = fd3();
    let mut line = TelegramLine::new(vec![(AT, KincoRs232::new(1, false))], Topology::Ring, None);
    let mut wire = Wire::new(38_400);
    let mut t = 0u64;
    g.bench_function("rs232_read_6041", |b| {
        b.iter(|| {
            t += 10_000_000;
            let now = Instant::from_nanos(t);
            wire.receive(now, black_box(&read));
            let end = now + Duration::from_millis(6);
            let mut bytes = [(Instant::ZERO, 0u8); 10];
            let mut n = 0;
            wire.arrived(end, &mut |at, x| {
                if let Some(s) = bytes.get_mut(n) {
                    *s = (at, x);
                    n += 1;
                }
            });
            for &(at, x) in bytes.iter().take(n) {
                line.on_byte(at, x, &mut drives, &mut wire);
            }
            wire.crossed(end);
            wire.flush(&mut |b| black_box(b).len());
        })
    });
    let frame = [0x01, 0x03, 0x32, 0x00, 0x00, 0x02, 0xCA, 0xB3];
    let mut rtu = RtuLine::new(
        19_200,
        vec![RtuDrive {
            at: AT,
            station: 1,
            map: register_map("kinco-fd3"),
        }],
    );
    let mut wire = Wire::new(19_200);
    g.bench_function("rtu_fc03_read_3200", |b| {
        b.iter(|| {
            t += 20_000_000;
            let now = Instant::from_nanos(t);
            wire.receive(now, black_box(&frame));
            let end = now + Duration::from_millis(15);
            let mut bytes = [(Instant::ZERO, 0u8); 8];
            let mut n = 0;
            wire.arrived(end, &mut |at, x| {
                if let Some(s) = bytes.get_mut(n) {
                    *s = (at, x);
                    n += 1;
                }
            });
            for &(at, x) in bytes.iter().take(n) {
                rtu.on_byte(at, x, &mut drives, &mut wire);
            }
            rtu.poll(end, &mut drives, &mut wire);
            wire.crossed(end);
            wire.flush(&mut |b| black_box(b).len());
        })
    });
    g.finish();
}

/// Round trips over the pty of a running cell at `baud` (RS232_Baudrate code `code`).
fn pty_round_trip(baud: u32, code: u16, count: usize) -> Result<(), String> {
    let dir = std::env::temp_dir().join(format!("drivetwin-bench-{}-{baud}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let path = dir.join("ttyKINCO");
    let drive = Station::new(
        &devices::KINCO_FD3,
        1,
        None,
        vec![Commissioning {
            index: 0x2FE0,
            sub: 0,
            bytes: code.to_le_bytes().to_vec(),
        }],
    )
    .map_err(|e| e.to_string())?;
    let cell = CanCell::one_bus(vec![drive]);
    let requests = [LineRequest {
        kind: Kind::Rs232,
        path: path.clone(),
        drive: AT,
    }];
    let serial = open_lines(&requests, &cell).map_err(|e| e.to_string())?;
    let cell_loop = CellLoop::new(
        cell,
        FrontEnds {
            serial,
            ..FrontEnds::default()
        },
    )
    .map_err(|e| e.to_string())?;
    let stop = cell_loop.stop_handle();
    let thread = std::thread::spawn(move || cell_loop.run());
    let host = Port::device(&path, baud).map_err(|e| e.to_string())?;
    let read = Request::Read {
        index: 0x6041,
        sub: 0,
    }
    .emit(1);
    let mut times = Vec::with_capacity(count);
    for i in 0..count + 20 {
        let t = StdInstant::now();
        host.write(&read);
        let mut got = 0;
        while got < 10 {
            if !host
                .wait_readable(Duration::from_millis(200))
                .map_err(|e| e.to_string())?
            {
                return Err("no answer".into());
            }
            let mut buf = [0u8; 32];
            got += host.read(&mut buf).map_err(|e| e.to_string())?;
        }
        if i >= 20 {
            times.push(t.elapsed());
        }
    }
    stop.stop();
    let _ = thread.join();
    let _ = std::fs::remove_dir_all(&dir);
    times.sort();
    let wire = Duration::from_nanos(20 * 10 * 1_000_000_000 / u64::from(baud));
    let p = |q: usize| {
        times
            .get(times.len() * q / 100)
            .copied()
            .unwrap_or_default()
    };
    println!(
        "pty round trip at {baud} bit/s: wire {:.3} ms, p50 {:.3} ms ({:+.1} %), p99 {:.3} ms",
        wire.as_secs_f64() * 1e3,
        p(50).as_secs_f64() * 1e3,
        (p(50).as_secs_f64() / wire.as_secs_f64() - 1.0) * 100.0,
        p(99).as_secs_f64() * 1e3
    );
    Ok(())
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    sans_io(&mut c);
    c.final_summary();
    let count = std::env::var("SERIAL_BENCH_COUNT")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(200);
    for (baud, code) in [(38_400, 270), (115_200, 90)] {
        if let Err(e) = pty_round_trip(baud, code, count) {
            eprintln!("pty round trip at {baud} bit/s: {e}");
        }
    }
}
