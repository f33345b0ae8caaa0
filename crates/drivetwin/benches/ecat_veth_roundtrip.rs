//! Round trip of a 1 kHz EtherCAT process-data cycle over a veth pair: the real `drivetwin run
//! --ethercat IF` runs in a private network namespace, this process is the master on the
//! other end with a raw socket and frames built with `crates/ethercat`'s codecs.
//!
//! Start-up as SOEM does it (station address, mailbox SMs, Pre-Op, SM2/SM3 and FMMUs for the
//! default mapping 1600h/1A00h — controlword out, statusword in — Safe-Op, Op), then one LRW
//! frame every 1 ms for `ECAT_ROUNDTRIP_SECONDS` (default 10): the time from `send` to the
//! reply's `recv` is recorded, and p50 / p99 / p99.9 / max are printed with the count of lost
//! frames (no reply within 100 ms) and of wrong working counters. Target: p99 under 100 µs.
//!
//! `ECAT_ROUNDTRIP_FIFO=1` runs this master and every thread of the twin under `SCHED_FIFO`
//! (priority 49), as a production EtherCAT master runs: the figures then show the twin and the
//! wire rather than how long the scheduler of a busy machine keeps either process waiting.
//!
//! `DRIVETWIN_BIN=path` runs another build of the twin.
//!
//! Needs root (network namespace, raw sockets) and `ip`; otherwise prints why and exits 0.
//! `cargo bench -p drivetwin --bench ecat_veth_roundtrip`; without cargo bench's `--bench`
//! argument (e.g. `cargo test --benches`) it runs for 1 s as a smoke test.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

#[path = "../tests/support/ecat_veth.rs"]
mod ecat_veth;

use std::io;
use std::mem;
use std::os::fd::{AsRawFd, OwnedFd};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use ecat_veth::EcatWire;
use ethercat::frame::{ETHERTYPE_ETHERCAT, SOURCE_MAC_RETURN_BIT};
use ethercat::register::RegisterAddress;
use ethercat::{Address, AlState, Command, EthernetFrame, Fmmu, Frame, FrameWriter, SyncManager};

/// SOEM's primary source MAC; the slave sets bit 0x02 of the first byte on the way back.
const MASTER_MAC: [u8; 6] = [0x01; 6];
const STATION: u16 = 0x1001;
/// The CMMP-AS SII: mailbox out 1000h / in 1080h, 128 bytes each (SII word 18h), process
/// data SM2 at 1100h, SM3 at 1180h.
const MAILBOX_OUT: u16 = 0x1000;
const MAILBOX_IN: u16 = 0x1080;
const MAILBOX_LEN: u16 = 0x80;
const SM2: u16 = 0x1100;
const SM3: u16 = 0x1180;
/// Default mapping: 1600h = controlword, 1A00h = statusword.
const OUTPUT_BYTES: u16 = 2;
const INPUT_BYTES: u16 = 2;
/// LRW working counter: outputs written (+2) and inputs read (+1).
const EXPECTED_WKC: u16 = 3;
const CYCLE: Duration = Duration::from_millis(1);
/// A reply later than this counts as lost.
const REPLY_TIMEOUT: Duration = Duration::from_millis(100);
const TARGET_P99: Duration = Duration::from_micros(100);
/// Real-time priority with `ECAT_ROUNDTRIP_FIFO=1`: just below the kernel's threaded
/// interrupt handlers (`SCHED_FIFO` 50), so they still run first.
const FIFO_PRIORITY: libc::c_int = 49;
/// `linux/if_packet.h`.
const PACKET_OUTGOING: u8 = 4;

