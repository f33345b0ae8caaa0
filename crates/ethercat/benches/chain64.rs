//! A cyclic frame through a line of 64 slaves in the sans-IO core: the ARMW of the DC
//! reference clock's system time that SOEM and ethercrab send every cycle (the ESC reference
//! kept beside the project, §8.1), then one LRW of 3 output and 6 input bytes per slave (a
//! CSP drive as SOEM maps it), 576 bytes in all. Each slave's device side takes its outputs
//! and posts its inputs after the frame, as the chain does. Target: 5 µs per frame. Its floor,
//! in the same run: one LRW of the same 9 bytes through a line of one slave.
//!
//! Criterion measures wall-clock time, which a machine shared with other processes stretches
//! by every time slice they take in the middle of a sample. After the criterion runs the
//! bench therefore also prints the CPU time this thread spent per frame (the scheduler's
//! account in `/proc/thread-self/schedstat`, over rounds of about 300 ms: the minimum and
//! the median of 7), which other processes stretch less (their cache traffic remains).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use criterion::{black_box, Criterion};
use ethercat::datagram::Command;
use ethercat::frame::{Address, EthernetFrame, Frame, FrameWriter};
use ethercat::{process_chain, Eeprom, Esc, EscConfig, Fmmu, FrameOutcome, MailboxLayout};
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

/// `slaves` slaves configured as SOEM leaves them: station addresses, mailbox, SM2/SM3 and
/// FMMUs at their logical offsets, in Op.
fn line_in_op(slaves: usize) -> Vec<Esc<'static>> {
    let cfg = EscConfig {
        mailbox: Some(MailboxLayout {
            rx_offset: 0x1000,
            rx_size: 0x80,
            tx_offset: 0x1080,
            tx_size: 0x80,
        }),
        ..EscConfig::default()
    };
    let mut line: Vec<Esc<'static>> = (0..slaves)
        .map(|_| Esc::new(cfg.clone(), Eeprom::None))
        .collect();
    for i in 0..slaves as u16 {
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

/// One cyclic frame: `template` copied in, passed through `line` at the next millisecond, then
/// each slave's device side takes its outputs and posts its inputs.
struct Cycle {
    line: Vec<Esc<'static>>,
    template: Vec<u8>,
    frame: Vec<u8>,
    now: u64,
}

impl Cycle {
    fn new(line: Vec<Esc<'static>>, template: Vec<u8>) -> Self {
        let frame = template.clone();
        Cycle {
            line,
            template,
            frame,
            now: 2_000_000,
        }
    }

    fn run(&mut self) -> FrameOutcome {
        const INPUTS: [u8; 6] = [0x37, 0x02, 1, 2, 3, 4];
        self.frame.copy_from_slice(&self.template);
        self.now += 1_000_000;
        let o = process_chain(
            &mut self.line,
            Instant::from_nanos(self.now),
            black_box(&mut self.frame),
        );
        for esc in self.line.iter_mut() {
            let _ = black_box(esc.process_outputs());
            let _ = esc.set_inputs(&INPUTS);
        }
        o
    }
}

/// The ARMW + LRW frame through 64 slaves.
fn chain() -> Cycle {
    let mut line = line_in_op(SLAVES);
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
    Cycle::new(line, template)
}

/// The floor: one LRW of one slave's 9 bytes through a line of one slave.
fn floor() -> Cycle {
    let line = line_in_op(1);
    let template = frame(&[(
        Command::Lrw,
        Address::Logical(0),
        vec![0x0F; usize::from(OUT + IN)],
    )]);
    Cycle::new(line, template)
}

fn chain_cycle(c: &mut Criterion) {
    let mut chain = chain();
    c.bench_function("armw_lrw_64_slave_frame", |b| {
        b.iter(|| black_box(chain.run()))
    });
    let mut floor = floor();
    c.bench_function("floor_lrw_1_slave_frame", |b| {
        b.iter(|| black_box(floor.run()))
    });
}

/// CPU time (ns) this thread has run, as the scheduler accounts it.
fn thread_cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(0)
}

/// Thread CPU time per `run`, in ns: (minimum, median) of 7 rounds of about 300 ms of wall
/// time each (the scheduler's account moves at its ticks and switches, so a round must span
/// many); `None` where that account cannot be read.
fn cpu_time_per_run(c: &mut Cycle) -> Option<(f64, f64)> {
    if thread_cpu_ns() == 0 {
        return None;
    }
    let t0 = std::time::Instant::now();
    let mut calibration = 0u64;
    while t0.elapsed() < Duration::from_millis(50) {
        black_box(c.run());
        calibration += 1;
    }
    let spent = t0.elapsed().as_nanos().max(1);
    let n = u64::try_from(u128::from(calibration) * 300_000_000 / spent)
        .unwrap_or(1)
        .max(1);
    let mut per_run: Vec<f64> = (0..7)
        .map(|_| {
            let t = thread_cpu_ns();
            for _ in 0..n {
                black_box(c.run());
            }
            thread_cpu_ns().saturating_sub(t) as f64 / n as f64
        })
        .collect();
    per_run.sort_by(f64::total_cmp);
    Some((per_run[0], per_run[3]))
}

fn main() {
    let mut c = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .configure_from_args();
    chain_cycle(&mut c);
    c.final_summary();
    let figures = [
        ("armw_lrw_64_slave_frame", cpu_time_per_run(&mut chain())),
        ("floor_lrw_1_slave_frame", cpu_time_per_run(&mut floor())),
    ];
    for (name, f) in figures {
        match f {
            Some((min, median)) => println!(
                "{name}: thread CPU time {:.3} µs per frame (median of 7 rounds; min {:.3} µs)",
                median / 1000.0,
                min / 1000.0
            ),
            None => println!("{name}: no thread CPU time (/proc/thread-self/schedstat)"),
        }
    }
}
