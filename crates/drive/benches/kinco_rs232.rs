//! The Kinco RS232 codec alone: a 10-byte telegram in, the answer out.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use drive::vendors::kinco::rs232::KincoRs232;
use od::{Instant, ObjectDictionary};

fn kinco_rs232(c: &mut Criterion) {
    let desc = &devices::KINCO_FD3;
    let mut od = ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).expect("storage");
    let mut port = KincoRs232::new(1, false);
    // KINCO-232-04 (read the statusword) and KINCO-232-01 (write the controlword).
    let read = [0x01, 0x40, 0x41, 0x60, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1E];
    let write = [0x01, 0x2B, 0x40, 0x60, 0x00, 0x2F, 0x00, 0x00, 0x00, 0x05];
    let mut g = c.benchmark_group("kinco_rs232");
    g.throughput(Throughput::Bytes(10));
    for (name, t) in [("read_6041", read), ("write_6040", write)] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut answer = [0u8; 10];
                port.on_bytes(Instant::ZERO, black_box(&t), &mut od, &mut |a| {
                    answer.copy_from_slice(a)
                });
                black_box(answer)
            })
        });
    }
    g.finish();
}

criterion_group!(benches, kinco_rs232);
criterion_main!(benches);
