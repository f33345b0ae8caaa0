//! Interpolated position mode (6060h = 7) of the CMMP-AS over CANopen, on the virtual clock:
//! the manual's preparation and activation sequence (vectors CMMP-IP-01, CMMP-IP-02,
//! CMMP-IP-03, CMMP-IP-04, CMMP-IP-05, CMMP-IP-06, CMMP-IP-07), the drive
//! synchronising to the SYNC grid (6061h −1 → 7), the SYNC-paced set-points interpolated
//! linearly, and the errors 34-0 / 34-1.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drivetwin::cell::param_store::ParamStore;

#[path = "support/can_bench.rs"]
mod can_bench;

use can_bench::CanBench as Bench;

fn tmpdir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("drivetwin-ip-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const OK: [u8; 4] = [0x60, 0, 0, 0];

fn ok(r: [u8; 8], index: u16, sub: u8) {
    let [lo, hi] = index.to_le_bytes();
    assert_eq!(
        r[..4],
        [OK[0], lo, hi, sub],
        "download {index:04X}h:{sub}: {r:02X?}"
    );
}

/// CMMP-IP-01, CMMP-IP-02, CMMP-IP-03, CMMP-IP-04, CMMP-IP-05: the preparation of §7.4.3, with save and reset for the 4 ms interval.
fn prepared(name: &str) -> Bench {
    let dir = tmpdir(name);
    let mut b = Bench::new(Some(ParamStore::new(&dir, "cmmp-as", 1)));
    ok(b.write(0x60C0, 0, &(-2i16).to_le_bytes()), 0x60C0, 0); // CMMP-IP-01
    ok(b.write(0x60C2, 2, &[(-4i8) as u8]), 0x60C2, 2); // CMMP-IP-02
    ok(b.write(0x60C2, 1, &[40]), 0x60C2, 1); // CMMP-IP-03
    ok(
        b.sdo(&[0x23, 0x10, 0x10, 0x01, b's', b'a', b'v', b'e']),
        0x1010,
        1,
    ); // CMMP-IP-04
    b.frame(0x000, &[0x81, 0x01]);
    assert!(
        b.out.iter().any(|f| f.id == 0x701 && f.data[0] == 0),
        "boot-up after the reset: {:?}",
        b.out
    );
    b.run_ms(10);
    assert_eq!(
        b.read(0x60C2, 1),
        40,
        "the stored interval survives the reset"
    );
    ok(b.write(0x60C4, 6, &[1]), 0x60C4, 6); // CMMP-IP-05
    b.frame(0x000, &[0x01, 0x01]); // NMT start: SYNC is consumed in Operational
    b.run_ms(2);
    b
}

/// CMMP-IP-06: SYNC every 4 ms, 6060h := 7; 6061h reads −1 while synchronising, then 7, and
/// −1 again when SYNC leaves the grid.
#[test]
fn cmmp_ip_06_6061_shows_minus_1_until_synchronised_to_the_sync_grid() {
    let mut b = prepared("sync");
    ok(b.write(0x6060, 0, &[7]), 0x6060, 0);
    b.run_ms(2);
    assert_eq!(b.read(0x6061, 0), -1, "no SYNC yet");
    // SYNC on a 10 ms grid does not match the 4 ms interval.
    b.syncs(5, 10, |_, _| {});
    assert_eq!(b.read(0x6061, 0), -1, "wrong grid");
    // The 4 ms grid: synchronised after two intervals.
    b.syncs(3, 4, |_, _| {});
    assert_eq!(b.read(0x6061, 0), 7);
    // SYNC stops: back to −1 (no error while not interpolating).
    b.run_ms(20);
    assert_eq!(b.read(0x6061, 0), -1, "SYNC left the grid");
    assert!(
        !b.out.iter().any(|f| f.id == 0x081),
        "no EMCY without interpolation"
    );
}

/// CMMP-IP-07: 60C1h:01 := 6064h, then enable_ip_mode (bit 4): ip_mode_active (bit 12) and one
/// set-point taken per SYNC.
#[test]
fn cmmp_ip_07_set_points_each_sync_are_interpolated_linearly() {
    let mut b = prepared("move");
    b.enable();
    ok(b.write(0x6060, 0, &[7]), 0x6060, 0);
    b.syncs(3, 4, |_, _| {});
    assert_eq!(b.read(0x6061, 0), 7);
    // Read 6064h, write it to 60C1h:01, then enable_ip_mode (bit 4).
    let p = b.read(0x6064, 0);
    ok(b.write(0x60C1, 1, &(p as i32).to_le_bytes()), 0x60C1, 1);
    b.write(0x6040, 0, &[0x1F, 0]);
    b.syncs(2, 4, |_, _| {});
    let sw = b.read(0x6041, 0);
    assert_eq!(sw & 0x1000, 0x1000, "ip_mode_active: {sw:#06x}");
    // 100 SYNCs, each 400 position units further (0.1 s at 100 000 units/s).
    let step = 400i64;
    let mut target = p;
    b.syncs(100, 4, |b, _| {
        target += step;
        ok(
            b.write(0x60C1, 1, &(target as i32).to_le_bytes()),
            0x60C1,
            1,
        );
    });
    let demand = b.read(0x6062, 0);
    let actual = b.read(0x6064, 0);
    assert!(
        (demand - target).abs() <= step,
        "the demand follows one SYNC behind: {demand} vs {target}"
    );
    assert!(
        (actual - target).abs() < 3 * step,
        "the axis follows: {actual} vs {target}"
    );
    let sw = b.read(0x6041, 0);
    assert_eq!(sw & 0x3000, 0x1000, "active, no following error: {sw:#06x}");
    // Halfway between two SYNCs the demand stands between the set-points (linear).
    target += step;
    ok(
        b.write(0x60C1, 1, &(target as i32).to_le_bytes()),
        0x60C1,
        1,
    );
    b.sync();
    b.run_ms(2);
    let mid = b.read(0x6062, 0);
    assert!(
        (mid - (target - step / 2)).abs() <= step / 8,
        "linear: {mid} between {} and {target}",
        target - step
    );
    // Relative set-points (60C1h:02 = 1): each a distance.
    b.run_ms(2);
    ok(b.write(0x60C1, 2, &[1]), 0x60C1, 2);
    b.syncs(10, 4, |b, _| {
        ok(b.write(0x60C1, 1, &(step as i32).to_le_bytes()), 0x60C1, 1);
    });
    // SYNC goes on (three silent periods would lose the grid: 34-1) without set-points.
    b.syncs(2, 4, |_, _| {});
    let demand = b.read(0x6062, 0);
    assert!(
        (demand - (target + 10 * step)).abs() <= 1,
        "relative: {demand} vs {}",
        target + 10 * step
    );
    // Bit 4 cleared (taken at the next control cycle): set-points are ignored, the drive
    // holds.
    b.write(0x6040, 0, &[0x0F, 0]);
    b.run_ms(1);
    b.syncs(3, 4, |b, _| {
        ok(b.write(0x60C1, 1, &(step as i32).to_le_bytes()), 0x60C1, 1);
    });
    assert_eq!(b.read(0x6041, 0) & 0x1000, 0, "ip_mode_active cleared");
    let held = b.read(0x6062, 0);
    assert!((held - demand).abs() <= 1, "holds: {held} vs {demand}");
}

#[test]
fn losing_the_grid_while_interpolating_is_error_34_1() {
    let mut b = prepared("lost");
    b.enable();
    ok(b.write(0x6060, 0, &[7]), 0x6060, 0);
    b.syncs(3, 4, |_, _| {});
    let p = b.read(0x6064, 0);
    ok(b.write(0x60C1, 1, &(p as i32).to_le_bytes()), 0x60C1, 1);
    b.write(0x6040, 0, &[0x1F, 0]);
    b.syncs(3, 4, |_, _| {});
    assert_eq!(b.read(0x6041, 0) & 0x1000, 0x1000);
    // The master stops sending SYNC.
    b.out.clear();
    let mut emcy = Vec::new();
    for _ in 0..30 {
        b.run_ms(1);
        emcy.extend(b.out.iter().filter(|f| f.id == 0x081).cloned());
        b.out.clear();
    }
    assert!(
        emcy.iter().any(|f| f.data[0..2] == [0x81, 0x87]),
        "EMCY 8781h (34-1): {emcy:?}"
    );
    let sw = b.read(0x6041, 0);
    assert_eq!(
        sw & 0x1008,
        0x0008,
        "fault, interpolation stopped: {sw:#06x}"
    );
    assert_eq!(b.read(0x6061, 0), -1);
}

#[test]
fn activation_off_the_grid_is_error_34_0_and_60c1_is_locked_by_buffer_clear() {
    let mut b = prepared("nosync");
    b.enable();
    ok(b.write(0x6060, 0, &[7]), 0x6060, 0);
    b.run_ms(2);
    // 60C4h:06 = 0 locks 60C1h: refused with the device-state abort.
    ok(b.write(0x60C4, 6, &[0]), 0x60C4, 6);
    let r = b.write(0x60C1, 1, &0i32.to_le_bytes());
    assert_eq!(r[0], 0x80);
    assert_eq!(u32::from_le_bytes([r[4], r[5], r[6], r[7]]), 0x0800_0022);
    ok(b.write(0x60C4, 6, &[1]), 0x60C4, 6);
    // enable_ip_mode without SYNC: 34-0 (EMCY 8780h).
    b.write(0x6040, 0, &[0x1F, 0]);
    let mut emcy = Vec::new();
    for _ in 0..5 {
        b.run_ms(1);
        emcy.extend(b.out.iter().filter(|f| f.id == 0x081).cloned());
        b.out.clear();
    }
    assert!(
        emcy.iter().any(|f| f.data[0..2] == [0x80, 0x87]),
        "EMCY 8780h (34-0): {emcy:?}"
    );
}

#[test]
fn sdo_traffic_between_syncs_keeps_the_grid() {
    // A master that polls 6061h every 2 ms beside a 10 ms SYNC: the drive synchronises.
    let dir = tmpdir("poll");
    let mut b = Bench::new(Some(ParamStore::new(&dir, "cmmp-as", 1)));
    ok(b.write(0x60C2, 1, &[10]), 0x60C2, 1);
    b.sdo(&[0x23, 0x10, 0x10, 0x01, b's', b'a', b'v', b'e']);
    b.frame(0x000, &[0x81, 0x01]);
    b.run_ms(10);
    ok(b.write(0x60C4, 6, &[1]), 0x60C4, 6);
    b.frame(0x000, &[0x01, 0x01]);
    ok(b.write(0x6060, 0, &[7]), 0x6060, 0);
    let mut seen = Vec::new();
    for _ in 0..30 {
        b.sync();
        for _ in 0..5 {
            b.run_ms(2);
            seen.push(b.read(0x6061, 0));
        }
    }
    let first = seen.iter().position(|m| *m == 7).expect("synchronised");
    assert!(first <= 15, "after three SYNCs: {seen:?}");
    assert!(
        seen[first..].iter().all(|m| *m == 7),
        "and stays so: {seen:?}"
    );
}
