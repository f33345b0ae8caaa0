//! The bus that takes time: a cell with a bit rate on the virtual clock. 127 heartbeats at
//! 125 kbit/s leave one after the other in identifier order, each taking its exact bit time; a SYNC
//! with 40 synchronous TPDOs behind it overloads 250 kbit/s (load above 100 %, late frames) and
//! fits at 1 Mbit/s.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use canbus::frame_time::{best_case_bits, bits_to_nanos, frame_bits, worst_case_bits};
use canopen::CanFrame;
use drivetwin::cell::bus_timing::BusFigures;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::station::{Commissioning, Station};
use drivetwin::cell_loop::virtual_clock::run_virtual;
use od::Instant;

fn commissioning(values: &[(u16, u8, &[u8])]) -> Vec<Commissioning> {
    values
        .iter()
        .map(|(index, sub, bytes)| Commissioning {
            index: *index,
            sub: *sub,
            bytes: bytes.to_vec(),
        })
        .collect()
}

/// `n` CMMP-AS dictionaries (no motor: only their CANopen side) with `values` commissioned,
/// the node-ID substituted for `node` in each value by `per_node`.
fn drives(n: u8, per_node: impl Fn(u8) -> Vec<Commissioning>) -> Vec<Station> {
    let desc = devices::by_name("cmmp-as").expect("cmmp-as");
    (1..=n)
        .map(|node| Station::new(desc, node, None, per_node(node)).expect("drive"))
        .collect()
}

fn run(
    cell: &mut CanCell,
    inputs: &[(Duration, CanFrame)],
    until: Duration,
) -> Vec<(Duration, CanFrame)> {
    let mut out = Vec::new();
    run_virtual(cell, inputs, until, &mut |t, f| out.push((t, *f)));
    out
}

/// 127 heartbeats at 125 kbit/s, all due at the same instant, arrive one after the other in
/// identifier order, each after its exact bit time. Decision: an estimate of "≈ 47–55 bits,
/// ≈ 50 ms" leaves out the 3-bit intermission and the stuff bits; with them a 1-byte frame is
/// 55–65 bits and the 127 take ≈ 58 ms, which the test asserts exactly.
#[test]
fn heartbeats_of_127_nodes_take_the_bit_time_the_formula_gives() {
    let heartbeat_ms = 100u16.to_le_bytes();
    let mut cell = CanCell::one_timed_bus(
        drives(127, |_| commissioning(&[(0x1017, 0, &heartbeat_ms)])),
        125_000,
        Duration::from_millis(1),
    );
    let out = run(&mut cell, &[], Duration::from_millis(180));
    let due = Duration::from_millis(100);
    let beats: Vec<_> = out
        .iter()
        .filter(|(t, f)| *t > due && (0x701..=0x77F).contains(&f.id))
        .collect();
    assert_eq!(beats.len(), 127, "one heartbeat per node");
    let ids: Vec<u32> = beats.iter().map(|(_, f)| f.id).collect();
    assert!(
        ids.windows(2).all(|w| w[0] < w[1]),
        "lowest identifier first"
    );
    // Back to back from the instant they were due: each arrives at the sum of the bit times.
    let mut at = due;
    for (t, f) in &beats {
        let bits = frame_bits(f);
        assert!(
            (best_case_bits(false, 1)..=worst_case_bits(false, 1)).contains(&bits),
            "{bits} bits"
        );
        at += Duration::from_nanos(bits_to_nanos(bits, 125_000));
        assert_eq!(*t, at, "heartbeat {:03X}h", f.id);
    }
    // ≈ 58 ms: 55 bits of a 1-byte frame (SOF to the intermission) plus its stuff bits.
    let spread = at - due;
    let bound = |bits: u32| Duration::from_nanos(127 * bits_to_nanos(bits, 125_000));
    assert!(
        bound(best_case_bits(false, 1)) <= spread && spread <= bound(worst_case_bits(false, 1)),
        "{spread:?}"
    );
}

/// Node `node`'s TPDO1 (statusword) on: COB-ID 180h + node, synchronous every SYNC.
fn sync_tpdo(node: u8) -> Vec<Commissioning> {
    let cob = (0x4000_0180u32 + u32::from(node)).to_le_bytes();
    commissioning(&[(0x1800, 1, &cob), (0x1800, 2, &[1])])
}

