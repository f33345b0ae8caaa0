//! The EtherCAT chain driven in-process with the datagrams SOEM sends (no sockets): start-up
//! from the SII, Pre-Op, a refused and an accepted Safe-Op, Op, and a cyclic exchange in
//! which the controlword and target written in the outputs reach the CiA 402 drive and its
//! statusword and position come back in the inputs. A chain joined to a cell's list of
//! stations (as the cell loop runs it) answers every frame as the chain that owns its drives.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

#[path = "support/ecat_inputs.rs"]
mod ecat_inputs;
use ecat_inputs::{phys, sm};

use canopen::CanFrame;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::config::CellFile;
use drivetwin::cell::param_saver::ParamSaver;
use drivetwin::cell::param_store::ParamStore;
use drivetwin::cell::station::Station;
use drivetwin::ecat::chain::{NoBuses, SlaveChain, SlaveDrive};
use ethercat::datagram::Command;
use ethercat::frame::{Address, EthernetFrame, Frame, FrameWriter};
use ethercat::{AlState, Fmmu, FrameOutcome};
use od::{Instant, ObjectAccess};

const MASTER_MAC: [u8; 6] = [0x01; 6];
const STATION: u16 = 0x1001;
const SM2: u16 = 0x1100;
const SM3: u16 = 0x1180;

struct Reply {
    data: Vec<u8>,
    wkc: u16,
}

impl Reply {
    fn u16(&self) -> u16 {
        u16::from_le_bytes([self.data[0], self.data[1]])
    }
}

struct Master {
    cell: SlaveChain,
    now: Instant,
    /// The cell the chain has joined, its CAN buses run beside the chain (none: the chain
    /// owns its drives).
    joined: Option<CanCell>,
    /// The frames the cell's CAN buses sent, as they came.
    can_sent: Vec<CanFrame>,
    /// Every frame as it came back, when asked for.
    returned: Option<Vec<Vec<u8>>>,
    /// The runtime's writer of the saves the slaves ask for (1010h), as the cell loop's.
    saver: ParamSaver<usize>,
    /// Whether the saves go to `saver` after every frame and poll (else the test takes them).
    runtime_saves: bool,
}

impl Master {
    fn new(cell: SlaveChain) -> Self {
        Master::start(cell, None)
    }

    /// `cell` joined to a cell's list behind a drive of the cell's own, as the cell loop
    /// joins a chain: its slaves name their drives by id there.
    fn joined(mut cell: SlaveChain) -> Self {
        let mut can = CanCell::new();
        let desc = devices::by_name("cmmp-as").unwrap();
        can.stations
            .push(Station::with_settings(desc, 9, None, vec![], Some(Default::default())).unwrap());
        cell.join_cell(&mut can);
        for i in 0..cell.len() {
            assert!(
                matches!(cell.drive(i), Some(SlaveDrive::Station { bus: None, .. })),
                "slave {i} names a station of the list"
            );
        }
        Master::start(cell, Some(can))
    }

    fn start(cell: SlaveChain, joined: Option<CanCell>) -> Self {
        let mut m = Master {
            cell,
            now: Instant::from_millis(1),
            joined,
            can_sent: Vec::new(),
            returned: None,
            saver: ParamSaver::default(),
            runtime_saves: true,
        };
        match &mut m.joined {
            Some(can) => {
                for b in 0..can.buses.len() {
                    can.boot(b, m.now, &mut m.can_sent);
                }
                m.cell.boot_with(m.now, can)
            }
            None => m.cell.boot(m.now),
        }
        m
    }

    /// A frame through the chain.
    fn pass(&mut self, frame: &mut [u8]) -> FrameOutcome {
        let outcome = match &mut self.joined {
            Some(can) => self.cell.on_frame_with(self.now, frame, can),
            None => self.cell.on_frame(self.now, frame),
        };
        self.hand_off_saves();
        outcome
    }

    /// The chain's drives (and the cell's CAN buses) run to `now`.
    fn poll(&mut self) {
        match &mut self.joined {
            Some(can) => {
                for b in 0..can.buses.len() {
                    can.poll(b, self.now, &mut self.can_sent);
                }
                self.cell.poll_with(self.now, can);
            }
            None => {
                self.cell.poll(self.now);
            }
        }
        self.hand_off_saves();
    }

    /// As the cell loop does after each frame and poll: the saves the slaves asked for go
    /// to the saver, and those it has written go back to their slaves.
    fn hand_off_saves(&mut self) {
        if !self.runtime_saves {
            return;
        }
        while let Some(req) = self.cell.take_save() {
            self.saver.start(req.slave, req.job);
        }
        while let Some((slave, result)) = self.saver.finished() {
            match &mut self.joined {
                Some(can) => self.cell.saved(slave, result, can),
                None => self.cell.saved(slave, result, &mut NoBuses),
            }
        }
    }

    fn send(&mut self, reqs: &[(Command, Address, Vec<u8>)]) -> Vec<Reply> {
        let mut buf = vec![0u8; 1514];
        let mut w = FrameWriter::ethernet(&mut buf, MASTER_MAC).unwrap();
        for (i, (c, a, d)) in reqs.iter().enumerate() {
            w.push(*c, i as u8, *a, d).unwrap();
        }
        let n = w.finish();
        buf.truncate(n);
        let outcome = self.pass(&mut buf);
        assert!(outcome.forward(), "{outcome:?}");
        if let Some(returned) = &mut self.returned {
            returned.push(buf.clone());
        }
        let eth = EthernetFrame::new_checked(&buf[..]).unwrap();
        assert_eq!(
            eth.source()[0],
            0x03,
            "returned-frame bit in the source MAC"
        );
        let f = Frame::new_checked(eth.payload()).unwrap();
        f.datagrams()
            .map(|d| {
                let d = d.unwrap();
                Reply {
                    data: d.data().to_vec(),
                    wkc: d.wkc(),
                }
            })
            .collect()
    }

    fn one(&mut self, c: Command, a: Address, d: &[u8]) -> Reply {
        self.send(&[(c, a, d.to_vec())]).remove(0)
    }
    fn fprd(&mut self, ado: u16, len: usize) -> Reply {
        self.one(Command::Fprd, phys(STATION, ado), &vec![0; len])
    }
    fn fpwr(&mut self, ado: u16, d: &[u8]) -> Reply {
        let r = self.one(Command::Fpwr, phys(STATION, ado), d);
        assert_eq!(r.wkc, 1, "FPWR {ado:#06x}");
        r
    }
    fn al(&mut self) -> (u16, u16) {
        let r = self.fprd(0x0130, 6);
        (r.u16(), u16::from_le_bytes([r.data[4], r.data[5]]))
    }
    fn sii(&mut self, word: u32) -> u32 {
        let mut cmd = vec![0x00, 0x01];
        cmd.extend_from_slice(&word.to_le_bytes());
        self.fpwr(0x0502, &cmd);
        assert_eq!(self.fprd(0x0502, 2).u16() & 0xF800, 0);
        let r = self.fprd(0x0508, 4);
        u32::from_le_bytes(r.data[..4].try_into().unwrap())
    }
    /// Let `ms` milliseconds pass with the runtime's tick.
    fn idle(&mut self, ms: u64) {
        for _ in 0..ms {
            self.tick();
        }
    }
    fn tick(&mut self) {
        self.now = self.now + std::time::Duration::from_millis(1);
        self.poll();
    }
}

fn cell() -> SlaveChain {
    SlaveChain::from_cell_file(
        &CellFile::single("cmmp-as", 1),
        drivetwin::vendors::VENDORS.runtime,
    )
    .expect("cell")
}

/// ecx_config_init up to Pre-Op (the ESC reference kept beside the project, §9.1, abridged).
fn to_preop(m: &mut Master) {
    let r = m.one(Command::Bwr, phys(0, 0x0120), &[0x11, 0x00]);
    assert_eq!(r.wkc, 1);
    let r = m.one(Command::Brd, phys(0, 0x0000), &[0, 0]);
    assert_eq!(r.wkc, 1, "one slave");
    let r = m.one(Command::Apwr, phys(0, 0x0010), &STATION.to_le_bytes());
    assert_eq!(r.wkc, 1);
    assert_eq!(m.sii(0x08), 0x1D, "vendor Festo");
    let desc = devices::by_name("cmmp-as").unwrap();
    assert_eq!(m.sii(0x0A), desc.product_code);
    assert_eq!(m.sii(0x18), 0x0080_1000, "SM0 mailbox 0x1000 / 0x80");
    let mut mbx = sm(0x1000, 0x80, 0x26);
    mbx.extend_from_slice(&sm(0x1080, 0x80, 0x22));
    m.fpwr(0x0800, &mbx);
    m.fpwr(0x0120, &[0x02, 0x00]);
    assert_eq!(m.al(), (0x0002, 0));
}