fn main() {
    let smoke = !std::env::args().any(|a| a == "--bench");
    let seconds: f64 = match std::env::var("ECAT_ROUNDTRIP_SECONDS") {
        Ok(s) => s.parse().unwrap_or_else(|_| {
            eprintln!("ECAT_ROUNDTRIP_SECONDS={s:?} is not a number of seconds");
            std::process::exit(2)
        }),
        Err(_) if smoke => 1.0,
        Err(_) => 10.0,
    };
    // DRIVETWIN_BIN (as for the pytest suite) benchmarks another build of the twin.
    let binary = std::env::var_os("DRIVETWIN_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_drivetwin")));
    // ECAT_ROUNDTRIP_TWIN_ARGS: more `drivetwin run` options, e.g. "--busy-poll".
    let extra: Vec<String> = std::env::var("ECAT_ROUNDTRIP_TWIN_ARGS")
        .map(|a| a.split_whitespace().map(str::to_owned).collect())
        .unwrap_or_default();
    let wire = match EcatWire::start(&binary, &extra) {
        Ok(w) => w,
        Err(why) => {
            println!("ecat_veth_roundtrip skipped: {why}");
            return;
        }
    };
    if std::env::var_os("ECAT_ROUNDTRIP_FIFO").is_some_and(|v| v != "0") {
        let twin = wire.twin.pid().expect("twin running");
        for pid in [std::process::id(), twin] {
            // A panic, not exit(): the guards still remove the twin and the veth pair.
            set_fifo(pid).unwrap_or_else(|e| panic!("SCHED_FIFO for {pid}: {e}"));
        }
        println!("SCHED_FIFO {FIFO_PRIORITY} for the master and the twin");
    }
    let mut master = Master::open(wire.master_if()).expect("master-side raw socket");
    master.start_up();
    let cycles = (seconds * 1000.0).round() as usize;
    let stats = master.measure(cycles);
    stats.print(seconds);
    let EcatWire { twin, veth } = wire;
    twin.stop().expect("drivetwin stops cleanly on SIGTERM");
    drop(veth);
}

/// A blocking raw socket on the master-side interface, bound to EtherType 0x88A4.
struct Master {
    fd: OwnedFd,
    tx: [u8; 128],
    rx: [u8; 1536],
    index: u8,
}

/// One returned datagram: its first bytes (as many as the start-up reads) and working
/// counter; a plain array, so the cyclic loop does not allocate.
struct Reply {
    data: [u8; 8],
    wkc: u16,
}

impl Master {
    fn open(interface: &str) -> io::Result<Master> {
        // The twin's own socket set-up (non-blocking: the master spins on `recvfrom`).
        let fd = drivetwin::ecat::link::open_raw(interface)?;
        Ok(Master {
            fd,
            tx: [0; 128],
            rx: [0; 1536],
            index: 0,
        })
    }

    /// Build a one-datagram frame in `self.tx`; returns its length.
    fn build(&mut self, command: Command, address: Address, data: &[u8]) -> usize {
        self.index = self.index.wrapping_add(1);
        let mut w = FrameWriter::ethernet(&mut self.tx, MASTER_MAC).expect("frame buffer");
        w.push(command, self.index, address, data)
            .expect("datagram fits");
        w.finish()
    }

    fn send(&self, len: usize) -> io::Result<()> {
        // SAFETY: `self.tx[..len]` is valid for reads; the socket is bound to the interface.
        let n = unsafe { libc::send(self.fd.as_raw_fd(), self.tx.as_ptr().cast(), len, 0) };
        if n < 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(())
    }

    /// Wait for the returned frame carrying the datagram index just sent; `None` when it does
    /// not come back within `timeout`. Frames with another index (late replies to an earlier
    /// cycle) are skipped.
    /// Like SOEM (`ecx_waitinframe` polls the socket in a loop until the frame is back or
    /// the timeout passes), the master spins on the socket while it waits for the reply.
    fn recv_reply(&mut self, timeout: Duration) -> Option<Reply> {
        let deadline = Instant::now() + timeout;
        loop {
            deadline.checked_duration_since(Instant::now())?;
            // SAFETY: `sockaddr_ll` is plain old data; all-zero is a valid value.
            let mut from: libc::sockaddr_ll = unsafe { mem::zeroed() };
            let mut from_len = mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t;
            // SAFETY: `self.rx` is valid for writes of its length, `from` for `from_len` bytes.
            let n = unsafe {
                libc::recvfrom(
                    self.fd.as_raw_fd(),
                    self.rx.as_mut_ptr().cast(),
                    self.rx.len(),
                    libc::MSG_DONTWAIT,
                    (&mut from as *mut libc::sockaddr_ll).cast::<libc::sockaddr>(),
                    &mut from_len,
                )
            };
            let Ok(n) = usize::try_from(n) else {
                std::hint::spin_loop();
                continue;
            };
            if from.sll_pkttype == PACKET_OUTGOING {
                continue;
            }
            if let Some(reply) = self.parse(n) {
                return Some(reply);
            }
        }
    }

