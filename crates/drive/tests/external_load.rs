//! An external load stepped with the plant (`drive::drive::external_load`): it sees every
//! plant cycle, its torque brakes the shaft, its switch reaches the drive's input, and its
//! error ends the step.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use core::time::Duration;

use drive::drive::external_load::{ExternalLoad, LoadReaction, Shaft};
use drive::drive::named_switches::NamedSwitch;
use od::Instant;

mod cmmp_rig;

use cmmp_rig::Rig;

/// A load of constant torque that actuates the home switch from its `home_at` cycle on and
/// fails at its `fail_at` cycle.
struct Probe {
    cycles: u64,
    torque_nm: f64,
    home_at: u64,
    fail_at: u64,
    last: Option<(Instant, f64, Shaft)>,
}

impl ExternalLoad for Probe {
    type Error = u64;
    fn plant_step(&mut self, now: Instant, dt_s: f64, shaft: Shaft) -> Result<LoadReaction, u64> {
        if self.cycles == self.fail_at {
            return Err(self.cycles);
        }
        self.cycles += 1;
        self.last = Some((now, dt_s, shaft));
        let home = (self.cycles == self.home_at).then_some(true);
        Ok(LoadReaction {
            torque_nm: self.torque_nm,
            switches: [None, None, home],
        })
    }
}

fn probe() -> Probe {
    Probe {
        cycles: 0,
        torque_nm: 5.0,
        home_at: 10,
        fail_at: u64::MAX,
        last: None,
    }
}

#[test]
fn the_load_steps_with_every_plant_cycle_and_brakes_the_coasting_shaft() {
    let mut r = Rig::new();
    let mut load = probe();
    let end = r.now + Duration::from_millis(10);
    r.d.step_with_load(end, &mut load).unwrap();
    let (now, dt, _) = load.last.unwrap();
    assert!(load.cycles > 10, "{} cycles", load.cycles);
    assert!(now <= end);
    assert!(dt > 0.0);
    // 5 N·m against the holding brake's 2.5 N·m and the motor's friction, output stage off:
    // the shaft slips backwards.
    assert!(r.d.shaft().velocity_rad_s < 0.0, "{:?}", r.d.shaft());
}

#[test]
fn the_loads_switch_reaches_the_drives_input() {
    let mut r = Rig::new();
    let input = r.d.switch_input(NamedSwitch::Home).unwrap();
    let mut load = probe();
    r.d.step_with_load(r.now + Duration::from_millis(5), &mut load)
        .unwrap();
    let (mask, levels) = r.d.forced_inputs();
    assert_ne!(mask & input.mask, 0);
    assert_eq!(levels & input.mask != 0, input.actuated_high);
}

#[test]
fn an_error_of_the_load_ends_the_step_and_is_returned() {
    let mut r = Rig::new();
    let mut load = probe();
    load.fail_at = 3;
    let e =
        r.d.step_with_load(r.now + Duration::from_millis(5), &mut load)
            .unwrap_err();
    assert_eq!(e, 3);
}