/// ecx_config_map_group's SM2/SM3 and FMMUs, then Safe-Op.
fn map(m: &mut Master, outputs: u16, inputs: u16) {
    m.fpwr(0x0810, &sm(SM2, outputs, 0x64));
    m.fpwr(0x0818, &sm(SM3, inputs, 0x20));
    m.fpwr(
        0x0600,
        &Fmmu::bytes(0, outputs, SM2, false, true).to_bytes(),
    );
    m.fpwr(
        0x0610,
        &Fmmu::bytes(u32::from(outputs), inputs, SM3, true, false).to_bytes(),
    );
}

fn lrw(m: &mut Master, outputs: &[u8], inputs: usize) -> Vec<u8> {
    let mut d = outputs.to_vec();
    d.resize(outputs.len() + inputs, 0);
    let r = m.one(Command::Lrw, Address::Logical(0), &d);
    assert_eq!(r.wkc, 3, "outputs written (2) + inputs read (1)");
    r.data[outputs.len()..].to_vec()
}

/// The controlwords that bring a CiA 402 drive to Operation enabled: shutdown, switch on,
/// enable operation (CiA 402 §6.2, Fig. 4, transitions 2, 3, 4).
const ENABLE: [u16; 3] = [0x0006, 0x0007, 0x000F];

/// Each of [`ENABLE`] for `cycles` master cycles, `cycle` sending one with that controlword;
/// what the last cycle returned.
fn enable<T: Default>(
    m: &mut Master,
    cycles: usize,
    mut cycle: impl FnMut(&mut Master, u16) -> T,
) -> T {
    let mut last = T::default();
    for cw in ENABLE {
        for _ in 0..cycles {
            last = cycle(m, cw);
        }
    }
    last
}

/// One 1 ms cycle on SYNC0 with frames half-way between two events: the frame with `cw`,
/// then the event; the statusword the frame brought back.
fn sync0_cycle(m: &mut Master, cw: u16) -> u16 {
    let half = std::time::Duration::from_micros(500);
    m.now = m.now + half;
    let sw = u16::from_le_bytes(lrw(m, &cw.to_le_bytes(), 2).try_into().unwrap());
    m.now = m.now + half;
    m.poll();
    sw
}

/// CMMP-ECAT-04: in Safe-Operational the inputs (statusword) are sent while the outputs'
/// set-points are ignored (an RxPDO with controlword 000Fh changes nothing); they count only
/// after Safe-Op → Op.
#[test]
fn soem_startup_and_cia402_enable_with_default_mapping() {
    let mut m = Master::new(cell());
    to_preop(&mut m);

    // SM2 of the wrong size: refused with 0x001D, the slave stays in Pre-Op with the error bit.
    map(&mut m, 3, 2);
    m.fpwr(0x0120, &[0x04, 0x00]);
    assert_eq!(m.al(), (0x0012, 0x001D));
    // The default mapping: 1600h = controlword, 1A00h = statusword (2 bytes each).
    map(&mut m, 2, 2);
    m.fpwr(0x0120, &[0x14, 0x00]);
    assert_eq!(m.al(), (0x0004, 0));
    let layout = m.cell.device(0).unwrap().layout().unwrap().clone();
    assert_eq!((layout.output_bytes, layout.input_bytes), (2, 2));

    // Safe-Op: inputs valid (SWITCH ON DISABLED), set-points ignored.
    m.idle(5);
    let sw = u16::from_le_bytes(lrw(&mut m, &[0x06, 0x00], 2).try_into().unwrap());
    assert_eq!(sw & 0x4F, 0x40, "switch on disabled: {sw:#06x}");
    m.idle(5);
    let sw = u16::from_le_bytes(lrw(&mut m, &[0x06, 0x00], 2).try_into().unwrap());
    assert_eq!(
        sw & 0x6F,
        0x40,
        "Safe-Op ignores the controlword: {sw:#06x}"
    );
    for _ in 0..5 {
        m.tick();
        lrw(&mut m, &[0x0F, 0x00], 2);
    }
    let sw = u16::from_le_bytes(lrw(&mut m, &[0x0F, 0x00], 2).try_into().unwrap());
    assert_eq!(sw & 0x6F, 0x40, "CW 000Fh ignored in Safe-Op: {sw:#06x}");
    assert_eq!(read_u16(&m, 0x6040), 0, "the drive's controlword unchanged");
    assert_eq!(m.cell.device(0).unwrap().outputs_applied, 0);

    m.fpwr(0x0120, &[0x08, 0x00]);
    assert_eq!(m.al(), (0x0008, 0));
    let mut sw = 0;
    for (cw, want) in [(0x0006u16, 0x21u16), (0x0007, 0x23), (0x000F, 0x27)] {
        let mut ok = false;
        for _ in 0..200 {
            m.tick();
            sw = u16::from_le_bytes(lrw(&mut m, &cw.to_le_bytes(), 2).try_into().unwrap());
            if sw & 0x6F == want {
                ok = true;
                break;
            }
        }
        assert!(
            ok,
            "controlword {cw:#06x}: statusword {sw:#06x}, want {want:#04x}"
        );
    }
    let dev = m.cell.model(0).unwrap();
    let mut b = [0u8; 2];
    dev.read(0x6040, 0, &mut b).unwrap();
    assert_eq!(
        u16::from_le_bytes(b),
        0x000F,
        "the controlword reached the drive"
    );
    assert_eq!(m.cell.esc(0).unwrap().al_state(), AlState::Op);

    // Back to Init: the layout is gone, the mailbox stops.
    m.fpwr(0x0120, &[0x01, 0x00]);
    assert_eq!(m.al(), (0x0001, 0));
    assert!(m.cell.device(0).unwrap().layout().is_none());
}

#[test]
fn remapped_pdos_carry_target_and_position() {
    let mut m = Master::new(cell());
    // What a master's CoE start-up writes in Pre-Op, written into the dictionary: outputs
    // controlword + mode + target position, inputs statusword + position actual value.
    {
        let model = m.cell.model_mut(0).unwrap();
        for (i, s, v) in [
            (0x1600u16, 0u8, 0u32),
            (0x1600, 2, 0x6060_0008),
            (0x1600, 3, 0x607A_0020),
            (0x1600, 0, 3),
            (0x1A00, 0, 0),
            (0x1A00, 2, 0x6064_0020),
            (0x1A00, 0, 2),
        ] {
            let bytes = v.to_le_bytes();
            let n = if s == 0 { 1 } else { 4 };
            model
                .write(i, s, &bytes[..n])
                .unwrap_or_else(|e| panic!("{i:04X}h:{s:02X}h: {e:?}"));
        }
    }
    to_preop(&mut m);
    // The old sizes are refused now: 0x001D for outputs, then 0x001E for inputs.
    map(&mut m, 2, 2);
    m.fpwr(0x0120, &[0x04, 0x00]);
    assert_eq!(m.al(), (0x0012, 0x001D));
    map(&mut m, 7, 2);
    m.fpwr(0x0120, &[0x14, 0x00]);
    assert_eq!(m.al(), (0x0012, 0x001E));
    map(&mut m, 7, 6);
    m.fpwr(0x0120, &[0x14, 0x00]);
    assert_eq!(m.al(), (0x0004, 0));
    m.fpwr(0x0120, &[0x08, 0x00]);
    assert_eq!(m.al(), (0x0008, 0));

    let target: i32 = 20_000;
    let out = |cw: u16| {
        let mut o = cw.to_le_bytes().to_vec();
        o.push(1); // profile position
        o.extend_from_slice(&target.to_le_bytes());
        o
    };
    let mut inputs = enable(&mut m, 50, |m, cw| {
        m.tick();
        lrw(m, &out(cw), 6)
    });
    let sw = u16::from_le_bytes([inputs[0], inputs[1]]);
    assert_eq!(sw & 0x6F, 0x27, "operation enabled: {sw:#06x}");
    // New set-point (bit 4), then wait for target reached (bit 10).
    let mut pos = 0;
    let mut reached = false;
    for k in 0..3000 {
        m.tick();
        let cw = if k < 20 { 0x001F } else { 0x000F };
        inputs = lrw(&mut m, &out(cw), 6);
        let sw = u16::from_le_bytes([inputs[0], inputs[1]]);
        pos = i32::from_le_bytes(inputs[2..6].try_into().unwrap());
        if k > 20 && sw & 0x0400 != 0 {
            reached = true;
            break;
        }
    }
    assert!(reached, "target reached; position {pos}");
    assert!((pos - target).abs() < 200, "position {pos} near {target}");
    let mut b = [0u8; 4];
    m.cell.model(0).unwrap().read(0x607A, 0, &mut b).unwrap();
    assert_eq!(
        i32::from_le_bytes(b),
        target,
        "the target reached the drive"
    );
}

