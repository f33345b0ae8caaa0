//! The default cell's CMMP-AS is a CiA 402 drive: it steps on the cell's clock and answers
//! the enable sequence through the CANopen stack.

use canopen::CanFrame;
use drivetwin::can_drive::CanDrive;
use drivetwin::cell::Cell;
use drivetwin::cell_config::CellFile;
use od::Instant;

fn cell() -> Cell {
    let spec = CellFile::single("cmmp-as", 1).drives().unwrap().remove(0);
    assert!(spec.settings.is_some(), "cmmp-as is a CiA 402 drive");
    let d = CanDrive::with_settings(
        spec.desc,
        spec.node,
        None,
        spec.commissioning,
        spec.settings,
    )
    .unwrap();
    Cell::new(vec![d])
}

fn run_until(cell: &mut Cell, now: &mut Instant, until: Instant, out: &mut Vec<CanFrame>) {
    while let Some(t) = cell.deadline() {
        if t > until {
            break;
        }
        *now = t.max(*now);
        cell.poll(*now, out);
    }
    *now = until;
}

fn sdo(cell: &mut Cell, now: Instant, data: [u8; 8]) -> [u8; 8] {
    let mut out = Vec::new();
    cell.on_frame(now, &CanFrame::full(0x601, data), &mut out);
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
    c.boot(now, &mut out);
    run_until(&mut c, &mut now, Instant::from_millis(10), &mut out);
    let sw = |c: &mut Cell, now| {
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
