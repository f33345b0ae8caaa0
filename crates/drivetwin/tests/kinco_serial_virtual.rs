//! The serial lines on the virtual clock: two Kinco FD3s, node 1 on an RS232 line (the 10-byte
//! telegrams, Kinco manual §10.2–10.3) and node 2 on an RS485 line (Modbus RTU, §12.3), both on the
//! CAN bus as well. The RS232 host enables node 1 in mode 3 and polls its position; CANopen enables
//! node 2, whose position the RTU host polls. Run twice: the outputs are equal bit for bit, and the
//! lines keep their wire time (a telegram's answer 20 characters after the request began, at
//! 38 400 bit/s 5.2 ms).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::path::PathBuf;
use std::time::Duration;

use canopen::CanFrame;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::station::Station;
use drivetwin::cell::stations::StationId;
use drivetwin::cell_loop::virtual_clock::{run_virtual_lines, Input, Output};
use drivetwin::serial::Kind;
use drivetwin::serial::LineRequest;
use drivetwin::vendors::kinco::rtu_line::RtuLine;

fn ms(t: u64) -> Duration {
    Duration::from_millis(t)
}

/// An RS232 telegram to node 1: `cmd`, index, sub, 4 data bytes, the negated sum (§2.1).
fn telegram(cmd: u8, index: u16, sub: u8, value: u32) -> Input {
    let [i0, i1] = index.to_le_bytes();
    let d = value.to_le_bytes();
    let mut t = vec![1, cmd, i0, i1, sub, d[0], d[1], d[2], d[3]];
    let sum = t.iter().fold(0u8, |a, b| a.wrapping_add(*b));
    t.push(sum.wrapping_neg());
    Input::Serial { line: 0, bytes: t }
}

/// A Modbus RTU FC 03h request to station 2: `qty` registers from `register`, CRC low first.
fn rtu_read(register: u16, qty: u16) -> Input {
    let [r0, r1] = register.to_be_bytes();
    let [q0, q1] = qty.to_be_bytes();
    let mut f = vec![2, 0x03, r0, r1, q0, q1];
    f.extend_from_slice(&modbus::rtu::crc_bytes(&f));
    Input::Serial { line: 1, bytes: f }
}

/// An expedited SDO download to node 2.
fn sdo2(index: u16, sub: u8, value: &[u8]) -> Input {
    let cs = match value.len() {
        1 => 0x2F,
        2 => 0x2B,
        _ => 0x23,
    };
    let [lo, hi] = index.to_le_bytes();
    let mut data = [cs, lo, hi, sub, 0, 0, 0, 0];
    data[4..4 + value.len()].copy_from_slice(value);
    Input::Can(CanFrame::new(0x602, &data).expect("frame"))
}

/// 300 rpm in the Kinco DEC (rpm × 512 × 10 000 / 1875).
const RPM_300: u32 = 819_200;

fn inputs() -> Vec<(Duration, Input)> {
    let mut v = vec![(ms(2), Input::Can(CanFrame::new(0, &[1, 0]).expect("NMT")))];
    // Node 1 over RS232: no DIN owns the controlword or the mode, mode 3, ramps, enable.
    for (i, (cmd, index, sub, value)) in [
        (0x2B, 0x2010, 0x03, 0),
        (0x2B, 0x2010, 0x05, 0),
        (0x2F, 0x6060, 0x00, 3),
        (0x23, 0x6083, 0x00, 16_384),
        (0x23, 0x6084, 0x00, 16_384),
        (0x23, 0x60FF, 0x00, RPM_300),
        (0x2B, 0x6040, 0x00, 0x06),
        (0x2B, 0x6040, 0x00, 0x0F),
    ]
    .into_iter()
    .enumerate()
    {
        v.push((ms(10 + 10 * i as u64), telegram(cmd, index, sub, value)));
    }
    // Node 2 over CANopen, the same set-up in mode −3 at −300 rpm.
    for (i, (index, sub, value)) in [
        (0x2010u16, 0x03u8, vec![0, 0]),
        (0x2010, 0x05, vec![0, 0]),
        (0x6060, 0x00, vec![(-3i8) as u8]),
        (0x60FF, 0x00, RPM_300.wrapping_neg().to_le_bytes().to_vec()),
        (0x6040, 0x00, vec![0x06, 0]),
        (0x6040, 0x00, vec![0x0F, 0]),
    ]
    .into_iter()
    .enumerate()
    {
        v.push((ms(15 + 10 * i as u64), sdo2(index, sub, &value)));
    }
    // The hosts poll: node 1's Pos_Actual over RS232, node 2's statusword and Pos_Actual
    // (3700h, two registers) over RTU — at 19 200 bit/s a request takes 4.2 ms, the silence
    // after it 1.8 ms, the answer 3.6 / 4.7 ms: 10 ms apart.
    for i in 0..30u64 {
        v.push((ms(120 + 25 * i), telegram(0x40, 0x6063, 0, 0)));
        v.push((ms(122 + 25 * i), rtu_read(0x3200, 1)));
        v.push((ms(132 + 25 * i), rtu_read(0x3700, 2)));
    }
    v.sort_by_key(|(t, _)| *t);
    v
}

type Outputs = Vec<(Duration, u8, Vec<u8>)>;

