//! Kinco analog inputs AIN1 / AIN2 (§6.2.1, §6.3):
//! the voltage through the input filter Analog1/2_Filter 2502h:01 / :04, minus Analog_Offset,
//! reduced by Analog_Dead toward zero (0 inside the dead band), is Analog1/2_out 2502h:0F /
//! :10. That is
//! - the speed command of modes −3 / 3 at Analog_Speed_Factor 2502h:0A rpm/V when
//!   Analog_Speed_Con 2502h:07 names the input, 0 outside the window Analog_Dead_Low …
//!   Analog_Dead_High 2502h:0E / :0D ([`analog_window`]);
//! - the torque command of mode 4 at Voltage_Torque_Factor 2FF0h:21 mNm/V when
//!   Analog_Torque_Con 2502h:08 names it;
//! - the maximum torque at Voltage_MaxT_Factor 2FF0h:22 mNm/V when Analog_MaxT_Con 2502h:09
//!   names it ("Max torque \[Nm\] = Analog_out \[V\] × Analog_MaxT_Factor \[Nm/V\]", L1343).
//!
//! The twin has no analog connector: the voltages are simulated ([`Drive::set_analog_input`])
//! and show in AN_V1 / AN_V2 2FF0h:16 / :17, the processed values in Analog1_out /
//! Analog2_out (0.01 V).
//!
//! Decisions: the filter is a first-order low pass whose time constant is Analog_Filter in ms
//! (the manual: "AIN1 filter (unit: ms)", no order given), stepped every logic cycle from the
//! voltage at power-on; the maximum torque limits the current set-point in every mode
//! (in mode 4 the torque command, in the others the velocity controller's output), by its
//! magnitude (a limit has no sign), through the motor's torque constant 6410h:0F; with
//! Analog_MaxT_Con = 0 the limit is the drive's own.

use super::hooks::Kinco;
use super::{analog_out, analog_speed_rpm, analog_window};
use crate::drive::Drive;

/// The simulated voltages of AIN1 and AIN2, 0.01 V, and the filter's state.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct AnalogInputs {
    pub(crate) centivolts: [i32; 2],
    /// The filtered voltages, 0.01 V; `None` until the first logic cycle.
    pub(crate) filtered: [Option<f64>; 2],
    /// The maximum current the analog max torque sets, mA (`None`: no analog limit), as the
    /// controller has it.
    pub(crate) max_current_ma: Option<u32>,
    /// Each filter's step factor with what it is for (Analog_Filter, the logic cycle):
    /// `exp` only when one of them changes.
    pub(crate) alpha: [FilterStep; 2],
    /// The inputs of the last logic cycle's values when both filters had settled on their
    /// voltages (`None`: not settled, or not computed yet).
    pub(crate) settled: Option<SettledOn>,
}

/// What the analog values are computed from besides the dictionary: the voltages, the logic
/// cycle and the torque constant (bits).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct SettledOn {
    centivolts: [i32; 2],
    cycle: core::time::Duration,
    every: u32,
    torque_constant: u64,
}

/// A filter's step factor `1 − e^(−dt/τ)` and the τ (ms) and logic cycle it is for.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct FilterStep {
    tau_ms: i64,
    cycle: core::time::Duration,
    every: u32,
    alpha: f64,
}

/// AIN1's and AIN2's objects: Analog_Filter 2502h:01 / :04, Analog_Dead 2FF0h:1D / :1F,
/// Analog_Offset 2FF0h:1E / :20, AN_V 2FF0h:16 / :17, Analog_out 2502h:0F / :10, as the
/// drive's parameter slots (found when compiling: every logic cycle reads and writes them).
#[derive(Clone, Copy)]
struct AinObjects {
    filter: usize,
    dead: usize,
    offset: usize,
    voltage: usize,
    out: usize,
}

/// The parameter slot of `index:sub` (`usize::MAX` if it has none: refused below).
const fn slot(index: u16, sub: u8) -> usize {
    match crate::drive::param_slot::<Kinco>(index, sub) {
        Some(s) => s,
        None => usize::MAX,
    }
}

const AIN: [AinObjects; 2] = [
    AinObjects {
        filter: slot(0x2502, 0x01),
        dead: slot(0x2FF0, 0x1D),
        offset: slot(0x2FF0, 0x1E),
        voltage: slot(0x2FF0, 0x16),
        out: slot(0x2502, 0x0F),
    },
    AinObjects {
        filter: slot(0x2502, 0x04),
        dead: slot(0x2FF0, 0x1F),
        offset: slot(0x2FF0, 0x20),
        voltage: slot(0x2FF0, 0x17),
        out: slot(0x2502, 0x10),
    },
];

// Every object of AIN is in the drive's parameter cache (`CACHED_OBJECTS`).
const _: () = {
    let mut rest: &[AinObjects] = &AIN;
    while let [a, tail @ ..] = rest {
        let slots = [a.filter, a.dead, a.offset, a.voltage, a.out];
        let mut left: &[usize] = &slots;
        while let [s, more @ ..] = left {
            assert!(*s != usize::MAX, "an analog input object is not cached");
            left = more;
        }
        rest = tail;
    }
};

