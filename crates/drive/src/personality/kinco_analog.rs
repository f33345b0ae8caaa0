//! Kinco analog inputs AIN1 / AIN2 (§6.2.1, §6.3; spec/kinco-fd-cd.md §5.2, §5.3, §6 item 2):
//! the voltage minus Analog_Offset, reduced by Analog_Dead toward zero (0 inside the dead
//! band), is the speed command of modes −3 / 3 at Analog_Speed_Factor 2502h:0A rpm/V when
//! Analog_Speed_Con 2502h:07 names the input, and the torque command of mode 4 at
//! Voltage_Torque_Factor 2FF0h:21 mNm/V when Analog_Torque_Con 2502h:08 names it.
//!
//! The twin has no analog connector: the voltages are simulated ([`Drive::set_analog_input`])
//! and show in AN_V1 / AN_V2 2FF0h:16 / :17, the processed values in Analog1_out /
//! Analog2_out 2502h:0F / :10 (0.01 V). Decision: Analog_Dead_High / Low and the input
//! filters 2502h:01 / :04 are not simulated (an ideal, noiseless source).

use super::kinco::{analog_out, analog_speed_rpm};
use crate::drive::Drive;

/// The simulated voltages of AIN1 and AIN2, 0.01 V.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct AnalogInputs {
    pub(crate) centivolts: [i32; 2],
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S> {
    /// The voltage at AIN`input` (1 or 2), volts, clamped to ±10 V.
    pub fn set_analog_input(&mut self, input: u8, volts: f64) {
        let v = if volts.is_finite() { volts } else { 0.0 };
        let cv = libm::round(v.clamp(-10.0, 10.0) * 100.0) as i32;
        if let Some(slot) = self
            .kinco
            .analog
            .centivolts
            .get_mut(usize::from(input.wrapping_sub(1)))
        {
            *slot = cv;
        }
    }

    /// Analog`n`_out of input `n` (1, 2) in 0.01 V: offset and dead band applied.
    fn analog_processed(&self, n: u8) -> i32 {
        let (dead, offset) = if n == 1 { (0x1D, 0x1E) } else { (0x1F, 0x20) };
        let v_in = self
            .kinco
            .analog
            .centivolts
            .get(usize::from(n.wrapping_sub(1)))
            .copied()
            .unwrap_or(0);
        analog_out(
            v_in,
            self.value(0x2FF0, offset) as i32,
            self.value(0x2FF0, dead) as i32,
        )
    }

    /// The speed command in rpm where Analog_Speed_Con 2502h:07 names an input.
    pub(crate) fn kinco_analog_speed_rpm(&self) -> Option<i32> {
        let n = match self.value(0x2502, 0x07) {
            1 => 1,
            2 => 2,
            _ => return None,
        };
        let factor = self.value(0x2502, 0x0A) as i32;
        Some(analog_speed_rpm(self.analog_processed(n), factor))
    }

    /// The torque command in mN·m where Analog_Torque_Con 2502h:08 names an input.
    pub(crate) fn kinco_analog_torque_mnm(&self) -> Option<i64> {
        let n = match self.value(0x2502, 0x08) {
            1 => 1,
            2 => 2,
            _ => return None,
        };
        let factor = self.value(0x2FF0, 0x21);
        Some(i64::from(self.analog_processed(n)) * factor / 100)
    }

    /// AN_V1 / AN_V2 and Analog1_out / Analog2_out.
    pub(crate) fn kinco_publish_analog(&mut self) {
        for n in [1u8, 2] {
            let raw = self
                .kinco
                .analog
                .centivolts
                .get(usize::from(n - 1))
                .copied()
                .unwrap_or(0);
            let out = self.analog_processed(n);
            let d = self.od.description();
            let (a, b) = (d.entry(0x2FF0, 0x15 + n), d.entry(0x2502, 0x0E + n));
            self.store(a, i64::from(raw));
            self.store(b, i64::from(out));
        }
    }
}
