//! The Nanotec closed-loop set-up (Nanotec §11.2): the long test run (6060h = −1) fills the
//! load-angle curve 200Ch and its readings 2012h / 2013h / 2018h; the short one (−2) finds the
//! encoder offset 200Bh once and, with 2001h = 3, enables the closed loop (200Ah = 1).

mod nanotec_rig;

use drive::stepper::StepperMode;
use drive::vendors::nanotec::STEPPER_LOAD_ANGLES;
use nanotec_rig::Rig;

fn run(r: &mut Rig, mode: i8, ms: u64) {
    r.w8(0x6060, 0, mode);
    r.run_ms(5);
    r.cw(0x001F);
    r.run_ms(ms);
}

#[test]
fn long_test_run_measures_the_load_angle_curve() {
    let mut r = Rig::new();
    r.enable();
    assert_eq!(r.i(0x2013, 1), 0, "nothing measured yet");
    run(&mut r, -1, 1000);
    assert_eq!(r.sw() & 0x0400, 0, "still running");
    r.run_ms(1100);
    assert_ne!(r.sw() & 0x0400, 0, "done");
    for (n, angle) in (1u8..).zip(STEPPER_LOAD_ANGLES) {
        assert_eq!(r.i(0x200C, n), i64::from(angle), "200Ch:{n}");
        assert_eq!(r.i(0x2013, n), i64::from(angle), "2013h:{n}");
        // 2004h:08 = 4096: support points 500 min⁻¹ apart.
        assert_eq!(r.i(0x2018, n), 500 * i64::from(n - 1), "2018h:{n}");
    }
}

#[test]
fn short_test_run_aligns_once_and_enables_the_closed_loop() {
    let mut r = Rig::new();
    r.w8(0x2001, 0, 3);
    r.run_ms(2);
    assert_eq!(r.i(0x200A, 0), 0, "2001h = 3 waits for the short test run");
    r.enable();
    run(&mut r, -2, 600);
    assert_ne!(r.sw() & 0x0400, 0, "done");
    let offset = r.i(0x200B, 0);
    assert_ne!(offset, 0, "200Bh found");
    assert_eq!(r.i(0x200A, 0), 1, "closed loop enabled");
    assert_eq!(r.d.stepper().unwrap().mode(), StepperMode::ClosedLoop);
    // A second run keeps the offset: it is determined only while 200Bh is 0.
    r.w16(0x200B, 0, 1234);
    r.cw(0x000F);
    r.cw(0x001F);
    r.run_ms(600);
    assert_eq!(r.i(0x200B, 0), 1234);
}

#[test]
fn bit_4_low_aborts_a_test_run() {
    let mut r = Rig::new();
    r.enable();
    run(&mut r, -2, 100);
    r.cw(0x000F);
    r.run_ms(1000);
    assert_eq!(r.i(0x200B, 0), 0, "aborted: nothing found");
}
