//! Application synchronisation: when the device takes the outputs of SM2 and latches its
//! inputs, and when it declares the synchronisation lost (spec §7.5, §8.2).
//!
//! Two modes, as a drive runs them:
//! * **Free run / SM-synchronous** (no SYNC0): the arrival of the frame is the time base; the
//!   device takes each output buffer when it arrives ("without DC the firmware can use the
//!   arrival of the EtherCAT frame as the time base").
//! * **DC SYNC0**: the drive's cycle is triggered by the SYNC0 event; the output buffer that
//!   arrived since the previous event is taken at the event, and the inputs are latched then.
//!   Every SYNC0 cycle must bring one new output buffer ("the EtherCAT frame cycle time must
//!   be exactly matched to the cycle time of the interpolator").
//!
//! The loss of synchronisation is judged as ETG.1020's sync error: the SM-event-missed
//! counter (0x1C32:0B) rises by [`MISS_WEIGHT`] at a SYNC0 event that finds no SM2 event
//! since the one before the previous event (the first SYNC0 without new outputs is the grid's
//! tolerance for a frame that lands just after its event, and costs nothing), falls by 1 with
//! every SM2 event, and the synchronisation is lost when it reaches the sync error counter
//! limit (0x10F1:02; a limit of 0 switches the check off). The limit is the device's own
//! 10F1h:02 where its dictionary has one, else [`DEFAULT_SYNC_ERROR_LIMIT`], the value of the
//! slave stack most devices are built on. So a single missed frame now and then is never an
//! error, two in a row cost 3, three in a row reach the default limit.
//! Decision (docs/decisions.md, "SYNC0 loss"): a drive manual that names the error but gives
//! no count, with no 10F1h in its dictionary, gets the standard counter with the standard
//! limit, never stricter than a device built on that stack.
//! Counting starts with the first output buffer after the device entered Op, so a master that
//! requests Op before it sends process data (ethercrab's `into_op`) is not punished.
//! Decision (docs/decisions.md, "SYNC0 events seen late"): an event the device's side runs a
//! cycle or more after its time ([`SyncMonitor::sync0_unobserved`]) takes its outputs but
//! costs nothing: a device sees every event in time, and the frames of that time may still
//! wait unread.

/// Added to the SM-event-missed counter for each SYNC0 event past the first without new
/// outputs.
pub const MISS_WEIGHT: u16 = 3;
/// The sync error counter limit (0x10F1:02) of a device whose dictionary names none.
pub const DEFAULT_SYNC_ERROR_LIMIT: u16 = 4;
/// SYNC0 events allowed per SM2 event (one output buffer per SYNC0 cycle: 0x1C32:01 = 2, no
/// subordinated cycles).
const SYNC0_PER_SM_EVENT: u16 = 1;

/// A synchronisation mode the slave runs, as a configurator offers it (ETG.2000 `Dc/OpMode`):
/// the value the master writes to 0x0980–0x0981 for it, and whether SYNC0 runs at the
/// master's cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SyncMode {
    /// `<Name>`.
    pub name: &'static str,
    /// `<Desc>`.
    pub desc: &'static str,
    /// `<AssignActivate>`: 0x0980 (low byte, cyclic unit control) and 0x0981 (high byte,
    /// activation: bit 0 cyclic operation, bit 1 SYNC0).
    pub assign_activate: u16,
    /// SYNC0 at the master's cycle (`<CycleTimeSync0 Factor="1">0`), no shift.
    pub sync0: bool,
}

/// The two modes above: SM-synchronous (0x0981 = 0, the frame's arrival is the time base)
/// and DC SYNC0 (0x0981 = 03h: cyclic operation and SYNC0, as SOEM's `ecx_dcsync0` and
/// ethercrab's `configure_dc_sync` write it). SYNC1 is not generated.
pub const SYNC_MODES: [SyncMode; 2] = [
    SyncMode {
        name: "SM-Synchron",
        desc: "SM-Synchron",
        assign_activate: 0x0000,
        sync0: false,
    },
    SyncMode {
        name: "DC",
        desc: "DC-Synchron",
        assign_activate: 0x0300,
        sync0: true,
    },
];

