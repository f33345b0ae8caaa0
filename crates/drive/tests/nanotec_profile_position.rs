//! Nanotec Profile Position (Nanotec ch. 4; the extract's §9 item 6): the §2.5–2.7 frames through
//! the CANopen node, the bit 12 handshake with the one-deep queue, relative targets, change on
//! set-point, and the target checks with their EMCYs and bit 11.

mod nanotec_rig;

use drive::drive::DriveEvent;
use nanotec_rig::Rig;

const OK_6040: [u8; 8] = [0x60, 0x40, 0x60, 0x00, 0x00, 0x00, 0x00, 0x00];
/// Increments of the motor model per revolution.
const INC_PER_REV: i64 = 65536;

/// Operation Enabled and PP through the manual's frames.
fn pp(r: &mut Rig) {
    r.enable();
    let a = r.sdo(&[0x2F, 0x60, 0x60, 0x00, 0x01]);
    assert_eq!(a, [0x60, 0x60, 0x60, 0x00, 0x00, 0x00, 0x00, 0x00]);
    r.run_ms(5);
}

/// Start with 1Fh, then 0Fh, as the manual's frames; both answered.
fn start(r: &mut Rig, cw: u8) {
    assert_eq!(r.sdo(&[0x2B, 0x40, 0x60, 0x00, cw, 0x00]), OK_6040);
    r.run_ms(2);
    assert_eq!(r.sdo(&[0x2B, 0x40, 0x60, 0x00, 0x0F, 0x00]), OK_6040);
    r.run_ms(2);
}

/// NT-PP-01: 6060h := 1 in Operation Enabled is answered `60 60 60 00 …` and selects PP.
#[test]
fn nt_pp_01_select_profile_position() {
    let mut r = Rig::new();
    pp(&mut r);
    assert_eq!(r.i(0x6061, 0), 1);
    assert_eq!(r.sw() & 0x006F, 0x0027, "still Operation Enabled");
}

/// NT-PP-02: 1Fh then 0Fh moves to 607Ah (absolute); a second toggle moves nothing, the
/// target is reached already.
#[test]
fn nt_pp_02_start_moves_to_the_target_and_a_second_toggle_does_nothing() {
    let mut r = Rig::new();
    pp(&mut r);
    r.w32(0x607A, 0, 3000);
    start(&mut r, 0x1F);
    assert!(r.until_target_reached(5000), "target reached");
    assert!((r.position() - 3000).abs() <= 10, "at {}", r.position());
    let before = r.d.plant_position();
    start(&mut r, 0x1F);
    r.run_ms(500);
    assert!((r.d.plant_position() - before).abs() < 100, "no movement");
    assert_ne!(r.sw() & 0x0400, 0, "target reached stays");
}

/// NT-PP-03: 607Ah := 00012345h by the manual's frame, then 1Fh / 0Fh: the drive moves to
/// 74 565 units = 37.2825 output revolutions with the default feed 2000/1.
#[test]
fn nt_pp_03_new_target_0x12345() {
    let mut r = Rig::new();
    pp(&mut r);
    // Faster than the default 2000 units/s (600 min⁻¹, well inside the open-loop stepper's
    // pull-out torque) so the move takes four seconds.
    r.w32(0x6081, 0, 20_000);
    r.w32(0x6083, 0, 100_000);
    r.w32(0x6084, 0, 100_000);
    let a = r.sdo(&[0x23, 0x7A, 0x60, 0x00, 0x45, 0x23, 0x01, 0x00]);
    assert_eq!(a, [0x60, 0x7A, 0x60, 0x00, 0x00, 0x00, 0x00, 0x00]);
    let start_inc = r.d.plant_position();
    start(&mut r, 0x1F);
    assert!(r.until_target_reached(10_000), "target reached");
    assert!((r.position() - 74_565).abs() <= 10, "at {}", r.position());
    let revs = (r.d.plant_position() - start_inc) as f64 / INC_PER_REV as f64;
    assert!((revs - 37.2825).abs() < 0.01, "{revs} revolutions");
}

