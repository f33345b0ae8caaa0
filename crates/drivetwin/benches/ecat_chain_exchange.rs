//! The slave side of one EtherCAT process-data cycle, in process and on the virtual clock: a
//! chain of 64 CMMP-AS in Op, joined to a cell's list of stations as the cell loop joins it,
//! one LRW frame a cycle through every slave ([`SlaveChain::pass_with`]) and then each
//! device's exchange ([`SlaveChain::exchange_with`]: outputs in, drive to the frame's time,
//! inputs out, mailbox). No socket, no loop: the cost the chain adds to every frame.
//!
//! Two rows:
//!
//! - `free run`: 4 kHz (250 µs), no SYNC0; the frame is the drive's time base (CMMP-AS §2.11
//!   "without DC");
//! - `dc`: SYNC0 every 1 ms (the CMMP-AS's interpolator cycle 60C2h is 1 ms at least, and a
//!   SYNC0 cycle other than it is refused with 0x0036), the frame half-way between two
//!   events, the event run by the chain's poll at its time as the cell loop runs it.
//!
//! The process data is the default mapping (1600h: controlword out, 1A00h: statusword in),
//! as `ecat_veth_roundtrip` maps it: 2 + 2 bytes a slave, working counter 3 × 64. The
//! outputs are zeros (the drives stay in "switch on disabled"; their physics runs).
//!
//! `cargo bench -p drivetwin --bench ecat_chain_exchange` measures each row's time per frame
//! (the whole chain) with criterion. For a count of instructions that does not depend on the
//! machine's load, `ECAT_CHAIN_FRAMES=N` runs N frames of each row (`ECAT_CHAIN_ROWS=free` or
//! `dc` for one) without criterion and exits; under
//! `valgrind --tool=callgrind` the difference of two such runs (N and M frames) divided by
//! N − M is the instructions per frame, the start-up cancelled out.
//!
//! `ECAT_CHAIN_BY_PHASE=N` runs N free-run frames and prints the median and the 90th
//! percentile of a frame's time by its place among 4 (a millisecond at 4 kHz): the drives
//! run their device logic every 500 µs, on every other frame.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

#[path = "../tests/support/cmmp_as_chain.rs"]
mod cmmp_as_chain;

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, Criterion};
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::config::CellFile;
use drivetwin::ecat::chain::SlaveChain;
use ethercat::register::RegisterAddress;
use ethercat::{Address, AlState, Command, EthernetFrame, Frame, FrameWriter};
use od::Instant;

use cmmp_as_chain::{
    configure_process_data, mailboxes, INPUT_BYTES, MASTER_MAC, OUTPUT_BYTES, STATION,
    WKC_PER_SLAVE,
};

/// A chain of real size: 64 drives (the 4 kHz target's chain, docs/performance.md).
const SLAVES: u16 = 64;
/// The free-run cycle: 4 kHz.
const FREE_RUN_CYCLE: Duration = Duration::from_micros(250);
/// The DC cycle: the CMMP-AS's shortest interpolator cycle (60C2h = 1 ms).
const DC_CYCLE: Duration = Duration::from_millis(1);

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Row {
    FreeRun,
    Dc,
}

impl Row {
    fn label(self) -> &'static str {
        match self {
            Row::FreeRun => "free run, 4 kHz",
            Row::Dc => "dc, SYNC0 1 kHz",
        }
    }

    fn cycle(self) -> Duration {
        match self {
            Row::FreeRun => FREE_RUN_CYCLE,
            Row::Dc => DC_CYCLE,
        }
    }
}

/// The master's side, sans-IO: frames built with `crates/ethercat`'s writer, passed through
/// the chain as the cell loop passes them.
struct Bench {
    chain: SlaveChain,
    cell: CanCell,
    now: Instant,
    row: Row,
    /// The LRW frame of every cycle (outputs zeros), built once.
    lrw: Vec<u8>,
    /// The frame the chain processes in place.
    frame: Vec<u8>,
    index: u8,
}

/// One returned datagram: its data and working counter.
struct Reply {
    data: Vec<u8>,
    wkc: u16,
}

impl Bench {
    fn new(row: Row) -> Bench {
        let path = std::env::temp_dir().join(format!(
            "ecat-chain-exchange-{}-{:?}.toml",
            std::process::id(),
            row
        ));
        let drive = |k: u16| {
            format!("[[drive]]\ndevice = \"cmmp-as\"\nnode = {k}\ninterfaces = [\"ethercat\"]\n\n")
        };
        let text: String = (1..=SLAVES).map(drive).collect();
        std::fs::write(&path, text).expect("the chain's cell file");
        let file = CellFile::load(&path).expect("cell file");
        let _ = std::fs::remove_file(&path);
        let mut chain =
            SlaveChain::from_cell_file(&file, drivetwin::vendors::VENDORS.runtime).expect("chain");
        assert_eq!(chain.len(), usize::from(SLAVES));
        // As the cell loop runs it: the chain's drives are stations of the cell's list.
        let mut cell = CanCell::new();
        chain.join_cell(&mut cell);
        let now = Instant::from_millis(1);
        chain.boot_with(now, &mut cell);
        let io = usize::from(SLAVES) * usize::from(OUTPUT_BYTES + INPUT_BYTES);
        let mut lrw = vec![0u8; 1536];
        let mut w = FrameWriter::ethernet(&mut lrw, MASTER_MAC).expect("frame buffer");
        w.push(Command::Lrw, 0xA5, Address::Logical(0), &vec![0; io])
            .expect("datagram fits");
        let n = w.finish();
        lrw.truncate(n);
        let mut b = Bench {
            chain,
            cell,
            now,
            row,
            frame: lrw.clone(),
            lrw,
            index: 0,
        };
        b.start_up();
        b
    }

