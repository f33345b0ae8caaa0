//! Frame processing time of the sans-IO core: a 1-slave cyclic frame with one LRW (3 output bytes,
//! 6 input bytes, as SOEM maps a CSP drive) and, in a second case, the FRMW of DC and an FPRD of AL
//! status as ethercrab appends (the ESC reference kept beside the project, §7.5, §9.4 step 18).
//! Target: under 2 µs per frame.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use ethercat::datagram::Command;
use ethercat::frame::{Address, FrameWriter};
use ethercat::{Eeprom, Esc, EscConfig, Fmmu, FrameOutcome, MailboxLayout};
use od::Instant;

fn frame(reqs: &[(Command, Address, &[u8])]) -> Vec<u8> {
    let mut buf = vec![0u8; 256];
    let mut w = FrameWriter::ethernet(&mut buf, [0x10; 6]).expect("buffer");
    for (i, (c, a, d)) in reqs.iter().enumerate() {
        w.push(*c, i as u8, *a, d).expect("datagram");
    }
    let n = w.finish();
    buf.truncate(n);
    buf
}

fn run(esc: &mut Esc<'_>, now: Instant, reqs: &[(Command, Address, &[u8])]) {
    let mut f = frame(reqs);
    let o = esc.process(now, &mut f);
    assert!(matches!(o, FrameOutcome::Processed { .. }), "{o:?}");
}

fn op_slave() -> Esc<'static> {
    let cfg = EscConfig {
        mailbox: Some(MailboxLayout {
            rx_offset: 0x1000,
            rx_size: 0x80,
            tx_offset: 0x1080,
            tx_size: 0x80,
        }),
        ..EscConfig::default()
    };
    let mut esc = Esc::new(cfg, Eeprom::None);
    let t = Instant::ZERO;
    let p = |ado| Address::Physical { adp: 0x1001, ado };
    run(
        &mut esc,
        t,
        &[(
            Command::Apwr,
            Address::Physical { adp: 0, ado: 0x10 },
            &[0x01, 0x10],
        )],
    );
    let sms: [u8; 32] = [
        0x00, 0x10, 0x80, 0x00, 0x26, 0, 1, 0, 0x80, 0x10, 0x80, 0x00, 0x22, 0, 1, 0, //
        0x00, 0x11, 3, 0, 0x64, 0, 1, 0, 0x80, 0x11, 6, 0, 0x20, 0, 1, 0,
    ];
    let f0 = Fmmu::bytes(0, 3, 0x1100, false, true).to_bytes();
    let f1 = Fmmu::bytes(3, 6, 0x1180, true, false).to_bytes();
    run(
        &mut esc,
        t,
        &[
            (Command::Fpwr, p(0x0800), &sms),
            (Command::Fpwr, p(0x0600), &f0),
            (Command::Fpwr, p(0x0610), &f1),
        ],
    );
    for s in [2u8, 4, 8] {
        run(&mut esc, t, &[(Command::Fpwr, p(0x0120), &[s, 0])]);
    }
    assert_eq!(esc.read_u16(0x0130), 8, "Op");
    esc
}

fn lrw_cycle(c: &mut Criterion) {
    let mut esc = op_slave();
    let outputs = [0x0F, 0x00, 0x08, 0, 0, 0, 0, 0, 0];
    let template = frame(&[(Command::Lrw, Address::Logical(0), &outputs)]);
    let mut f = template.clone();
    let mut now = 1_000_000u64;
    c.bench_function("lrw_1_slave_frame", |b| {
        b.iter(|| {
            f.copy_from_slice(&template);
            now += 1_000_000;
            let o = esc.process(Instant::from_nanos(now), black_box(&mut f));
            let _ = esc.process_outputs();
            let _ = esc.set_inputs(&[0x37, 0x02, 1, 2, 3, 4]);
            black_box(o)
        })
    });
    let mut esc = op_slave();
    let template = frame(&[
        (
            Command::Frmw,
            Address::Physical {
                adp: 0x1001,
                ado: 0x0910,
            },
            &[0; 8],
        ),
        (Command::Lrw, Address::Logical(0), &outputs),
        (
            Command::Fprd,
            Address::Physical {
                adp: 0x1001,
                ado: 0x0130,
            },
            &[0; 2],
        ),
    ]);
    let mut f = template.clone();
    c.bench_function("frmw_lrw_fprd_1_slave_frame", |b| {
        b.iter(|| {
            f.copy_from_slice(&template);
            now += 1_000_000;
            let o = esc.process(Instant::from_nanos(now), black_box(&mut f));
            black_box(o)
        })
    });
}

criterion_group!(benches, lrw_cycle);
criterion_main!(benches);
