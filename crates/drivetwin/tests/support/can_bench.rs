//! A CMMP-AS cell on the virtual clock, driven frame by frame: the rig of the CANopen tests
//! (SDO, SYNC, EMCY, the CI terminal) that run the real cell without a bus.
#![allow(dead_code)] // each test file uses a part of it

use canopen::CanFrame;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::config::CellFile;
use drivetwin::cell::param_store::ParamStore;
use drivetwin::cell::station::Station;
use od::Instant;

/// The default cell's CMMP-AS (node 1, heartbeat and CiA 402 FAULT value commissioned), its
/// parameters kept in `store` if given; not yet booted.
pub fn cmmp_cell(store: Option<ParamStore>) -> CanCell {
    device_cell("cmmp-as", store)
}

/// The default cell of device file `device` (node 1), not yet booted.
pub fn device_cell(device: &str, store: Option<ParamStore>) -> CanCell {
    let spec = CellFile::single(device, 1)
        .drives(drivetwin::vendors::VENDORS.runtime)
        .expect("the default cell")
        .remove(0);
    assert!(spec.settings.is_some(), "{device} is a CiA 402 drive");
    let d = Station::with_settings(
        spec.desc,
        spec.node,
        store,
        spec.commissioning,
        spec.settings,
    )
    .expect("the drive");
    CanCell::one_bus(vec![d])
}

/// The cell booted and run 10 ms, the frames it sends collected.
pub struct CanBench {
    pub cell: CanCell,
    pub now: Instant,
    pub out: Vec<CanFrame>,
}

impl CanBench {
    pub fn new(store: Option<ParamStore>) -> Self {
        Self::device("cmmp-as", store)
    }

    /// [`CanBench::new`] with the drive of device file `device`.
    pub fn device(device: &str, store: Option<ParamStore>) -> Self {
        let mut b = CanBench {
            cell: device_cell(device, store),
            now: Instant::ZERO,
            out: Vec::new(),
        };
        b.cell.boot(0, b.now, &mut b.out);
        b.run_ms(10);
        b
    }

    /// Runs the cell's clock `ms` on, every deadline in turn.
    pub fn run_ms(&mut self, ms: u64) {
        let until = Instant::from_nanos(self.now.as_nanos() + ms * 1_000_000);
        while let Some(t) = self.cell.deadline() {
            if t > until {
                break;
            }
            self.now = t.max(self.now);
            self.cell.poll(0, self.now, &mut self.out);
        }
        self.now = until;
        self.cell.poll(0, self.now, &mut self.out);
    }

    /// The frames sent since the last call.
    pub fn sent(&mut self) -> Vec<CanFrame> {
        std::mem::take(&mut self.out)
    }

    /// One frame to the cell now; what it answers is in `out` (cleared before).
    pub fn frame(&mut self, id: u16, data: &[u8]) {
        self.out.clear();
        let f = CanFrame::new(id, data).expect("a CAN frame");
        self.cell.on_frame(0, self.now, &f, &mut self.out);
    }

    /// An SDO request to node 1 (padded to 8 bytes) and its answer.
    pub fn sdo(&mut self, request: &[u8]) -> [u8; 8] {
        let mut data = [0u8; 8];
        data[..request.len()].copy_from_slice(request);
        self.frame(0x601, &data);
        self.out
            .iter()
            .find(|f| f.id == 0x581)
            .map(|f| f.data)
            .expect("SDO answer")
    }

    /// An expedited upload, sign-extended from its size.
    pub fn read(&mut self, index: u16, sub: u8) -> i64 {
        let [lo, hi] = index.to_le_bytes();
        let r = self.sdo(&[0x40, lo, hi, sub]);
        assert_eq!(r[0] & 0xF0, 0x40, "upload {index:04X}h:{sub}: {r:02X?}");
        match r[0] {
            0x4F => i64::from(r[4] as i8),
            0x4B => i64::from(i16::from_le_bytes([r[4], r[5]])),
            _ => i64::from(i32::from_le_bytes([r[4], r[5], r[6], r[7]])),
        }
    }

    /// An expedited download of 1, 2 or 4 bytes; the answer.
    pub fn write(&mut self, index: u16, sub: u8, value: &[u8]) -> [u8; 8] {
        let [lo, hi] = index.to_le_bytes();
        let cmd = match value.len() {
            1 => 0x2F,
            2 => 0x2B,
            _ => 0x23,
        };
        let mut req = vec![cmd, lo, hi, sub];
        req.extend_from_slice(value);
        self.sdo(&req)
    }

    pub fn statusword(&mut self) -> u16 {
        self.read(0x6041, 0) as u16
    }

    /// Shutdown, switch on, enable operation: OPERATION ENABLED.
    pub fn enable(&mut self) {
        for cw in [0x06u8, 0x07, 0x0F] {
            self.write(0x6040, 0, &[cw, 0]);
            self.run_ms(5);
        }
        assert_eq!(self.statusword() & 0x6F, 0x27, "operation enabled");
    }

    pub fn sync(&mut self) {
        self.frame(0x080, &[]);
    }

    /// `n` SYNCs every `period_ms`, running the clock between them; `each` before each SYNC.
    pub fn syncs(&mut self, n: usize, period_ms: u64, mut each: impl FnMut(&mut CanBench, usize)) {
        for k in 0..n {
            each(self, k);
            self.sync();
            self.run_ms(period_ms);
        }
    }

    pub fn drive(&mut self) -> &mut drive::vendors::AnyDrive<Vec<u8>> {
        self.cell.stations[0]
            .model
            .drive_mut()
            .expect("a CiA 402 drive")
    }
}
