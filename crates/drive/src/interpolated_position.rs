//! Interpolated position mode (CiA 402 mode 7): linear interpolation (CiA 402 60C0h
//! interpolation_sub_mode_select 0, a one-deep data record) between set-points that arrive
//! one per SYNC on a fixed grid, the interpolation period 60C2h. The periods a drive takes,
//! when a new 60C2h takes effect and whether the buffer 60C4h:06 starts locked are the
//! vendor's (the vendor hooks `ip_period` and `ip_buffer_open_at_reset`, its write hooks);
//! the engine's are CiA 402's (any period units × 10^index s, 60C2h at once, the buffer as
//! 60C4h:06 says).
//!
//! Sans-IO: the drive tells the interpolator of each SYNC ([`Interpolator::sync`]: a CANopen
//! SYNC, an EtherCAT SYNC0 event, or the EtherCAT frame in free run), hands it the set-points
//! written to 60C1h:01 ([`Interpolator::set_point`]) and asks for the demand position of each
//! control cycle ([`Interpolator::demand`]).
//!
//! Synchronisation: the set-points come one per SYNC, so the interpolator finds the SYNC grid
//! before it runs and notices when the grid is lost (a personality with
//! `ip_changing_until_synchronised` shows 6061h = −1 meanwhile). CiA 402 gives no tolerance;
//! decision: an interval between two SYNCs is on the grid when it is within half
//! a period of 60C2h; two on-grid intervals in a row synchronise, and a synchronised drive
//! loses the grid after [`OFF_GRID_LIMIT`] off-grid intervals in a row or when no SYNC came for
//! [`SILENCE_PERIODS`] periods. A master on a loaded machine jitters; a stopped or wrong grid
//! is what the drive has to notice.

use core::time::Duration;

use od::Instant;

/// Off-grid intervals in a row that lose the synchronisation.
pub const OFF_GRID_LIMIT: u8 = 3;
/// Periods without SYNC that lose the synchronisation.
pub const SILENCE_PERIODS: u64 = 3;
/// On-grid intervals in a row that synchronise.
const ON_GRID_NEEDED: u8 = 2;

/// What a SYNC or the passing of time did to the synchronisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SyncChange {
    None,
    /// The drive is now synchronised to the grid (6061h shows 7).
    Synchronised,
    /// The grid was lost (6061h shows −1); `while_active`: interpolation was running (the
    /// personality's [`Fault::FieldbusSyncError`](crate::personality::Fault::FieldbusSyncError)).
    Lost {
        while_active: bool,
    },
}

/// The linear interpolator and its SYNC grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Interpolator {
    period: Duration,
    /// The period is the SYNC interval, measured (a PLL locked on SYNC; the personality's
    /// `ip_follows_sync`), not 60C2h; 60C1h needs no unlocking.
    follows_sync: bool,
    unlocked: bool,
    last_sync: Option<Instant>,
    on_grid: u8,
    off_grid: u8,
    synced: bool,
    active: bool,
    engaged: bool,
    /// The newest set-point since the last SYNC (internal increments).
    latched: Option<f64>,
    /// The segment being interpolated: from `from` at `start` to `to` one period later.
    from: f64,
    to: f64,
    start: Instant,
}

impl Interpolator {
    /// An interpolator for the period of 60C2h (when a changed 60C2h takes effect is the
    /// personality's: at once, or with the next [`Interpolator::reset`]).
    pub fn new(period: Duration) -> Self {
        Interpolator {
            period,
            follows_sync: false,
            unlocked: false,
            last_sync: None,
            on_grid: 0,
            off_grid: 0,
            synced: false,
            active: false,
            engaged: false,
            latched: None,
            from: 0.0,
            to: 0.0,
            start: Instant::ZERO,
        }
    }

    /// The interpolation period in force.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// An interpolator whose period is the SYNC interval (`ip_follows_sync`): the first two
    /// intervals within half of each other lock it; 60C1h is always open.
    pub fn following_sync() -> Self {
        Interpolator {
            follows_sync: true,
            unlocked: true,
            ..Interpolator::new(Duration::ZERO)
        }
    }

    /// Reset application: the new period from 60C2h, and everything starts again.
    pub fn reset(&mut self, period: Duration) {
        *self = if self.follows_sync {
            Interpolator::following_sync()
        } else {
            Interpolator::new(period)
        };
    }

    /// A new interpolation period from 60C2h, in force at once (the grid is checked against
    /// it from the next SYNC on); an interpolator that follows SYNC keeps measuring its own.
    pub fn set_period(&mut self, period: Duration) {
        if !self.follows_sync {
            self.period = period;
        }
    }

