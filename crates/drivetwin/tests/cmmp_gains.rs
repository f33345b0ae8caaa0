//! Controller time constants written over SDO change the controller the drive runs, as the CMMP-AS
//! manual scales them (the vector catalogue kept beside the project, §1.12): 60F6h:02 and
//! 60F9h:02 are the reset (integral) times of the current and speed controllers in µs.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use drive::control::Gains;

#[path = "support/can_bench.rs"]
mod can_bench;

use can_bench::CanBench as Bench;

fn write_u16(b: &mut Bench, index: u16, sub: u8, value: u16) {
    let answer = b.write(index, sub, &value.to_le_bytes());
    assert_eq!(
        answer[0], 0x60,
        "{index:04X}h:{sub:02X} = {value}: {answer:02X?}"
    );
}

/// The integral gain per sample a reset time gives: Kp · T / Tn.
fn integral(kp: f64, dt: f64, tn_s: f64) -> f64 {
    kp * dt / tn_s
}

fn gains(b: &mut Bench) -> Gains {
    *b.drive().axis().gains()
}

/// CMMP-GAIN-02: current-controller time constant 0.6 ms is 60F6h:02 = 600 (µs); written over
/// SDO, the current controller integrates with Kp·T/0.6 ms, and twice the time halves it.
#[test]
fn cmmp_gain_02_current_time_written_over_sdo() {
    let mut b = Bench::new(None);
    write_u16(&mut b, 0x60F6, 2, 600);
    b.run_ms(2);
    let g = gains(&mut b);
    assert!((g.cur_ki - integral(g.cur_kp, g.dt, 600e-6)).abs() < 1e-9 * g.cur_ki.abs().max(1.0));
    write_u16(&mut b, 0x60F6, 2, 1200);
    b.run_ms(2);
    let g2 = gains(&mut b);
    assert!(
        (g2.cur_ki - g.cur_ki / 2.0).abs() < 1e-9 * g.cur_ki.abs().max(1.0),
        "{g2:?}"
    );
    assert_eq!(b.read(0x60F6, 2), 1200);
}

/// CMMP-GAIN-04: speed-controller time constant 2.0 ms is 60F9h:02 = 2000 (µs); written over
/// SDO, the speed controller integrates with Kp·T_vel/2 ms, and 4 ms halves it.
#[test]
fn cmmp_gain_04_velocity_time_written_over_sdo() {
    let mut b = Bench::new(None);
    write_u16(&mut b, 0x60F9, 2, 2000);
    b.run_ms(2);
    let g = gains(&mut b);
    let dt_vel = g.dt * f64::from(g.vel_every);
    assert!((g.vel_ki - integral(g.vel_kp, dt_vel, 2e-3)).abs() < 1e-9 * g.vel_ki.abs().max(1.0));
    write_u16(&mut b, 0x60F9, 2, 4000);
    b.run_ms(2);
    let g2 = gains(&mut b);
    assert!(
        (g2.vel_ki - g.vel_ki / 2.0).abs() < 1e-9 * g.vel_ki.abs().max(1.0),
        "{g2:?}"
    );
}
