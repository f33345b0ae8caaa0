//! The Kinco FD3 of `drivetwin run --device kinco-fd3 --node 1` as a cell on the virtual
//! clock, frame by frame: a bus master's set-up (no DIN owns the controlword or the mode),
//! the enable of Tab. 6-5 (06h → 0Fh), mode 3 at 300 rpm read back in DEC, the absolute move
//! of §8.15 (KINCO-CW-01), and the following-error EMCY 8611h (KINCO-DIAG-03).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use canopen::CanFrame;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::config::CellFile;
use drivetwin::cell::station::Station;
use od::Instant;

struct Bench {
    cell: CanCell,
    now: Instant,
    out: Vec<CanFrame>,
}

impl Bench {
    fn new() -> Self {
        let spec = CellFile::single("kinco-fd3", 1)
            .drives(drivetwin::vendors::VENDORS.runtime)
            .expect("a Kinco cell")
            .remove(0);
        assert!(spec.settings.is_some(), "kinco-fd3 is a CiA 402 drive");
        let d = Station::with_settings(
            spec.desc,
            spec.node,
            None,
            spec.commissioning,
            spec.settings,
        )
        .expect("the Kinco FD3");
        let mut b = Bench {
            cell: CanCell::one_bus(vec![d]),
            now: Instant::ZERO,
            out: Vec::new(),
        };
        b.cell.boot(0, b.now, &mut b.out);
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
            self.cell.poll(0, self.now, &mut self.out);
        }
        self.now = until;
        self.cell.poll(0, self.now, &mut self.out);
    }

    fn sdo(&mut self, request: [u8; 8]) -> [u8; 8] {
        self.out.clear();
        self.cell
            .on_frame(0, self.now, &CanFrame::full(0x601, request), &mut self.out);
        self.out
            .iter()
            .find(|f| f.id == 0x581)
            .map(|f| f.data)
            .expect("an SDO answer")
    }

    fn write(&mut self, index: u16, sub: u8, value: i64, size: u8) {
        let cmd = match size {
            1 => 0x2F,
            2 => 0x2B,
            _ => 0x23,
        };
        let [i0, i1] = index.to_le_bytes();
        let v = (value as u32).to_le_bytes();
        let a = self.sdo([cmd, i0, i1, sub, v[0], v[1], v[2], v[3]]);
        assert_eq!(a[0], 0x60, "{index:04X}h:{sub:02X}: {a:02X?}");
    }

    fn read(&mut self, index: u16, sub: u8) -> i64 {
        let [i0, i1] = index.to_le_bytes();
        let a = self.sdo([0x40, i0, i1, sub, 0, 0, 0, 0]);
        let raw = i32::from_le_bytes([a[4], a[5], a[6], a[7]]);
        match a[0] {
            0x4F => i64::from(raw as i8),
            0x4B => i64::from(raw as i16),
            0x43 => i64::from(raw),
            _ => panic!("{index:04X}h: {a:02X?}"),
        }
    }

    /// A bus master's set-up: Din1_Function and Din3_Function 0, ramps of 100 rps/s.
    fn bus_master_setup(&mut self) {
        self.write(0x2010, 0x03, 0, 2);
        self.write(0x2010, 0x05, 0, 2);
        self.write(0x6083, 0, 16_384, 4);
        self.write(0x6084, 0, 16_384, 4);
    }
}

/// DEC of `rpm` (as the sibling FD manuals give it, 10 000 increments per revolution).
fn dec(rpm: i64) -> i64 {
    rpm * 512 * 10_000 / 1875
}

#[test]
fn factory_setup_refuses_the_bus_controlword() {
    let mut b = Bench::new();
    let a = b.sdo([0x2B, 0x40, 0x60, 0, 0x0F, 0, 0, 0]);
    assert_eq!(a[0], 0x80);
    assert_eq!(u32::from_le_bytes([a[4], a[5], a[6], a[7]]), 0x0800_0021);
    assert_eq!(b.read(0x6061, 0), -4, "Din_Mode0");
}

#[test]
fn mode_3_runs_at_300_rpm_over_sdo() {
    let mut b = Bench::new();
    b.bus_master_setup();
    b.write(0x6060, 0, 3, 1);
    b.write(0x6040, 0, 0x06, 2);
    b.run_ms(5);
    b.write(0x6040, 0, 0x0F, 2);
    b.run_ms(5);
    assert_eq!(b.read(0x6041, 0) & 0x6F, 0x27);
    b.write(0x60FF, 0, dec(300), 4);
    b.run_ms(500);
    let v = b.read(0x606C, 0);
    assert!((v - dec(300)).abs() < dec(5), "606Ch = {v}");
    let rpm = b.read(0x2FF0, 0x14);
    assert!((rpm - 300).abs() <= 2, "Real_Speed_RPM {rpm}");
    // OUT1 Ready, OUT2 brake released (the motor turns).
    assert_eq!(b.read(0x2010, 0x14) & 0b11, 0b11);
}

/// KINCO-CW-01 over SDO: 06h → 2Fh → 607Ah = 50 000 → 3Fh.
#[test]
fn kinco_cw_01_absolute_move_over_sdo() {
    let mut b = Bench::new();
    b.bus_master_setup();
    b.write(0x6081, 0, dec(600), 4);
    b.write(0x6060, 0, 1, 1);
    b.write(0x6040, 0, 0x06, 2);
    b.run_ms(5);
    b.write(0x6040, 0, 0x2F, 2);
    b.run_ms(5);
    b.write(0x607A, 0, 50_000, 4);
    b.write(0x6040, 0, 0x3F, 2);
    b.run_ms(1500);
    let sw = b.read(0x6041, 0);
    assert_eq!(sw & 0x0400, 0x0400, "target reached: {sw:04X}");
    let p = b.read(0x6063, 0);
    assert!((p - 50_000).abs() <= 20, "6063h = {p}");
}

/// KINCO-DIAG-03 on the bus: the following error beyond 6065h sends EMCY 8611h on 81h
/// with Error_State bit 9 in 2601h.
#[test]
fn kinco_diag_03_following_error_emcy() {
    let mut b = Bench::new();
    b.bus_master_setup();
    b.write(0x2FF0, 0x0E, 1, 2);
    assert_eq!(b.read(0x6065, 0), 100);
    b.write(0x6060, 0, -3, 1);
    b.write(0x6040, 0, 0x06, 2);
    b.run_ms(5);
    b.write(0x6040, 0, 0x0F, 2);
    b.run_ms(5);
    b.write(0x6060, 0, 1, 1);
    b.run_ms(5);
    b.write(0x6081, 0, dec(3000), 4);
    b.write(0x6083, 0, 0, 4); // no ramp: the set-point jumps ahead of the motor
    b.write(0x6040, 0, 0x2F, 2);
    b.write(0x607A, 0, 200_000, 4);
    b.out.clear();
    b.write(0x6040, 0, 0x3F, 2);
    b.out.clear();
    b.run_ms(50);
    let emcy = b
        .out
        .iter()
        .find(|f| f.id == 0x81)
        .copied()
        .expect("an EMCY");
    assert_eq!(&emcy.data[..3], &[0x11, 0x86, 0x01], "8611h, generic error");
    assert_eq!(b.read(0x2601, 0), 1 << 9);
    assert_eq!(b.read(0x6041, 0) & 0x4F, 0x08, "fault");
}
