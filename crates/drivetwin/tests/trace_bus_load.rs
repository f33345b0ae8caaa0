//! The bus load in the trace. A cell of 40 drives with synchronous TPDOs at 1 Mbit/s on the virtual
//! clock, traced to a pcap with the bus's bit rate: the load file beside it (`<trace>.load.csv`,
//! `drivetwin::trace::bus_load`) read back holds one line per 500 ms window, each the bit time of
//! the frames of that window over its length, near the load the cell's timed bus reports; the pcap
//! itself is the classic one (magic, link type 227).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use canbus::frame_time::{bits_to_nanos, frame_bits};
use canopen::CanFrame;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::station::{Commissioning, Station};
use drivetwin::cell_loop::virtual_clock::run_virtual;
use drivetwin::trace::bus_load::{load_path, parse_load};
use drivetwin::trace::TraceWriter;
use od::Instant;

const BITRATE: u32 = 1_000_000;

/// 40 CMMP-AS dictionaries, TPDO1 synchronous on every SYNC.
fn cell() -> CanCell {
    let desc = devices::by_name("cmmp-as").expect("cmmp-as");
    let drives = (1..=40u8)
        .map(|node| {
            let cob = (0x4000_0180u32 + u32::from(node)).to_le_bytes();
            let c = vec![
                Commissioning {
                    index: 0x1800,
                    sub: 1,
                    bytes: cob.to_vec(),
                },
                Commissioning {
                    index: 0x1800,
                    sub: 2,
                    bytes: vec![1],
                },
            ];
            Station::new(desc, node, None, c).expect("drive")
        })
        .collect();
    CanCell::one_timed_bus(drives, BITRATE, Duration::from_millis(5))
}

/// NMT start of every node, then a SYNC every 5 ms for 1.6 s.
fn inputs() -> Vec<(Duration, CanFrame)> {
    let mut v = vec![(
        Duration::from_millis(1),
        CanFrame::new(0x000, &[0x01, 0x00]).expect("nmt"),
    )];
    for i in 0..320u64 {
        v.push((
            Duration::from_millis(5 + 5 * i),
            CanFrame::new(0x080, &[]).expect("sync"),
        ));
    }
    v
}

#[test]
fn the_trace_of_a_timed_bus_has_its_load_per_window() {
    let dir = std::env::temp_dir().join(format!("trace-bus-load-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("bus.pcap");
    let mut cell = cell();
    let mut trace =
        TraceWriter::create_for_bus(&path, "vcan0", cell.buses[0].timed_bitrate()).expect("trace");
    let mut out = Vec::new();
    let until = Duration::from_millis(1604);
    run_virtual(&mut cell, &inputs(), until, &mut |t, f| {
        trace.write(t, f).expect("written");
        out.push((t, *f));
    });
    trace.flush().expect("flushed");
    let reported = cell.buses[0]
        .bus_figures(Instant::from_nanos(until.as_nanos() as u64))
        .expect("a timed bus")
        .load_percent;

    let pcap = std::fs::read(&path).expect("pcap");
    assert_eq!(
        pcap.get(..4),
        Some(&[0xD4, 0xC3, 0xB2, 0xA1][..]),
        "classic pcap"
    );
    assert_eq!(pcap.get(20..24), Some(&227u32.to_le_bytes()[..]));
    assert_eq!(pcap.len(), 24 + 32 * out.len(), "every frame in the pcap");

    let text = std::fs::read_to_string(load_path(&path)).expect("the load file");
    assert!(text.starts_with("# drivetwin bus load: bitrate 1000000 bit/s, window 500 ms"));
    let rows = parse_load(&text).expect("parses");
    // 1.6 s of frames from the first one: three complete windows (the fourth is open).
    assert_eq!(rows.len(), 3, "{text}");
    let mut start = out.first().map(|(t, _)| *t).expect("frames");
    for r in &rows {
        assert_eq!(r.window, r.end - start, "{r:?}");
        let counted: Vec<_> = out
            .iter()
            .filter(|(t, _)| *t >= start && *t < r.end)
            .collect();
        assert_eq!(r.frames as usize, counted.len(), "{r:?}");
        let nanos: u64 = counted
            .iter()
            .map(|(_, f)| bits_to_nanos(frame_bits(f), BITRATE))
            .sum();
        let computed = nanos as f64 * 100.0 / (r.end - start).as_nanos() as f64;
        assert!(
            (r.load_percent - computed).abs() < 0.01,
            "{r:?} vs {computed}"
        );
        start = r.end;
    }
    // 40 TPDOs and a SYNC every 5 ms fit at 1 Mbit/s; the trace's load is the cell's own.
    let last = rows.last().expect("a window").load_percent;
    assert!(last > 30.0 && last < 100.0, "{last}");
    assert!(
        (last - reported).abs() < 0.05 * reported,
        "{last} vs {reported}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A bus without a bit rate has no bit time: its trace has no load file.
#[test]
fn an_untimed_bus_writes_no_load_file() {
    let dir = std::env::temp_dir().join(format!("trace-no-load-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("bus.log");
    let mut trace = TraceWriter::create_for_bus(&path, "vcan0", None).expect("trace");
    let sync = CanFrame::new(0x080, &[]).expect("sync");
    trace.write(Duration::from_secs(1), &sync).expect("written");
    trace.flush().expect("flushed");
    assert!(std::fs::read_to_string(&path)
        .expect("candump")
        .contains("vcan0 080#"));
    assert!(!load_path(&path).exists());
    let _ = std::fs::remove_dir_all(&dir);
}
