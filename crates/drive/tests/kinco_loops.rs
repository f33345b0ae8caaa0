//! The Kinco loop objects as the controller's gains (manual ch. 7 §7.3, Tab. 7-3 / 7-4,
//! L1846-1905 of its text kept beside the project; crates/drive/src/vendors/kinco/loops.rs):
//! written over SDO, they change the loop as the manual's units say — Kpp in 0.01 Hz sets the
//! following error v / (2π · Kpp / 100), K_Velocity_FF‰ takes it away, Velocity_BW × the inertia
//! ratio sets the velocity loop's bandwidth, Kvi removes a load's speed error.

mod kinco_rig;

use kinco_rig::{dec_rpm, Rig, INC_PER_REV};

/// An SDO download of `len` bytes (1, 2, 4) of `v` to `index:sub`; the answer is 60h.
fn sdo_write(r: &mut Rig, index: u16, sub: u8, v: i64, len: usize) {
    let cs = match len {
        1 => 0x2F,
        2 => 0x2B,
        _ => 0x23,
    };
    let [i0, i1] = index.to_le_bytes();
    let d = (v as u32).to_le_bytes();
    let answer = r.sdo(&[cs, i0, i1, sub, d[0], d[1], d[2], d[3]]);
    assert_eq!(
        answer.first(),
        Some(&0x60),
        "{index:04X}h:{sub:02X}: {answer:02X?}"
    );
}

/// The following error |Pos_Error 60FBh:08| while a long relative move runs at 600 rpm.
fn following_error(r: &mut Rig) -> f64 {
    r.w32(0x607A, 0, 50 * INC_PER_REV);
    r.cw(0x4F);
    r.cw(0x5F);
    r.run_ms(300);
    let mut sum = 0.0;
    for _ in 0..100 {
        r.run_ms(1);
        sum += r.i(0x60FB, 0x08) as f64;
    }
    (sum / 100.0).abs()
}

/// A drive in mode 1 with Profile_Speed 600 rpm (100 000 inc/s).
fn in_mode_1() -> Rig {
    let mut r = Rig::new();
    r.enable_in(1);
    r
}

/// Kpp 60FBh:01 in 0.01 Hz: without feed-forward the following error at 100 000 inc/s is
/// v / (2π · Kpp / 100): 1592 inc at Kpp 1000 (10 Hz), 796 at 2000 written over SDO.
#[test]
fn kpp_sets_the_following_error() {
    let v = 600.0 / 60.0 * INC_PER_REV as f64;
    for kpp in [1000i64, 2000] {
        let mut r = in_mode_1();
        sdo_write(&mut r, 0x2FF0, 0x1A, 0, 2);
        sdo_write(&mut r, 0x60FB, 0x01, kpp, 2);
        let want = v / (2.0 * std::f64::consts::PI * kpp as f64 / 100.0);
        let e = following_error(&mut r);
        assert!(
            (e / want - 1.0).abs() < 0.1,
            "Kpp {kpp}: {e} inc, manual {want}"
        );
    }
}

/// K_Velocity_FF‰ 2FF0h:1A: 1000 (100 %) takes the following error away, 500 halves it.
#[test]
fn velocity_feed_forward_takes_the_following_error_away() {
    let mut errors = Vec::new();
    for ff in [0i64, 500, 1000] {
        let mut r = in_mode_1();
        sdo_write(&mut r, 0x2FF0, 0x1A, ff, 2);
        errors.push(following_error(&mut r));
    }
    let (none, half, full) = (errors[0], errors[1], errors[2]);
    assert!((half / none - 0.5).abs() < 0.1, "{half} against {none}");
    assert!(full.abs() < 0.05 * none, "{full} against {none}");
}

/// The time the speed takes to reach 63 % of a 300 rpm step in mode −3, ms.
fn rise_ms(r: &mut Rig) -> u32 {
    r.enable_in(-3);
    r.w32(0x60FF, 0, dec_rpm(300.0));
    for ms in 1..200 {
        r.run_ms(1);
        if r.rpm() >= 0.632 * 300.0 {
            return ms;
        }
    }
    200
}

/// Velocity_BW 2FF0h:0A sets Kvp[0] = Velocity_BW × Inertia_Ratio (Tab. 7-3); with the right
/// ratio (1.0: the twin's motor runs without load) the loop has that bandwidth: 20 Hz rises in
/// about 1 / (2π · 20 Hz) = 8 ms, 40 Hz in half of it. The wrong ratio 2.0 doubles Kvp and
/// with it the real bandwidth.
#[test]
fn velocity_bandwidth_by_the_inertia_ratio() {
    let rise = |ratio: i64, bw: i64| {
        let mut r = Rig::new();
        sdo_write(&mut r, 0x3040, 0x0B, ratio, 2);
        sdo_write(&mut r, 0x2FF0, 0x0A, bw, 2);
        assert_eq!(r.i(0x60F9, 0x01), bw * ratio, "Kvp[0]");
        rise_ms(&mut r)
    };
    let (slow, fast, wrong) = (rise(10, 20), rise(10, 40), rise(20, 20));
    assert!((6..=11).contains(&slow), "20 Hz: {slow} ms");
    let ratio = f64::from(slow) / f64::from(fast);
    assert!((1.6..=2.6).contains(&ratio), "{slow} / {fast} ms");
    assert_eq!(wrong, fast, "ratio 2.0 = twice the gain");
}

