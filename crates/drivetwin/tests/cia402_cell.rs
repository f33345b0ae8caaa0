//! The default cell's CMMP-AS is a CiA 402 drive: it steps on the cell's clock and answers
//! the enable sequence through the CANopen stack.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use canopen::CanFrame;
use drivetwin::cell::can_cell::CanCell;
use od::Instant;

#[path = "support/can_bench.rs"]
mod can_bench;

use can_bench::cmmp_cell;

fn cell() -> CanCell {
    cmmp_cell(None)
}

fn run_until(cell: &mut CanCell, now: &mut Instant, until: Instant, out: &mut Vec<CanFrame>) {
    while let Some(t) = cell.deadline() {
        if t > until {
            break;
        }
        *now = t.max(*now);
        cell.poll(0, *now, out);
    }
    *now = until;
}

fn sdo(cell: &mut CanCell, now: Instant, data: [u8; 8]) -> [u8; 8] {
    let mut out = Vec::new();
    cell.on_frame(0, now, &CanFrame::full(0x601, data), &mut out);
    out.iter()
        .find(|f| f.id == 0x581)
        .map(|f| f.data)
        .expect("SDO answer")
}

#[test]
fn enable_sequence_over_sdo_on_the_virtual_clock() {
    let mut c = cell();
    let mut out = Vec::new();
    let mut now = Instant::ZERO;
    c.boot(0, now, &mut out);
    run_until(&mut c, &mut now, Instant::from_millis(10), &mut out);
    let sw = |c: &mut CanCell, now| {
        let r = sdo(c, now, [0x40, 0x41, 0x60, 0, 0, 0, 0, 0]);
        u16::from_le_bytes([r[4], r[5]])
    };
    assert_eq!(sw(&mut c, now) & 0x4F, 0x40);
    for (cw, want) in [(0x06u8, 0x21u16), (0x07, 0x23), (0x0F, 0x27)] {
        sdo(&mut c, now, [0x2B, 0x40, 0x60, 0, cw, 0, 0, 0]);
        let until = Instant::from_nanos(now.as_nanos() + 2_000_000);
        run_until(&mut c, &mut now, until, &mut out);
        assert_eq!(sw(&mut c, now) & 0x6F, want);
    }
}

/// The SDO vectors the CiA 402 drive decides, as frames on the running cell: CMMP-SDO-16
/// (enable_logic forced to 2 with CANopen active), CMMP-SDO-15 (compatibility bits 0 and 2
/// set each other), CMMP-SDO-10 ("load" refused with the output stage on), CMMP-SDO-09 (the
/// same "load" accepted with it off).
#[test]
fn cmmp_sdo_10_15_16_on_the_drive() {
    let mut c = cell();
    let mut out = Vec::new();
    let mut now = Instant::ZERO;
    c.boot(0, now, &mut out);
    run_until(&mut c, &mut now, Instant::from_millis(10), &mut out);
    // CMMP-SDO-16.
    assert_eq!(
        sdo(&mut c, now, [0x40, 0x10, 0x65, 0x10, 0, 0, 0, 0]),
        [0x4B, 0x10, 0x65, 0x10, 0x02, 0x00, 0, 0]
    );
    // CMMP-SDO-15.
    assert_eq!(
        sdo(&mut c, now, [0x2B, 0x10, 0x65, 0xF0, 0x04, 0x00, 0, 0]),
        [0x60, 0x10, 0x65, 0xF0, 0, 0, 0, 0]
    );
    assert_eq!(
        sdo(&mut c, now, [0x40, 0x10, 0x65, 0xF0, 0, 0, 0, 0]),
        [0x4B, 0x10, 0x65, 0xF0, 0x05, 0x00, 0, 0]
    );
    // CMMP-SDO-10: output stage enabled.
    for cw in [0x06u8, 0x07, 0x0F] {
        sdo(&mut c, now, [0x2B, 0x40, 0x60, 0, cw, 0, 0, 0]);
        let until = Instant::from_nanos(now.as_nanos() + 2_000_000);
        run_until(&mut c, &mut now, until, &mut out);
    }
    let load = [0x23, 0x11, 0x10, 0x01, 0x6C, 0x6F, 0x61, 0x64];
    assert_eq!(
        sdo(&mut c, now, load),
        [0x80, 0x11, 0x10, 0x01, 0x22, 0x00, 0x00, 0x08]
    );
    // CMMP-SDO-09: output stage off, the same frame is taken.
    sdo(&mut c, now, [0x2B, 0x40, 0x60, 0, 0x00, 0, 0, 0]);
    let until = Instant::from_nanos(now.as_nanos() + 2_000_000);
    run_until(&mut c, &mut now, until, &mut out);
    assert_eq!(sdo(&mut c, now, load), [0x60, 0x11, 0x10, 0x01, 0, 0, 0, 0]);
}
