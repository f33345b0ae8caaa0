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
//! PNU 1066 shows the output stage's temperature. The limits are PNU 1068's (its values are
//! the device file's CHOSEN ones, the manual prints none); the warning margin of 5 K is
//! CHOSEN (App. D: "warning clears when below the threshold", no threshold printed). 15h and
//! 16h are "ackable only once the temperature is back in range" (AfterCause): the cause ends
//! [`HYSTERESIS_K`] inside the range. The CMMO-ST has no motor temperature sensor; the motor
//! temperature is simulated (and shown by the console) but not supervised.

use super::device::{pnu_index, FhppDevice};
use crate::drive::plant_supervision::HYSTERESIS_K;
use crate::encoder_fault::EncoderFault;
use crate::thermal::{self, ThermalData};

/// App. D numbers.
const ENCODER: u8 = 0x06;
const STAGE_EXCEEDED: u8 = 0x15;
const STAGE_TOO_LOW: u8 = 0x16;
const STAGE_WARNING: u8 = 0x33;
/// Decision (CHOSEN): 33h comes 5 K below the maximum of PNU 1068:2.
const WARNING_MARGIN_K: f64 = 5.0;

/// The conditions in bit order of `PlantWatch::raised`, with their message.
const CONDITIONS: [u8; 4] = [STAGE_WARNING, STAGE_EXCEEDED, STAGE_TOO_LOW, ENCODER];

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
            let _ =
                self.od_mut()
                    .set_value(pnu_index(1066), 1, od::Value::Signed(i64::from(shown)));
        }
        let (low, high) = match self.plant_watch.limits {
            Some(l) => l,
            None => {
                // PNU 1068 is read-only: read once.
                let limit = |sub: u8, default: f64| match self.od().value(pnu_index(1068), sub) {
                    Some(od::Value::Signed(v)) => v as f64,
                    _ => default,
                };
                let l = (limit(1, -10.0), limit(2, 85.0));
                self.plant_watch.limits = Some(l);
                l
            }
        };
        let encoder = self.plant_watch.encoder;
        for (bit, code) in CONDITIONS.iter().enumerate() {
            let raised = self.plant_watch.raised & (1 << bit) != 0;
            let h = if raised { HYSTERESIS_K } else { 0.0 };
            let present = match *code {
                STAGE_WARNING => stage > high - WARNING_MARGIN_K - h,
                STAGE_EXCEEDED => stage > high - h,
                STAGE_TOO_LOW => stage < low + h,
                _ => encoder.signal_lost() || encoder.implausible(),
            };
            if present == raised {
                continue;
            }
            if present {
                self.plant_watch.raised |= 1 << bit;
                self.fault(*code);
            } else {
                self.plant_watch.raised &= !(1 << bit);
                self.clear_fault(*code);
            }
        }
    }
}
