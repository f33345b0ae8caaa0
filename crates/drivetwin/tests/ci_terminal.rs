//! The CI terminal of a CMMP-AS drive (manual §3.2.3): its SDO simulation answers from the
//! drive's dictionary, and a write acts as an SDO download of the node would.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use canopen::CanFrame;
use drive::vendors::festo_cmmp_as::ci_terminal;
use drivetwin::cell::can_cell::CanCell;
use drivetwin::cell::stations::StationId;
use od::Instant;

#[path = "support/can_bench.rs"]
mod can_bench;

fn cell() -> CanCell {
    let mut c = can_bench::cmmp_cell(None);
    c.boot(0, Instant::ZERO, &mut Vec::new());
    c
}

/// The answer to `line` typed at the CI terminal of drive `drive`, which reaches the drive
/// as its local interfaces do (`CanCell::local_access`); `None` without the drive.
fn ci_line(c: &mut CanCell, drive: usize, now: Instant, line: &[u8]) -> Option<String> {
    let mut reply = None;
    c.local_access(
        StationId::from_index(drive),
        now,
        &mut Vec::new(),
        &mut |od| {
            reply = Some(ci_terminal::execute(line, od).as_str().to_owned());
        },
    );
    reply
}

fn ci(c: &mut CanCell, now: Instant, line: &str) -> String {
    ci_line(c, 0, now, line.as_bytes()).expect("drive 0")
}

/// CMMP-CI-01, CMMP-CI-02, CMMP-CI-03, CMMP-CI-04 on the running drive: mode display (the
/// drive's own value), a controlword write echoed, the position factor, and the read-only
/// statusword.
#[test]
fn ci_vectors_on_a_cmmp_as_drive() {
    let mut c = cell();
    let t = Instant::from_millis(5);
    assert_eq!(ci(&mut c, t, "=606000:01"), "=606000:01");
    let t = Instant::from_millis(50);
    assert_eq!(ci(&mut c, t, "?606100"), "=606100:01");
    assert_eq!(ci(&mut c, t, "=604000:000F"), "=604000:000F");
    assert_eq!(c.stations[0].od().get_unsigned(0x6040, 0), Some(0x0F));
    assert_eq!(ci(&mut c, t, "?609301"), "=609301:00000001");
    assert_eq!(ci(&mut c, t, "=604100:0000"), "!06010002");
    assert_eq!(ci(&mut c, t, "?1234"), "!05040001");
    assert_eq!(ci_line(&mut c, 1, t, b"?606100"), None);
}

/// A write of 1017h starts the heartbeat at the new period, as the SDO download does; PDO
/// parameters are refused in Operational (CMMP-AS §3.3.3), as over SDO.
#[test]
fn a_console_write_acts_like_an_sdo_download() {
    let mut c = cell();
    let mut out: Vec<CanFrame> = Vec::new();
    assert_eq!(ci(&mut c, Instant::ZERO, "=101700:0064"), "=101700:0064");
    let mut now = Instant::ZERO;
    while let Some(t) = c.deadline() {
        if t > Instant::from_millis(350) {
            break;
        }
        now = t.max(now);
        c.poll(0, now, &mut out);
    }
    let hb: Vec<_> = out.iter().filter(|f| f.id == 0x701).collect();
    assert_eq!(hb.len(), 3, "heartbeat every 100 ms: {out:?}");
    c.on_frame(0, now, &CanFrame::new(0, &[0x01, 0x01]).unwrap(), &mut out);
    assert_eq!(ci(&mut c, now, "=180001:C0000187"), "!08000022");
}
