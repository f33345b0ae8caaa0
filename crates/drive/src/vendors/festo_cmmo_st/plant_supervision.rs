//! The CMMO-ST's own supervision of its plant's physics: the output stage's temperature
//! ([`crate::thermal`], heated by the stepper's phase current) and the encoder
//! ([`crate::encoder_fault`]), raising the messages of App. D:
//!
//! | condition                                  | App. D |
//! |--------------------------------------------|--------|
//! | output stage within 5 K of its maximum     | 33h Output stage temperature warning |
//! | output stage above PNU 1068:2 (maximum)    | 15h Output stage temperature exceeded |
//! | output stage below PNU 1068:1 (minimum)    | 16h Output stage temperature too low |
//! | encoder signal lost / implausible counts   | 06h Encoder (measuring system) |
//!
//! The messages, the objects holding the limits and the one showing the output stage's
//! temperature are the device file's (`[device.plant]`: 33h, 15h, 16h, 06h, PNU 1068:1 / :2,
//! PNU 1066); a condition without a message is not supervised. The limits' values are the
//! device file's CHOSEN ones (the manual prints none); without an object the drive model's own
//! (−10 °C, 85 °C). The warning margin of 5 K is CHOSEN (App. D: "warning clears when below
//! the threshold", no threshold printed). 15h and 16h are "ackable only once the temperature
//! is back in range" (AfterCause): the cause ends [`HYSTERESIS_K`] inside the range. The
//! CMMO-ST has no motor temperature sensor; the motor temperature is simulated (and shown by
//! the console) but not supervised.

use super::device::FhppDevice;
use super::diagnostics;
use crate::drive::plant_supervision::HYSTERESIS_K;
use crate::encoder_fault::EncoderFault;
use crate::thermal::{self, ThermalData};

/// Decision (CHOSEN): the stage warning comes 5 K below the stage's limit.
const WARNING_MARGIN_K: f64 = 5.0;
/// The drive model's own limits of the output stage, °C, where the device file names no object.
const STAGE_LIMITS_C: (f64, f64) = (-10.0, 85.0);

/// A condition of the supervision, in bit order of `PlantWatch::raised`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Condition {
    StageWarning,
    StageOver,
    StageUnder,
    EncoderLost,
    EncoderImplausible,
}

const CONDITIONS: [Condition; 5] = [
    Condition::StageWarning,
    Condition::StageOver,
    Condition::StageUnder,
    Condition::EncoderLost,
    Condition::EncoderImplausible,
];

impl Condition {
    /// Its message in the device file (`None`: not supervised).
    fn message(self, plant: &od::PlantSupervision) -> Option<&'static str> {
        match self {
            Condition::StageWarning => plant.stage_warning,
            Condition::StageOver => plant.stage_over,
            Condition::StageUnder => plant.stage_under,
            Condition::EncoderLost => plant.encoder_lost,
            Condition::EncoderImplausible => plant.encoder_implausible,
        }
    }
}

/// Whether a condition of `raised` other than `bit` has the message `message` (two conditions
/// may share one: the encoder's 06h).
fn shared(plant: &od::PlantSupervision, raised: u8, bit: usize, message: &str) -> bool {
    CONDITIONS
        .iter()
        .enumerate()
        .any(|(b, c)| b != bit && raised & (1 << b) != 0 && c.message(plant) == Some(message))
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> FhppDevice<S> {
    /// The plant's temperatures and encoder.
    pub fn plant_watch(&self) -> &crate::drive::plant_supervision::PlantWatch {
        &self.plant_watch
    }

    /// The ambient temperature, °C.
    pub fn set_ambient_temperature(&mut self, celsius: f64) {
        self.plant_watch.thermal.set_ambient_c(celsius);
    }

    /// The thermal figures of the motor and the output stage.
    pub fn set_thermal_data(&mut self, data: ThermalData) {
        self.plant_watch.thermal.set_data(data);
    }

    /// Faults the encoder (or repairs it).
    pub fn set_encoder_fault(&mut self, fault: EncoderFault) {
        self.plant_watch.encoder.set_fault(fault);
    }

    /// One cycle of `dt` s (see the module doc).
    pub(super) fn supervise_plant(&mut self, dt: f64) {
        let plant = self.od().description().plant;
        let stepper = self.stepper();
        let load = thermal::load(stepper.current_a(), stepper.data().rated_current);
        let shaft = stepper.encoder_increments();
        let w = &mut self.plant_watch;
        w.heat(dt, load, true);
        w.encoder.update(shaft);
        let stage = w.thermal.stage_c();
        let shown = crate::rounding::round(stage).clamp(-128.0, 127.0) as i8;
        if w.shown.map(|(_, s)| s) != Some(i16::from(shown)) {
            w.shown = Some((0, i16::from(shown)));
            if let Some((index, sub)) = plant.stage_temperature {
                let _ = self
                    .od_mut()
                    .set_value(index, sub, od::Value::Signed(i64::from(shown)));
            }
        }
        let (low, high) = match self.plant_watch.limits {
            Some(l) => l,
            None => {
                // PNU 1068 is read-only: read once.
                let limit = |object: Option<(u16, u8)>, default: f64| match object
                    .and_then(|(index, sub)| self.od().value(index, sub))
                {
                    Some(od::Value::Signed(v)) => v as f64,
                    Some(od::Value::Unsigned(v)) => v as f64,
                    _ => default,
                };
                let l = (
                    limit(plant.stage_low_limit, STAGE_LIMITS_C.0),
                    limit(plant.stage_limit, STAGE_LIMITS_C.1),
                );
                self.plant_watch.limits = Some(l);
                l
            }
        };
        let encoder = self.plant_watch.encoder;
        for (bit, condition) in CONDITIONS.iter().enumerate() {
            let Some(message) = condition.message(&plant) else {
                continue;
            };
            let raised = self.plant_watch.raised & (1 << bit) != 0;
            let h = if raised { HYSTERESIS_K } else { 0.0 };
            let present = match condition {
                Condition::StageWarning => stage > high - WARNING_MARGIN_K - h,
                Condition::StageOver => stage > high - h,
                Condition::StageUnder => stage < low + h,
                Condition::EncoderLost => encoder.signal_lost(),
                Condition::EncoderImplausible => encoder.implausible(),
            };
            if present == raised {
                continue;
            }
            let others = shared(&plant, self.plant_watch.raised, bit, message);
            if present {
                self.plant_watch.raised |= 1 << bit;
            } else {
                self.plant_watch.raised &= !(1 << bit);
            }
            // Checked when building: the message is a row of the table, an App. D number.
            let (false, Some(code)) = (others, diagnostics::number(message)) else {
                continue;
            };
            if present {
                self.fault(code);
            } else {
                self.clear_fault(code);
            }
        }
    }
}