/// NMT start of every node, then a SYNC every 5 ms for 1 s.
fn sync_inputs() -> Vec<(Duration, CanFrame)> {
    let mut v = vec![(
        Duration::from_millis(1),
        CanFrame::new(0x000, &[0x01, 0x00]).expect("nmt"),
    )];
    for i in 0..200u64 {
        let sync = CanFrame::new(0x080, &[]).expect("sync");
        v.push((Duration::from_millis(5 + 5 * i), sync));
    }
    v
}

fn sync_cell(bitrate: u32) -> (Vec<(Duration, CanFrame)>, BusFigures) {
    let mut cell = CanCell::one_timed_bus(drives(40, sync_tpdo), bitrate, Duration::from_millis(5));
    let out = run(&mut cell, &sync_inputs(), Duration::from_millis(1004));
    let figures = cell.buses[0]
        .bus_figures(Instant::from_millis(1004))
        .expect("a timed bus");
    (out, figures)
}

/// A SYNC with 40 synchronous TPDOs. The bit formula decides the cycle: 40 frames of at least
/// 47 bits are 1.9 ms at 1 Mbit/s, more than a 1 ms SYNC cycle, so the test runs the SYNC at 5 ms
/// (decision: 1 Mbit/s fits this cycle, not a 1 ms one). At 250 kbit/s the TPDOs need ≈ 11 ms per
/// 5 ms cycle: load above 100 %, late frames, a growing queue; at 1 Mbit/s the same cell fits.
#[test]
fn a_sync_with_40_tpdos_overloads_250_kbit_and_fits_at_1_mbit() {
    let (out, slow) = sync_cell(250_000);
    assert!(slow.load_percent > 150.0, "{slow:?}");
    assert!(
        slow.late > 0 && slow.longest_wait > Duration::from_millis(5),
        "{slow:?}"
    );
    let tpdos_slow = out
        .iter()
        .filter(|(_, f)| (0x181..=0x1A8).contains(&f.id))
        .count();

    let (out, fast) = sync_cell(1_000_000);
    assert!(
        fast.load_percent > 30.0 && fast.load_percent < 100.0,
        "{fast:?}"
    );
    assert_eq!(fast.late, 0, "{fast:?}");
    assert_eq!(fast.dropped, 0, "{fast:?}");
    let tpdos_fast = out
        .iter()
        .filter(|(_, f)| (0x181..=0x1A8).contains(&f.id))
        .count();
    // 200 SYNCs × 40 TPDOs at 1 Mbit/s; far fewer made it at 250 kbit/s.
    assert_eq!(tpdos_fast, 200 * 40);
    assert!(
        tpdos_slow < tpdos_fast * 6 / 10,
        "{tpdos_slow} of {tpdos_fast}"
    );
    // The load the formula gives: every frame's bit time over the second.
    let asked: u64 = out
        .iter()
        .filter(|(t, _)| *t <= Duration::from_millis(1004))
        .map(|(_, f)| bits_to_nanos(frame_bits(f), 1_000_000))
        .sum();
    let computed = asked as f64 / 1_004_000_000.0 * 100.0;
    assert!(
        (fast.load_percent - computed).abs() < 5.0,
        "reported {} vs computed {computed}",
        fast.load_percent
    );
}

/// Without a bit rate the bus keeps the behaviour of before: frames cross at once.
#[test]
fn without_a_bit_rate_frames_cross_at_once() {
    let heartbeat_ms = 100u16.to_le_bytes();
    let mut cell = CanCell::one_bus(drives(3, |_| commissioning(&[(0x1017, 0, &heartbeat_ms)])));
    let out = run(&mut cell, &[], Duration::from_millis(150));
    let beats: Vec<_> = out
        .iter()
        .filter(|(t, f)| *t > Duration::ZERO && (0x701..=0x703).contains(&f.id))
        .collect();
    assert_eq!(beats.len(), 3);
    assert!(beats.iter().all(|(t, _)| *t == Duration::from_millis(100)));
    assert!(cell.buses[0]
        .bus_figures(Instant::from_millis(150))
        .is_none());
}