/// NT-PP-04: bit 12 follows bit 4 when idle; a queued set-point (bit 5 = 0 while moving)
/// keeps bit 12 until the drive takes it; a new one while queued overwrites it.
#[test]
fn nt_pp_04_set_point_acknowledge_and_the_one_deep_queue() {
    let mut r = Rig::new();
    pp(&mut r);
    r.cw(0x000F);
    assert_eq!(r.sw() & 0x1000, 0);
    r.w32(0x607A, 0, 0);
    r.cw(0x001F);
    assert_ne!(r.sw() & 0x1000, 0, "1 after 001Fh");
    r.cw(0x000F);
    assert_eq!(r.sw() & 0x1000, 0, "0 after 000Fh");
    // A long move, then a queued one: bit 12 stays set after bit 4 falls.
    r.w32(0x607A, 0, 8000);
    r.cw(0x001F);
    r.cw(0x000F);
    r.run_ms(100);
    r.w32(0x607A, 0, 1000);
    r.cw(0x001F);
    r.cw(0x000F);
    assert_ne!(r.sw() & 0x1000, 0, "queued: bit 12 kept");
    // The newest queued job overwrites the queued one.
    r.w32(0x607A, 0, 2000);
    r.cw(0x001F);
    r.cw(0x000F);
    for _ in 0..500 {
        r.run_ms(20);
        if r.sw() & 0x1400 == 0x0400 {
            break;
        }
    }
    assert_eq!(r.sw() & 0x1000, 0, "taken: bit 12 drops");
    assert!(
        (r.position() - 2000).abs() <= 10,
        "the last queued target: {}",
        r.position()
    );
}

/// NT-PP-05: 5Fh (bits 4 and 6) with 607Ah = 2000 moves +2000 from where the drive is, one
/// output revolution.
#[test]
fn nt_pp_05_relative_move() {
    let mut r = Rig::new();
    pp(&mut r);
    r.w32(0x607A, 0, 1500);
    start(&mut r, 0x1F);
    assert!(r.until_target_reached(5000));
    let inc = r.d.plant_position();
    r.w32(0x607A, 0, 2000);
    start(&mut r, 0x5F);
    r.run_ms(20);
    assert!(r.until_target_reached(5000));
    assert!((r.position() - 3500).abs() <= 10, "at {}", r.position());
    let moved = r.d.plant_position() - inc;
    assert!((moved - INC_PER_REV).abs() < 400, "one revolution: {moved}");
}

