//! The Kinco Modbus RTU server alone: the manual's §12.3 frames in, the replies out.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use drive::vendors::kinco::rtu::{ErrorStyle, KincoRtu, RegisterMapping, MAX_FRAME};
use od::ObjectDictionary;

fn kinco_rtu(c: &mut Criterion) {
    let desc = &devices::KINCO_FD3;
    let mut od = ObjectDictionary::new(desc, 1, vec![0u8; desc.storage_size]).expect("storage");
    let map: Vec<RegisterMapping> = devices::addresses("kinco-fd3")
        .expect("kinco-fd3")
        .modbus
        .iter()
        .map(|r| RegisterMapping {
            register: r.register,
            index: r.index,
            sub: r.sub,
        })
        .collect();
    let server = KincoRtu {
        station: 1,
        map: &map,
        errors: ErrorStyle::Read81h,
    };
    // KINCO-MB-01, -02, -03.
    let frames: [(&str, &[u8]); 3] = [
        (
            "fc03_read_3200",
            &[0x01, 0x03, 0x32, 0x00, 0x00, 0x02, 0xCA, 0xB3],
        ),
        (
            "fc06_write_3100",
            &[0x01, 0x06, 0x31, 0x00, 0x00, 0x0F, 0xC7, 0x32],
        ),
        (
            "fc10_write_6f00",
            &[
                0x01, 0x10, 0x6F, 0x00, 0x00, 0x02, 0x04, 0x55, 0x55, 0x00, 0x08, 0x1A, 0x47,
            ],
        ),
    ];
    let mut g = c.benchmark_group("kinco_rtu");
    g.throughput(Throughput::Elements(1));
    for (name, f) in frames {
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut out = [0u8; MAX_FRAME];
                let n = server.handle_frame(black_box(f), &mut od, &mut out);
                black_box((n, out[0]))
            })
        });
    }
    g.finish();
}

criterion_group!(benches, kinco_rtu);
criterion_main!(benches);