    /// 60C4h:06 buffer_clear: 1 unlocks 60C1h, 0 clears the (one-deep) buffer and locks it.
    pub fn set_unlocked(&mut self, unlocked: bool) {
        self.unlocked = unlocked;
        if !unlocked {
            self.latched = None;
        }
    }

    /// 60C1h accepts set-points (60C4h:06 = 1).
    pub fn is_unlocked(&self) -> bool {
        self.unlocked
    }

    /// 6061h may show 7.
    pub fn is_synchronised(&self) -> bool {
        self.synced
    }

    /// Statusword bit 12 ip_mode_active.
    pub fn is_active(&self) -> bool {
        self.active
    }

    /// A segment exists (interpolation ran since the mode was entered): the demand comes from
    /// it, also after enable_ip_mode was cleared.
    pub fn is_engaged(&self) -> bool {
        self.engaged
    }

    /// The last set-point taken (the base of a relative set-point, 60C1h:02 = 1).
    pub fn last_set_point(&self) -> f64 {
        self.latched.unwrap_or(self.to)
    }

    /// A write to 60C1h:01 (already absolute, in increments): "a write triggers the internal
    /// transfer"; it is taken at the next SYNC. Ignored unless interpolation is active (the
    /// manual: records are evaluated only after ip_mode_active).
    pub fn set_point(&mut self, increments: f64) {
        if self.active {
            self.latched = Some(increments);
        }
    }

    /// A SYNC at `now`; `position` is the demand position of this instant.
    pub fn sync(&mut self, now: Instant) -> SyncChange {
        let mut change = SyncChange::None;
        if let Some(last) = self.last_sync {
            let interval = now.saturating_since(last).as_nanos();
            let period = self.period.as_nanos();
            let on_grid = period > 0 && interval.abs_diff(period) <= period / 2;
            if self.follows_sync {
                // The PLL follows the SYNC interval.
                self.period = now.saturating_since(last);
            }
            if on_grid {
                self.off_grid = 0;
                self.on_grid = self.on_grid.saturating_add(1);
                if !self.synced && self.on_grid >= ON_GRID_NEEDED {
                    self.synced = true;
                    change = SyncChange::Synchronised;
                }
            } else {
                self.on_grid = 0;
                self.off_grid = self.off_grid.saturating_add(1);
                if self.synced && self.off_grid >= OFF_GRID_LIMIT {
                    change = self.lose();
                }
            }
        }
        self.last_sync = Some(now);
        if self.active {
            // The next segment: from where the interpolation stands to the newest set-point
            // (or on at the last one when none came).
            let here = self.demand(now).0;
            self.from = here;
            if let Some(p) = self.latched.take() {
                self.to = p;
            } else {
                self.to = here;
            }
            self.start = now;
        }
        change
    }

    /// Time passes without SYNC: after [`SILENCE_PERIODS`] periods the grid is lost.
    pub fn check(&mut self, now: Instant) -> SyncChange {
        let silent = self.last_sync.is_some_and(|t| {
            now.saturating_since(t).as_nanos()
                > self.period.as_nanos() * u128::from(SILENCE_PERIODS)
        });
        if silent && self.synced {
            self.lose()
        } else {
            SyncChange::None
        }
    }

    fn lose(&mut self) -> SyncChange {
        let while_active = self.active;
        self.synced = false;
        self.active = false;
        self.on_grid = 0;
        self.off_grid = 0;
        self.latched = None;
        SyncChange::Lost { while_active }
    }

    /// An error or leaving OPERATION ENABLED: interpolation stops, and the grid is found
    /// again before it restarts.
    pub fn interrupt(&mut self) {
        self.active = false;
        self.engaged = false;
        self.synced = false;
        self.on_grid = 0;
        self.off_grid = 0;
        self.latched = None;
    }

    /// enable_ip_mode set while synchronised: interpolation starts where the drive stands;
    /// `pending` is a set-point already written (where 60C1h:01 shares the target 607Ah), taken
    /// at the next SYNC.
    pub fn activate_with(&mut self, position: f64, now: Instant, pending: Option<f64>) {
        self.activate(position, now);
        self.latched = pending;
    }

    /// enable_ip_mode set while synchronised: interpolation starts where the drive stands.
    pub fn activate(&mut self, position: f64, now: Instant) {
        self.active = true;
        self.engaged = true;
        self.latched = None;
        self.from = position;
        self.to = position;
        self.start = now;
    }

    /// enable_ip_mode cleared: no more set-points are taken; the drive holds where the
    /// current segment ends.
    pub fn deactivate(&mut self) {
        self.active = false;
        self.latched = None;
    }