#[test]
fn chain_of_two_slaves_counts_both() {
    let mut file = CellFile::single("cmmp-as", 1);
    let mut second = file.drive[0].clone();
    second.node = 2;
    file.drive.push(second);
    let mut m = Master::new(
        SlaveChain::from_cell_file(&file, drivetwin::vendors::VENDORS.runtime).expect("cell"),
    );
    assert_eq!(m.cell.len(), 2);
    let r = m.one(Command::Brd, phys(0, 0x0000), &[0, 0]);
    assert_eq!(r.wkc, 2);
    for i in 0..2u16 {
        let r = m.one(
            Command::Apwr,
            phys(i.wrapping_neg(), 0x0010),
            &(0x1001 + i).to_le_bytes(),
        );
        assert_eq!(r.wkc, 1);
    }
    assert_eq!(m.cell.esc(1).unwrap().station_address(), 0x1002);
}

/// CMMP-ECAT-02: the identity 1018h:01 read over CoE is Festo's vendor ID 0000001Dh (the ESI's
/// `<Vendor><Id>#x1D</Id>`, checked in `esi.rs`; the SII's in `to_preop`).
#[test]
fn sdo_upload_over_coe_through_the_chain() {
    let mut m = Master::new(cell());
    to_preop(&mut m);
    // CoE SDO upload request 1018h:01 (expedited), mailbox counter 1, padded to the SM0 size.
    let mut req = vec![0u8; 0x80];
    req[..16].copy_from_slice(&[
        10, 0, 0, 0, 0, 0x13, 0x00, 0x20, 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0,
    ]);
    m.fpwr(0x1000, &req);
    // The device answers after the frame; the master polls SM1's status, then reads it.
    assert_eq!(m.fprd(0x080D, 1).data[0] & 0x08, 0x08, "reply posted");
    let r = m.fprd(0x1080, 0x80);
    assert_eq!(r.data[5] & 0x0F, 0x03, "CoE");
    assert_eq!(
        u16::from_le_bytes([r.data[6], r.data[7]]) >> 12,
        3,
        "SDO response"
    );
    assert_eq!(&r.data[9..12], &[0x18, 0x10, 0x01]);
    assert_eq!(&r.data[12..16], &[0x1D, 0, 0, 0], "vendor Festo");
    assert_eq!(m.cell.device(0).unwrap().coe_counters().aborts_sent, 0);
}

/// SOEM's `ecx_dcsync0`: SYNC0 every `cycle_ns` from a whole cycle 10 ms ahead; returns the
/// system time of the first event.
fn dc_sync0(m: &mut Master, cycle_ns: u32) -> u64 {
    m.fpwr(0x0981, &[0]);
    m.fpwr(0x0980, &[0]);
    let r = m.fprd(0x0910, 8);
    let t = u64::from_le_bytes(r.data[..8].try_into().unwrap());
    let c = u64::from(cycle_ns);
    let start = (t + 10_000_000) / c * c + c;
    m.fpwr(0x0990, &start.to_le_bytes());
    m.fpwr(0x09A0, &cycle_ns.to_le_bytes());
    m.fpwr(0x0981, &[0x03]);
    start
}

/// A drive on EtherCAT alone keeps its error register (1001h) and its newest error in the
/// history (1003h:01) as a CANopen node does (CiA 301 §7.5.2.2, §7.5.2.3).
fn assert_error_kept(m: &Master, register: u8, code: u16) {
    let model = m.cell.model(0).unwrap();
    let mut r = [0u8; 1];
    model.read(0x1001, 0, &mut r).unwrap();
    assert_eq!(r[0], register, "1001h error register");
    let mut h = [0u8; 4];
    model.read(0x1003, 1, &mut h).unwrap();
    assert_eq!(
        u32::from_le_bytes(h) & 0xFFFF,
        u32::from(code),
        "1003h:01 newest error"
    );
}

fn read_u16(m: &Master, index: u16) -> u16 {
    let mut b = [0u8; 2];
    m.cell.model(0).unwrap().read(index, 0, &mut b).unwrap();
    u16::from_le_bytes(b)
}

/// From Pre-Op to Op on DC SYNC0 every 1 ms, the clock half-way past the first event, the
/// drive enabled by the master's cycles.
fn enabled_on_sync0(m: &mut Master) {
    let first = dc_sync0(m, 1_000_000);
    map(m, 2, 2);
    m.fpwr(0x0120, &[0x04, 0x00]);
    m.fpwr(0x0120, &[0x08, 0x00]);
    assert_eq!(m.al(), (0x0008, 0));
    let esc_time = m.cell.esc(0).unwrap().system_time_at(m.now);
    m.now = m.now + std::time::Duration::from_nanos(first - esc_time + 500_000);
    m.poll();
    let sw = enable(m, 60, sync0_cycle);
    assert_eq!(sw & 0x6F, 0x27, "operation enabled on SYNC0: {sw:#06x}");
}

/// The twin's loop held off its CPU: the SYNC0 events it runs a cycle or more after their
/// time, before the frame that waited in the socket meanwhile, cost the master nothing (a
/// device sees each event and each frame in time, and a master waiting for its answer sends
/// no more). The same events seen in time without a frame lose the grid (the test above).
#[test]
fn sync0_events_the_loop_runs_late_are_not_the_masters() {
    let mut m = Master::new(cell());
    to_preop(&mut m);
    enabled_on_sync0(&mut m);
    let missed = m.cell.device(0).unwrap().sync_monitor().missed;
    // 7.5 ms without a poll (half a cycle after an event before), then the frame: eight
    // events run first, seven of them a cycle or more late (the first takes the last
    // outputs), the eighth at its time, two events after the outputs: it costs 3, and the
    // frame takes 1 back. Seen in time, the third event without outputs lost the grid.
    m.now = m.now + std::time::Duration::from_micros(7_500);
    let sw = u16::from_le_bytes(lrw(&mut m, &0x000Fu16.to_le_bytes(), 2).try_into().unwrap());
    assert_eq!(m.al(), (0x0008, 0), "still in Op");
    let dev = m.cell.device(0).unwrap();
    assert_eq!(
        dev.sync_monitor().missed - missed,
        7,
        "the events ran, without outputs"
    );
    assert_eq!(dev.sync_monitor().error_counter(), 2);
    assert_eq!(sw & 0x6F, 0x27, "{sw:#06x}");
    // Back on the grid: the master's next cycles keep the slave in Op.
    for _ in 0..20 {
        sync0_cycle(&mut m, 0x000F);
    }
    assert_eq!(m.cell.device(0).unwrap().sync_monitor().error_counter(), 0);
    assert_eq!(m.al(), (0x0008, 0));
    assert_eq!(m.cell.device(0).unwrap().sync_errors, 0);
}

/// An answer the twin sends a cycle or more after its frame arrived (the loop held off its
/// CPU) holds back a master that waits for each answer: the SYNC0 events until a cycle after
/// the answer find no outputs through the twin's delay, and cost the master nothing, though
/// the last of them runs in time. A master that stops after that is found by the events
/// after them.
#[test]
fn sync0_events_a_late_answer_held_back_are_not_the_masters() {
    let ms = std::time::Duration::from_millis;
    let us = std::time::Duration::from_micros;
    let mut m = Master::new(cell());
    to_preop(&mut m);
    enabled_on_sync0(&mut m);
    assert_eq!(m.cell.device(0).unwrap().sync_monitor().error_counter(), 0);
    // A frame half-way between two events; its answer goes out 3.3 ms later. The events
    // meanwhile run then: two a cycle or more late, the third 0.8 ms late, in time.
    let arrived = m.now + us(500);
    m.now = arrived;
    lrw(&mut m, &0x000Fu16.to_le_bytes(), 2);
    let answered = arrived + us(3_300);
    m.cell.answered(arrived, answered);
    m.now = answered;
    m.poll();
    // The master's next frame comes at once.
    m.now = m.now + us(20);
    lrw(&mut m, &0x000Fu16.to_le_bytes(), 2);
    let dev = m.cell.device(0).unwrap();
    assert_eq!(
        dev.sync_monitor().error_counter(),
        0,
        "the third event cost nothing"
    );
    assert_eq!(m.al(), (0x0008, 0), "still in Op");
    // The master stops: the event within a cycle of the answer takes its outputs, the next
    // two without outputs lose the grid as for any master that stops.
    for _ in 0..3 {
        m.now = m.now + ms(1);
        m.poll();
    }
    assert_eq!(m.al(), (0x0008, 0), "two missed cycles are tolerated");
    m.now = m.now + ms(1);
    m.poll();
    assert_eq!(m.al(), (0x0014, 0x001A), "Safe-Op, synchronisation error");
}

/// Without a late answer the same events, the last in time, cost the master 3 (three events
/// since its outputs), and its next frame takes 1 back.
#[test]
fn sync0_events_after_a_prompt_answer_count_as_before() {
    let us = std::time::Duration::from_micros;
    let mut m = Master::new(cell());
    to_preop(&mut m);
    enabled_on_sync0(&mut m);
    let arrived = m.now + us(500);
    m.now = arrived;
    lrw(&mut m, &0x000Fu16.to_le_bytes(), 2);
    // Answered within the cycle: no hold.
    m.cell.answered(arrived, arrived + us(200));
    m.now = arrived + us(3_300);
    m.poll();
    m.now = m.now + us(20);
    lrw(&mut m, &0x000Fu16.to_le_bytes(), 2);
    assert_eq!(m.cell.device(0).unwrap().sync_monitor().error_counter(), 2);
    assert_eq!(m.al(), (0x0008, 0), "still in Op");
}

