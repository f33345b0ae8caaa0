//! The cost of the timed CAN bus model per frame: bit-exact frame length (stuffing and
//! CRC-15) and the arbitration among waiting frames.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use canbus::frame_time::frame_bits;
use canbus::timed_bus::TimedBus;
use canbus::CanFrame;
use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use od::Instant;

fn timed_bus(c: &mut Criterion) {
    let frame = CanFrame::new(0x181, &[0x37, 0x06, 0x10, 0x27, 0, 0, 0x55, 0xAA]).expect("frame");
    c.bench_function("frame_bits_8_bytes", |b| {
        b.iter(|| frame_bits(black_box(&frame)))
    });

    // 40 TPDOs ready at one SYNC, drained in arbitration order: cost per frame.
    let mut g = c.benchmark_group("timed_bus");
    g.throughput(Throughput::Elements(40));
    g.bench_function("sync_burst_40_frames_at_1mbit", |b| {
        let mut bus: TimedBus<64> = TimedBus::new(1_000_000);
        let mut t = 0u64;
        b.iter(|| {
            let now = Instant::from_nanos(t);
            for node in 1..=40u16 {
                let f = CanFrame::new(0x180 + node, &[node as u8; 8]).expect("frame");
                let _ = bus.submit(now, node, f);
            }
            while let Some(d) = bus.deadline() {
                while let Some(tx) = bus.poll(d) {
                    black_box(tx);
                }
            }
            t += 10_000_000;
        })
    });
    g.finish();
}

criterion_group!(benches, timed_bus);
criterion_main!(benches);
