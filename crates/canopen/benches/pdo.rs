//! The PDO path: one SYNC in, every TPDO of a drive with 4 synchronous TPDOs out.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use canopen::{CanFrame, Node};
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use od::{Instant, ObjectAccess, ObjectDictionary};

fn sync_to_tpdos(c: &mut Criterion) {
    let desc = &devices::CMMP_AS;
    let mut od = ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).expect("storage");
    // Four TPDOs on every SYNC, with the manual's default mappings (up to 48 bits each).
    for n in 0..4u16 {
        od.write(0x1800 + n, 2, &[1]).expect("transmission type");
        let cob = 0x4000_0181u32 + 0x100 * u32::from(n);
        od.write(0x1800 + n, 1, &cob.to_le_bytes()).expect("enable");
    }
    let mut node: Node = Node::new(1, desc.cia301);
    node.boot(Instant::ZERO, &od, &mut |_| {});
    let start = CanFrame::new(0x000, &[0x01, 0x01]).expect("frame");
    node.on_frame(Instant::ZERO, &start, &mut od, &mut |_| {});
    let sync = CanFrame::new(0x080, &[]).expect("frame");
    let mut count = 0usize;
    node.on_frame(Instant::ZERO, &sync, &mut od, &mut |_| count += 1);
    assert_eq!(count, 4, "four TPDOs per SYNC");
    c.bench_function("sync_to_4_tpdos", |b| {
        b.iter(|| {
            let mut n = 0usize;
            node.on_frame(Instant::ZERO, black_box(&sync), &mut od, &mut |f| {
                black_box(f);
                n += 1;
            });
            n
        })
    });
}

criterion_group!(benches, sync_to_tpdos);
criterion_main!(benches);