    /// The first datagram of a returned frame with the current index.
    fn parse(&self, len: usize) -> Option<Reply> {
        let eth = EthernetFrame::new_checked(self.rx.get(..len)?).ok()?;
        if eth.ethertype() != ETHERTYPE_ETHERCAT || eth.source()[0] & SOURCE_MAC_RETURN_BIT == 0 {
            return None;
        }
        let frame = Frame::new_checked(eth.payload()).ok()?;
        let dg = frame.datagrams().next()?.ok()?;
        if dg.index() != self.index {
            return None;
        }
        let mut data = [0; 8];
        for (d, s) in data.iter_mut().zip(dg.data()) {
            *d = *s;
        }
        Some(Reply {
            data,
            wkc: dg.wkc(),
        })
    }

    /// One datagram out and back (start-up).
    fn exchange(&mut self, command: Command, address: Address, data: &[u8]) -> Reply {
        let len = self.build(command, address, data);
        self.send(len).expect("send");
        self.recv_reply(REPLY_TIMEOUT)
            .unwrap_or_else(|| panic!("no reply to {command:?} {address:?}"))
    }

    fn fpwr(&mut self, register: u16, data: &[u8]) {
        let r = self.exchange(Command::Fpwr, phys(STATION, register), data);
        assert_eq!(r.wkc, 1, "FPWR {register:#06x}");
    }

    /// AL status and AL status code.
    fn al_status(&mut self) -> (u16, u16) {
        let r = self.exchange(
            Command::Fprd,
            phys(STATION, RegisterAddress::AlStatus.addr()),
            &[0; 6],
        );
        assert_eq!(r.wkc, 1, "FPRD AL status");
        (
            u16::from_le_bytes([r.data[0], r.data[1]]),
            u16::from_le_bytes([r.data[4], r.data[5]]),
        )
    }

    fn request(&mut self, state: AlState) {
        self.fpwr(RegisterAddress::AlControl.addr(), &[state as u8, 0]);
    }

    fn lrw(&mut self) -> Reply {
        let io = [0u8; (OUTPUT_BYTES + INPUT_BYTES) as usize];
        self.exchange(Command::Lrw, Address::Logical(0), &io)
    }

    /// Init → Pre-Op → Safe-Op → Op with the default mapping (the ESC reference kept beside the
    /// project, §9.1).
    fn start_up(&mut self) {
        let r = self.exchange(
            Command::Bwr,
            phys(0, RegisterAddress::AlControl.addr()),
            &[AlState::Init as u8 | 0x10, 0],
        );
        assert_eq!(r.wkc, 1, "one slave answers the broadcast");
        let r = self.exchange(
            Command::Apwr,
            phys(0, RegisterAddress::ConfiguredStationAddress.addr()),
            &STATION.to_le_bytes(),
        );
        assert_eq!(r.wkc, 1, "station address set");
        let mut mailboxes = SyncManager::new(MAILBOX_OUT, MAILBOX_LEN, 0x26, true)
            .to_bytes()
            .to_vec();
        mailboxes
            .extend_from_slice(&SyncManager::new(MAILBOX_IN, MAILBOX_LEN, 0x22, true).to_bytes());
        self.fpwr(RegisterAddress::Sm0.addr(), &mailboxes);
        self.request(AlState::PreOp);
        assert_eq!(self.al_status(), (AlState::PreOp as u16, 0), "Pre-Op");

        self.fpwr(
            RegisterAddress::sync_manager(2),
            &SyncManager::new(SM2, OUTPUT_BYTES, 0x64, true).to_bytes(),
        );
        self.fpwr(
            RegisterAddress::sync_manager(3),
            &SyncManager::new(SM3, INPUT_BYTES, 0x20, true).to_bytes(),
        );
        self.fpwr(
            RegisterAddress::fmmu(0),
            &Fmmu::bytes(0, OUTPUT_BYTES, SM2, false, true).to_bytes(),
        );
        self.fpwr(
            RegisterAddress::fmmu(1),
            &Fmmu::bytes(u32::from(OUTPUT_BYTES), INPUT_BYTES, SM3, true, false).to_bytes(),
        );
        self.request(AlState::SafeOp);
        assert_eq!(self.al_status(), (AlState::SafeOp as u16, 0), "Safe-Op");

        // Outputs before and while Op is requested, as SOEM does.
        self.lrw();
        self.request(AlState::Op);
        for _ in 0..200 {
            self.lrw();
            if self.al_status().0 == AlState::Op as u16 {
                return;
            }
            std::thread::sleep(CYCLE);
        }
        panic!("no Op: AL status {:?}", self.al_status());
    }