#[test]
fn sync0_cycle_other_than_the_interpolator_cycle_is_refused() {
    let mut m = Master::new(cell());
    to_preop(&mut m);
    // 60C2h = 1 ms (default); SYNC0 every 2 ms: refused with 0x0036.
    dc_sync0(&mut m, 2_000_000);
    map(&mut m, 2, 2);
    m.fpwr(0x0120, &[0x04, 0x00]);
    assert_eq!(m.al(), (0x0012, 0x0036), "DC SYNC0 cycle time");
    dc_sync0(&mut m, 1_000_000);
    m.fpwr(0x0120, &[0x14, 0x00]);
    assert_eq!(m.al(), (0x0004, 0));
}

#[test]
fn sync0_takes_the_outputs_and_stopped_cycles_are_a_sync_error() {
    let mut m = Master::new(cell());
    to_preop(&mut m);
    let first = dc_sync0(&mut m, 1_000_000);
    map(&mut m, 2, 2);
    m.fpwr(0x0120, &[0x04, 0x00]);
    m.fpwr(0x0120, &[0x08, 0x00]);
    assert_eq!(m.al(), (0x0008, 0));
    // Run the clock to just past the first SYNC0 event, then cycle with frames half-way
    // between two events (system time = local time here: the master never wrote 0x0920).
    let esc_time = m.cell.esc(0).unwrap().system_time_at(m.now);
    let to_first = first - esc_time;
    m.now = m.now + std::time::Duration::from_nanos(to_first + 500_000);
    m.poll();
    let half = std::time::Duration::from_micros(500);
    // The controlword of a frame reaches the drive at the next SYNC0, not before.
    let before = read_u16(&m, 0x6040);
    lrw(&mut m, &[0x06, 0x00], 2);
    assert_eq!(read_u16(&m, 0x6040), before, "not before SYNC0");
    m.now = m.now + half;
    m.poll();
    assert_eq!(read_u16(&m, 0x6040), 0x0006, "taken at SYNC0");
    let sw = enable(&mut m, 60, sync0_cycle);
    assert_eq!(sw & 0x6F, 0x27, "operation enabled on SYNC0: {sw:#06x}");
    let dev = m.cell.device(0).unwrap();
    assert_eq!(dev.sync_monitor().missed, 0);
    assert_eq!(dev.sync_errors, 0);

    // The master stops: three SYNC0 events without outputs are a sync error.
    for _ in 0..2 {
        m.now = m.now + std::time::Duration::from_millis(1);
        m.poll();
    }
    assert_eq!(m.al(), (0x0008, 0), "two missed cycles are tolerated");
    m.now = m.now + std::time::Duration::from_millis(1);
    m.poll();
    assert_eq!(
        m.al(),
        (0x0014, 0x001A),
        "Safe-Op + error, synchronisation error"
    );
    assert_eq!(m.cell.device(0).unwrap().sync_errors, 1);
    // The drive reports it (63-4, EMCY 8781h) and leaves operation enabled.
    let drive = m.cell.model(0).unwrap().drive().unwrap();
    assert_eq!(drive.errors(), &[0x8781], "63-4 with EMCY code 8781h");
    // Fallen to Safe-Op, the slave still counts the master's output write: SM2 stays
    // enabled until Safe-Op → Pre-Op, as the slave stack disables it (docs/decisions.md,
    // "Working counter in Safe-Op"); the set-point is not taken (`lrw` checks 3).
    let cw = read_u16(&m, 0x6040);
    lrw(&mut m, &[0x1F, 0x00], 2);
    m.now = m.now + std::time::Duration::from_millis(1);
    m.cell.poll(m.now);
    assert_eq!(read_u16(&m, 0x6040), cw, "Safe-Op ignores the set-points");
    for _ in 0..50 {
        m.tick();
    }
    let sw = read_u16(&m, 0x6041);
    assert_eq!(sw & 0x4F, 0x08, "fault: {sw:#06x}");
}

