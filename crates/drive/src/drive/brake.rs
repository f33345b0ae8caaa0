//! The holding brake: its delays after the output stage goes on and before it goes off, and
//! the output stage switched off behind it.

use super::*;

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// The device file's brake timing ([`od::BrakeTiming`], `[device.brake]`): each delay the
    /// sum of its objects in ms.
    pub(super) fn brake_delays(&self) -> BrakeDelays {
        let timing = &self.od.description().brake;
        if timing.only_with_brake && !self.settings.brake_fitted {
            return BrakeDelays {
                release: Duration::ZERO,
                motion: Duration::ZERO,
                engage: Duration::ZERO,
            };
        }
        let ms = |objects: &[(u16, u8)]| {
            objects.iter().fold(Duration::ZERO, |sum, (i, s)| {
                sum + Duration::from_millis(self.described_value(*i, *s).max(0) as u64)
            })
        };
        BrakeDelays {
            release: ms(timing.release),
            motion: ms(timing.motion),
            engage: ms(timing.engage),
        }
    }

    /// A brake delay is running (Nanotec §11.8: mode changes wait for it).
    pub(crate) fn brake_wait(&self) -> bool {
        self.power_off_at.is_some() || self.release_at.is_some_and(|t| self.now < t)
    }

    pub(crate) fn power_off(&mut self) {
        self.power_off_at = None;
        self.demand = Demand::Off;
        if self.settings.brake_fitted {
            self.brake_engaged = true;
            self.axis.hold_brake(true);
        }
    }

    pub(super) fn brake_timers(&mut self) {
        if self.power_off_at.is_some_and(|t| self.now >= t) {
            self.power_off();
        }
        if self.brake_release_at.is_some_and(|t| self.now >= t) {
            self.brake_release_at = None;
            self.brake_engaged = false;
        }
        // CMMP-AS §5.13/5.16: with 60FEh:02 bit 0 set the host works the brake through
        // 60FEh:01 bit 0 (1 = brake applied, CiA 402 "set brake"); otherwise it follows the
        // output stage.
        if self.settings.brake_fitted {
            let manual = self.cycle_value(0x60FE, 2) & 1 != 0;
            let engaged = if manual {
                self.cycle_value(0x60FE, 1) & 1 != 0
            } else {
                self.brake_engaged
            };
            if self.axis.motor().brake() != engaged {
                self.axis.hold_brake(engaged);
            }
            // Without host control 60FEh:01 bit 0 reads the brake's state ("depends on the
            // state of the brake", L4203–4215).
            let data = self.cycle_value(0x60FE, 1);
            let shown = (data & !1) | i64::from(engaged);
            if !manual && shown != data && self.personality.capabilities.brake_in_60fe {
                self.store(self.param(0x60FE, 1), shown);
            }
        }
    }
}

/// The brake's delays after the output stage goes on and before it goes off.
#[derive(Debug, Clone, Copy)]
pub(super) struct BrakeDelays {
    /// Output stage on → brake open.
    pub(super) release: Duration,
    /// Output stage on → the set-point released (operational).
    pub(super) motion: Duration,
    /// Brake closed → output stage off.
    pub(super) engage: Duration,
}
