//! Nanotec homing (Nanotec ch. 5; the extract's §9 item 10): the methods of 6098h, the 6099h
//! speeds, 609Ah only when starting, the immediate speed change at the switch and the immediate
//! stop at the end, bit 4 low aborts, bits 12 / 13.

mod nanotec_rig;

use drive::drive::named_switches::NamedSwitch;
use drive::drive::DriveSettings;
use drive::travel::TravelSettings;
use drive::vendors::nanotec::NANOTEC;
use nanotec_rig::Rig;

/// The home switch cam of the default travel starts at 40 000 increments.
const CAM_LOW: i64 = 40_000;

fn homing(r: &mut Rig, method: i8) {
    r.enable();
    r.w8(0x6098, 0, method);
    r.w8(0x6060, 0, 6);
    r.run_ms(5);
}

/// The rig on a travel without the home switch cam: input 6 is what is forced.
fn rig_without_cam() -> Rig {
    Rig::with(DriveSettings {
        travel: TravelSettings {
            home_switch: None,
            ..TravelSettings::default()
        },
        ..DriveSettings::default()
    })
}

/// Homing with `method` started (controlword bit 4): the set-point's speed (6062h, units per
/// ms) every ms until the statusword shows one of `bits`, at most `ms` of them.
fn homing_speeds(r: &mut Rig, method: i8, ms: u32, bits: u16) -> Vec<i64> {
    homing(r, method);
    r.cw(0x001F);
    let mut last = r.i(0x6062, 0);
    let mut speeds = Vec::new();
    for _ in 0..ms {
        r.run_ms(1);
        let p = r.i(0x6062, 0);
        speeds.push(p - last);
        last = p;
        if r.sw() & bits != 0 {
            break;
        }
    }
    speeds
}