/// The `Dc` modes the ESI offers are the ones the slave runs: a configurator writes each
/// `OpMode`'s AssignActivate to 0x0980–0x0981 (after the start time and, for a SYNC0 mode, the
/// master's cycle as SYNC0 cycle, 1 ms = 60C2h here); the slave reaches Op, and takes a
/// frame's controlword at the frame (SM-synchronous) or at the next SYNC0 event (DC).
#[test]
fn the_esi_dc_modes_are_the_ones_the_slave_runs() {
    let mut esi = String::new();
    drivetwin::export::esi::write_esi(devices::by_name("cmmp-as").unwrap(), &mut esi).unwrap();
    let dc = &esi[esi.find("<Dc>").expect("<Dc>")..esi.find("</Dc>").expect("</Dc>")];
    let modes: Vec<(u16, bool)> = dc
        .split("<OpMode>")
        .skip(1)
        .map(|m| {
            let a = m.split("<AssignActivate>#x").nth(1).unwrap();
            let a = u16::from_str_radix(&a[..a.find('<').unwrap()], 16).unwrap();
            (
                a,
                m.contains(r#"<CycleTimeSync0 Factor="1">0</CycleTimeSync0>"#),
            )
        })
        .collect();
    assert_eq!(modes, [(0x0000, false), (0x0300, true)]);
    for (assign, sync0) in modes {
        let mut m = Master::new(cell());
        to_preop(&mut m);
        m.fpwr(0x0981, &[0]);
        let first = sync0.then(|| {
            let r = m.fprd(0x0910, 8);
            let t = u64::from_le_bytes(r.data[..8].try_into().unwrap());
            let start = (t + 10_000_000) / 1_000_000 * 1_000_000 + 1_000_000;
            m.fpwr(0x0990, &start.to_le_bytes());
            m.fpwr(0x09A0, &1_000_000u32.to_le_bytes());
            start
        });
        m.fpwr(0x0980, &assign.to_le_bytes());
        map(&mut m, 2, 2);
        m.fpwr(0x0120, &[0x04, 0x00]);
        m.fpwr(0x0120, &[0x08, 0x00]);
        assert_eq!(m.al(), (0x0008, 0), "Op in mode {assign:#06x}");
        assert_eq!(
            m.cell.esc(0).unwrap().sync0_cycle_ns(),
            sync0.then_some(1_000_000),
            "SYNC0 in mode {assign:#06x}"
        );
        if let Some(first) = first {
            let esc_time = m.cell.esc(0).unwrap().system_time_at(m.now);
            m.now = m.now + std::time::Duration::from_nanos(first - esc_time + 500_000);
            m.cell.poll(m.now);
        }
        let before = read_u16(&m, 0x6040);
        lrw(&mut m, &[0x06, 0x00], 2);
        if sync0 {
            assert_eq!(read_u16(&m, 0x6040), before, "DC: not before SYNC0");
            m.now = m.now + std::time::Duration::from_micros(500);
            m.cell.poll(m.now);
        }
        assert_eq!(read_u16(&m, 0x6040), 0x0006, "taken in mode {assign:#06x}");
    }
}

/// Fuzz finding `ethercat_chain` crash-2ad63ffb: a master that sets a SYNC0 cycle of a few
/// nanoseconds (in Pre-Op, where nothing checks it against 60C2h) made the chain due every few
/// nanoseconds: 100 000 polls did not get the clock 0.5 ms further, and the runtime spun. Such
/// a grid is served at most every `SYNC0_SERVICE_FLOOR`, its events counted in batches.
#[test]
fn sync0_cycle_of_nanoseconds_does_not_spin_the_loop_fuzz_ecat_2ad63ffb() {
    let mut m = Master::new(cell());
    to_preop(&mut m);
    let first = dc_sync0(&mut m, 3);
    let esc_time = m.cell.esc(0).unwrap().system_time_at(m.now);
    m.now = m.now + std::time::Duration::from_nanos(first - esc_time);
    let end = m.now + std::time::Duration::from_millis(5);
    let mut polls = 0u32;
    while let Some(t) = m.cell.deadline().filter(|t| *t <= end) {
        polls += 1;
        assert!(polls <= 1_000, "{polls} polls, the deadline at {t:?}");
        m.now = t.max(m.now);
        m.poll();
    }
    assert!(polls >= 5, "the events are still served: {polls} polls");
    // The slave goes on answering and the drive stays where a SYNC0 grid in Pre-Op leaves it.
    assert_eq!(m.al(), (0x0002, 0));
    let drive = m.cell.model(0).unwrap().drive().unwrap();
    assert!(drive.errors().is_empty(), "{:?}", drive.errors());
}

#[test]
fn interpolated_position_runs_on_the_frame_cycle_in_free_run() {
    // The ESI of the CMMP-AS's CiA 402 EtherCAT interface is "…CIA402_IP7": IP mode with the
    // frame as the SYNC (free run, CMMP-AS §2.11). Outputs: controlword + 60C1h:01, inputs:
    // statusword + position actual value.
    let mut m = Master::new(cell());
    {
        let model = m.cell.model_mut(0).unwrap();
        for (i, s, v, n) in [
            (0x1600u16, 0u8, 0u32, 1usize),
            (0x1600, 2, 0x60C1_0120, 4),
            (0x1600, 0, 2, 1),
            (0x1A00, 0, 0, 1),
            (0x1A00, 2, 0x6064_0020, 4),
            (0x1A00, 0, 2, 1),
            (0x60C4, 6, 1, 1),
            (0x6060, 0, 7, 1),
        ] {
            model
                .write(i, s, &v.to_le_bytes()[..n])
                .unwrap_or_else(|e| panic!("{i:04X}h:{s:02X}h: {e:?}"));
        }
    }
    to_preop(&mut m);
    map(&mut m, 6, 6);
    m.fpwr(0x0120, &[0x04, 0x00]);
    m.fpwr(0x0120, &[0x08, 0x00]);
    assert_eq!(m.al(), (0x0008, 0));
    let out = |cw: u16, target: i32| {
        let mut o = cw.to_le_bytes().to_vec();
        o.extend_from_slice(&target.to_le_bytes());
        o
    };
    let mut pos = 0;
    let mut inputs = enable(&mut m, 20, |m, cw| {
        m.tick();
        let inputs = lrw(m, &out(cw, pos), 6);
        pos = i32::from_le_bytes(inputs[2..6].try_into().unwrap());
        inputs
    });
    let mut b = [0u8; 1];
    m.cell.model(0).unwrap().read(0x6061, 0, &mut b).unwrap();
    assert_eq!(b[0] as i8, 7, "synchronised to the 1 ms frame cycle");
    // enable_ip_mode, then 200 set-points 100 units apart, one per frame.
    let mut target = pos;
    for _ in 0..5 {
        m.tick();
        inputs = lrw(&mut m, &out(0x001F, target), 6);
    }
    let sw = u16::from_le_bytes([inputs[0], inputs[1]]);
    assert_eq!(sw & 0x1000, 0x1000, "ip_mode_active: {sw:#06x}");
    for _ in 0..200 {
        target += 100;
        m.tick();
        inputs = lrw(&mut m, &out(0x001F, target), 6);
    }
    // The position loop settles on the last set-point within 0.2 s.
    for _ in 0..200 {
        m.tick();
        inputs = lrw(&mut m, &out(0x001F, target), 6);
    }
    let sw = u16::from_le_bytes([inputs[0], inputs[1]]);
    let pos = i32::from_le_bytes(inputs[2..6].try_into().unwrap());
    assert_eq!(sw & 0x3000, 0x1000, "active, no following error: {sw:#06x}");
    let mut d = [0u8; 4];
    m.cell.model(0).unwrap().read(0x6062, 0, &mut d).unwrap();
    let demand = i32::from_le_bytes(d);
    assert!(
        (pos - target).abs() < 50,
        "followed the set-points: {pos} vs {target}, demand {demand}"
    );
}

/// One CoE SDO request (the 8 SDO bytes after the CoE header, `sdo` padded with zeros)
/// through the mailbox, counter `counter`; the SDO bytes of the answer.
fn coe_request(m: &mut Master, counter: u8, sdo: &[u8]) -> [u8; 8] {
    let mut req = vec![0u8; 0x80];
    // Mailbox header: length 10, address 0, channel/priority 0, type CoE (3) and counter;
    // CoE header: SDO request (2 << 12).
    req[..8].copy_from_slice(&[10, 0, 0, 0, 0, 0x03 | counter << 4, 0x00, 0x20]);
    req[8..8 + sdo.len()].copy_from_slice(sdo);
    m.fpwr(0x1000, &req);
    wait_for_reply(m);
    let r = m.fprd(0x1080, 0x80);
    assert_eq!(r.data[5] & 0x0F, 0x03, "CoE");
    r.data[8..16].try_into().unwrap()
}

/// Polls SM1's status until the reply is posted, as SOEM's ecx_mbxreceive does: a reply that
/// waits for the device (a 1010h "save" writing its file on a thread of its own) comes a few
/// ticks later; every poll meanwhile is answered with its working counter.
fn wait_for_reply(m: &mut Master) {
    for _ in 0..5_000 {
        let r = m.fprd(0x080D, 1);
        assert_eq!(r.wkc, 1, "SM1 status read while the device works");
        if r.data[0] & 0x08 != 0 {
            return;
        }
        m.tick();
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    panic!("no reply posted");
}

/// One expedited CoE SDO download (`data` of 1, 2 or 4 bytes); the answer's SDO bytes
/// (command, index, sub-index, data/abort code).
fn coe_download(m: &mut Master, counter: u8, index: u16, sub: u8, data: &[u8]) -> [u8; 8] {
    let cmd = 0x23 | ((4 - data.len() as u8) << 2);
    let [i0, i1] = index.to_le_bytes();
    let mut sdo = vec![cmd, i0, i1, sub];
    sdo.extend_from_slice(data);
    coe_request(m, counter, &sdo)
}

/// One expedited CoE SDO upload; the answer's SDO bytes.
fn coe_upload(m: &mut Master, counter: u8, index: u16, sub: u8) -> [u8; 8] {
    let [i0, i1] = index.to_le_bytes();
    coe_request(m, counter, &[0x40, i0, i1, sub])
}

/// CMMP-ECAT-01: the manual's (corrected) ESI start-up command — `<Transition>PS</Transition>`,
/// `<Index>#x6060</Index>`, `<SubIndex>0</SubIndex>`, `<Data>03</Data>` — as a master carries
/// it out: a CoE download of 6060h:00 := 3 on the way from Pre-Op to Safe-Op. The drive
/// takes it and runs in profile velocity (6061h = 3).
#[test]
fn esi_init_command_sets_velocity_mode_on_pre_op_to_safe_op() {
    let esi = r#"<Mailbox><CoE><InitCmd><Transition>PS</Transition><Index>#x6060</Index>
        <SubIndex>0</SubIndex><Data>03</Data><Comment>velocity mode</Comment></InitCmd>
        </CoE></Mailbox>"#;
    let doc = roxmltree::Document::parse(esi).unwrap();
    let cmd = doc
        .descendants()
        .find(|n| n.has_tag_name("InitCmd"))
        .unwrap();
    let field = |t: &str| {
        cmd.children()
            .find(|c| c.has_tag_name(t))
            .and_then(|c| c.text())
            .unwrap()
    };
    assert_eq!(field("Transition"), "PS");
    let index = u16::from_str_radix(field("Index").trim_start_matches("#x"), 16).unwrap();
    let sub: u8 = field("SubIndex").parse().unwrap();
    let data: Vec<u8> = (0..field("Data").len() / 2)
        .map(|i| u8::from_str_radix(&field("Data")[2 * i..2 * i + 2], 16).unwrap())
        .collect();
    assert_eq!((index, sub, data.as_slice()), (0x6060, 0, &[3u8][..]));

    let mut m = Master::new(cell());
    to_preop(&mut m);
    assert_eq!(
        coe_download(&mut m, 1, index, sub, &data),
        [0x60, 0x60, 0x60, 0x00, 0, 0, 0, 0],
        "SDO download response"
    );
    map(&mut m, 2, 2);
    m.fpwr(0x0120, &[0x04, 0x00]);
    assert_eq!(m.al(), (0x0004, 0));
    m.idle(50);
    let model = m.cell.model(0).unwrap();
    let mut b = [0u8; 1];
    model.read(0x6061, 0, &mut b).unwrap();
    assert_eq!(b[0], 3, "modes_of_operation_display: profile velocity");
}

/// CMMP-ECAT-03: RxPDO 1600h = 6040h:0 (16 bit), 6060h:0 (8 bit) on SM2: the output image
/// `0F 00 03` is controlword 000Fh and mode 3, packed in order, little-endian.
#[test]
fn rxpdo_controlword_and_mode_packed_in_order() {
    let mut m = Master::new(cell());
    {
        let model = m.cell.model_mut(0).unwrap();
        for (i, s, v) in [
            (0x1600u16, 0u8, 0u32),
            (0x1600, 1, 0x6040_0010),
            (0x1600, 2, 0x6060_0008),
            (0x1600, 0, 2),
        ] {
            let bytes = v.to_le_bytes();
            let n = if s == 0 { 1 } else { 4 };
            model.write(i, s, &bytes[..n]).unwrap();
        }
    }
    to_preop(&mut m);
    map(&mut m, 3, 2);
    m.fpwr(0x0120, &[0x04, 0x00]);
    assert_eq!(m.al(), (0x0004, 0), "3 output bytes accepted");
    m.fpwr(0x0120, &[0x08, 0x00]);
    assert_eq!(m.al(), (0x0008, 0));
    for _ in 0..20 {
        m.tick();
        lrw(&mut m, &[0x0F, 0x00, 0x03], 2);
    }
    assert_eq!(read_u16(&m, 0x6040), 0x000F);
    let mut b = [0u8; 1];
    let model = m.cell.model(0).unwrap();
    model.read(0x6060, 0, &mut b).unwrap();
    assert_eq!(b[0], 3, "modes_of_operation from the third byte");
}

/// 1010h:01 "save" over CoE with a state directory writes the drive's file before the answer;
/// the next start (a new chain on the same directory) powers on with the saved value, and a
/// chain without a state directory with the default.
#[test]
fn save_over_coe_survives_a_restart_with_a_state_dir() {
    let dir = std::env::temp_dir().join(format!("drivetwin-ecat-save-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let file = CellFile::single("cmmp-as", 1);
    let start = |state: Option<&std::path::Path>| {
        let mut m = Master::new(
            SlaveChain::with_state_dir(&file, drivetwin::vendors::VENDORS.runtime, state)
                .expect("cell"),
        );
        to_preop(&mut m);
        m
    };
    let mut m = start(Some(&dir));
    let velocity = 12_345u32.to_le_bytes();
    assert_eq!(coe_download(&mut m, 1, 0x6081, 0, &velocity)[0], 0x60);
    assert!(
        !dir.join("cmmp-as-node1.params").exists(),
        "a write alone is volatile"
    );
    assert_eq!(coe_download(&mut m, 2, 0x1010, 1, b"save")[0], 0x60);
    assert!(
        dir.join("cmmp-as-node1.params").exists(),
        "saved before the answer"
    );

    let mut m = start(Some(&dir));
    assert_eq!(
        coe_upload(&mut m, 1, 0x6081, 0)[4..8],
        velocity,
        "the saved value"
    );
    let mut m = start(None);
    assert_eq!(
        coe_upload(&mut m, 1, 0x6081, 0)[4..8],
        1000u32.to_le_bytes(),
        "the default without a state directory"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// One CMMP-AS on a chain whose parameters are saved in `dir`, in Pre-Op.
fn cmmp_as_saving_to(dir: &std::path::Path) -> Master {
    let file = CellFile::single("cmmp-as", 1);
    let mut m = Master::new(
        SlaveChain::with_state_dir(&file, drivetwin::vendors::VENDORS.runtime, Some(dir))
            .expect("cell"),
    );
    to_preop(&mut m);
    m
}

/// A CoE download of "save" to 1010h:01 (mailbox counter 1) written into the receive mailbox,
/// its reply not read.
fn ask_for_a_save(m: &mut Master) {
    let mut req = vec![0u8; 0x80];
    req[..16].copy_from_slice(&[
        10, 0, 0, 0, 0, 0x13, 0x00, 0x20, 0x23, 0x10, 0x10, 0x01, b's', b'a', b'v', b'e',
    ]);
    m.fpwr(0x1000, &req);
}

/// tests/interop/test_kill9.py saw pysoem's 1010h:01 "save" over CoE fail with a wrong working
/// counter ~18 ms after the request under full CPU load, the file written all the same: the
/// twin wrote and fsynced the file inside the frame, on the loop thread, so the frame and the
/// master's next frames came back late. The save now runs beside the loop: the frame that
/// brings the request returns at once with the reply held, the master's polls meanwhile are
/// answered with their working counter, and the reply comes once the file is written.
#[test]
fn coe_save_holds_its_reply_not_the_loop_kill9_wrong_wkc() {
    let dir = std::env::temp_dir().join(format!("drivetwin-ecat-held-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut m = cmmp_as_saving_to(&dir);
    ask_for_a_save(&mut m);
    assert!(
        m.cell.device(0).unwrap().saving(),
        "the frame returned with the save under way, its reply held"
    );
    wait_for_reply(&mut m);
    assert!(!m.cell.device(0).unwrap().saving());
    assert!(
        dir.join("cmmp-as-node1.params").exists(),
        "the reply comes once the file is written"
    );
    let r = m.fprd(0x1080, 0x80);
    assert_eq!(
        &r.data[8..12],
        &[0x60, 0x10, 0x10, 0x01],
        "download response"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The chain writes no file itself: a 1010h:01 "save" over CoE holds its reply until the
/// runtime has taken the save (`take_save`, once), written it, and handed the result back
/// (`saved`); only then is the file there and the download response posted.
#[test]
fn the_chain_asks_the_runtime_for_the_save_and_writes_no_file() {
    let dir = std::env::temp_dir().join(format!("drivetwin-ecat-asks-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut m = cmmp_as_saving_to(&dir);
    m.runtime_saves = false;
    ask_for_a_save(&mut m);
    for _ in 0..20 {
        m.tick();
        assert_eq!(
            m.fprd(0x080D, 1).data[0] & 0x08,
            0,
            "no reply before the save"
        );
    }
    let params = dir.join("cmmp-as-node1.params");
    assert!(!params.exists(), "the chain wrote no file");
    assert!(m.cell.device(0).unwrap().saving());
    let save = m.cell.take_save().expect("the save asked for");
    assert_eq!(save.slave, 0);
    assert!(m.cell.take_save().is_none(), "asked once");
    let result = save.job.run();
    assert!(params.exists(), "the runtime wrote it");
    m.cell.saved(0, result, &mut NoBuses);
    assert!(!m.cell.device(0).unwrap().saving());
    assert_ne!(m.fprd(0x080D, 1).data[0] & 0x08, 0, "the reply posted");
    let r = m.fprd(0x1080, 0x80);
    assert_eq!(
        &r.data[8..12],
        &[0x60, 0x10, 0x10, 0x01],
        "download response"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A save whose file cannot be written (a directory stands where its temporary file goes) is
/// refused over CoE with 0800 0020h, the abort CiA 301 and the CMMP-AS manual give for a
/// faulty store access, once the write has failed.
#[test]
fn coe_save_that_cannot_write_is_aborted_0800_0020() {
    let dir = std::env::temp_dir().join(format!("drivetwin-ecat-nowrite-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("cmmp-as-node1.params.tmp")).unwrap();
    let mut m = cmmp_as_saving_to(&dir);
    let answer = coe_download(&mut m, 1, 0x1010, 1, b"save");
    assert_eq!(
        answer,
        [0x80, 0x10, 0x10, 0x01, 0x20, 0x00, 0x00, 0x08],
        "abort 0800 0020h"
    );
    // The mailbox goes on.
    assert_eq!(coe_upload(&mut m, 2, 0x1018, 1)[0], 0x43);
    let _ = std::fs::remove_dir_all(&dir);
}

/// One CMMP-AS that is CANopen node 1 and an EtherCAT slave at once (for testing only: the
/// real one runs one fieldbus at a time, CMMP-AS §2.3), as `examples/mixed.toml` shows it.
const ON_BOTH_FIELDBUSES: &str = r#"
[[drive]]
device = "cmmp-as"
node = 1
interfaces = ["canopen", "ethercat"]
allow_unreal_interfaces = true
ethercat = "ecat0"
"#;

/// The drive of [`ON_BOTH_FIELDBUSES`] built as `drivetwin run` builds it: a station of the
/// cell's CAN bus, served over CoE as well, that the chain's one slave names; its parameters
/// saved in `dir`. The bus booted, the chain in Pre-Op.
fn cmmp_as_on_both_saving_to(dir: &std::path::Path) -> Master {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("cell.toml");
    std::fs::write(&path, ON_BOTH_FIELDBUSES).unwrap();
    let file = CellFile::load(&path).unwrap();
    let spec = file
        .drives(drivetwin::vendors::VENDORS.runtime)
        .unwrap()
        .remove(0);
    assert!(
        spec.canopen && spec.ethercat.is_some(),
        "on both fieldbuses"
    );
    let store = ParamStore::new(dir, spec.desc.name, spec.node);
    let settings = spec.settings.map(|mut s| {
        s.ethercat = true;
        s
    });
    let mut station = Station::with_settings(
        spec.desc,
        spec.node,
        Some(store),
        spec.commissioning,
        settings,
    )
    .unwrap();
    station.serve_coe();
    let can = CanCell::one_bus(vec![station]);
    let id = can.buses[0].members()[0];
    let mut chain = SlaveChain::empty();
    chain
        .push(spec.desc, SlaveDrive::Station { id, bus: Some(0) })
        .unwrap();
    let mut m = Master::start(chain, Some(can));
    m.idle(10);
    to_preop(&mut m);
    m
}

/// One CAN frame to the joined cell's first bus now; the frames it sent in answer.
fn can_frame(m: &mut Master, id: u16, data: &[u8]) -> Vec<CanFrame> {
    let can = m.joined.as_mut().expect("a cell with a CAN bus");
    let mut out = Vec::new();
    can.on_frame(0, m.now, &CanFrame::new(id, data).unwrap(), &mut out);
    out
}

/// An expedited SDO request to CANopen node 1 (padded to 8 bytes); the answer.
fn can_sdo(m: &mut Master, request: &[u8]) -> [u8; 8] {
    let mut data = [0u8; 8];
    data[..request.len()].copy_from_slice(request);
    can_frame(m, 0x601, &data)
        .iter()
        .find(|f| f.id == 0x581)
        .map(|f| f.data)
        .expect("SDO answer")
}

/// 6081h "profile velocity" read over CANopen and over CoE (`counter`): the two values.
fn profile_velocity_on_both(m: &mut Master, counter: u8) -> (u32, u32) {
    let can = can_sdo(m, &[0x40, 0x81, 0x60, 0x00]);
    assert_eq!(can[0], 0x43, "SDO upload of 4 bytes: {can:02X?}");
    let coe = coe_upload(m, counter, 0x6081, 0);
    assert_eq!(coe[0], 0x43, "CoE upload of 4 bytes: {coe:02X?}");
    (
        u32::from_le_bytes(can[4..8].try_into().unwrap()),
        u32::from_le_bytes(coe[4..8].try_into().unwrap()),
    )
}

/// 6081h as the drive's parameter file holds it (none: not stored).
fn stored_profile_velocity(dir: &std::path::Path) -> Option<u32> {
    let stored = ParamStore::new(dir, "cmmp-as", 1).load().unwrap();
    let v = stored.iter().find(|v| (v.index, v.sub) == (0x6081, 0))?;
    Some(u32::from_le_bytes(v.bytes.as_slice().try_into().unwrap()))
}

/// NMT "reset node" to node 1 over CAN (CiA 301 §7.2.8.3.1.1): the node boots again (its
/// boot-up message) with what was last stored.
fn reset_node_over_can(m: &mut Master) {
    m.can_sent.clear();
    let mut sent = can_frame(m, 0x000, &[0x81, 0x01]);
    m.idle(10);
    sent.append(&mut m.can_sent);
    assert!(
        sent.iter().any(|f| f.id == 0x701 && f.data[0] == 0x00),
        "boot-up after the reset: {sent:?}"
    );
}

/// The drive of [`ON_BOTH_FIELDBUSES`] saving to a fresh state directory
/// (`drivetwin-ecat-{name}-<pid>`, returned), its saves written by the runtime where
/// `runtime_saves`: 6081h "profile velocity" at its default on both fieldbuses, then `value`
/// written to it over CoE (mailbox counters 1 and 2; [`ask_for_a_save`] takes 1 next).
fn on_both_with_profile_velocity(
    name: &str,
    value: u32,
    runtime_saves: bool,
) -> (Master, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("drivetwin-ecat-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut m = cmmp_as_on_both_saving_to(&dir);
    m.runtime_saves = runtime_saves;
    assert_eq!(profile_velocity_on_both(&mut m, 1), (1000, 1000), "default");
    assert_eq!(
        coe_download(&mut m, 2, 0x6081, 0, &value.to_le_bytes())[0],
        0x60
    );
    (m, dir)
}

/// A drive that is a CANopen node and an EtherCAT slave at once saves over CoE as one on
/// EtherCAT alone: the reply waits until the runtime has written the file; the file holds the
/// value written over CoE; the CANopen side, which shares the dictionary and the stored set,
/// starts from it after an NMT reset, and so does the drive after a restart on the same state
/// directory.
#[test]
fn a_drive_on_canopen_and_ethercat_saves_over_coe_for_both() {
    let saved = 12_345u32;
    let (mut m, dir) = on_both_with_profile_velocity("both", saved, false);
    assert_eq!(profile_velocity_on_both(&mut m, 3), (saved, saved));

    ask_for_a_save(&mut m);
    for _ in 0..20 {
        m.tick();
        assert_eq!(
            m.fprd(0x080D, 1).data[0] & 0x08,
            0,
            "no reply before the save"
        );
    }
    assert_eq!(stored_profile_velocity(&dir), None, "no file yet");
    let save = m.cell.take_save().expect("the save asked for");
    assert_eq!(save.slave, 0);
    let result = save.job.run();
    assert_eq!(
        stored_profile_velocity(&dir),
        Some(saved),
        "the file written"
    );
    assert_eq!(m.fprd(0x080D, 1).data[0] & 0x08, 0, "no reply yet");
    let can = m.joined.as_mut().unwrap();
    m.cell.saved(0, result, can);
    assert_ne!(m.fprd(0x080D, 1).data[0] & 0x08, 0, "the reply posted");
    let r = m.fprd(0x1080, 0x80);
    assert_eq!(
        &r.data[8..12],
        &[0x60, 0x10, 0x10, 0x01],
        "download response"
    );

    // A value written over CANopen and not saved is gone after the reset.
    let r = can_sdo(&mut m, &[0x23, 0x81, 0x60, 0x00, 0x09, 0x03, 0x00, 0x00]);
    assert_eq!(r[0], 0x60, "SDO download: {r:02X?}");
    assert_eq!(profile_velocity_on_both(&mut m, 4), (777, 777));
    reset_node_over_can(&mut m);
    assert_eq!(
        profile_velocity_on_both(&mut m, 5),
        (saved, saved),
        "the saved value after NMT reset node"
    );

    let mut m = cmmp_as_on_both_saving_to(&dir);
    assert_eq!(
        profile_velocity_on_both(&mut m, 1),
        (saved, saved),
        "the saved value after a restart"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// 1011h:01 "load" over CANopen on a drive that is an EtherCAT slave as well: the defaults
/// are the current set at once, over CoE too; the stored set stays until the next save
/// (CMMP-AS §5.1), so the next NMT reset starts from it again. The save over CoE before it
/// is written on the runtime's loop (the file has a writer there, the CANopen node): the
/// frame that brings it returns with its reply posted.
#[test]
fn a_restore_over_canopen_is_seen_over_coe() {
    let saved = 23_456u32;
    let (mut m, dir) = on_both_with_profile_velocity("restore", saved, true);
    ask_for_a_save(&mut m);
    assert!(!m.cell.device(0).unwrap().saving(), "written on the loop");
    assert_ne!(m.fprd(0x080D, 1).data[0] & 0x08, 0, "the reply posted");
    assert_eq!(m.fprd(0x1080, 0x80).data[8], 0x60, "download response");
    assert_eq!(stored_profile_velocity(&dir), Some(saved));

    let r = can_sdo(&mut m, &[0x23, 0x11, 0x10, 0x01, b'l', b'o', b'a', b'd']);
    assert_eq!(r[0], 0x60, "\"load\" over CANopen: {r:02X?}");
    assert_eq!(
        profile_velocity_on_both(&mut m, 3),
        (1000, 1000),
        "the default, over CoE too"
    );
    assert_eq!(
        stored_profile_velocity(&dir),
        Some(saved),
        "the stored set stays"
    );
    reset_node_over_can(&mut m);
    assert_eq!(
        profile_velocity_on_both(&mut m, 4),
        (saved, saved),
        "the stored set after NMT reset node"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A cell file's EDS drive on a chain is a slave with that description, its SII built.
#[test]
fn a_chain_of_eds_drives() {
    let dir = std::env::temp_dir().join(format!("drivetwin-eds-ecat-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cell = dir.join("cell.toml");
    let eds = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/interop/data/eds/epos4_like.eds");
    let drive = |n| {
        format!(
            "[[drive]]\neds = \"{}\"\nnode = {n}\ninterfaces = [\"ethercat\"]\n",
            eds.display()
        )
    };
    std::fs::write(&cell, format!("{}{}", drive(1), drive(2))).unwrap();
    let file = drivetwin::cell::config::CellFile::load(&cell).unwrap();
    let chain = SlaveChain::from_cell_file(&file, drivetwin::cell::Vendors::NONE).unwrap();
    assert_eq!(chain.len(), 2);
    let desc = chain.device(1).unwrap().description();
    assert!(desc.object(0x1C12).is_some());
    assert_eq!(desc.vendor_id, 0xFB);
    assert!(
        chain.model(1).unwrap().drive().is_some(),
        "a CiA 402 drive behind it"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// One drive of `epos4_like.eds` alone on a chain (60C2h as the file gives it: 1 ms).
fn eds_chain(dir: &std::path::Path) -> SlaveChain {
    std::fs::create_dir_all(dir).unwrap();
    let cell = dir.join("cell.toml");
    let eds = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/interop/data/eds/epos4_like.eds");
    std::fs::write(
        &cell,
        format!(
            "[[drive]]\neds = \"{}\"\nnode = 1\ninterfaces = [\"ethercat\"]\n",
            eds.display()
        ),
    )
    .unwrap();
    let file = CellFile::load(&cell).unwrap();
    SlaveChain::from_cell_file(&file, drivetwin::cell::Vendors::NONE).unwrap()
}

/// ecx_config_init up to Pre-Op with the mailbox the SII names (words 18h / 1Ah).
fn to_preop_from_sii(m: &mut Master) {
    m.one(Command::Bwr, phys(0, 0x0120), &[0x11, 0x00]);
    let r = m.one(Command::Apwr, phys(0, 0x0010), &STATION.to_le_bytes());
    assert_eq!(r.wkc, 1);
    let (rx, tx) = (m.sii(0x18), m.sii(0x1A));
    let half = |w: u32, shift: u32| u16::try_from((w >> shift) & 0xFFFF).unwrap();
    let mut mbx = sm(half(rx, 0), half(rx, 16), 0x26);
    mbx.extend_from_slice(&sm(half(tx, 0), half(tx, 16), 0x22));
    m.fpwr(0x0800, &mbx);
    m.fpwr(0x0120, &[0x02, 0x00]);
    assert_eq!(m.al(), (0x0002, 0));
}

/// The generic CiA 402 drive from an EDS on SYNC0, as the CMMP-AS above: the set-points of
/// a frame are taken at the next SYNC0 event; when the master's cycles stop, the slave falls
/// back to Safe-Op with 0x001A, takes no more set-points, and the drive says so with CiA
/// 402's 8700h "sync controller" and Fault, rather than stand in Operation enabled on the
/// last set-point while the master goes on sending new ones.
#[test]
fn an_eds_drive_on_sync0_reports_a_lost_synchronisation() {
    let dir = std::env::temp_dir().join(format!("drivetwin-eds-sync0-{}", std::process::id()));
    let mut m = Master::new(eds_chain(&dir));
    to_preop_from_sii(&mut m);
    enabled_on_sync0(&mut m);
    assert_eq!(m.cell.device(0).unwrap().sync_errors, 0);

    // The outputs of the last frame are taken at the next event; three events after it
    // without outputs are the error.
    m.idle(5);
    assert_eq!(
        m.al(),
        (0x0014, 0x001A),
        "Safe-Op + error, synchronisation error"
    );
    let drive = m.cell.model(0).unwrap().drive().unwrap();
    assert_eq!(drive.errors(), &[0x8700], "CiA 402 8700h sync controller");
    m.idle(50);
    let sw = read_u16(&m, 0x6041);
    assert_eq!(sw & 0x4F, 0x08, "fault: {sw:#06x}");
    assert_error_kept(&m, 0x11, 0x8700);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The same drive in free run: when the master's frames stop for longer than the process-data
/// watchdog (100 ms at the ESC's reset values), the slave falls back to Safe-Op with 0x001B
/// and the drive, whose EDS names no message for it, reports CiA 301's 8250h "RPDO timeout"
/// and goes to Fault.
#[test]
fn an_eds_drive_whose_process_data_stop_reports_it() {
    let dir = std::env::temp_dir().join(format!("drivetwin-eds-wd-{}", std::process::id()));
    let mut m = Master::new(eds_chain(&dir));
    to_preop_from_sii(&mut m);
    map(&mut m, 2, 2);
    m.fpwr(0x0120, &[0x04, 0x00]);
    m.fpwr(0x0120, &[0x08, 0x00]);
    assert_eq!(m.al(), (0x0008, 0));
    let sw = enable(&mut m, 30, |m, cw| {
        lrw(m, &cw.to_le_bytes(), 2);
        m.tick();
        u16::from_le_bytes(lrw(m, &cw.to_le_bytes(), 2).try_into().unwrap())
    });
    assert_eq!(sw & 0x6F, 0x27, "operation enabled: {sw:#06x}");
    m.idle(150);
    assert_eq!(m.al(), (0x0014, 0x001B), "Safe-Op + error, SM watchdog");
    assert_eq!(m.cell.device(0).unwrap().watchdog_expiries, 1);
    let drive = m.cell.model(0).unwrap().drive().unwrap();
    assert_eq!(drive.errors(), &[0x8250], "CiA 301 8250h RPDO timeout");
    m.idle(50);
    let sw = read_u16(&m, 0x6041);
    assert_eq!(sw & 0x4F, 0x08, "fault: {sw:#06x}");
    assert_error_kept(&m, 0x11, 0x8250);
    let _ = std::fs::remove_dir_all(&dir);
}

/// What a master sends a chain of one CMMP-AS from power-on to Operation enabled: SII reads,
/// mailbox and process-data set-up, a CoE upload, Safe-Op, Op, then LRW cycles, each with
/// an APRD of the AL status, and a last CoE upload; every frame as it came back.
fn start_up_frames(mut m: Master) -> Vec<Vec<u8>> {
    m.returned = Some(Vec::new());
    to_preop(&mut m);
    assert_eq!(coe_upload(&mut m, 1, 0x1018, 1)[4], 0x1D, "vendor Festo");
    map(&mut m, 2, 2);
    m.fpwr(0x0120, &[0x04, 0x00]);
    m.fpwr(0x0120, &[0x08, 0x00]);
    assert_eq!(m.al(), (0x0008, 0));
    let sw = enable(&mut m, 20, |m, cw| {
        m.tick();
        let sw = u16::from_le_bytes(lrw(m, &cw.to_le_bytes(), 2).try_into().unwrap());
        let al = m.one(Command::Aprd, phys(0, 0x0130), &[0, 0]);
        assert_eq!((al.wkc, al.u16()), (1, 0x0008), "Op");
        sw
    });
    assert_eq!(sw & 0x6F, 0x27, "operation enabled: {sw:#06x}");
    assert_eq!(
        coe_upload(&mut m, 2, 0x6041, 0)[0],
        0x4B,
        "statusword over CoE"
    );
    m.returned.take().unwrap()
}

/// The cell loop joins a chain to the cell's list of stations (`SlaveChain::join`), its
/// slaves then naming their drives by id (`SlaveDrive::Station`): the master cannot tell.
/// Each frame of the same sequence comes back byte for byte as from the chain that owns its
/// drive.
#[test]
fn a_chain_joined_to_the_cells_stations_answers_as_one_that_owns_its_drives() {
    let own = start_up_frames(Master::new(cell()));
    let joined = start_up_frames(Master::joined(cell()));
    assert!(own.len() > 60, "{} frames", own.len());
    assert_eq!(own.len(), joined.len(), "as many frames");
    for (k, (a, b)) in own.iter().zip(&joined).enumerate() {
        assert_eq!(a, b, "frame {k}");
    }
}

/// A CMMP-AS in Op in free run whose master stops sending: the ESC's process-data watchdog
/// (0x0420 × (0x0400 + 2) × 40 ns, spec/ethercat-esc.md §7.6), here 0x0420 = 300 at the
/// reset divider (100 µs ticks) = 30 ms, counts from the last complete SM2 write. Up to 30 ms
/// of silence the slave stays in Op (never stricter than the ESC); past it, it falls back to
/// Safe-Op with 0x001B and the drive raises App. B.3 62-5 "EtherCAT: faulty cyclic data
/// transfer" (cmmp-as-3: "safety shutdown because cyclic data failed"): a message without a
/// CiA code, so EMCY 1000h generic error (docs/decisions.md), and the drive in Fault.
#[test]
fn cmmp_as_whose_process_data_stop_falls_after_the_watchdog_time() {
    let mut m = Master::new(cell());
    to_preop(&mut m);
    map(&mut m, 2, 2);
    m.fpwr(0x0420, &300u16.to_le_bytes());
    m.fpwr(0x0120, &[0x04, 0x00]);
    m.fpwr(0x0120, &[0x08, 0x00]);
    assert_eq!(m.al(), (0x0008, 0));
    let sw = enable(&mut m, 30, |m, cw| {
        m.tick();
        u16::from_le_bytes(lrw(m, &cw.to_le_bytes(), 2).try_into().unwrap())
    });
    assert_eq!(sw & 0x6F, 0x27, "operation enabled: {sw:#06x}");
    assert_eq!(m.fprd(0x0440, 2).u16() & 1, 1, "0x0440: the watchdog runs");
    // 30 ms after the last SM2 write: still Op, the drive still enabled.
    m.idle(30);
    assert_eq!(m.al(), (0x0008, 0), "Op up to the watchdog time");
    assert_eq!(m.cell.device(0).unwrap().watchdog_expiries, 0);
    assert_eq!(read_u16(&m, 0x6041) & 0x6F, 0x27, "still operation enabled");
    // 1 ms past it: Safe-Op + error indication, 0x001B; 0x0440 bit 0 shows it expired and
    // the counter 0x0442 counts it.
    m.idle(1);
    assert_eq!(m.al(), (0x0014, 0x001B), "Safe-Op + error, SM watchdog");
    assert_eq!(m.cell.device(0).unwrap().watchdog_expiries, 1);
    assert_eq!(m.fprd(0x0440, 2).u16() & 1, 0, "0x0440: expired");
    assert_eq!(m.fprd(0x0442, 1).data, [1], "0x0442: one expiry");
    let drive = m.cell.model(0).unwrap().drive().unwrap();
    assert_eq!(
        drive.errors(),
        &[0x1000],
        "62-5 as EMCY 1000h generic error"
    );
    m.idle(50);
    let sw = read_u16(&m, 0x6041);
    assert_eq!(sw & 0x4F, 0x08, "fault (safety shutdown): {sw:#06x}");
    assert_error_kept(&m, 0x01, 0x1000);
}
