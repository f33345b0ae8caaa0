//! The CMMP-AS's own supervision of its plant's physics (`drive::drive::plant_supervision`):
//! a motor heated by its current raises 18-0 (warning) and then 03-0 (App. B), a hot power
//! stage 04-0, a pulled encoder cable 08-0, each with its reaction, EMCY and display.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use std::time::Duration;

use drive::device_control::State;
use drive::drive::{DriveEvent, DriveSettings};
use drive::encoder_fault::EncoderFault;
use drive::thermal::ThermalData;
use drive::vendors::festo_cmmp_as::display::Display;
use drive::vendors::festo_cmmp_as::messages::Number;
use od::{ObjectAccess, Value};

mod cmmp_rig;

use cmmp_rig::Rig;

impl Rig {
    fn quick() -> Self {
        let mut r = Rig::with(DriveSettings {
            mode_change_time: Duration::from_millis(2),
            ..DriveSettings::default()
        });
        // Seconds instead of minutes, so the test heats the motor in simulated seconds.
        r.d.set_thermal_data(ThermalData {
            motor_time_constant_s: 2.0,
            ..ThermalData::default()
        });
        r
    }
    /// The motor's own rated current in 6075h (the default 296 mA is a smaller motor's),
    /// 3 × of it as the peak.
    fn rated_motor(&mut self) {
        self.w32(0x6075, 0, 1300);
        self.d.write(0x6073, 0, &3000u16.to_le_bytes()).unwrap();
    }
    fn enable_velocity(&mut self, rpm: i32) {
        self.d.write(0x6060, 0, &[3]).unwrap();
        self.run_ms(10);
        self.cw(0x06);
        self.cw(0x07);
        self.cw(0x0F);
        assert_eq!(self.sw() & 0x6F, 0x27);
        self.w32(0x60FF, 0, i64::from(rpm));
    }
    fn signed(&self, index: u16, sub: u8) -> i64 {
        match self.d.od().value(index, sub).unwrap() {
            Value::Signed(s) => s,
            Value::Unsigned(u) => u as i64,
            v => panic!("{v:?}"),
        }
    }
    fn events(&mut self) -> Vec<DriveEvent> {
        std::iter::from_fn(|| self.d.take_event()).collect()
    }
    fn warning_active(&self) -> bool {
        self.sw() & 0x0080 != 0
    }
}

/// A blocked shaft at a hot ambient: the current heats the motor past 6510h:2F − 5 K (18-0,
/// a warning: statusword bit 7, the display, no fault) and then past 6510h:2F (03-0, EMCY
/// 4310h, quick stop into FAULT); the fault reset is refused until the motor has cooled.
#[test]
fn a_motor_heated_by_its_current_warns_then_faults_03_0() {
    let mut r = Rig::quick();
    assert_eq!(
        r.signed(0x6510, 0x2E),
        25,
        "6510h:2E shows the motor at ambient"
    );
    r.d.set_ambient_temperature(45.0);
    r.rated_motor();
    r.enable_velocity(1000);
    r.d.axis_mut().set_blocked(true);
    let mut warned_at = None;
    let mut faulted_at = None;
    for ms in 0..20_000u64 {
        r.run_ms(1);
        let t = r.d.plant_watch().thermal.motor_c();
        if warned_at.is_none() && r.warning_active() {
            assert!(t > 95.0 && t < 100.0, "18-0 within 5 K of 100 °C: {t}");
            assert_eq!(r.d.state(), State::OperationEnabled, "a warning only");
            assert_eq!(r.d.display(), Display::Warning(Number { main: 18, sub: 0 }));
            warned_at = Some(ms);
        }
        if r.d.errors().contains(&0x4310) {
            assert!(t > 100.0, "{t}");
            faulted_at = Some(ms);
            break;
        }
    }
    let (warned, faulted) = (warned_at.unwrap(), faulted_at.unwrap());
    assert!(
        warned < faulted,
        "the warning first: {warned} ms, {faulted} ms"
    );
    assert!(r.events().contains(&DriveEvent::Error {
        code: 0x4310,
        register: 0x08
    }));
    assert!(r.signed(0x6510, 0x2E) >= 100, "6510h:2E shows it");
    r.run_ms(100);
    assert_eq!(r.d.state(), State::Fault, "03-0: QStop, then FAULT");
    assert_eq!(r.d.display(), Display::Error(Number { main: 3, sub: 0 }));
    let memory =
        r.d.diagnostic_memory()
            .map(|e| e.number)
            .collect::<Vec<_>>();
    assert!(memory.contains(&Number { main: 3, sub: 0 }), "{memory:?}");
    // Still hot: the fault reset is refused.
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.d.state(), State::Fault);
    // Cooled in a 25 °C cabinet with the shaft free: the reset is taken.
    r.d.axis_mut().set_blocked(false);
    r.d.set_ambient_temperature(25.0);
    r.run_ms(10_000);
    assert!(r.d.plant_watch().thermal.motor_c() < 40.0);
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
    assert!(!r.warning_active(), "the warning ended with its cause");
}

