//! EMCY frames and the error history 1003h of the CMMP-AS over CANopen, on the virtual clock:
//! errors the drive raises go out as EMCY through the CiA 301 stack (spec/vectors.md §1.6).

use canopen::CanFrame;
use drive::device_control::State;
use drivetwin::can_drive::CanDrive;
use drivetwin::cell::Cell;
use drivetwin::cell_config::CellFile;
use od::Instant;

struct Bench {
    cell: Cell,
    now: Instant,
    out: Vec<CanFrame>,
}

impl Bench {
    fn new() -> Self {
        let spec = CellFile::single("cmmp-as", 1).drives().unwrap().remove(0);
        let d = CanDrive::with_settings(
            spec.desc,
            spec.node,
            None,
            spec.commissioning,
            spec.settings,
        )
        .unwrap();
        let mut b = Bench {
            cell: Cell::new(vec![d]),
            now: Instant::ZERO,
            out: Vec::new(),
        };
        b.cell.boot(b.now, &mut b.out);
        b.run_ms(10);
        b
    }

    fn run_ms(&mut self, ms: u64) {
        let until = Instant::from_nanos(self.now.as_nanos() + ms * 1_000_000);
        while let Some(t) = self.cell.deadline() {
            if t > until {
                break;
            }
            self.now = t.max(self.now);
            self.cell.poll(self.now, &mut self.out);
        }
        self.now = until;
        self.cell.poll(self.now, &mut self.out);
    }

    /// The frames sent since the last call.
    fn sent(&mut self) -> Vec<CanFrame> {
        std::mem::take(&mut self.out)
    }

    fn sdo(&mut self, request: &[u8]) -> [u8; 8] {
        let mut data = [0u8; 8];
        data[..request.len()].copy_from_slice(request);
        self.out.clear();
        let f = CanFrame::new(0x601, &data).unwrap();
        self.cell.on_frame(self.now, &f, &mut self.out);
        self.out
            .iter()
            .find(|f| f.id == 0x581)
            .map(|f| f.data)
            .expect("SDO answer")
    }

    fn statusword(&mut self) -> u16 {
        let r = self.sdo(&[0x40, 0x41, 0x60, 0x00]);
        assert_eq!(r[0], 0x4B, "{r:02X?}");
        u16::from_le_bytes([r[4], r[5]])
    }

    fn drive(&mut self) -> &mut drive::drive::Drive<Vec<u8>> {
        self.cell.drives[0]
            .model
            .drive_mut()
            .expect("a CiA 402 drive")
    }

    fn enable(&mut self) {
        for cw in [0x06u8, 0x07, 0x0F] {
            self.sdo(&[0x2B, 0x40, 0x60, 0x00, cw, 0x00]);
            self.run_ms(5);
        }
        assert_eq!(self.statusword() & 0x6F, 0x27);
    }
}

fn emcy(frames: &[CanFrame]) -> Vec<[u8; 8]> {
    frames
        .iter()
        .filter(|f| f.id == 0x081)
        .map(|f| f.data)
        .collect()
}

/// CMMP-EMCY-03: motor over-temperature 03-0 (code 4310h, Tab. 3.9 temperature bit) with a
/// stopping reaction: `081: 10 43 09 00 00 00 00 00`, and the drive goes to FAULT.
#[test]
fn cmmp_emcy_03_motor_over_temperature() {
    let mut b = Bench::new();
    b.enable();
    b.sent();
    b.drive()
        .inject_fault(0x4310, canopen::emcy::register::TEMPERATURE);
    b.run_ms(2);
    assert_eq!(emcy(&b.sent()), vec![[0x10, 0x43, 0x09, 0, 0, 0, 0, 0]]);
    b.run_ms(500);
    // The cell sets 6510h:F0 bit 7 (CiA 402 FAULT value 0008h) for CiA 402 masters.
    assert_eq!(
        b.statusword() & 0x4F,
        0x08,
        "FAULT after the stopping reaction"
    );
    assert_eq!(b.drive().state(), State::Fault);
}

