//! Kinco auto-tuning, the inertia measurement (§7.1, §4.3.2 tn03):
//! over communication WriteFUN_CTL 3041h:05 = 1, then Tuning_Method 3040h:01 = 1; the motor
//! oscillates for under a second within Safe_Dist 3040h:06 (0.01 rev); the result is in
//! Tuning_Method and Inertia_Get_Result 3040h:09 (1 success; 0 the drive could not be
//! enabled; −3 ratio above 25, −4 above 50), the ratio in Inertia_Ratio 3040h:0B
//! ((J_load + J_motor) × 10 / J_motor, KINCO-SC-10, -12) and the stiffness 3040h:08 set to
//! 4 … 12 (higher inertia, lower stiffness; 7 … 10 for −3) with Kpp 60FBh:01 and Velocity_BW
//! 2FF0h:0A from the stiffness table (Tab. 7-2).
//!
//! Decisions: the run is 0.8 s, four periods of a 5 Hz sine of ±Safe_Dist / 2 around the
//! position where it starts under a half-sine envelope (at rest at both ends), with the drive enabled (Operation Enabled; otherwise result 0 at
//! once); the measured inertia is the plant's (motor and load) against the rotor's Jr_Motor
//! 6410h:10; the stiffness is 12 − (ratio − 10) / 20 within 4 … 12 on success, 8 for −3,
//! unchanged otherwise;
//! 3040h:01 = 1 without WriteFUN_CTL = 1 is refused with 0800 0022h.

use core::time::Duration;

use super::hooks::Kinco;
use crate::drive::refusal::Request;
use od::{AbortCode, ObjectAccess as _};

use super::{inertia_ratio, tuning_result, STIFFNESS};
use crate::device_control::State;
use crate::drive::Drive;
use od::Instant;

/// The length of a run.
pub const TUNING_RUN: Duration = Duration::from_millis(800);
/// The oscillation's frequency, Hz.
const FREQUENCY: f64 = 5.0;

/// A tuning run in progress.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct TuningRun {
    /// When it ends and where it oscillates (internal increments); `None`: no run.
    pub(crate) run: Option<(Instant, Instant, f64)>,
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Kinco> {
    /// 3040h:01 Tuning_Method: 1 starts a run (module doc).
    pub(crate) fn kinco_write_tuning_method(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        if data.first() != Some(&1) {
            return self.od.write(index, sub, data);
        }
        if self.kinco_refusal(Request::Write { index, sub }).is_some() {
            return Err(AbortCode::DEVICE_STATE);
        }
        self.od.write(index, sub, data)?;
        if self.dc.state() == State::OperationEnabled {
            let center = self.traj.position;
            self.vendor.tuning.run = Some((self.now, self.now + TUNING_RUN, center));
        } else {
            self.kinco_tuning_result(0, 30, None);
        }
        Ok(())
    }

    pub(crate) fn kinco_tuning_active(&self) -> bool {
        self.vendor.tuning.run.is_some()
    }

    /// One cycle of the run: the oscillation, then the result.
    pub(crate) fn kinco_tuning_step(&mut self) {
        let Some((start, end, center)) = self.vendor.tuning.run else {
            return;
        };
        if self.dc.state() != State::OperationEnabled {
            self.vendor.tuning.run = None;
            self.kinco_tuning_result(0, 30, None);
            return;
        }
        let t = self.now.saturating_since(start).as_secs_f64();
        let amplitude = self.value(0x3040, 0x06).clamp(0, 40) as f64 * 0.01 * 65536.0 / 2.0;
        let w = 2.0 * core::f64::consts::PI * FREQUENCY;
        // A half-sine envelope over the run: it starts and ends at rest, where it started.
        let wt = core::f64::consts::PI / TUNING_RUN.as_secs_f64();
        let (env, d_env) = (libm::sin(wt * t), wt * libm::cos(wt * t));
        self.traj.position = center + amplitude * env * libm::sin(w * t);
        self.traj.velocity = amplitude * (d_env * libm::sin(w * t) + env * w * libm::cos(w * t));
        let v = self.traj.velocity;
        self.position_demand(v);
        if self.now >= end {
            self.vendor.tuning.run = None;
            self.traj.position = center;
            self.traj.velocity = 0.0;
            let j_total = self.axis.motor().data().inertia;
            let jr = self.value(0x6410, 0x10);
            let j_motor = if jr > 0 { jr as f64 * 1e-6 } else { j_total };
            let measured = inertia_ratio(j_total - j_motor, j_motor);
            let (result, ratio) = tuning_result(measured);
            let stiffness = match result {
                1 => Some((12 - (ratio - 10) / 20).clamp(4, 12)),
                -3 => Some(8),
                _ => None,
            };
            self.kinco_tuning_result(result, ratio, stiffness);
        }
    }

    fn kinco_tuning_result(&mut self, result: i8, ratio: i32, stiffness: Option<i32>) {
        let set = |d: &mut Self, index: u16, sub: u8, v: i64| {
            let e = d.od.description().entry(index, sub);
            d.store(e, v);
        };
        set(self, 0x3040, 0x01, i64::from(result));
        set(self, 0x3040, 0x09, i64::from(result));
        set(self, 0x3040, 0x0B, i64::from(ratio));
        if let Some(s) =
            stiffness.filter(|s| usize::try_from(*s).is_ok_and(|s| s < STIFFNESS.len()))
        {
            // Kpp, Velocity_BW and Kvp from the table's row at the measured ratio
            // (kinco_loops.rs).
            set(self, 0x3040, 0x08, i64::from(s));
            self.kinco_apply_stiffness();
        }
    }
}
