//! A frame's path through the cell loop allocates nothing (docs/performance.md, "EtherCAT: a
//! frame's turn at the floor"): a CMMP-AS on an EtherCAT chain in Op, cycled with LRW frames
//! at 1 kHz over a veth pair, makes no heap allocation on the loop's thread for 1000 cycles
//! (each frame read from the receive ring, passed through the ESC, sent, then the device's
//! exchange and its drive's step), neither with the loop sleeping between frames nor with
//! `--busy-poll` spinning on the ring. Counted with a global allocator on the loop's thread
//! alone; the master is this test, on a tokio runtime of its own.
//!
//! Needs root (raw sockets, a veth pair) and `ip`; otherwise it prints why and passes as
//! skipped.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use drivetwin::cell::config::CellFile;
use drivetwin::cell_loop::{CellLoop, EthercatChain, FrontEnds};
use drivetwin::ecat::chain::SlaveChain;
use drivetwin::ecat::link::{EthercatSocket, SlaveSocket};
use ethercat::register::RegisterAddress;
use ethercat::{Address, AlState, Command, EthernetFrame, Fmmu, Frame, FrameWriter, SyncManager};
use platform::alloc::Counting;

#[path = "support/ecat_veth.rs"]
mod ecat_veth;

#[global_allocator]
static ALLOCATOR: Counting = Counting;

const MASTER_MAC: [u8; 6] = [0x01; 6];
const STATION: u16 = 0x1001;
/// The CMMP-AS SII: mailboxes at 1000h / 1080h, 128 bytes; process data SM2 1100h, SM3 1180h.
const SM2: u16 = 0x1100;
const SM3: u16 = 0x1180;
/// Default mapping 1600h / 1A00h: controlword out, statusword in.
const OUTPUT_BYTES: u16 = 2;
const INPUT_BYTES: u16 = 2;
const CYCLES: usize = 1000;

/// The master: one datagram per frame, its reply's data and working counter.
struct Master {
    socket: EthercatSocket,
    index: u8,
}

impl Master {
    async fn exchange(
        &mut self,
        command: Command,
        address: Address,
        data: &[u8],
    ) -> (Vec<u8>, u16) {
        self.index = self.index.wrapping_add(1);
        let mut tx = [0u8; 128];
        let mut w = FrameWriter::ethernet(&mut tx, MASTER_MAC).unwrap();
        w.push(command, self.index, address, data).unwrap();
        let n = w.finish();
        self.socket.send(&tx[..n]).await.unwrap();
        let mut rx = [0u8; 1536];
        loop {
            let n =
                tokio::time::timeout(Duration::from_secs(2), self.socket.recv_returned(&mut rx))
                    .await
                    .unwrap_or_else(|_| panic!("no reply to {command:?} {address:?}"))
                    .unwrap();
            let eth = EthernetFrame::new_checked(&rx[..n]).unwrap();
            let frame = Frame::new_checked(eth.payload()).unwrap();
            let dg = frame.datagrams().next().unwrap().unwrap();
            if dg.index() == self.index {
                return (dg.data().to_vec(), dg.wkc());
            }
        }
    }

    async fn fpwr(&mut self, register: u16, data: &[u8]) {
        let address = Address::Physical {
            adp: STATION,
            ado: register,
        };
        let (_, wkc) = self.exchange(Command::Fpwr, address, data).await;
        assert_eq!(wkc, 1, "FPWR {register:#06x}");
    }

    async fn al_state(&mut self) -> u16 {
        let address = Address::Physical {
            adp: STATION,
            ado: RegisterAddress::AlStatus.addr(),
        };
        let (data, _) = self.exchange(Command::Fprd, address, &[0; 2]).await;
        u16::from_le_bytes([data[0], data[1]]) & 0x0F
    }

    async fn lrw(&mut self) -> u16 {
        let io = [0u8; (OUTPUT_BYTES + INPUT_BYTES) as usize];
        self.exchange(Command::Lrw, Address::Logical(0), &io)
            .await
            .1
    }