/// What a SYNC0 event brings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sync0Outcome {
    /// A new output buffer arrived in this cycle: the device takes it now.
    pub take_outputs: bool,
    /// The error counter reached the limit with this event (reported once).
    pub lost: bool,
}

/// The synchronisation state of one device.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SyncMonitor {
    pending: bool,
    armed: bool,
    lost: bool,
    /// The SM-event-missed counter (0x1C32:0B).
    counter: u16,
    /// SYNC0 events since the last SM2 event.
    since_outputs: u16,
    /// The sync error counter limit (0x10F1:02).
    limit: u16,
    /// SYNC0 events handled.
    pub events: u64,
    /// SYNC0 events without a new output buffer while armed.
    pub missed: u64,
}

impl Default for SyncMonitor {
    fn default() -> Self {
        Self::new()
    }
}

impl SyncMonitor {
    pub const fn new() -> Self {
        SyncMonitor {
            pending: false,
            armed: false,
            lost: false,
            counter: 0,
            since_outputs: 0,
            limit: DEFAULT_SYNC_ERROR_LIMIT,
            events: 0,
            missed: 0,
        }
    }

    /// Leaving Op, or SYNC0 reconfigured: start again (the counters of events stay), with
    /// `limit` as the sync error counter limit (0x10F1:02).
    pub fn reset(&mut self, limit: u16) {
        self.pending = false;
        self.armed = false;
        self.lost = false;
        self.counter = 0;
        self.since_outputs = 0;
        self.limit = limit;
    }

    /// A new output buffer arrived (in Op): an SM2 event.
    pub fn outputs_received(&mut self) {
        self.pending = true;
        self.armed = true;
        self.since_outputs = 0;
        self.counter = self.counter.saturating_sub(1);
    }

    /// A new output buffer is waiting for the next SYNC0 event.
    pub fn outputs_pending(&self) -> bool {
        self.pending
    }

    /// The synchronisation was lost and not reset since.
    pub fn is_lost(&self) -> bool {
        self.lost
    }

    /// The SM-event-missed counter (0x1C32:0B).
    pub fn error_counter(&self) -> u16 {
        self.counter
    }

    /// SYNC0 events since the last SM2 event: at a loss, how long the outputs had stopped.
    pub fn since_outputs(&self) -> u16 {
        self.since_outputs
    }

    /// The sync error counter limit in force (0x10F1:02).
    pub fn limit(&self) -> u16 {
        self.limit
    }

    /// One SYNC0 event.
    pub fn sync0(&mut self) -> Sync0Outcome {
        self.events = self.events.wrapping_add(1);
        let take_outputs = core::mem::take(&mut self.pending);
        if !self.armed {
            return Sync0Outcome {
                take_outputs,
                lost: false,
            };
        }
        if !take_outputs {
            self.missed = self.missed.wrapping_add(1);
        }
        if self.since_outputs > SYNC0_PER_SM_EVENT && self.counter <= self.limit {
            self.counter = self.counter.saturating_add(MISS_WEIGHT);
        }
        self.since_outputs = self.since_outputs.saturating_add(1);
        let lost = !self.lost && self.limit != 0 && self.counter >= self.limit;
        self.lost |= lost;
        Sync0Outcome { take_outputs, lost }
    }

    /// `n` SYNC0 events that the device's side ran a cycle or more after their time (its
    /// processor was held off): the first takes a waiting output buffer as any event does, but
    /// none counts against the master. Output buffers that arrived before them may still wait
    /// unread (a master that waits for its answer sends no more meanwhile), so the device
    /// cannot tell a master that stopped from its own delay, and a device that sees every
    /// event in time would not have lost the grid.
    pub fn sync0_unobserved(&mut self, n: u64) -> Sync0Outcome {
        self.events = self.events.wrapping_add(n);
        let take_outputs = core::mem::take(&mut self.pending);
        if self.armed && n > 0 {
            let without = n - u64::from(take_outputs);
            self.missed = self.missed.wrapping_add(without);
            let n16 = u16::try_from(n).unwrap_or(u16::MAX);
            self.since_outputs = self.since_outputs.saturating_add(n16);
        }
        Sync0Outcome {
            take_outputs,
            lost: false,
        }
    }

