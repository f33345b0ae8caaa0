//! The drive's own supervision of its plant's physics: the motor and power-stage
//! temperatures of [`crate::thermal`] and the encoder of [`crate::encoder_fault`]. Each
//! drive raises its manual's message for what it finds, as its device file names it
//! (`[device.plant]`, [`od::PlantSupervision`]), through the same path as every other message
//! (reaction, EMCY, 1003h, display):
//!
//! | condition                                      | key of `[device.plant]` |
//! |------------------------------------------------|-------------------------|
//! | motor within [`WARNING_MARGIN_K`] of its limit | `motor_warning`         |
//! | motor above its limit                          | `motor_over`            |
//! | power stage above its limit                    | `stage_over`            |
//! | encoder signal lost                            | `encoder_lost`          |
//! | implausible encoder counts                     | `encoder_implausible`   |
//!
//! The device file names the messages, the objects holding the limits and those showing the
//! temperatures. Where a manual has no limit object the limit is CHOSEN
//! ([`CHOSEN_MOTOR_LIMIT_C`], [`CHOSEN_STAGE_LIMIT_C`]).
//!
//! A cause stays while its condition does and goes [`HYSTERESIS_K`] below the limit (CHOSEN,
//! so a temperature at the limit does not chatter); an error then waits for the fault reset
//! as any other. A message raised by its number from outside is not touched.

use od::{Diagnostic, PlantSupervision, Value};

use super::diagnostics::emcy_code;
use super::Drive;
use crate::encoder_fault::{Encoder, EncoderFault};
use crate::personality::Vendor;
use crate::thermal::{self, Thermal};

/// Decision (CHOSEN): the motor limit of a drive without a limit object, °C.
pub const CHOSEN_MOTOR_LIMIT_C: f64 = 100.0;
/// Decision (CHOSEN): the power-stage limit of a drive without a limit object, °C.
pub const CHOSEN_STAGE_LIMIT_C: f64 = 90.0;
/// Decision (CHOSEN): a cause goes this far below its limit, K.
pub const HYSTERESIS_K: f64 = 2.0;
/// The motor warning comes this far below the motor's limit, K.
pub const WARNING_MARGIN_K: f64 = 5.0;

/// A condition the supervision watches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
enum Condition {
    MotorWarning = 0,
    MotorOver = 1,
    StageOver = 2,
    EncoderLost = 3,
    EncoderImplausible = 4,
}

impl Condition {
    /// The message the device file names for it.
    fn message(self, plant: &PlantSupervision) -> Option<&'static str> {
        match self {
            Condition::MotorWarning => plant.motor_warning,
            Condition::MotorOver => plant.motor_over,
            Condition::StageOver => plant.stage_over,
            Condition::EncoderLost => plant.encoder_lost,
            Condition::EncoderImplausible => plant.encoder_implausible,
        }
    }
}

const CONDITIONS: [Condition; 5] = [
    Condition::MotorWarning,
    Condition::MotorOver,
    Condition::StageOver,
    Condition::EncoderLost,
    Condition::EncoderImplausible,
];

/// The plant's temperatures and encoder, and what the supervision has raised from them.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlantWatch {
    pub thermal: Thermal,
    pub encoder: Encoder,
    /// Bit n: condition n raised by the supervision (not yet gone).
    pub(crate) raised: u8,
    /// The whole degrees last shown (motor, stage), so the objects are written on a change.
    pub(crate) shown: Option<(i16, i16)>,
    /// Limits read once from read-only objects (CMMO-ST PNU 1068), °C.
    pub(crate) limits: Option<(f64, f64)>,
    /// Time (s) and ∫(I / I_rated)² dt since the last thermal step.
    pub(crate) pending: (f64, f64),
}

/// The thermal model and the temperature supervision step every 10 ms with the mean load
/// of the cycles between: the time constants are seconds, and a step every cycle cost the
/// drive step 2 % of its time. The encoder is read every cycle while it is faulted.
const THERMAL_PERIOD_S: f64 = 0.010;