    /// A one-datagram frame through the chain and the devices' exchange after it, as the
    /// cell loop runs them (start-up).
    fn exchange(&mut self, command: Command, address: Address, data: &[u8]) -> Reply {
        self.index = self.index.wrapping_add(1);
        let mut buf = vec![0u8; 1536];
        let mut w = FrameWriter::ethernet(&mut buf, MASTER_MAC).expect("frame buffer");
        w.push(command, self.index, address, data)
            .expect("datagram fits");
        let n = w.finish();
        buf.truncate(n);
        let outcome = self.chain.pass_with(self.now, &mut buf, &mut self.cell);
        assert!(outcome.forward(), "{outcome:?}");
        self.chain.exchange_with(self.now, &mut self.cell);
        let eth = EthernetFrame::new_checked(&buf[..]).expect("ethernet");
        let f = Frame::new_checked(eth.payload()).expect("ethercat");
        let d = f.datagrams().next().expect("a datagram").expect("valid");
        Reply {
            data: d.data().to_vec(),
            wkc: d.wkc(),
        }
    }

    fn fpwr(&mut self, station: u16, register: u16, data: &[u8]) {
        let r = self.exchange(Command::Fpwr, phys(station, register), data);
        assert_eq!(r.wkc, 1, "FPWR {station:#06x} {register:#06x}");
    }

    fn fprd(&mut self, station: u16, register: u16, len: usize) -> Vec<u8> {
        let r = self.exchange(Command::Fprd, phys(station, register), &vec![0; len]);
        assert_eq!(r.wkc, 1, "FPRD {station:#06x} {register:#06x}");
        r.data
    }

    /// Every slave's AL status is `state` with no status code.
    fn all_in(&mut self, state: AlState) -> bool {
        (0..SLAVES).all(|k| {
            let d = self.fprd(STATION + k, RegisterAddress::AlStatus.addr(), 6);
            (
                u16::from_le_bytes([d[0], d[1]]),
                u16::from_le_bytes([d[4], d[5]]),
            ) == (state as u16, 0)
        })
    }

    /// Requests `state` of every slave at once (a broadcast write of AL control).
    fn request(&mut self, state: AlState) {
        let r = self.exchange(
            Command::Bwr,
            phys(0, RegisterAddress::AlControl.addr()),
            &[state as u8, 0],
        );
        assert_eq!(r.wkc, SLAVES, "every slave takes the AL control write");
    }

    /// Init → Pre-Op → Safe-Op → Op with the default mapping, as SOEM does it (the ESC
    /// reference kept beside the project, §9.1); SYNC0 as SOEM's `ecx_dcsync0` for the DC row.
    fn start_up(&mut self) {
        let r = self.exchange(
            Command::Bwr,
            phys(0, RegisterAddress::AlControl.addr()),
            &[AlState::Init as u8 | 0x10, 0],
        );
        assert_eq!(r.wkc, SLAVES, "every slave answers the broadcast");
        let mailboxes = mailboxes();
        for k in 0..SLAVES {
            let r = self.exchange(
                Command::Apwr,
                phys(
                    0u16.wrapping_sub(k),
                    RegisterAddress::ConfiguredStationAddress.addr(),
                ),
                &(STATION + k).to_le_bytes(),
            );
            assert_eq!(r.wkc, 1, "station address of slave {k} set");
            self.fpwr(STATION + k, RegisterAddress::Sm0.addr(), &mailboxes);
        }
        self.request(AlState::PreOp);
        assert!(self.all_in(AlState::PreOp), "Pre-Op");

        let mut first_event = 0;
        for k in 0..SLAVES {
            if self.row == Row::Dc {
                first_event = self.sync0(STATION + k);
            }
            configure_process_data(k, SLAVES, |station, register, data| {
                self.fpwr(station, register, data)
            });
        }
        self.request(AlState::SafeOp);
        assert!(self.all_in(AlState::SafeOp), "Safe-Op");
        if self.row == Row::Dc {
            // Half a cycle past the first event of every slave's grid (the last set).
            let esc_time = self.chain.esc(0).expect("slave 0").system_time_at(self.now);
            let ahead = first_event.saturating_sub(esc_time) + DC_CYCLE.as_nanos() as u64 / 2;
            self.now = self.now + Duration::from_nanos(ahead);
            self.chain.poll_with(self.now, &mut self.cell);
        }
        // Outputs before and while Op is requested, as SOEM does.
        self.cycle();
        self.request(AlState::Op);
        for _ in 0..20 {
            self.cycle();
        }
        assert!(self.all_in(AlState::Op), "Op");
        for _ in 0..100 {
            self.cycle();
        }
        assert!(self.all_in(AlState::Op), "still in Op after 100 cycles");
    }