/// NT-PP-06: a target beyond the software limits 607Dh: EMCY 0800h and bit 11, no move;
/// the next valid target clears both. A relative target that overflows: EMCY 1000h.
#[test]
fn nt_pp_06_software_limit_and_overflow_emcy_with_bit_11() {
    let mut r = Rig::new();
    pp(&mut r);
    r.w32(0x607D, 1, -10_000);
    r.w32(0x607D, 2, 10_000);
    r.events();
    r.w32(0x607A, 0, 20_000);
    start(&mut r, 0x1F);
    r.run_ms(200);
    assert_eq!(
        r.events(),
        [DriveEvent::Error {
            code: 0x0800,
            register: 0x01
        }]
    );
    assert_ne!(r.sw() & 0x0800, 0, "bit 11");
    assert_eq!(r.sw() & 0x006F, 0x0027, "no fault: Operation Enabled");
    assert!(r.position().abs() <= 10, "no move: {}", r.position());
    // Home offset corrects the limits: max − offset.
    r.w32(0x607C, 0, 5000);
    r.w32(0x607A, 0, 6000);
    start(&mut r, 0x1F);
    r.run_ms(10);
    assert_ne!(r.sw() & 0x0800, 0, "6000 > 10000 − 5000");
    // A valid target clears the EMCY and bit 11.
    r.w32(0x607A, 0, 2000);
    start(&mut r, 0x1F);
    assert_eq!(r.events(), [DriveEvent::Cleared { code: 0x0800 }]);
    assert_eq!(r.sw() & 0x0800, 0);
    assert!(r.until_target_reached(5000));
    // A relative move past 2³¹: position overflow. Homing method 35 puts the position at
    // the home offset, near the top of the range.
    r.w32(0x607D, 1, 0);
    r.w32(0x607D, 2, 0);
    r.w32(0x607C, 0, 2_100_000_000);
    r.w8(0x6098, 0, 35);
    r.w8(0x6060, 0, 6);
    r.run_ms(5);
    r.cw(0x001F);
    r.run_ms(20);
    assert_ne!(r.sw() & 0x1000, 0, "homing attained");
    // Within the encoder's resolution (one increment = one unit).
    assert!(
        (r.position() - 2_100_000_000).abs() <= 1,
        "{}",
        r.position()
    );
    r.cw(0x000F);
    r.w8(0x6060, 0, 1);
    r.run_ms(5);
    r.w32(0x607A, 0, 100_000_000);
    start(&mut r, 0x5F);
    assert_eq!(
        r.events(),
        [DriveEvent::Error {
            code: 0x1000,
            register: 0x01
        }]
    );
    assert_ne!(r.sw() & 0x0800, 0);
}

/// §4.1: a target outside the position range limit 607Bh wraps round inside
/// [min, max] ("controlled overflow") and sets bit 11.
#[test]
fn range_limit_wraps_the_target_with_bit_11() {
    let mut r = Rig::new();
    pp(&mut r);
    r.w32(0x607B, 1, 0);
    r.w32(0x607B, 2, 3999);
    r.w32(0x607A, 0, 5000); // 5000 − 4000 = 1000
    start(&mut r, 0x1F);
    assert!(r.until_target_reached(5000));
    assert!(
        (r.position() - 1000).abs() <= 10,
        "wrapped to {}",
        r.position()
    );
    assert_ne!(r.sw() & 0x0800, 0, "bit 11 after a wrap");
    r.w32(0x607A, 0, 2000);
    start(&mut r, 0x1F);
    assert_eq!(r.sw() & 0x0800, 0, "a target inside clears bit 11");
}

/// §4.2 bit 9: a queued job with change on set-point follows without braking at the first
/// target; without bit 9 the drive stops there first.
#[test]
fn change_on_set_point_passes_the_first_target_at_speed() {
    let speed_at_first_target = |bit9: u16| {
        let mut r = Rig::new();
        pp(&mut r);
        r.w32(0x6081, 0, 4000);
        r.w32(0x6083, 0, 40_000);
        r.w32(0x6084, 0, 40_000);
        r.w32(0x607A, 0, 4000);
        r.cw(0x001F);
        r.cw(0x000F);
        r.run_ms(50);
        r.w32(0x607A, 0, 8000);
        r.cw(0x001F | bit9);
        r.cw(0x000F | bit9);
        // The slowest the set-point gets between the two targets.
        let mut slowest = f64::MAX;
        let mut last = r.i(0x6062, 0);
        for _ in 0..1000 {
            r.run_ms(5);
            let p = r.i(0x6062, 0);
            if (3000..5000).contains(&p) {
                slowest = slowest.min((p - last) as f64 / 0.005);
            }
            last = p;
        }
        assert!((r.position() - 8000).abs() <= 10, "at {}", r.position());
        slowest
    };
    let on_the_fly = speed_at_first_target(0x0200);
    let stopping = speed_at_first_target(0);
    assert!(
        on_the_fly > 3000.0,
        "bit 9: {on_the_fly} units/s at the first target"
    );
    assert!(
        stopping < 500.0,
        "no bit 9: {stopping} units/s at the first target"
    );
}