/// EMCY frames of node `node` (80h + node) in `out` after `from`: (time, code).
fn emcys(out: &[(Duration, CanFrame)], node: u32, from: Duration) -> Vec<(Duration, u16)> {
    out.iter()
        .filter(|(t, f)| *t >= from && f.id == 0x80 + node)
        .map(|(t, f)| (*t, u16::from_le_bytes([f.payload()[0], f.payload()[1]])))
        .collect()
}

fn heartbeats(out: &[(Duration, CanFrame)], node: u32) -> Vec<Duration> {
    out.iter()
        .filter(|(_, f)| f.id == 0x700 + node && f.payload() == [0x7F])
        .map(|(t, _)| *t)
        .collect()
}

/// Bus faults: a disturbed node's transmit errors (8 each) make it error passive at 16 and take it
/// off the bus at 32 (ISO 11898-1); each personality reacts as its manual says. The Kinco
/// FD3 (CiA 301's usage: its manual has no entry) sends EMCY 8120h when passive and 0000h when
/// active again; the Nanotec 8140h and 0000h after bus-off recovery; the CMMP-AS goes to FAULT with
/// 12-1 "CAN: bus off" (8120h), whose EMCY leaves once it is back on the bus (1408 bit times
/// later).
#[test]
fn error_passive_and_bus_off_with_each_personalitys_reaction() {
    let heartbeat = 10u16.to_le_bytes();
    let hb = commissioning(&[(0x1017, 0, &heartbeat)]);
    let cmmp = devices::by_name("cmmp-as").expect("cmmp-as");
    let kinco = devices::by_name("kinco-fd3").expect("kinco-fd3");
    let nanotec = devices::by_name("nanotec-smci47s").expect("nanotec");
    let drives = vec![
        Station::with_settings(cmmp, 1, None, hb.clone(), Some(Default::default())).expect("1"),
        Station::new(kinco, 2, None, hb.clone()).expect("2"),
        Station::with_settings(nanotec, 3, None, hb.clone(), Some(Default::default())).expect("3"),
    ];
    let mut cell = CanCell::one_timed_bus(drives, 500_000, Duration::from_millis(1));
    let at = |ms| Instant::from_millis(ms);
    cell.buses[0].plan_disturbance(at(100), 2, 16);
    cell.buses[0].plan_disturbance(at(200), 3, 32);
    cell.buses[0].plan_disturbance(at(300), 1, 32);
    // NMT start: heartbeats say 05h (operational)… the test looks at the 7Fh ones of Pre-Op.
    let out = run(&mut cell, &[], Duration::from_millis(400));

    // Kinco: passive on its 16th failed heartbeat, active again with the next good one.
    let bench_emcy = emcys(&out, 2, Duration::from_millis(100));
    assert_eq!(
        bench_emcy.iter().map(|(_, c)| *c).collect::<Vec<_>>(),
        [0x8120, 0x0000],
        "{bench_emcy:?}"
    );
    // Nanotec: its 8120h fails with the rest of its frames, then it is off the bus (no
    // heartbeat for the recovery); back, 8140h and its clearing (0000h), as CiA 301 has it.
    let nt = emcys(&out, 3, Duration::from_millis(200));
    assert_eq!(
        nt.iter().map(|(_, c)| *c).collect::<Vec<_>>(),
        [0x8140, 0x0000],
        "{nt:?}"
    );
    let beats = heartbeats(&out, 3);
    let gap = beats
        .windows(2)
        .filter(|w| w[0] >= Duration::from_millis(195))
        .map(|w| w[1] - w[0])
        .next()
        .expect("heartbeats after the disturbance");
    assert!(gap >= Duration::from_millis(10), "{gap:?}");
    // CMMP-AS: bus off, then FAULT (6041h bit 3) and its 12-1 EMCY once back.
    let cm = emcys(&out, 1, Duration::from_millis(300));
    assert!(cm.iter().any(|(_, c)| *c == 0x8120), "{cm:?}");
    let mut sw = [0u8; 2];
    od::ObjectAccess::read(&cell.stations[0].model, 0x6041, 0, &mut sw).expect("6041h");
    assert_ne!(u16::from_le_bytes(sw) & 0x0008, 0, "FAULT: {sw:02X?}");
    // Everybody is back on the bus and error active.
    assert!(cell.buses[0]
        .node_faults()
        .all(|(_, f)| f.confinement.state() == canbus::fault_confinement::ErrorState::Active));
}