    /// SOEM's `ecx_dcsync0` on `station`: SYNC0 every [`DC_CYCLE`] from a whole cycle 10 ms
    /// ahead; the system time of the first event.
    fn sync0(&mut self, station: u16) -> u64 {
        self.fpwr(station, 0x0981, &[0]);
        self.fpwr(station, 0x0980, &[0]);
        let t = self.fprd(station, 0x0910, 8);
        let t = u64::from_le_bytes(t[..8].try_into().expect("8 bytes"));
        let c = DC_CYCLE.as_nanos() as u64;
        let start = (t + 10_000_000) / c * c + c;
        self.fpwr(station, 0x0990, &start.to_le_bytes());
        self.fpwr(station, 0x09A0, &(c as u32).to_le_bytes());
        self.fpwr(station, 0x0981, &[0x03]);
        start
    }

    /// One cycle: the LRW frame through the chain and the devices' exchange after it; on DC,
    /// half a cycle later the SYNC0 event the chain's poll runs. Returns the working counter.
    fn cycle(&mut self) -> u16 {
        let cycle = self.row.cycle();
        match self.row {
            Row::FreeRun => self.now = self.now + cycle,
            Row::Dc => self.now = self.now + cycle / 2,
        }
        self.frame.copy_from_slice(&self.lrw);
        let outcome = self
            .chain
            .pass_with(self.now, &mut self.frame, &mut self.cell);
        self.chain.exchange_with(self.now, &mut self.cell);
        if self.row == Row::Dc {
            self.now = self.now + cycle / 2;
            self.chain.poll_with(self.now, &mut self.cell);
        }
        debug_assert!(outcome.forward());
        lrw_wkc(&self.frame)
    }
}

/// The working counter of the LRW frame (its one datagram's last two bytes).
fn lrw_wkc(frame: &[u8]) -> u16 {
    let n = frame.len();
    u16::from_le_bytes([frame[n - 2], frame[n - 1]])
}

fn phys(adp: u16, ado: u16) -> Address {
    Address::Physical { adp, ado }
}

fn rows() -> Vec<Row> {
    match std::env::var("ECAT_CHAIN_ROWS").as_deref() {
        Ok("free") => vec![Row::FreeRun],
        Ok("dc") => vec![Row::Dc],
        _ => vec![Row::FreeRun, Row::Dc],
    }
}

fn bench_exchange(c: &mut Criterion) {
    let mut group = c.benchmark_group("ecat_chain_exchange");
    for row in rows() {
        let mut b = Bench::new(row);
        let expected = WKC_PER_SLAVE * SLAVES;
        assert_eq!(b.cycle(), expected, "{}: working counter", row.label());
        group.bench_function(format!("{} slaves, {}", SLAVES, row.label()), |it| {
            it.iter(|| black_box(b.cycle()))
        });
        assert_eq!(b.cycle(), expected, "{}: working counter", row.label());
        assert!(b.all_in(AlState::Op), "{}: still in Op", row.label());
    }
    group.finish();
}

criterion_group!(benches, bench_exchange);

/// A frame's time (ns) by its place among 4, each place's list sorted.
fn by_phase(frames: usize) -> [Vec<u64>; 4] {
    let mut b = Bench::new(Row::FreeRun);
    let mut times: [Vec<u64>; 4] = Default::default();
    for i in 0..frames {
        let start = std::time::Instant::now();
        black_box(b.cycle());
        times[i % 4].push(start.elapsed().as_nanos() as u64);
    }
    for t in &mut times {
        t.sort_unstable();
    }
    times
}

fn main() {
    if let Ok(frames) = std::env::var("ECAT_CHAIN_BY_PHASE") {
        let frames: usize = frames
            .parse()
            .expect("ECAT_CHAIN_BY_PHASE is a count of frames");
        for (place, t) in by_phase(frames.max(4)).iter().enumerate() {
            println!(
                "frame {place} of 4: p50 {:.1} µs, p90 {:.1} µs",
                t[t.len() / 2] as f64 / 1e3,
                t[t.len() * 9 / 10] as f64 / 1e3
            );
        }
        return;
    }
    // ECAT_CHAIN_FRAMES=N: N frames of each row without criterion (for callgrind).
    if let Ok(frames) = std::env::var("ECAT_CHAIN_FRAMES") {
        let frames: u64 = frames
            .parse()
            .expect("ECAT_CHAIN_FRAMES is a count of frames");
        for row in rows() {
            let mut b = Bench::new(row);
            let expected = WKC_PER_SLAVE * SLAVES;
            for _ in 0..frames {
                assert_eq!(b.cycle(), expected, "{}: working counter", row.label());
            }
            println!("{}: {frames} frames, {SLAVES} slaves", row.label());
        }
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
