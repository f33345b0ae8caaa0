//! The sans-IO stack alone: an SDO expedited upload request in, the response out.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use canopen::{CanFrame, Node};
use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use od::{Instant, ObjectDictionary};

fn sdo_expedited_upload(c: &mut Criterion) {
    let desc = &devices::CMMP_AS;
    let mut od = ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).expect("storage");
    let mut node: Node = Node::new(1, desc.cia301);
    node.boot(Instant::ZERO, &od, &mut |_| {});
    // Read 6041h:00 (statusword), CMMP-SDO-03.
    let req = CanFrame::new(0x601, &[0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0]).expect("frame");
    let mut g = c.benchmark_group("sdo_server");
    g.throughput(Throughput::Elements(1));
    g.bench_function("expedited_upload_6041", |b| {
        b.iter(|| {
            let mut resp = None;
            node.on_frame(Instant::ZERO, black_box(&req), &mut od, &mut |f| {
                resp = Some(f)
            });
            black_box(resp)
        })
    });
    let write = CanFrame::new(0x601, &[0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0, 0]).expect("frame");
    g.bench_function("expedited_download_1017", |b| {
        b.iter(|| {
            let mut resp = None;
            node.on_frame(Instant::ZERO, black_box(&write), &mut od, &mut |f| {
                resp = Some(f)
            });
            black_box(resp)
        })
    });
    g.finish();
}

criterion_group!(benches, sdo_expedited_upload);
criterion_main!(benches);