    /// Demand position and speed (increments, increments/s) at `now`: linear from `from` to
    /// `to` over one period, then standing at `to`.
    pub fn demand(&self, now: Instant) -> (f64, f64) {
        let period = self.period.as_secs_f64();
        if period <= 0.0 {
            return (self.to, 0.0);
        }
        let t = now.saturating_since(self.start).as_secs_f64();
        if t >= period {
            (self.to, 0.0)
        } else {
            let v = (self.to - self.from) / period;
            (self.from + v * t, v)
        }
    }
}

/// The interpolation period of 60C2h as CiA 402 defines it: ip_time_units × 10^ip_time_index
/// s; `None` for a period of 0 or one the twin's nanoseconds cannot hold (index below −9 or
/// above 3).
pub fn period_of_60c2(units: u8, index: i8) -> Option<Duration> {
    let exponent = u32::try_from(i32::from(index) + 9).ok()?;
    if units == 0 || index > 3 {
        return None;
    }
    let ns = 10u64.checked_pow(exponent)?.checked_mul(u64::from(units))?;
    Some(Duration::from_nanos(ns))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: u64) -> Instant {
        Instant::from_millis(v)
    }

    #[test]
    fn cia402_period_is_units_times_ten_to_the_index() {
        assert_eq!(period_of_60c2(4, -3), Some(Duration::from_millis(4)));
        assert_eq!(period_of_60c2(20, -3), Some(Duration::from_millis(20)));
        assert_eq!(period_of_60c2(250, -6), Some(Duration::from_micros(250)));
        assert_eq!(period_of_60c2(1, 0), Some(Duration::from_secs(1)));
        assert_eq!(period_of_60c2(0, -3), None);
        assert_eq!(period_of_60c2(1, -10), None);
        assert_eq!(period_of_60c2(1, 4), None);
        // Both encodings of one period mean the same.
        assert_eq!(period_of_60c2(40, -4), Some(Duration::from_millis(4)));
    }

    #[test]
    fn synchronises_after_two_intervals_on_the_grid() {
        let mut ip = Interpolator::new(Duration::from_millis(4));
        assert_eq!(ip.sync(ms(0)), SyncChange::None);
        assert_eq!(ip.sync(ms(4)), SyncChange::None);
        assert_eq!(ip.sync(ms(8)), SyncChange::Synchronised);
        assert!(ip.is_synchronised());
        // Jitter within half a period keeps it.
        assert_eq!(ip.sync(ms(13)), SyncChange::None);
        assert_eq!(ip.sync(ms(15)), SyncChange::None);
        assert!(ip.is_synchronised());
    }

    #[test]
    fn a_wrong_grid_never_synchronises() {
        // SYNC every 10 ms against a 4 ms period.
        let mut ip = Interpolator::new(Duration::from_millis(4));
        for k in 0..10 {
            assert_eq!(ip.sync(ms(10 * k)), SyncChange::None);
        }
        assert!(!ip.is_synchronised());
    }

    #[test]
    fn silence_loses_the_grid() {
        let mut ip = Interpolator::new(Duration::from_millis(4));
        for k in 0..3 {
            ip.sync(ms(4 * k));
        }
        ip.activate(0.0, ms(8));
        assert_eq!(ip.check(ms(20)), SyncChange::None);
        assert_eq!(ip.check(ms(21)), SyncChange::Lost { while_active: true });
        assert!(!ip.is_active() && !ip.is_synchronised());
    }

    #[test]
    fn interpolates_linearly_between_set_points_one_per_sync() {
        let mut ip = Interpolator::new(Duration::from_millis(4));
        for k in 0..3 {
            ip.sync(ms(4 * k));
        }
        ip.set_point(999.0);
        assert_eq!(ip.last_set_point(), 0.0, "ignored before activation");
        ip.activate(100.0, ms(8));
        assert_eq!(ip.demand(ms(9)), (100.0, 0.0));
        ip.set_point(500.0);
        ip.sync(ms(12));
        // 400 increments in 4 ms: 100 000 increments/s, a quarter at 1 ms.
        let (p, v) = ip.demand(ms(13));
        assert!(
            (p - 200.0).abs() < 1e-9 && (v - 100_000.0).abs() < 1e-6,
            "{p} {v}"
        );
        assert_eq!(ip.demand(ms(16)).0, 500.0);
        // No new set-point: the next segment stands.
        ip.sync(ms(16));
        assert_eq!(ip.demand(ms(18)), (500.0, 0.0));
        ip.deactivate();
        ip.set_point(900.0);
        ip.sync(ms(20));
        assert_eq!(
            ip.demand(ms(22)).0,
            500.0,
            "records ignored once bit 4 is cleared"
        );
    }
}
