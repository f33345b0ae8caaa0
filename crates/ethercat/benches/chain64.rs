//! A cyclic frame through a line of 64 slaves in the sans-IO core: the ARMW of the DC
//! reference clock's system time that SOEM and ethercrab send every cycle (the ESC reference
//! kept beside the project, §8.1), then one LRW of 3 output and 6 input bytes per slave (a
//! CSP drive as SOEM maps it), 576 bytes in all. Each slave's device side takes its outputs
//! and posts its inputs after the frame, as the chain does. Target: 5 µs per frame.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use ethercat::datagram::Command;
use ethercat::frame::{Address, EthernetFrame, Frame, FrameWriter};
use ethercat::{process_chain, Eeprom, Esc, EscConfig, Fmmu, MailboxLayout};
use od::Instant;

const SLAVES: usize = 64;
const OUT: u16 = 3;
const IN: u16 = 6;

fn frame(reqs: &[(Command, Address, Vec<u8>)]) -> Vec<u8> {
    let mut buf = vec![0u8; 1514];
    let mut w = FrameWriter::ethernet(&mut buf, [0x10; 6]).expect("buffer");
    for (i, (c, a, d)) in reqs.iter().enumerate() {
        w.push(*c, i as u8, *a, d).expect("datagram");
    }
    let n = w.finish();
    buf.truncate(n);
    buf
}

fn send(line: &mut [Esc<'_>], reqs: &[(Command, Address, Vec<u8>)]) -> Vec<u16> {
    let mut f = frame(reqs);
    let o = process_chain(line, Instant::ZERO, &mut f);
    assert!(o.forward(), "{o:?}");
    let eth = EthernetFrame::new_checked(&f[..]).unwrap();
    let frame = Frame::new_checked(eth.payload()).unwrap();
    frame.datagrams().map(|d| d.unwrap().wkc()).collect()
}

/// 64 slaves configured as SOEM leaves them: station addresses, mailbox, SM2/SM3 and FMMUs
/// at their logical offsets, in Op.
fn line_in_op() -> Vec<Esc<'static>> {
    let cfg = EscConfig {
        mailbox: Some(MailboxLayout {
            rx_offset: 0x1000,
            rx_size: 0x80,
            tx_offset: 0x1080,
            tx_size: 0x80,
        }),
        ..EscConfig::default()
    };
    let mut line: Vec<Esc<'static>> = (0..SLAVES)
        .map(|_| Esc::new(cfg.clone(), Eeprom::None))
        .collect();
    for i in 0..SLAVES as u16 {
        let adp = i.wrapping_neg();
        let st = 0x1001 + i;
        send(
            &mut line,
            &[(
                Command::Apwr,
                Address::Physical { adp, ado: 0x10 },
                st.to_le_bytes().to_vec(),
            )],
        );
        let p = |ado| Address::Physical { adp: st, ado };
        let mut sms = vec![
            0x00, 0x10, 0x80, 0x00, 0x26, 0, 1, 0, 0x80, 0x10, 0x80, 0x00, 0x22, 0, 1, 0,
        ];
        sms.extend_from_slice(&[0x00, 0x11]);
        sms.extend_from_slice(&OUT.to_le_bytes());
        sms.extend_from_slice(&[0x64, 0, 1, 0, 0x80, 0x11]);
        sms.extend_from_slice(&IN.to_le_bytes());
        sms.extend_from_slice(&[0x20, 0, 1, 0]);
        let base = u32::from(i) * u32::from(OUT + IN);
        let f0 = Fmmu::bytes(base, OUT, 0x1100, false, true).to_bytes();
        let f1 = Fmmu::bytes(base + u32::from(OUT), IN, 0x1180, true, false).to_bytes();
        send(
            &mut line,
            &[
                (Command::Fpwr, p(0x0800), sms),
                (Command::Fpwr, p(0x0600), f0.to_vec()),
                (Command::Fpwr, p(0x0610), f1.to_vec()),
            ],
        );
        for s in [2u8, 4, 8] {
            send(&mut line, &[(Command::Fpwr, p(0x0120), vec![s, 0])]);
        }
        assert_eq!(line[usize::from(i)].read_u16(0x0130), 8, "slave {i} in Op");
    }
    line
}

fn chain_cycle(c: &mut Criterion) {
    let mut line = line_in_op();
    let bytes = SLAVES * usize::from(OUT + IN);
    let template = frame(&[
        (
            Command::Armw,
            Address::Physical {
                adp: 0,
                ado: 0x0910,
            },
            vec![0; 8],
        ),
        (Command::Lrw, Address::Logical(0), vec![0x0F; bytes]),
    ]);
    {
        let mut f = template.clone();
        process_chain(&mut line, Instant::from_nanos(1_000_000), &mut f);
        let eth = EthernetFrame::new_checked(&f[..]).unwrap();
        let wkcs: Vec<u16> = Frame::new_checked(eth.payload())
            .unwrap()
            .datagrams()
            .map(|d| d.unwrap().wkc())
            .collect();
        assert_eq!(
            wkcs,
            vec![SLAVES as u16, 3 * SLAVES as u16],
            "ARMW: every DC slave; LRW: 2 + 1 per slave"
        );
    }
    let mut f = template.clone();
    let mut now = 2_000_000u64;
    let inputs = [0x37u8, 0x02, 1, 2, 3, 4];
    c.bench_function("armw_lrw_64_slave_frame", |b| {
        b.iter(|| {
            f.copy_from_slice(&template);
            now += 1_000_000;
            let o = process_chain(&mut line, Instant::from_nanos(now), black_box(&mut f));
            for esc in line.iter_mut() {
                let _ = black_box(esc.process_outputs());
                let _ = esc.set_inputs(&inputs);
            }
            black_box(o)
        })
    });
}

criterion_group!(benches, chain_cycle);
criterion_main!(benches);