impl PlantWatch {
    /// Adds one cycle of `dt` s at `load` ((I / I_rated)², [`thermal::load`]) and steps the
    /// thermal model with the mean load once [`THERMAL_PERIOD_S`] has gathered, or at once
    /// with `now`; true when it stepped, and the supervision is due.
    pub(crate) fn heat(&mut self, dt: f64, load: f64, now: bool) -> bool {
        self.pending.0 += dt;
        self.pending.1 += load * dt;
        if !now && self.pending.0 < THERMAL_PERIOD_S {
            return false;
        }
        let (elapsed, load_dt) = core::mem::take(&mut self.pending);
        if elapsed > 0.0 {
            self.thermal.step(elapsed, load_dt / elapsed);
        }
        true
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// The plant's temperatures and encoder.
    pub fn plant_watch(&self) -> &PlantWatch {
        &self.plant_watch
    }

    /// The ambient temperature of the drive and its motor, °C.
    pub fn set_ambient_temperature(&mut self, celsius: f64) {
        self.plant_watch.thermal.set_ambient_c(celsius);
    }

    /// The thermal figures (time constants, rises) of the motor and the power stage.
    pub fn set_thermal_data(&mut self, data: thermal::ThermalData) {
        self.plant_watch.thermal.set_data(data);
    }

    /// Faults the encoder (or repairs it).
    pub fn set_encoder_fault(&mut self, fault: EncoderFault) {
        self.plant_watch.encoder.set_fault(fault);
    }

    /// One logic cycle of `dt` s: the temperatures follow the motor current, the encoder
    /// takes its reading, the supervision compares them with its limits.
    pub(super) fn supervise_plant(&mut self, dt: f64) {
        let (current, rated) = match &self.stepper {
            Some(s) => (s.motor.current_a(), s.motor.data().rated_current),
            None => (
                self.axis.motor().current(),
                self.axis.motor().data().rated_current,
            ),
        };
        let faulted = self.plant_watch.encoder.fault() != EncoderFault::Connected;
        if faulted {
            // A connected encoder reads true (its error is 0 since it was connected).
            let shaft = self.shaft_position();
            self.plant_watch.encoder.update(shaft);
        }
        let w = &mut self.plant_watch;
        // Every cycle while a condition is raised or the encoder faulted, and at the first.
        let now = faulted || w.raised != 0 || w.shown.is_none();
        if !w.heat(dt, thermal::load(current, rated), now) {
            return;
        }
        self.show_temperatures();
        let (motor_limit, stage_limit) = self.temperature_limits();
        let motor = self.plant_watch.thermal.motor_c();
        let stage = self.plant_watch.thermal.stage_c();
        let encoder = self.plant_watch.encoder;
        for c in CONDITIONS {
            let raised = self.plant_watch.raised & (1 << c as u8) != 0;
            let over = |t: f64, limit: f64| {
                if raised {
                    t > limit - HYSTERESIS_K
                } else {
                    t > limit
                }
            };
            let present = match c {
                Condition::MotorWarning => over(motor, motor_limit - WARNING_MARGIN_K),
                Condition::MotorOver => over(motor, motor_limit),
                Condition::StageOver => over(stage, stage_limit),
                Condition::EncoderLost => encoder.signal_lost(),
                Condition::EncoderImplausible => encoder.implausible(),
            };
            if present != raised {
                self.plant_condition(c, present);
            }
        }
    }

    /// The motor's and the power stage's limit, °C.
    fn temperature_limits(&self) -> (f64, f64) {
        let plant = &self.od.description().plant;
        let limit = |object: Option<(u16, u8)>, chosen: f64| match object {
            Some((i, s)) => self.described_value(i, s) as f64,
            None => chosen,
        };
        (
            limit(plant.motor_limit, CHOSEN_MOTOR_LIMIT_C),
            limit(plant.stage_limit, CHOSEN_STAGE_LIMIT_C),
        )
    }

    /// The temperatures in the drive's objects, when a whole degree changes.
    fn show_temperatures(&mut self) {
        let t = &self.plant_watch.thermal;
        let degrees = |c: f64| crate::rounding::round(c).clamp(-32768.0, 32767.0) as i16;
        let now = (degrees(t.motor_c()), degrees(t.stage_c()));
        if self.plant_watch.shown == Some(now) {
            return;
        }
        self.plant_watch.shown = Some(now);
        let (motor, stage) = now;
        let plant = &self.od.description().plant;
        if let Some((i, sub)) = plant.motor_temperature {
            let _ = self.od.set_value(i, sub, Value::Signed(motor.into()));
        }
        if let Some((i, sub)) = plant.stage_temperature {
            let _ = self.od.set_value(i, sub, Value::Signed(stage.into()));
        }
    }

    /// Condition `c` has come (`present`) or gone: its message raised or its cause ended.
    fn plant_condition(&mut self, c: Condition, present: bool) {
        let bit = 1u8 << c as u8;
        if present {
            self.plant_watch.raised |= bit;
        } else {
            self.plant_watch.raised &= !bit;
        }
        let plant = &self.od.description().plant;
        let Some(number) = c.message(plant) else {
            return;
        };
        let Some(row) = self.od.description().diagnostic(number) else {
            return;
        };
        // Two conditions may share a message (CMMP-AS 08-0): it goes when both have.
        let shared = CONDITIONS.iter().any(|o| {
            *o != c
                && self.plant_watch.raised & (1 << *o as u8) != 0
                && o.message(plant) == Some(number)
        });
        if present {
            if !shared {
                self.raise_row(row);
            }
        } else if !shared {
            self.end_row(row);
        }
    }

    /// Message `row` raised by the drive's own supervision: the personality's reaction, and
    /// an error stays a cause (it blocks the fault reset) until [`Drive::end_row`].
    pub(crate) fn raise_row(&mut self, row: &'static Diagnostic) {
        let code = emcy_code(row);
        let r = V::message_reaction(self, row, false);
        self.report_error(code, row.register, r);
        if (self.faults.contains(&code) || self.notices.contains(&code))
            && !self.causes.contains(&code)
        {
            let _ = self.causes.push(code);
        }
    }

    /// The cause of message `row` has gone: a warning or an EMCY-only message ends, an error
    /// waits for the fault reset. A message also raised by its number stays.
    pub(crate) fn end_row(&mut self, row: &'static Diagnostic) {
        let code = emcy_code(row);
        if self.injected_code(code) {
            return;
        }
        if let Some(i) = self.causes.iter().position(|c| *c == code) {
            self.causes.remove(i);
        }
        V::message_cleared(self, row);
        self.clear_notice(code);
    }
}

/// An encoder fault from its name: `ok` / `connected`, `disconnected`, `noisy` (with an
/// amplitude in internal increments).
pub fn encoder_fault(name: &str, amplitude: u32) -> Option<EncoderFault> {
    Some(match name {
        "ok" | "connected" => EncoderFault::Connected,
        "disconnected" | "broken" => EncoderFault::Disconnected,
        "noisy" => EncoderFault::Noisy { amplitude },
        _ => return None,
    })
}