#[test]
fn the_methods_of_the_manual() {
    let mut methods: Vec<i8> = NANOTEC.homing_methods.iter().map(|(m, _)| *m).collect();
    methods.sort();
    assert_eq!(
        methods,
        [-7, -6, -5, -4, -3, -2, 19, 20, 21, 22, 33, 34, 35]
    );
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
    let speeds = homing_speeds(&mut r, 19, 3000, 0x1000);
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

/// Methods 33 / 34 (§5.3): at 6099h:02 to the index mark (a quarter revolution into every
/// revolution of the default travel), reverse, move off the mark, stop; the mark reads the
/// home offset.
#[test]
fn methods_33_and_34_reverse_off_the_index_mark() {
    const INDEX: i64 = 16_384;
    for (method, direction, mark) in [(33, 1, INDEX), (34, -1, INDEX - 65_536)] {
        let mut r = Rig::new();
        r.w32(0x607C, 0, 50);
        let speeds = homing_speeds(&mut r, method, 6000, 0x3000);
        assert_eq!(
            r.sw() & 0x3000,
            0x1000,
            "{method}: attained {:#06x}",
            r.sw()
        );
        // Out at 6099h:02 (500 units/s = 0.5 per ms), back the other way.
        let out: i64 = speeds.iter().filter(|s| s.signum() == direction).sum();
        let back = speeds.iter().position(|s| s.signum() == -direction);
        // 33: the mark is 500 units ahead; 34: 1500 units behind.
        assert!(
            out.abs() >= 490,
            "{method}: searched for the mark: {out} units"
        );
        assert!(
            speeds.len() > 900,
            "{method}: at 6099h:02, {} ms",
            speeds.len()
        );
        let back = back.expect("reversed at the mark");
        assert!(
            speeds[..back].iter().all(|s| s.signum() != -direction),
            "{method}: one way out"
        );
        // Stands on the far side of the mark as seen from the search: just off it.
        let at = r.d.plant_position();
        assert!(
            (at - mark) * direction <= 0 && (at - mark).abs() < 300,
            "{method}: off the mark {mark}: {at}"
        );
        assert!(
            (r.position() - 50).abs() <= 2,
            "{method}: home offset, {}",
            r.position()
        );
        let p = r.i(0x6062, 0);
        r.run_ms(100);
        assert_eq!(r.i(0x6062, 0), p, "{method}: stands");
    }
}

/// Method −2: clockwise until the shaft blocks on the end stop; the blocked position reads
/// the home offset.
#[test]
fn method_minus_2_homes_on_block() {
    let mut r = Rig::with(DriveSettings {
        travel: TravelSettings {
            positive_stop: Some(2 * 65536),
            ..TravelSettings::default()
        },
        ..DriveSettings::default()
    });
    r.w32(0x607C, 0, 100);
    homing(&mut r, -2);
    r.cw(0x001F);
    for _ in 0..100 {
        r.run_ms(50);
        if r.sw() & 0x3000 != 0 {
            break;
        }
    }
    assert_eq!(r.sw() & 0x3000, 0x1000, "attained: {:#06x}", r.sw());
    // At the stop, within one electrical period (4 full steps = 1311 increments): the open
    // loop's rotor settles in the nearest equilibrium of the held current vector.
    let at = r.d.plant_position();
    assert!(
        at <= 2 * 65536 && 2 * 65536 - at < 1311,
        "on the stop: {at}"
    );
    assert!(
        (r.position() - 100).abs() <= 2,
        "home offset: {}",
        r.position()
    );
}

/// Method −4: as 19 with the external I/O node's bit: 2010h:01 selects bit 3 of 2010h:02,
/// which the master sets (as an RPDO would) while the axis is beyond 3000 units.
#[test]
fn method_minus_4_uses_the_external_io_bit_2010h() {
    let mut r = Rig::new();
    r.w8(0x2010, 1, 3);
    homing(&mut r, -4);
    r.cw(0x001F);
    let mut sent = false;
    for _ in 0..3000 {
        r.run_ms(1);
        let on = r.i(0x6064, 0) >= 3000;
        if on != sent {
            r.w8(0x2010, 2, if on { 0x08 } else { 0x00 });
            sent = on;
        }
        if r.sw() & 0x3000 != 0 {
            break;
        }
    }
    assert_eq!(r.sw() & 0x3000, 0x1000, "attained: {:#06x}", r.sw());
    // The wired cam (from 1221 units) was passed over; the reference is the external edge.
    let at = r.d.plant_position() * 2000 / 65536;
    assert!((at - 3000).abs() < 30, "at the external switch: {at} units");
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

/// §9.1: the reference switch is input 6, in 60FDh bit 2 and bit 21; bit n of
/// `force_inputs` is input n, bits 16 … 21 show inputs 1 … 6.
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
    r.d.force_inputs(1 << 6, 0); // input 6 held low on the cam
    r.run_ms(2);
    assert_eq!(r.i(0x60FD, 0), 0, "the cam drives input 6, forced low");
}

/// Input 6 forced by name (`home`, as a cell file, the control handle or the REST API force
/// it) is what 60FDh shows in bits 2 and 21; the Nanotec has no limit-switch input (§9.1
/// names none), and the inputs past 6 show nothing.
#[test]
fn the_home_switch_by_name_is_input_6() {
    let mut r = rig_without_cam();
    let input = r.d.switch_input(NamedSwitch::Home).expect("input 6");
    assert_eq!((input.mask, input.actuated_high), (1 << 6, true));
    assert_eq!(r.d.switch_input(NamedSwitch::LimitPositive), None);
    assert_eq!(r.d.switch_input(NamedSwitch::LimitNegative), None);
    assert_eq!(r.d.set_switch(NamedSwitch::LimitPositive, Some(true)), None);
    r.d.set_switch(NamedSwitch::Home, Some(true));
    r.run_ms(2);
    assert_eq!(r.i(0x60FD, 0), (1 << 21) | (1 << 2));
    r.d.force_inputs(0xFF80, 0xFF80); // bits 7 … 15: no input of the manual's
    r.run_ms(2);
    assert_eq!(r.i(0x60FD, 0), 0);
}

/// Methods 19 … 22 watch input 6: forced HIGH by name while the axis is beyond 3000 units in
/// the method's search direction (19 / 22 clockwise, 20 / 21 counter-clockwise, §5.3), the
/// search turns there, crawls back until input 6 is LOW and reads the home offset at its edge.
/// The travel has no cam: the forced input alone is the switch.
#[test]
fn methods_19_to_22_home_on_input_6_forced() {
    for (method, direction) in [(19i8, 1i64), (20, -1), (21, -1), (22, 1)] {
        let mut r = rig_without_cam();
        homing(&mut r, method);
        r.cw(0x001F);
        let mut on = false;
        let mut seen_60fd = 0;
        for _ in 0..5000 {
            r.run_ms(1);
            let beyond = r.i(0x6064, 0) * direction >= 3000;
            if beyond != on {
                r.d.set_switch(NamedSwitch::Home, Some(beyond));
                on = beyond;
            }
            if on {
                seen_60fd |= r.i(0x60FD, 0);
            }
            if r.sw() & 0x3000 != 0 {
                break;
            }
        }
        assert_eq!(
            r.sw() & 0x3000,
            0x1000,
            "{method}: attained {:#06x}",
            r.sw()
        );
        assert_eq!(seen_60fd, (1 << 21) | (1 << 2), "{method}: 60FDh while on");
        let at = r.d.plant_position() * 2000 / 65536;
        assert!(
            (at - 3000 * direction).abs() < 30,
            "{method}: at input 6's edge: {at} units"
        );
        assert!(r.position().abs() <= 2, "{method}: {}", r.position());
    }
}
