//! Nanotec torque mode (Nanotec ch. 8; the extract's §9 item 9): only in closed loop (200Ah = 1),
//! the current from 6071h and 2004h:01, the speed limited by 607Fh, halt and statusword bit 10.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

mod nanotec_rig;

use nanotec_rig::Rig;

/// Closed loop on (2001h), Operation Enabled, torque mode.
fn torque(r: &mut Rig) {
    r.w8(0x2001, 0, 1);
    r.run_ms(2);
    assert_eq!(r.i(0x200A, 0), 1);
    r.enable();
    r.w8(0x6060, 0, 4);
    r.run_ms(5);
    assert_eq!(r.i(0x6061, 0), 4);
}

#[test]
fn torque_mode_needs_the_closed_loop() {
    let mut r = Rig::new();
    r.enable();
    assert_eq!(r.i(0x200A, 0), 0, "open loop");
    // 0800 0022h: present device state.
    assert_eq!(
        r.sdo(&[0x2F, 0x60, 0x60, 0x00, 0x04]),
        [0x80, 0x60, 0x60, 0x00, 0x22, 0x00, 0x00, 0x08]
    );
}

/// 6071h = 500 ‰ of 2004h:01 = 100 % of the 2 A motor: 1 A, 0.25 N·m; with no load the
/// motor runs up to the 607Fh limit of 300 min⁻¹ and stays there.
#[test]
fn torque_accelerates_to_the_607f_speed_limit() {
    let mut r = Rig::new();
    torque(&mut r);
    r.d.write_u8(0x2004, 1, 100);
    r.w32(0x607F, 0, 300);
    r.d.write_i16(0x6071, 500);
    // The unloaded rotor (2·10⁻⁵ kg·m²) reaches 300 min⁻¹ in about 2.5 ms.
    r.run_ms(1);
    let i = r.d.stepper().unwrap().current_a();
    assert!((i - 1.0).abs() < 0.1, "{i} A while accelerating");
    r.run_ms(2000);
    let rpm = f64::from(r.d.plant_velocity_rpm());
    assert!((270.0..=305.0).contains(&rpm), "{rpm} min⁻¹ at the limit");
    // Negative torque: the limit holds in the other direction too.
    r.d.write_i16(0x6071, -500);
    r.run_ms(3000);
    let rpm = f64::from(r.d.plant_velocity_rpm());
    assert!((-305.0..-270.0).contains(&rpm), "{rpm} min⁻¹");
}

/// Bit 10 with bit 8 (§8.3 table): set torque reached (1, 0); braking (0, 1); stopped (1, 1).
#[test]
fn halt_and_bit_10() {
    let mut r = Rig::new();
    torque(&mut r);
    r.w32(0x607F, 0, 3000);
    r.d.write_u8(0x2004, 1, 100);
    r.d.write_i16(0x6071, 100);
    r.run_ms(20);
    assert_ne!(r.sw() & 0x0400, 0, "set torque reached");
    r.cw(0x010F);
    r.run_ms(5);
    r.run_ms(2000);
    assert_ne!(r.sw() & 0x0400, 0, "stopped");
    assert!(f64::from(r.d.plant_velocity_rpm()).abs() < 1.0);
    r.cw(0x000F);
    r.run_ms(500);
    assert!(f64::from(r.d.plant_velocity_rpm()) > 10.0, "runs again");
}

trait Writes {
    fn write_u8(&mut self, index: u16, sub: u8, v: u8);
    fn write_i16(&mut self, index: u16, v: i16);
}

impl Writes for drive::drive::Drive<Vec<u8>, drive::vendors::nanotec::Nanotec> {
    fn write_u8(&mut self, index: u16, sub: u8, v: u8) {
        od::ObjectAccess::write(self, index, sub, &[v]).unwrap();
    }
    fn write_i16(&mut self, index: u16, v: i16) {
        od::ObjectAccess::write(self, index, 0, &v.to_le_bytes()).unwrap();
    }
}

/// Halt after a reversal, as a master sees it: once bit 10 shows "stopped" the motor stands
/// (no settling drift afterwards), here at the interop test's 607Fh = 120 min⁻¹.
#[test]
fn halt_reports_stopped_only_once_the_motor_stands() {
    let mut r = Rig::new();
    torque(&mut r);
    r.w32(0x607F, 0, 120);
    r.d.write_i16(0x6071, 300);
    r.run_ms(300);
    r.d.write_i16(0x6071, -300);
    r.run_ms(500);
    r.cw(0x010F);
    let mut waited = 0;
    while r.sw() & 0x0400 == 0 {
        r.run_ms(1);
        waited += 1;
        assert!(waited < 2000, "stopped within 2 s");
    }
    let a = r.i(0x6064, 0);
    for _ in 0..400 {
        r.run_ms(1);
        assert_ne!(r.sw() & 0x0400, 0, "stays stopped");
        // The closed loop holds the shaft where it stopped: no hunting against the detent
        // and the friction (the controller compensates the detent, stepper.rs).
        assert_eq!(r.i(0x6064, 0), a, "stands still after bit 10");
    }
}
