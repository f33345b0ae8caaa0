//! Distributed clocks (SYNC0 active, 0x0981 = 03h): the drive's cycle follows SYNC0 (CMMP-AS
//! §2.11: "the current controller is synchronised to the DC clock, and configured PDOs are
//! evaluated or sent on it"). The output buffer that arrived in a cycle is taken at the next
//! SYNC0 event and the inputs are latched there; a SYNC0 cycle that differs from the
//! interpolator cycle 60C2h is refused on Pre-Op → Safe-Op (and Safe-Op → Op) with 0x0036
//! ("the EtherCAT frame cycle must equal the interpolator cycle tr"). When the master's cycles
//! stop or fall off the SYNC0 grid ([`SyncMonitor`](ethercat::SyncMonitor)) in Op, the slave
//! falls back to Safe-Op with 0x001A and the drive reports 63-4 "no SYNC in IPO cycle" with a
//! fault reaction. Events the loop runs a cycle or more after their time (it was held off its
//! CPU, and the master's frame may wait unread meanwhile) do not count against the master
//! (docs/decisions.md, "SYNC0 events seen late").

use std::time::Duration;

use drive::personality::Fault;
use ethercat::sync_monitor::DEFAULT_SYNC_ERROR_LIMIT;
use ethercat::{AlState, AlStatusCode, Esc};
use od::Instant;

use crate::cell::device_model::Model;

use super::process_data::read_unsigned;
use super::slave::Bound;

/// ETG.1020 error settings 10F1h and its sub-index 2, the sync error counter limit.
const SYNC_ERROR_SETTINGS: u16 = 0x10F1;
const SYNC_ERROR_COUNTER_LIMIT: u8 = 2;

/// At most this many SYNC0 events are run one by one after a pause; the rest are counted at
/// once, as events seen late.
const MAX_SYNC0_BURST: u64 = 16;
/// A SYNC0 grid finer than this is served at most this often, its events counted in batches
/// (the burst above). Decision: 0x09A0 takes any cycle and nothing checks it before Pre-Op →
/// Safe-Op (0x0036 against 60C2h), where a real ESC would pulse that fast and the drive's PDI
/// could not follow; served event by event, a grid of nanoseconds made the chain due every
/// few nanoseconds and the runtime spin (fuzz finding, `ethercat_cell.rs`
/// `sync0_cycle_of_nanoseconds_does_not_spin_the_loop_fuzz_ecat_2ad63ffb`). 50 µs lies below
/// the drive's 250 µs controller cycle (6510h:B1): every grid it could follow is served event
/// by event as before.
pub const SYNC0_SERVICE_FLOOR: Duration = Duration::from_micros(50);