    /// Init → Pre-Op → Safe-Op → Op with the default mapping, as SOEM does it.
    async fn start_up(&mut self) {
        let all = |ado| Address::Physical { adp: 0, ado };
        let (_, wkc) = self
            .exchange(
                Command::Bwr,
                all(RegisterAddress::AlControl.addr()),
                &[0x11, 0],
            )
            .await;
        assert_eq!(wkc, 1, "one slave");
        let station = RegisterAddress::ConfiguredStationAddress.addr();
        self.exchange(Command::Apwr, all(station), &STATION.to_le_bytes())
            .await;
        let mut mailboxes = SyncManager::new(0x1000, 0x80, 0x26, true)
            .to_bytes()
            .to_vec();
        mailboxes.extend_from_slice(&SyncManager::new(0x1080, 0x80, 0x22, true).to_bytes());
        self.fpwr(RegisterAddress::Sm0.addr(), &mailboxes).await;
        let control = RegisterAddress::AlControl.addr();
        self.fpwr(control, &[AlState::PreOp as u8, 0]).await;
        assert_eq!(self.al_state().await, AlState::PreOp as u16);
        let sm2 = SyncManager::new(SM2, OUTPUT_BYTES, 0x64, true).to_bytes();
        self.fpwr(RegisterAddress::sync_manager(2), &sm2).await;
        let sm3 = SyncManager::new(SM3, INPUT_BYTES, 0x20, true).to_bytes();
        self.fpwr(RegisterAddress::sync_manager(3), &sm3).await;
        let out = Fmmu::bytes(0, OUTPUT_BYTES, SM2, false, true).to_bytes();
        self.fpwr(RegisterAddress::fmmu(0), &out).await;
        let inputs = Fmmu::bytes(u32::from(OUTPUT_BYTES), INPUT_BYTES, SM3, true, false);
        self.fpwr(RegisterAddress::fmmu(1), &inputs.to_bytes())
            .await;
        self.fpwr(control, &[AlState::SafeOp as u8, 0]).await;
        assert_eq!(self.al_state().await, AlState::SafeOp as u16);
        self.lrw().await;
        self.fpwr(control, &[AlState::Op as u8, 0]).await;
        for _ in 0..200 {
            self.lrw().await;
            if self.al_state().await == AlState::Op as u16 {
                return;
            }
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        panic!("no Op");
    }
}

/// Allocations on the loop's thread over [`CYCLES`] LRW cycles at 1 kHz in Op.
fn allocations_per_frame_path(busy_poll: bool) -> Option<u64> {
    // SAFETY-free root check: a raw socket is refused without CAP_NET_RAW.
    let pair = match ecat_veth::VethPair::create() {
        Ok(p) => p,
        Err(why) => {
            eprintln!("skipped: {why}");
            return None;
        }
    };
    let socket = match SlaveSocket::open(&pair.twin_if) {
        Ok(s) => s,
        Err(why) => {
            eprintln!("skipped: no raw socket ({why})");
            return None;
        }
    };
    let chain = SlaveChain::from_cell_file(
        &CellFile::single("cmmp-as", 1),
        drivetwin::vendors::VENDORS.runtime,
    )
    .expect("a chain of one CMMP-AS");
    let cell_loop = CellLoop::new(
        drivetwin::cell::can_cell::CanCell::new(),
        FrontEnds {
            ethercat: vec![EthercatChain {
                chain,
                socket,
                trace: None,
            }],
            busy_poll,
            ..FrontEnds::default()
        },
    )
    .expect("the loop");
    let stop = cell_loop.stop_handle();
    let thread = std::thread::Builder::new()
        .name("cell".into())
        .spawn(move || {
            Counting::mark_this_thread();
            cell_loop.run().map(|_| ())
        })
        .expect("the loop's thread");
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    let count = rt.block_on(async {
        let mut master = Master {
            socket: EthercatSocket::open(&pair.master_if).expect("master socket"),
            index: 0,
        };
        master.start_up().await;
        let mut tick = tokio::time::interval(Duration::from_millis(1));
        // Warm-up: what the loop sets up once (its first turns in Op) is not the frame's path.
        for _ in 0..200 {
            tick.tick().await;
            assert_eq!(master.lrw().await, 3);
        }
        Counting::open_window();
        for _ in 0..CYCLES {
            tick.tick().await;
            assert_eq!(
                master.lrw().await,
                3,
                "outputs written (2) and inputs read (1)"
            );
        }
        Counting::close_window()
    });
    stop.stop();
    thread.join().expect("the loop ends").expect("the loop ran");
    Some(count)
}

#[test]
fn the_frame_path_allocates_nothing_sleeping_or_busy_polling() {
    for busy_poll in [false, true] {
        let Some(n) = allocations_per_frame_path(busy_poll) else {
            return;
        };
        assert_eq!(
            n, 0,
            "{n} allocations on the loop's thread in {CYCLES} cycles (busy_poll {busy_poll})"
        );
    }
}