/// Analog_MaxT_Con 2502h:09 (and the speed / torque selectors): 1 = AIN1, 2 = AIN2.
fn input_of(selector: i64) -> Option<u8> {
    match selector {
        1 => Some(1),
        2 => Some(2),
        _ => None,
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Kinco> {
    /// The entry in parameter slot `slot`.
    #[inline(always)]
    fn slot_entry(&self, slot: usize) -> Option<&'static od::Entry> {
        self.params.get(slot).copied().flatten()
    }

    /// The voltage at AIN`input` (1 or 2), volts, clamped to ±10 V.
    pub fn set_analog_input(&mut self, input: u8, volts: f64) {
        let v = if volts.is_finite() { volts } else { 0.0 };
        let cv = libm::round(v.clamp(-10.0, 10.0) * 100.0) as i32;
        if let Some(slot) = self
            .vendor
            .analog
            .centivolts
            .get_mut(usize::from(input.wrapping_sub(1)))
        {
            *slot = cv;
        }
    }

    /// Analog`n`_out of input `n` (1, 2) in 0.01 V: filter, offset and dead band applied.
    fn analog_processed(&self, n: u8) -> i32 {
        let i = usize::from(n.wrapping_sub(1));
        let Some(objects) = AIN.get(i) else {
            return 0;
        };
        let raw = self.vendor.analog.centivolts.get(i).copied().unwrap_or(0);
        let v_in = self
            .vendor
            .analog
            .filtered
            .get(i)
            .copied()
            .flatten()
            // `libm::round(f) as i32`, without libm's software path.
            .map_or(raw, |f| {
                crate::rounding::round_i64(f).clamp(i32::MIN.into(), i32::MAX.into()) as i32
            });
        analog_out(
            v_in,
            self.read(self.slot_entry(objects.offset)) as i32,
            self.read(self.slot_entry(objects.dead)) as i32,
        )
    }

    /// The speed command in rpm where Analog_Speed_Con 2502h:07 names an input.
    pub(crate) fn kinco_analog_speed_rpm(&self) -> Option<i32> {
        let n = input_of(self.cycle_value(0x2502, 0x07))?;
        let factor = self.value(0x2502, 0x0A) as i32;
        let out = analog_window(
            self.analog_processed(n),
            self.value(0x2502, 0x0D) as i32,
            self.value(0x2502, 0x0E) as i32,
        );
        Some(analog_speed_rpm(out, factor))
    }

    /// The torque command in mN·m where Analog_Torque_Con 2502h:08 names an input.
    pub(crate) fn kinco_analog_torque_mnm(&self) -> Option<i64> {
        let n = input_of(self.cycle_value(0x2502, 0x08))?;
        let factor = self.value(0x2FF0, 0x21);
        Some(i64::from(self.analog_processed(n)) * factor / 100)
    }

    /// The maximum torque in mN·m where Analog_MaxT_Con 2502h:09 names an input (§6.2.1).
    pub(crate) fn kinco_analog_max_torque_mnm(&self) -> Option<i64> {
        let n = input_of(self.cycle_value(0x2502, 0x09))?;
        let factor = self.value(0x2FF0, 0x22);
        Some((i64::from(self.analog_processed(n)) * factor / 100).abs())
    }

    /// The maximum current of the analog max torque, A, for the torque mode's own clamp.
    pub(crate) fn kinco_analog_max_current_a(&self) -> Option<f64> {
        self.vendor
            .analog
            .max_current_ma
            .map(|ma| f64::from(ma) / 1000.0)
    }

    /// One logic cycle: the input filters, AN_V1 / AN_V2 and Analog1_out / Analog2_out, and
    /// the analog max torque as the controller's current limit.
    pub(crate) fn kinco_publish_analog(&mut self) {
        let (cycle, every) = (self.cycle, self.logic_every);
        let on = SettledOn {
            centivolts: self.vendor.analog.centivolts,
            cycle,
            every,
            torque_constant: self.settings.motor.torque_constant.to_bits(),
        };
        // Each filter on its voltage (a step of it adds (v − f)·α = 0), the voltages and the
        // cycle as then and the dictionary as the last cycle's `publish` left it (τ, offsets,
        // dead bands, the max-torque selector and factor, the stored values): this cycle
        // would compute and store the same values.
        if self.vendor.analog.settled == Some(on) && self.published.intact() {
            return;
        }
        for (i, objects) in AIN.iter().enumerate() {
            let raw = self.vendor.analog.centivolts.get(i).copied().unwrap_or(0);
            let tau = self.read(self.slot_entry(objects.filter)).max(0);
            let analog = &mut self.vendor.analog;
            if let (Some(slot), Some(cached)) =
                (analog.filtered.get_mut(i), analog.alpha.get_mut(i))
            {
                let f = slot.get_or_insert(f64::from(raw));
                let alpha = if tau > 0 {
                    if (cached.tau_ms, cached.cycle, cached.every) != (tau, cycle, every) {
                        let dt_ms = cycle.as_secs_f64() * f64::from(every) * 1000.0;
                        *cached = FilterStep {
                            tau_ms: tau,
                            cycle,
                            every,
                            alpha: 1.0 - libm::exp(-dt_ms / tau as f64),
                        };
                    }
                    cached.alpha
                } else {
                    1.0
                };
                *f += (f64::from(raw) - *f) * alpha;
            }
            let out = self.analog_processed(i as u8 + 1);
            for (slot, v) in [(objects.voltage, raw), (objects.out, out)] {
                self.store(self.slot_entry(slot), i64::from(v));
            }
        }
        let kt = self.settings.motor.torque_constant;
        let limit = self
            .kinco_analog_max_torque_mnm()
            .filter(|_| kt > 0.0)
            .map(|mnm| crate::rounding::round(mnm as f64 / kt) as u32);
        if limit != self.vendor.analog.max_current_ma {
            self.vendor.analog.max_current_ma = limit;
            self.params_dirty = true;
        }
        let analog = &mut self.vendor.analog;
        let settled = analog
            .filtered
            .iter()
            .zip(analog.centivolts)
            .all(|(f, raw)| f.is_some_and(|f| f.to_bits() == f64::from(raw).to_bits()));
        analog.settled = settled.then_some(on);
    }
}