/// 6510h:2F max_motor_temperature is the limit: lowered to 50 °C, a motor at rated current in a
/// 25 °C cabinet (settling at 85 °C) faults.
#[test]
fn the_motor_limit_is_6510h_2f() {
    let mut r = Rig::quick();
    r.d.write(0x6510, 0x2F, &50i16.to_le_bytes()).unwrap();
    r.rated_motor();
    r.enable_velocity(1000);
    r.d.axis_mut().set_blocked(true);
    r.run_ms(3000);
    assert!(r.d.errors().contains(&0x4310), "{:?}", r.d.errors());
}

/// A power stage hotter than 6510h:32 (a hot cabinet, output stage off): 04-0, EMCY 4210h.
#[test]
fn a_hot_power_stage_is_04_0() {
    let mut r = Rig::quick();
    assert_eq!(r.signed(0x6510, 0x32), 100);
    r.d.set_thermal_data(ThermalData {
        stage_time_constant_s: 1.0,
        ..ThermalData::default()
    });
    r.d.set_ambient_temperature(110.0);
    r.run_ms(5_000);
    assert!(r.signed(0x6510, 0x31) > 100);
    assert!(r.d.errors().contains(&0x4210), "{:?}", r.d.errors());
    assert!(r.events().contains(&DriveEvent::Error {
        code: 0x4210,
        register: 0x08
    }));
}

/// The encoder cable pulled while the motor turns: the reading stands still, 08-0 (EMCY 7380h)
/// stops the drive; with the cable back the fault reset is taken and the reading follows the
/// shaft again.
#[test]
fn a_pulled_encoder_cable_is_08_0() {
    let mut r = Rig::quick();
    r.enable_velocity(600);
    r.run_ms(500);
    r.d.set_encoder_fault(EncoderFault::Disconnected);
    r.run_ms(2);
    let frozen = r.signed(0x6063, 0);
    assert!(r.d.errors().contains(&0x7380), "{:?}", r.d.errors());
    assert!(
        r.events().contains(&DriveEvent::Error {
            code: 0x7380,
            register: 0x01
        }) || r.d.errors().contains(&0x7380)
    );
    r.run_ms(200);
    assert_eq!(r.d.state(), State::Fault);
    assert_eq!(r.d.display(), Display::Error(Number { main: 8, sub: 0 }));
    assert_eq!(r.signed(0x6063, 0), frozen, "no counts without the cable");
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.d.state(), State::Fault, "the cause is still there");
    r.d.set_encoder_fault(EncoderFault::Connected);
    r.run_ms(2);
    r.cw(0x00);
    r.cw(0x80);
    assert_eq!(r.d.state(), State::SwitchOnDisabled);
    assert_ne!(
        r.signed(0x6063, 0),
        frozen,
        "the reading follows the shaft again"
    );
}

/// Noise within the plausibility limit roughens the reading only; beyond it the drive calls
/// it 08-0 too.
#[test]
fn encoder_noise_beyond_plausibility_is_08_0() {
    let mut r = Rig::quick();
    r.d.set_encoder_fault(EncoderFault::Noisy { amplitude: 20 });
    let readings = (0..20)
        .map(|_| {
            r.run_ms(1);
            r.signed(0x6063, 0)
        })
        .collect::<Vec<_>>();
    assert!(readings.iter().any(|p| *p != readings[0]), "{readings:?}");
    assert!(readings.iter().all(|p| p.abs() <= 20), "{readings:?}");
    assert!(r.d.errors().is_empty());
    r.d.set_encoder_fault(EncoderFault::Noisy { amplitude: 5000 });
    r.run_ms(2);
    assert!(r.d.errors().contains(&0x7380), "{:?}", r.d.errors());
}