/// Kvi (the PI corner in Hz) removes the speed error a load torque leaves; Kvi_Mix 2FF0h:19
/// reads 32 × Kvi + Kvi/32, and writing it sets Kvi = 0 and Kvi/32 = the value (Tab. 7-3).
#[test]
fn kvi_removes_the_speed_error_under_load() {
    let error = |kvi_mix: i64| {
        let mut r = Rig::new();
        sdo_write(&mut r, 0x2FF0, 0x19, kvi_mix, 2);
        assert_eq!((r.i(0x60F9, 0x02), r.i(0x60F9, 0x07)), (0, kvi_mix));
        r.enable_in(-3);
        r.w32(0x60FF, 0, dec_rpm(300.0));
        r.d.axis_mut().motor_mut().set_load_torque(0.3);
        r.run_ms(1000);
        (r.rpm() - 300.0).abs()
    };
    let (without, with) = (error(0), error(320));
    assert!(with < 2.0, "Kvi_Mix 320 (10 Hz): {with} rpm off");
    assert!(without > 20.0, "Kvi 0: {without} rpm off");

    let mut r = Rig::new();
    sdo_write(&mut r, 0x60F9, 0x02, 5, 2);
    sdo_write(&mut r, 0x60F9, 0x07, 3, 2);
    assert_eq!(r.i(0x2FF0, 0x19), 163, "32 × 5 + 3");
}

/// Stiffness 3040h:08 (tn01) takes effect at once (§4.3.2): stiffness 20 sets Kpp 3334 and
/// Kvp = 120 Hz × Inertia_Ratio 3.0 (Tab. 7-2), and the following error drops to a third of
/// stiffness 12's.
#[test]
fn stiffness_sets_the_loop_from_the_table() {
    let mut r = in_mode_1();
    sdo_write(&mut r, 0x2FF0, 0x1A, 0, 2);
    let e12 = following_error(&mut r);
    let mut r = in_mode_1();
    sdo_write(&mut r, 0x2FF0, 0x1A, 0, 2);
    sdo_write(&mut r, 0x3040, 0x08, 20, 1);
    assert_eq!(r.i(0x60FB, 0x01), 3334);
    assert_eq!(r.i(0x2FF0, 0x0A), 120);
    assert_eq!(r.i(0x60F9, 0x01), 3600);
    let e20 = following_error(&mut r);
    let want = 1000.0 / 3334.0;
    assert!((e20 / e12 / want - 1.0).abs() < 0.1, "{e20} / {e12}");
}

/// Kvi_Sum_Limit 60F9h:08 bounds the velocity integrator (of 2¹⁵ = the current limit): at the
/// default the integral carries a load torque and the speed error goes; limited to 0 it
/// carries nothing and the error stays as without Kvi.
#[test]
fn kvi_sum_limit_bounds_the_integral() {
    let error = |limit: i64| {
        let mut r = Rig::new();
        sdo_write(&mut r, 0x2FF0, 0x19, 320, 2);
        sdo_write(&mut r, 0x60F9, 0x08, limit, 2);
        r.enable_in(-3);
        r.w32(0x60FF, 0, dec_rpm(300.0));
        r.d.axis_mut().motor_mut().set_load_torque(0.3);
        r.run_ms(1000);
        (r.rpm() - 300.0).abs()
    };
    let (free, none) = (error(32768), error(0));
    assert!(free < 2.0, "Kvi_Sum_Limit 2^15: {free} rpm off");
    assert!(none > 20.0, "Kvi_Sum_Limit 0: {none} rpm off");
}

/// Output_Filter_N 60F9h:15 low-passes the current set-point (f = −ln(1 − 1/N) / (2π ·
/// 62.5 µs): 20 Hz at N = 127), so a speed step rises later than unfiltered (N = 1).
#[test]
fn output_filter_slows_the_current_set_point() {
    let rise = |n: i64| {
        let mut r = Rig::new();
        sdo_write(&mut r, 0x60F9, 0x15, n, 1);
        rise_ms(&mut r)
    };
    let (plain, filtered) = (rise(1), rise(127));
    assert!(
        filtered >= plain + 3,
        "N = 1: {plain} ms, N = 127: {filtered} ms"
    );
}

/// The notch (Notch_On 60F9h:04 = 1, Notch_N 60F9h:03: 10 · N + 100 Hz) takes its frequency
/// out of the current set-point: against a 100 Hz load torque the velocity loop answers with
/// a 100 Hz current; with the notch on at 100 Hz (N = 0) that current is mostly gone, and a
/// notch at 1000 Hz (N = 90) leaves it as it was.
#[test]
fn the_notch_takes_its_frequency_out_of_the_current() {
    let ripple = |on: bool, n: i64| {
        let mut r = Rig::new();
        sdo_write(&mut r, 0x60F9, 0x03, n, 1);
        sdo_write(&mut r, 0x60F9, 0x04, i64::from(on), 1);
        r.enable_in(-3);
        r.w32(0x60FF, 0, dec_rpm(300.0));
        r.run_ms(300);
        let (mut lo, mut hi) = (f32::MAX, f32::MIN);
        // 100 Hz: ten load values a period, one per millisecond.
        for k in 0..300 {
            let t = f64::from(k) * 1e-3;
            let load = 0.2 * libm::sin(2.0 * std::f64::consts::PI * 100.0 * t);
            r.d.axis_mut().motor_mut().set_load_torque(load);
            r.run_ms(1);
            if k >= 100 {
                let i = r.d.axis().current_demand_ma() as f32;
                lo = lo.min(i);
                hi = hi.max(i);
            }
        }
        hi - lo
    };
    let (off, at_100, at_1000) = (ripple(false, 0), ripple(true, 0), ripple(true, 90));
    assert!(
        at_100 < 0.5 * off,
        "off {off} mA, notch at 100 Hz {at_100} mA"
    );
    assert!(
        (at_1000 - off).abs() < 0.15 * off,
        "off {off} mA, notch at 1000 Hz {at_1000} mA"
    );
}