/// CMMP-EMCY-07: `601: 2F 03 10 00 00` clears the history (`581: 60 03 10 00`, then 1003h:00
/// reads 0), and does not acknowledge the error: the drive stays in FAULT and sends no EMCY.
/// The acknowledgement through the state machine then sends `081: 00 …` (CMMP-EMCY-01).
#[test]
fn cmmp_emcy_07_clearing_the_history_does_not_acknowledge() {
    let mut b = Bench::new();
    b.enable();
    b.drive()
        .inject_fault(0x4310, canopen::emcy::register::TEMPERATURE);
    b.run_ms(500);
    assert_eq!(
        b.sdo(&[0x40, 0x03, 0x10, 0x00]),
        [0x4F, 0x03, 0x10, 0x00, 0x01, 0, 0, 0]
    );
    b.sent();
    assert_eq!(
        b.sdo(&[0x2F, 0x03, 0x10, 0x00, 0x00]),
        [0x60, 0x03, 0x10, 0x00, 0, 0, 0, 0]
    );
    assert!(emcy(&b.sent()).is_empty(), "no EMCY for the history write");
    assert_eq!(
        b.sdo(&[0x40, 0x03, 0x10, 0x00]),
        [0x4F, 0x03, 0x10, 0x00, 0x00, 0, 0, 0]
    );
    b.run_ms(10);
    assert!(emcy(&b.sent()).is_empty(), "no EMCY");
    assert_eq!(b.statusword() & 0x4F, 0x08, "still FAULT");
    assert_eq!(b.drive().state(), State::Fault);
    assert_eq!(b.drive().errors(), &[0x4310]);
    // The cause removed and the error acknowledged: the reset EMCY.
    b.drive().clear_fault(0x4310);
    b.sdo(&[0x2B, 0x40, 0x60, 0x00, 0x00, 0x00]);
    b.run_ms(2);
    b.sdo(&[0x2B, 0x40, 0x60, 0x00, 0x80, 0x00]);
    b.run_ms(2);
    let frames = b.sent();
    assert_eq!(b.statusword() & 0x4F, 0x40);
    assert_eq!(emcy(&frames), vec![[0; 8]]);
}

/// CMMP-EMCY-02, CMMP-EMCY-06 from the drive's own I²t monitor: 6510h:38 = 1, the shaft
/// blocked at maximum current; after iit_time_motor (2 s) the I²t reaches 100 % and error 31-0
/// goes out as `081: 12 23 03 00 00 00 00 00` (generic + current); 1003h holds it.
#[test]
fn cmmp_emcy_02_i2t_motor_error_31_0() {
    let mut b = Bench::new();
    b.sdo(&[0x2B, 0x10, 0x65, 0x38, 0x01, 0x00]);
    b.sdo(&[0x2F, 0x60, 0x60, 0x00, 0x03]);
    b.run_ms(10);
    b.enable();
    b.drive().axis_mut().set_blocked(true);
    b.sdo(&[0x23, 0xFF, 0x60, 0x00, 0xE8, 0x03, 0x00, 0x00]); // 60FFh := 1000 min⁻¹
    b.sent();
    b.run_ms(1900);
    assert!(emcy(&b.sent()).is_empty(), "not before 2 s at I_max");
    b.run_ms(200);
    assert_eq!(emcy(&b.sent()), vec![[0x12, 0x23, 0x03, 0, 0, 0, 0, 0]]);
    assert_eq!(
        b.sdo(&[0x40, 0x03, 0x10, 0x00]),
        [0x4F, 0x03, 0x10, 0x00, 0x01, 0, 0, 0]
    );
    assert_eq!(
        b.sdo(&[0x40, 0x03, 0x10, 0x01]),
        [0x43, 0x03, 0x10, 0x01, 0x12, 0x23, 0x00, 0x00]
    );
    b.run_ms(500);
    assert_eq!(b.drive().state(), State::Fault);
}
