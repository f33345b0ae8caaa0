//! Nanotec Interpolated Position (Nanotec ch. 7; the extract's §9 item 7): the PLL locks on the
//! SYNC interval (60C2h ignored) and shows it in bit 8; a set-point sent after SYNC k is latched at
//! SYNC k+1 and reached at SYNC k+2 (the two-period lag of the manual's figure); 60C1h:01 and 607Ah
//! are one target; a quick stop stops abruptly.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod nanotec_rig;

use nanotec_rig::Rig;
use od::ObjectAccess;

/// The SYNC period of the manual's figure.
const PERIOD_MS: u64 = 4;

fn sync(r: &mut Rig) {
    r.run_ms(PERIOD_MS);
    let now = r.now;
    r.d.sync(now);
}

/// SYNCs until the PLL reports the lock (bit 8), at most 5.
fn lock(r: &mut Rig) {
    for _ in 0..5 {
        sync(r);
        r.run_ms(0);
        if r.sw() & 0x0100 != 0 {
            return;
        }
    }
    panic!("no PLL lock: {:#06x}", r.sw());
}

/// Operation Enabled in IP with the PLL locked; the set-point primed with the position.
fn ip(r: &mut Rig) {
    r.enable();
    r.w8(0x6060, 0, 7);
    r.run_ms(2);
    lock(r);
    let here = r.i(0x6062, 0);
    r.w32(0x60C1, 1, here);
    r.cw(0x001F);
}

#[test]
fn pll_locks_on_the_sync_interval_bit_8() {
    let mut r = Rig::new();
    r.enable();
    r.w8(0x6060, 0, 7);
    assert_eq!(r.sw() & 0x0100, 0, "no SYNC yet");
    // A period 60C2h does not give (60C2h says 1 ms): three intervals of 4 ms lock it.
    for _ in 0..4 {
        sync(&mut r);
    }
    r.run_ms(1);
    assert_ne!(r.sw() & 0x0100, 0, "PLL sync complete");
    assert_eq!(r.i(0x6061, 0), 7);
    // SYNC stops: the lock is lost.
    r.run_ms(10 * PERIOD_MS);
    assert_eq!(r.sw() & 0x0100, 0);
}

#[test]
fn set_points_are_latched_at_the_next_sync_and_reached_two_periods_later() {
    let mut r = Rig::new();
    ip(&mut r);
    assert_ne!(r.sw() & 0x1000, 0, "IP mode active");
    let start = r.i(0x6062, 0);
    // The figure: +2 units per SYNC.
    let mut sent = Vec::new();
    for k in 1..=6 {
        let p = start + 2 * k;
        r.w32(0x60C1, 1, p);
        sent.push(p);
        // SYNC k+1: the set-point of after SYNC k is latched; the segment towards it starts.
        r.run_ms(1);
        let now = r.now;
        r.d.sync(now);
        // One period later it is there; in between the demand lies between the two.
        r.run_ms(PERIOD_MS - 1);
        let demand = r.i(0x6062, 0);
        let previous = if k >= 2 { sent[k as usize - 2] } else { start };
        assert!(
            demand >= previous && demand <= p,
            "SYNC {k}: demand {demand}, sent {sent:?}"
        );
    }
    // Two periods after the last set-point was sent the demand stands on it.
    r.run_ms(1);
    let now = r.now;
    r.d.sync(now);
    r.run_ms(PERIOD_MS);
    assert_eq!(r.i(0x6062, 0), *sent.last().unwrap());
}

#[test]
fn ip_set_point_and_target_position_are_one_object() {
    let mut r = Rig::new();
    r.w32(0x60C1, 1, 1234);
    assert_eq!(r.i(0x607A, 0), 1234);
    r.w32(0x607A, 0, -77);
    assert_eq!(r.i(0x60C1, 1), -77);
}

#[test]
fn a_stale_set_point_is_driven_to_when_ip_starts() {
    let mut r = Rig::new();
    // PP to 2000 first, so the shared target is not where IP starts from.
    r.enable_pp();
    r.w32(0x607A, 0, 2000);
    r.cw(0x001F);
    r.cw(0x000F);
    assert!(r.until_target_reached(5000));
    r.w32(0x60C1, 1, 0); // stale: the position is 2000
    r.w8(0x6060, 0, 7);
    r.run_ms(2);
    lock(&mut r);
    // Bit 4 between two SYNCs on the grid.
    r.d.write(0x6040, 0, &0x001Fu16.to_le_bytes()).unwrap();
    sync(&mut r);
    r.run_ms(PERIOD_MS + 1);
    assert_eq!(
        r.i(0x6062, 0),
        0,
        "the drive jumps to the stale set-point in one period"
    );
}

#[test]
fn quick_stop_in_ip_is_abrupt() {
    let mut r = Rig::new();
    ip(&mut r);
    let start = r.i(0x6062, 0);
    // Moving at 40 units per 4 ms = 10 000 units/s.
    for k in 1..=50 {
        r.w32(0x60C1, 1, start + 40 * k);
        sync(&mut r);
    }
    let before = r.i(0x6062, 0);
    r.d.write(0x6040, 0, &0x000Bu16.to_le_bytes()).unwrap();
    r.run_ms(3);
    let after = r.i(0x6062, 0);
    assert!(
        (after - before).abs() <= 45,
        "stopped at once: {before} → {after}"
    );
    r.run_ms(20);
    assert_eq!(r.sw() & 0x004F, 0x0040, "Switch On Disabled");
}