    /// `n` SYNC0 events at once without outputs (the device was not polled for a while):
    /// the outcome of the first, whether any lost the synchronisation, and the rest counted
    /// as missed.
    pub fn sync0_many(&mut self, n: u64) -> Sync0Outcome {
        // After this many events without outputs the counter stands above any limit.
        let settle = u64::from(self.limit) / u64::from(MISS_WEIGHT) + 3;
        let mut first = self.sync0();
        for _ in 1..n.min(settle) {
            first.lost |= self.sync0().lost;
        }
        if n > settle {
            let rest = n - settle;
            self.events = self.events.wrapping_add(rest);
            if self.armed {
                self.missed = self.missed.wrapping_add(rest);
            }
            let rest16 = u16::try_from(rest).unwrap_or(u16::MAX);
            self.since_outputs = self.since_outputs.saturating_add(rest16);
        }
        first
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_counting_before_the_first_outputs() {
        let mut m = SyncMonitor::new();
        for _ in 0..100 {
            assert_eq!(
                m.sync0(),
                Sync0Outcome {
                    take_outputs: false,
                    lost: false
                }
            );
        }
        assert_eq!(m.missed, 0);
        assert_eq!(m.events, 100);
    }

    #[test]
    fn one_buffer_per_cycle_keeps_the_counter_at_zero() {
        let mut m = SyncMonitor::new();
        for _ in 0..1000 {
            m.outputs_received();
            let o = m.sync0();
            assert!(o.take_outputs && !o.lost);
        }
        assert_eq!(m.error_counter(), 0);
    }

    #[test]
    fn three_missed_cycles_in_a_row_lose_the_synchronisation_once() {
        let mut m = SyncMonitor::new();
        m.outputs_received();
        assert!(m.sync0().take_outputs);
        assert!(!m.sync0().lost);
        assert!(!m.sync0().lost);
        assert!(m.sync0().lost, "third miss reaches the limit");
        assert!(m.is_lost());
        assert!(!m.sync0().lost, "reported once");
        assert_eq!(m.missed, 4);
        m.reset(DEFAULT_SYNC_ERROR_LIMIT);
        assert!(!m.is_lost());
        assert!(!m.sync0().lost, "disarmed after a reset");
    }

    #[test]
    fn an_occasional_slip_is_tolerated() {
        // A master whose cycle slips: every fourth SYNC0 finds no new buffer (and the next
        // one finds two; only the newer counts).
        let mut m = SyncMonitor::new();
        for i in 0..10_000 {
            if i % 4 != 3 {
                m.outputs_received();
            }
            assert!(!m.sync0().lost, "cycle {i}");
        }
        assert_eq!(m.missed, 2500);
    }

    #[test]
    fn a_single_miss_every_other_cycle_costs_nothing() {
        // The first SYNC0 event without new outputs is the grid's tolerance (a frame that
        // lands just after its event): alone it never counts, however often it comes.
        let mut m = SyncMonitor::new();
        for i in 0..10_000 {
            if i % 2 == 0 {
                m.outputs_received();
            }
            assert!(!m.sync0().lost, "cycle {i}");
            assert_eq!(m.error_counter(), 0);
        }
        assert_eq!(m.missed, 5000);
    }

    #[test]
    fn two_misses_in_a_row_every_third_cycle_are_an_error() {
        // Each pair costs 3, each buffer takes 1 away: the counter climbs to the limit.
        let mut m = SyncMonitor::new();
        let mut lost_at = None;
        for i in 0..30 {
            if i % 3 == 0 {
                m.outputs_received();
            }
            if m.sync0().lost {
                lost_at.get_or_insert(i);
            }
        }
        assert_eq!(lost_at, Some(5), "3, then 3 - 1 + 3 = 5 >= 4");
    }

    #[test]
    fn a_master_catching_up_after_a_stall_pays_the_counter_back() {
        // SSC takes 1 off the counter at every SM2 event: a master that was held off for two
        // SYNC0 events (3) and sends its overdue frames back to back before the next event
        // stands at 0 again, so the same stall right after is still no error.
        let mut m = SyncMonitor::new();
        m.outputs_received();
        assert!(m.sync0().take_outputs);
        for _ in 0..2 {
            for _ in 0..2 {
                assert!(!m.sync0().lost);
            }
            assert_eq!(m.error_counter(), 3);
            for _ in 0..3 {
                m.outputs_received();
            }
            assert_eq!(m.error_counter(), 0);
            assert!(!m.sync0().lost);
        }
        assert!(!m.is_lost());
    }

    #[test]
    fn events_seen_late_cost_the_master_nothing() {
        // The device's side ran 20 events late, then the frame that waited meanwhile: in sync.
        let mut m = SyncMonitor::new();
        m.outputs_received();
        assert!(m.sync0().take_outputs);
        m.outputs_received();
        let o = m.sync0_unobserved(20);
        assert!(o.take_outputs && !o.lost);
        assert_eq!(m.error_counter(), 0);
        assert_eq!((m.events, m.missed, m.since_outputs()), (21, 19, 20));
        m.outputs_received();
        assert!(!m.sync0().lost);
        assert_eq!(m.error_counter(), 0);
        // The same 20 events seen in time lose the grid.
        let mut m = SyncMonitor::new();
        m.outputs_received();
        assert!(m.sync0().take_outputs);
        m.outputs_received();
        assert!(m.sync0_many(20).lost);
    }

    #[test]
    fn a_stopped_master_is_still_seen_after_late_events() {
        // Events seen late leave the count of events since the outputs standing: the next
        // two seen in time without outputs reach the limit, as after any two missed cycles.
        let mut m = SyncMonitor::new();
        m.outputs_received();
        m.sync0();
        assert!(!m.sync0_unobserved(5).lost);
        assert!(!m.sync0().lost);
        assert!(m.sync0().lost);
    }

    #[test]
    fn since_outputs_counts_the_events_after_the_last_buffer() {
        let mut m = SyncMonitor::new();
        m.outputs_received();
        assert_eq!(m.since_outputs(), 0);
        for k in 1..=5 {
            m.sync0();
            assert_eq!(m.since_outputs(), k);
        }
        m.outputs_received();
        assert_eq!(m.since_outputs(), 0);
    }

    #[test]
    fn a_burst_of_k_missed_cycles_trips_from_three_on() {
        for k in 0..8u32 {
            let mut m = SyncMonitor::new();
            for _ in 0..100 {
                m.outputs_received();
                assert!(!m.sync0().lost);
            }
            let mut lost = false;
            for _ in 0..k {
                lost |= m.sync0().lost;
            }
            // The master is back: one buffer per cycle again.
            for _ in 0..100 {
                m.outputs_received();
                lost |= m.sync0().lost;
            }
            assert_eq!(lost, k >= 3, "{k} missed in a row");
        }
    }

    #[test]
    fn the_device_limit_decides_and_zero_switches_the_check_off() {
        // 10F1h:02 = 12: up to five misses in a row (0, 3, 6, 9, 12 at the fifth) ...
        let burst = |limit: u16, k: u32| {
            let mut m = SyncMonitor::new();
            m.reset(limit);
            m.outputs_received();
            let mut lost = m.sync0().lost;
            for _ in 0..k {
                lost |= m.sync0().lost;
            }
            (lost, m.error_counter())
        };
        assert_eq!(burst(12, 4), (false, 9));
        assert_eq!(burst(12, 5), (true, 12));
        assert!(!burst(0, 1000).0, "limit 0: no sync error");
        assert_eq!(SyncMonitor::new().limit(), DEFAULT_SYNC_ERROR_LIMIT);
    }

    #[test]
    fn many_events_at_once() {
        let mut m = SyncMonitor::new();
        m.outputs_received();
        let o = m.sync0_many(1000);
        assert!(o.take_outputs);
        assert!(m.is_lost());
        assert_eq!(m.events, 1000);
        assert_eq!(m.missed, 999);
    }
}