    /// `cycles` LRW frames, one per millisecond; the hot loop does not allocate.
    fn measure(&mut self, cycles: usize) -> Stats {
        let mut round_trips = Vec::with_capacity(cycles);
        let mut stats = Stats::default();
        let io = [0u8; (OUTPUT_BYTES + INPUT_BYTES) as usize];
        let began = Instant::now();
        let mut next = began;
        for _ in 0..cycles {
            let len = self.build(Command::Lrw, Address::Logical(0), &io);
            let sent = Instant::now();
            if self.send(len).is_err() {
                stats.lost += 1;
            } else {
                match self.recv_reply(REPLY_TIMEOUT) {
                    Some(reply) => {
                        round_trips.push(sent.elapsed());
                        stats.wrong_wkc += u32::from(reply.wkc != EXPECTED_WKC);
                    }
                    None => stats.lost += 1,
                }
            }
            // Absolute schedule; a cycle that overran starts the next one at once.
            next += CYCLE;
            let now = Instant::now();
            if next > now {
                std::thread::sleep(next - now);
            } else {
                stats.overruns += 1;
                next = now;
            }
        }
        stats.elapsed = began.elapsed();
        round_trips.sort_unstable();
        stats.round_trips = round_trips;
        stats
    }
}

/// Put every thread of process `pid` under `SCHED_FIFO` at [`FIFO_PRIORITY`].
fn set_fifo(pid: u32) -> io::Result<()> {
    let param = libc::sched_param {
        sched_priority: FIFO_PRIORITY,
    };
    for task in std::fs::read_dir(format!("/proc/{pid}/task"))? {
        let Some(tid) = task?
            .file_name()
            .to_str()
            .and_then(|t| t.parse::<libc::pid_t>().ok())
        else {
            continue;
        };
        // SAFETY: `param` is a valid sched_param for the duration of the call.
        if unsafe { libc::sched_setscheduler(tid, libc::SCHED_FIFO, &param) } != 0 {
            return Err(io::Error::last_os_error());
        }
    }
    Ok(())
}

fn phys(adp: u16, ado: u16) -> Address {
    Address::Physical { adp, ado }
}

#[derive(Debug, Default)]
struct Stats {
    /// Sorted send → receive times of the frames that came back.
    round_trips: Vec<Duration>,
    lost: u32,
    wrong_wkc: u32,
    /// Cycles that took longer than the cycle time (the next one started late).
    overruns: u32,
    elapsed: Duration,
}

impl Stats {
    /// Nearest-rank percentile `p` (0..=1) of the sorted round trips.
    fn percentile(&self, p: f64) -> Duration {
        let n = self.round_trips.len();
        if n == 0 {
            return Duration::ZERO;
        }
        let rank = ((p * n as f64).ceil() as usize).clamp(1, n);
        self.round_trips[rank - 1]
    }

    fn print(&self, seconds: f64) {
        let us = |d: Duration| d.as_secs_f64() * 1e6;
        let sent = self.round_trips.len() as u32 + self.lost;
        println!(
            "ecat_veth_roundtrip: {sent} LRW cycles at 1 kHz in {:.2} s (asked {seconds} s), \
             {} lost, {} wrong working counter, {} overran the 1 ms cycle",
            self.elapsed.as_secs_f64(),
            self.lost,
            self.wrong_wkc,
            self.overruns
        );
        let p99 = self.percentile(0.99);
        println!(
            "round trip: p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs \
             (target p99 < {} µs: {})",
            us(self.percentile(0.50)),
            us(p99),
            us(self.percentile(0.999)),
            us(self.round_trips.last().copied().unwrap_or_default()),
            TARGET_P99.as_micros(),
            if p99 < TARGET_P99 && self.lost == 0 {
                "met"
            } else {
                "NOT met"
            }
        );
    }
}