/// One run: every output as (time, tag, bytes): 0 CAN, 20 RS232, 21 RS485.
fn run() -> Outputs {
    let desc = devices::by_name("kinco-fd3").expect("kinco-fd3");
    let drives = (1..=2)
        .map(|n| {
            Station::with_settings(desc, n, None, vec![], Some(Default::default())).expect("drive")
        })
        .collect();
    let mut cell = CanCell::one_bus(drives);
    let requests = [
        LineRequest {
            kind: Kind::Rs232,
            path: PathBuf::from("rs232"),
            drive: StationId::from_index(0),
        },
        LineRequest {
            kind: Kind::Rs485,
            path: PathBuf::from("rs485"),
            drive: StationId::from_index(1),
        },
    ];
    let mut lines =
        (drivetwin::vendors::VENDORS.serial_lines.virtual_lines)(&requests, &cell).expect("lines");
    let mut outputs = Vec::new();
    run_virtual_lines(
        &mut cell,
        &mut [],
        &mut [],
        &mut lines,
        &inputs(),
        ms(900),
        &mut |t, o| match o {
            Output::Can(f) => {
                let mut b = f.id.to_le_bytes().to_vec();
                b.extend_from_slice(f.payload());
                outputs.push((t, 0, b));
            }
            Output::Serial { line, bytes } => outputs.push((t, 20 + line as u8, bytes.to_vec())),
            Output::Modbus { .. } | Output::Ethercat { .. } => {}
        },
    );
    let rtu = lines
        .get(1)
        .and_then(|l| l.protocol().as_any().downcast_ref::<RtuLine>())
        .map(RtuLine::counters)
        .expect("the RTU line");
    assert_eq!((rtu.answered, rtu.bad_crc), (60, 0), "{rtu:?}");
    outputs
}

/// The bytes of line `tag` cut into `len`-byte answers, with the time the last byte crossed.
fn answers(outputs: &Outputs, tag: u8, len: usize) -> Vec<(Duration, Vec<u8>)> {
    let mut bytes = Vec::new();
    let mut out = Vec::new();
    for (t, _, b) in outputs.iter().filter(|(_, g, _)| *g == tag) {
        bytes.extend_from_slice(b);
        while bytes.len() >= len {
            out.push((*t, bytes.drain(..len).collect()));
        }
    }
    out
}

#[test]
fn serial_lines_on_the_virtual_clock_are_deterministic() {
    let a = run();
    let b = run();
    assert_eq!(a.len(), b.len());
    assert_eq!(a, b, "two runs, the same outputs bit for bit");

    // RS232: 8 write answers 60h, then 30 position reads 43h; the first answer 20
    // characters (10 bits each at 38 400 bit/s) after its request at 10 ms.
    let rs232 = answers(&a, 20, 10);
    assert_eq!(rs232.len(), 38, "{rs232:02X?}");
    assert!(rs232[..8].iter().all(|(_, t)| t[1] == 0x60), "{rs232:02X?}");
    let wire = 20 * drivetwin::serial::wire::char_time(38_400);
    assert_eq!(
        wire,
        Duration::from_nanos(5_208_320),
        "20 characters of 260.416 µs"
    );
    assert_eq!(rs232[0].0, ms(10) + wire);
    let positions: Vec<i32> = rs232[8..]
        .iter()
        .map(|(_, t)| {
            assert_eq!(&t[..5], &[1, 0x43, 0x63, 0x60, 0]);
            i32::from_le_bytes([t[5], t[6], t[7], t[8]])
        })
        .collect();
    assert!(
        positions.windows(2).all(|w| w[1] > w[0]) && positions[29] > 20_000,
        "node 1 turns forward at 300 rpm: {positions:?}"
    );

    // RS485: statusword 0437h (operation enabled, target reached, bit 10) and a falling
    // position for node 2 (−300 rpm); every frame's CRC checks.
    let rtu: Vec<&Vec<u8>> = a
        .iter()
        .filter(|(_, g, _)| *g == 21)
        .map(|(_, _, b)| b)
        .collect();
    let mut frames = Vec::new();
    let mut pending: Vec<u8> = Vec::new();
    for b in rtu {
        pending.extend_from_slice(b);
        // Answers are 7 (1 register) and 9 bytes (2 registers) and alternate.
        loop {
            let want = if frames.len() % 2 == 0 { 7 } else { 9 };
            if pending.len() < want {
                break;
            }
            let f: Vec<u8> = pending.drain(..want).collect();
            let (body, crc) = f.split_at(want - 2);
            assert_eq!(
                modbus::rtu::crc_bytes(body),
                [crc[0], crc[1]],
                "CRC of {f:02X?}"
            );
            frames.push(f);
        }
    }
    assert_eq!(frames.len(), 60);
    let last_sw = frames[58].clone();
    assert_eq!(&last_sw[..3], &[2, 0x03, 2]);
    assert_eq!(
        u16::from_be_bytes([last_sw[3], last_sw[4]]) & 0x6F,
        0x27,
        "enabled"
    );
    let pos = |f: &Vec<u8>| {
        let lo = u16::from_be_bytes([f[3], f[4]]);
        let hi = u16::from_be_bytes([f[5], f[6]]);
        (u32::from(hi) << 16 | u32::from(lo)) as i32
    };
    assert!(
        pos(&frames[59]) < pos(&frames[31]) - 10_000,
        "node 2 turns back"
    );
}