impl Bound<'_> {
    /// Runs the SYNC0 events due at `now`: the drive steps to each event, takes the outputs
    /// of the cycle and latches its inputs; a lost synchronisation in Op falls back to
    /// Safe-Op with 0x001A.
    ///
    /// Runs after every frame: without SYNC0 (free run) it only looks at the ESC's SYNC0
    /// registers, inlined where it is called; the events run apart.
    #[inline]
    pub(super) fn run_sync0(&mut self, esc: &mut Esc<'_>, now: Instant) {
        if self.dev.sync_config.is_none() && esc.sync0_cycle_ns().is_none() {
            self.dev.next_sync0 = None;
            return;
        }
        self.run_sync0_events(esc, now);
    }

    #[inline(never)]
    fn run_sync0_events(&mut self, esc: &mut Esc<'_>, now: Instant) {
        let config = esc.sync0_cycle_ns().map(|cycle| (cycle, esc.sync0_start()));
        if config != self.dev.sync_config {
            // SYNC0 switched on, off or moved: a new grid, a new count.
            self.dev.sync_config = config;
            let limit = self.sync_error_limit();
            self.dev.sync.reset(limit);
            self.dev.next_sync0_sys = config.and_then(|_| esc.next_sync0_at(now));
        }
        let Some((cycle, _)) = config else {
            self.dev.next_sync0 = None;
            return;
        };
        let cycle = u64::from(cycle);
        let sys_now = esc.system_time_at(now);
        let mut burst = 0;
        // An event run this far after its time was not seen in time: the loop was held off,
        // and the master's frames may lie unread in the socket (`SyncMonitor::sync0_unobserved`);
        // nor was one while a late answer held the master back ([`SlaveChain::answered`]).
        let seen_late = cycle.max(SYNC0_SERVICE_FLOOR.as_nanos() as u64);
        while let Some(at_sys) = self.dev.next_sync0_sys.filter(|t| *t <= sys_now) {
            let behind = (sys_now - at_sys) / cycle;
            // The local instant of the event: `now` less how far the event lies back.
            let at = Instant::from_nanos(now.as_nanos().saturating_sub(sys_now - at_sys));
            self.step(at);
            burst += 1;
            let late = sys_now - at_sys >= seen_late || self.dev.held_master_at(at);
            let (outcome, events) = if burst >= MAX_SYNC0_BURST {
                (self.dev.sync.sync0_unobserved(behind + 1), behind + 1)
            } else if late {
                (self.dev.sync.sync0_unobserved(1), 1)
            } else {
                (self.dev.sync.sync0(), 1)
            };
            let state = esc.al_state();
            if outcome.take_outputs && state == AlState::Op {
                let pending = core::mem::take(&mut self.dev.pending);
                self.apply_outputs(&pending);
                self.dev.pending = pending;
                self.dev.outputs_applied += 1;
            }
            self.sync_drive(at);
            if outcome.lost && state == AlState::Op {
                self.sync_lost(esc, at, now);
            }
            if matches!(esc.al_state(), AlState::SafeOp | AlState::Op) {
                self.post_inputs(esc);
            }
            self.dev.next_sync0_sys = Some(at_sys.wrapping_add(events.wrapping_mul(cycle)));
        }
        let floor =
            (cycle < SYNC0_SERVICE_FLOOR.as_nanos() as u64).then(|| now + SYNC0_SERVICE_FLOOR);
        self.dev.next_sync0 = self.dev.next_sync0_sys.map(|t| {
            let at = Instant::from_nanos(now.as_nanos().saturating_add(t.saturating_sub(sys_now)));
            floor.map_or(at, |f| at.max(f))
        });
    }

    /// The sync error counter limit: the dictionary's 10F1h:02 "Sync Error Counter Limit"
    /// (ETG.1020) where the device has one, else the slave stack's default.
    pub(super) fn sync_error_limit(&self) -> u16 {
        let model: &Model = self.model;
        read_unsigned(model, SYNC_ERROR_SETTINGS, SYNC_ERROR_COUNTER_LIMIT)
            .map_or(DEFAULT_SYNC_ERROR_LIMIT, |v| {
                u16::try_from(v).unwrap_or(u16::MAX)
            })
    }

    /// A SYNC for the drive (interpolated position mode's time base).
    pub(super) fn sync_drive(&mut self, at: Instant) {
        if let Some(drive) = self.model.drive_mut() {
            drive.sync(at);
        }
        self.forward_events();
    }

    /// The master's cycles stopped or left the SYNC0 grid at the event at `at`, run at `now`.
    pub(super) fn sync_lost(&mut self, esc: &mut Esc<'_>, at: Instant, now: Instant) {
        self.dev.sync_errors += 1;
        tracing::warn!(
            station = esc.station_address(),
            missed = self.dev.sync.missed,
            // The SYNC0 events since the last output buffer, and the buffers taken in Op:
            // whether the master's frames stopped or came off the grid.
            without_outputs = self.dev.sync.since_outputs(),
            sync0_events = self.dev.sync.events,
            outputs_applied = self.dev.outputs_applied,
            // Whether the outputs were late at the slave (the last buffer long before the
            // event) or the loop ran the event late (`run_late_us`).
            last_outputs_before_us = self
                .dev
                .last_outputs_at
                .map(|o| at.saturating_since(o).as_micros()),
            run_late_us = now.saturating_since(at).as_micros(),
            "synchronisation lost: Safe-Op, 0x001A"
        );
        esc.fall_back(AlState::SafeOp, AlStatusCode::SYNCHRONIZATION_ERROR);
        self.dev.layout_inputs_only();
        // The drive reports a lost synchronisation as its personality's fieldbus
        // synchronisation error. The CMMP-AS's B.3 63-4 "EtherCAT: no SYNC in IPO cycle" has
        // no CiA code in Tab. B.2; decision: its "fieldbus synchronisation error" (34-1,
        // 8781h, error register 11h), the one the manual gives for a lost SYNC.
        let error = self.model.drive_mut().and_then(|drive| {
            let e = drive.personality().error(Fault::FieldbusSyncError)?;
            Some((drive, e))
        });
        if let Some((drive, e)) = error {
            // The error is raised once; its cause is gone with it, so a fault reset clears it.
            drive.inject_fault(e.code, e.register);
            drive.clear_fault(e.code);
        }
        self.forward_events();
    }

    /// SYNC0 on and its cycle differs from the interpolator cycle: 0x0036.
    pub(super) fn check_sync0(&self, esc: &Esc<'_>) -> Result<(), AlStatusCode> {
        // The interpolator cycle tr is the drive's 60C2h as it took it at power-on (CMMP-AS
        // §7.4.1: a change takes effect only after save and reset).
        let ipo = self
            .model
            .drive()
            .map(|d| d.interpolation_period().as_nanos());
        match (esc.sync0_cycle_ns(), ipo) {
            (Some(cycle), Some(ipo)) if u128::from(cycle) != ipo => {
                Err(AlStatusCode::DC_SYNC0_CYCLE_TIME)
            }
            _ => Ok(()),
        }
    }
}
