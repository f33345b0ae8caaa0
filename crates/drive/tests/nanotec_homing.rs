//! Nanotec homing (spec/nanotec-canopen.md §5.2, §9 item 10): the methods of 6098h, the
//! 6099h speeds, 609Ah only when starting, the immediate speed change at the switch and the
//! immediate stop at the end, bit 4 low aborts, bits 12 / 13.

mod nanotec_rig;

use drive::personality::nanotec::NANOTEC;
use nanotec_rig::Rig;

/// The home switch cam of the default travel starts at 40 000 increments.
const CAM_LOW: i64 = 40_000;

fn homing(r: &mut Rig, method: i8) {
    r.enable();
    r.w8(0x6098, 0, method);
    r.w8(0x6060, 0, 6);
    r.run_ms(5);
}

#[test]
fn the_methods_of_the_manual() {
    let mut methods: Vec<i8> = NANOTEC.homing_methods.iter().map(|(m, _)| *m).collect();
    methods.sort();
    assert_eq!(methods, [19, 20, 21, 22, 33, 34, 35]);
}

/// Method 35: the position becomes the home offset, the shaft does not move.
#[test]
fn method_35_sets_the_home_offset_without_moving() {
    let mut r = Rig::new();
    r.w32(0x607C, 0, 777);
    homing(&mut r, 35);
    let before = r.d.plant_position();
    r.cw(0x001F);
    r.run_ms(20);
    assert_eq!(r.sw() & 0x3000, 0x1000, "homing attained, no error");
    assert!((r.position() - 777).abs() <= 1, "{}", r.position());
    assert!((r.d.plant_position() - before).abs() < 100, "no motion");
}

/// Method 19: clockwise at 6099h:01 onto the switch, then counter-clockwise at 6099h:02
/// until it is free; the reversal is immediate (no 609Ah ramp), the stop at the end too.
#[test]
fn method_19_switch_reversal_is_immediate() {
    let mut r = Rig::new();
    homing(&mut r, 19);
    r.cw(0x001F);
    // Speeds of the set-point, units per ms, every ms.
    let mut last = r.i(0x6062, 0);
    let mut speeds = Vec::new();
    for _ in 0..3000 {
        r.run_ms(1);
        let p = r.i(0x6062, 0);
        speeds.push(p - last);
        last = p;
        if r.sw() & 0x1000 != 0 {
            break;
        }
    }
    assert_eq!(r.sw() & 0x3000, 0x1000, "attained: {:#06x}", r.sw());
    // Search 2000 units/s = 2 per ms, crawl 500 units/s = 0.5 per ms backwards.
    let search = speeds.iter().filter(|s| **s == 2).count();
    let crawl = speeds.iter().filter(|s| (-1..=0).contains(*s)).count();
    assert!(search > 100, "searched at 6099h:01: {speeds:?}");
    assert!(crawl > 10, "crawled back at 6099h:02");
    // Between the two: no ramp (609Ah = 4000 units/s² would take 600 ms).
    let turn = speeds.iter().rposition(|s| *s > 0).unwrap();
    assert!(
        speeds[turn + 1..].iter().all(|s| *s <= 0),
        "no positive speed after the turn"
    );
    assert!(
        speeds[turn] >= 1,
        "still at speed just before the switch: {}",
        speeds[turn]
    );
    // The reference is the cam's edge; the position there reads the home offset (0).
    assert!(r.position().abs() <= 2, "{}", r.position());
    let edge = r.d.plant_position();
    assert!((edge - CAM_LOW).abs() < 800, "at the cam edge: {edge}");
    // Stands.
    let p = r.i(0x6062, 0);
    r.run_ms(100);
    assert_eq!(r.i(0x6062, 0), p);
}

/// Bit 4 back to 0 aborts the search: neither attained nor error.
#[test]
fn bit_4_low_aborts() {
    let mut r = Rig::new();
    homing(&mut r, 20);
    r.cw(0x001F);
    r.run_ms(100);
    r.cw(0x000F);
    r.run_ms(100);
    assert_eq!(r.sw() & 0x3000, 0);
    let p = r.i(0x6062, 0);
    r.run_ms(100);
    assert_eq!(r.i(0x6062, 0), p, "stopped");
}

/// §5.8: the reference switch is input 6, in 60FDh bit 2 and bit 21.
#[test]
fn reference_switch_is_input_6_in_60fd() {
    let mut r = Rig::new();
    assert_eq!(r.i(0x60FD, 0), 0, "off the cam");
    r.enable_pp();
    r.w32(0x607A, 0, 2000); // 65 536 increments: on the cam (40 000 … 90 000)
    r.cw(0x001F);
    r.cw(0x000F);
    assert!(r.until_target_reached(5000));
    assert_eq!(r.i(0x60FD, 0), (1 << 21) | (1 << 2));
    r.d.force_inputs(1 << 1, 1 << 1); // input 1 high
    r.run_ms(2);
    assert_eq!(r.i(0x60FD, 0), (1 << 16) | (1 << 21) | (1 << 2));
}
