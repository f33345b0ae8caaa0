//! An SDO round trip through the socketcand server on loopback: a raw socketcand client sends
//! an expedited upload request, the cell answers, the client reads the response frame. Prints
//! p50 / p99 of the round trip next to criterion's mean.

use std::time::{Duration, Instant as WallInstant};

use criterion::{criterion_group, criterion_main, Criterion};
use drivetwin::can::bus::Bus;
use drivetwin::can::drive::CanDrive;
use drivetwin::can::socketcand;
use drivetwin::cell::runtime;
use drivetwin::cell::Cell;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

struct Client {
    stream: TcpStream,
    buf: Vec<u8>,
}

impl Client {
    async fn read_message(&mut self) -> String {
        loop {
            if let Some(end) = self.buf.iter().position(|b| *b == b'>') {
                let msg: Vec<u8> = self.buf.drain(..=end).collect();
                return String::from_utf8_lossy(&msg).trim().to_string();
            }
            let mut chunk = [0u8; 512];
            let n = self.stream.read(&mut chunk).await.expect("read");
            assert!(n > 0, "server closed");
            self.buf.extend_from_slice(&chunk[..n]);
        }
    }

    async fn round_trip(&mut self) {
        self.stream
            .write_all(b"< send 601 8 40 41 60 00 00 00 00 00 >")
            .await
            .expect("write");
        loop {
            let m = self.read_message().await;
            if m.starts_with("< frame 581 ") {
                return;
            }
        }
    }
}

async fn setup() -> Client {
    let bus = Bus::new(drivetwin::can::bus::DEFAULT_CAPACITY);
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = listener.local_addr().expect("addr");
    tokio::spawn(socketcand::serve(listener, bus.clone(), "vcan0"));
    let drive = CanDrive::new(&devices::CMMP_AS, 1, None, vec![]).expect("drive");
    tokio::spawn(runtime::run_realtime(
        Cell::new(vec![drive]),
        bus,
        None,
        std::future::pending(),
    ));
    let stream = TcpStream::connect(addr).await.expect("connect");
    stream.set_nodelay(true).expect("nodelay");
    let mut c = Client {
        stream,
        buf: Vec::new(),
    };
    assert_eq!(c.read_message().await, "< hi >");
    c.stream.write_all(b"< open vcan0 >").await.expect("open");
    assert_eq!(c.read_message().await, "< ok >");
    c.stream.write_all(b"< rawmode >").await.expect("raw");
    assert_eq!(c.read_message().await, "< ok >");
    tokio::time::sleep(Duration::from_millis(200)).await;
    c
}

fn bench(c: &mut Criterion) {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    let mut client = rt.block_on(setup());

    // Percentiles from a plain sample.
    let mut samples: Vec<Duration> = rt.block_on(async {
        for _ in 0..200 {
            client.round_trip().await;
        }
        let mut v = Vec::with_capacity(5000);
        for _ in 0..5000 {
            let t = WallInstant::now();
            client.round_trip().await;
            v.push(t.elapsed());
        }
        v
    });
    samples.sort();
    let pct = |p: f64| samples[((samples.len() as f64 * p) as usize).min(samples.len() - 1)];
    println!(
        "socketcand SDO round trip over loopback: p50 {:?}, p99 {:?}, max {:?} ({} samples)",
        pct(0.50),
        pct(0.99),
        samples[samples.len() - 1],
        samples.len()
    );

    c.bench_function("socketcand_sdo_round_trip", |b| {
        b.iter_custom(|iters| {
            rt.block_on(async {
                let t = WallInstant::now();
                for _ in 0..iters {
                    client.round_trip().await;
                }
                t.elapsed()
            })
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
