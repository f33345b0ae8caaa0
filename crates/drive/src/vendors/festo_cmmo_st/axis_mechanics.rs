//! The mechanics around the CMMO-ST's motor that homing looks for (§6.2, fhpp §5.3): the
//! fixed stops at the two ends of the stroke, the reference switch (a digital input of the
//! controller) and the index (zero) pulse of the encoder, once per motor revolution.
//!
//! Positions are in motor revolutions from the shaft angle at power-on (the plant's angle 0),
//! so they do not depend on the user scaling PNU 1001…1005. The stepper plant
//! ([`crate::stepper::Stepper::set_end_stops`]) makes the stops physical; the switch and the
//! index are read from the shaft angle here.
//!
//! Defaults (chosen so that every method of Tab. 6.2 works out of the box on the dictionary's
//! default axis, rotary, 36000 SINC = 1 revolution, search velocity 0.25 rev/s, and so that
//! the moves of a twin that had no stops before still fit):
//! - stops at −3 and +47 revolutions: a 50-revolution stroke (500 mm on a 10 mm-per-revolution
//!   spindle) with the power-on position 3 revolutions from its negative end (−17 finds it
//!   after 12 s, −18 after 188 s at the default search velocity);
//! - the reference switch a cam around the power-on position, −0.05 … +0.05 rev, so methods
//!   23 and 27 both start on it and leave it (CiA 402 "homing on home switch");
//! - the index pulse at 0.3 rev of every revolution: 33 finds it at −0.7 rev, 34 at +0.3 rev,
//!   and behind the switch edges it lies 0.65 rev (23) and 0.25 rev (27) away, far from 2Eh.

use core::f64::consts::TAU;

/// The axis mechanics of the simulation (no PNU holds them: FCT's "axis" page and the wiring).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisMechanics {
    /// Fixed stops (negative, positive end), motor revolutions; `None`: endless axis.
    pub end_stops: Option<(f64, f64)>,
    /// Reference switch active from … to …, motor revolutions (a cam); `None`: none fitted.
    pub reference_switch: Option<(f64, f64)>,
    /// Index pulse at this fraction of every motor revolution; `None`: an encoder without
    /// index track (or a broken one: homing on the index ends with 23h).
    pub index_pulse: Option<f64>,
}

impl Default for AxisMechanics {
    fn default() -> Self {
        AxisMechanics {
            end_stops: Some((-3.0, 47.0)),
            reference_switch: Some((-0.05, 0.05)),
            index_pulse: Some(0.3),
        }
    }
}

impl AxisMechanics {
    /// The end stops as shaft angles, rad.
    pub fn stops_rad(&self) -> Option<(f64, f64)> {
        self.end_stops.map(|(lo, hi)| (lo * TAU, hi * TAU))
    }

    /// Whether a switch is wired (methods 23 / 27 need one, Tab. 6.2).
    pub fn has_switch(&self) -> bool {
        self.reference_switch.is_some()
    }

    /// The reference switch input at shaft angle `angle` rad.
    pub fn switch_active(&self, angle: f64) -> bool {
        self.reference_switch.is_some_and(|(lo, hi)| {
            let rev = angle / TAU;
            lo <= rev && rev <= hi
        })
    }

    /// The index pulse passed while the shaft turned from `from` to `to` rad: its angle, rad.
    /// Moving either way, the pulse nearest `to` that lies between the two counts.
    pub fn index_crossed(&self, from: f64, to: f64) -> Option<f64> {
        let offset = self.index_pulse?;
        let a = libm::floor(from / TAU - offset);
        let b = libm::floor(to / TAU - offset);
        if a == b {
            return None;
        }
        // Positive: pulse n = ⌊b⌋ was passed; negative: pulse ⌊a⌋ was.
        let n = if b > a { b } else { a };
        Some((n + offset) * TAU)
    }

    /// Distance from `angle` rad to the next index pulse ahead in direction `dir` (±1), as a
    /// fraction of a revolution in [0, 1); `None` without an index.
    pub fn index_distance(&self, angle: f64, dir: f64) -> Option<f64> {
        let offset = self.index_pulse?;
        let x = angle / TAU - offset;
        let frac = x - libm::floor(x);
        Some(if dir >= 0.0 { (1.0 - frac) % 1.0 } else { frac })
    }
}
