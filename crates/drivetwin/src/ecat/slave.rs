//! One slave behind its ESC: the device's protocol state ([`SlaveDevice`]) and, bound to its
//! drive for the length of one call (`Bound`), what it does after a frame and between
//! frames, and the ESC's AL state hooks.
//!
//! * Free run (no SYNC0): after every frame the newest complete output buffer is written
//!   object by object through [`od::ObjectAccess::write`] in Op only (Safe-Op ignores set-points,
//!   CMMP-AS §4.2); the drive runs up to the frame's time; the mapped objects are read back
//!   into the input buffer (Safe-Op and Op), which the master reads with its next frame, one
//!   cycle later, as from a real ESC whose PDI runs beside the wire. With SYNC0, the
//!   [`sync0`](super::sync0) module.
//! * Between frames the runtime polls the chain at least every [`TICK`], so the drive (and
//!   the ESC's process-data watchdog) runs while the master is silent; in real time up to
//!   [`STEP_GRACE`] later ([`SlaveChain::wake_by`](super::chain::SlaveChain::wake_by)), so
//!   that the loop's wake-up for it falls between a master's frames, not onto them.

use std::collections::VecDeque;
use std::time::Duration;

use canopen::emcy::EmcyProducer;
use drive::drive::DriveEvent;
use ethercat::coe::{self, CoeConfig, CoeServer};
use ethercat::sii::SiiConfig;
use ethercat::{AlHook, AlState, AlStatusCode, Esc, SyncMonitor};
use od::{DeviceDescription, Instant};

use crate::cell::device_model::Model;
use crate::cell::param_store::{ParamStore, StoredValue};

use super::coe_dispatch::SaveInFlight;
use super::process_data::Layout;
use super::slave_drive::{BusDrives, SlaveDrive};
use super::sync0::SYNC0_SERVICE_FLOOR;

/// How often the drives run at least when no frame arrives.
pub const TICK: Duration = Duration::from_millis(1);

/// How late a loop in real time may step a drive that no frame stepped
/// ([`SlaveChain::wake_by`](super::chain::SlaveChain::wake_by)).
pub const STEP_GRACE: Duration = Duration::from_micros(500);

/// CiA 301 Tab. 21 "RPDO timeout": the error a drive without a message of its own for an
/// expired process-data watchdog reports ([`Bound::watchdog_expired`]).
const PROCESS_DATA_TIMEOUT: u16 = 0x8250;

/// The protocol state of one slave behind its ESC: CoE server, process-data layout, SYNC0
/// grid. The drive itself is reached through [`SlaveDrive`], so the same drive may be a
/// CANopen node of the cell as well (`DESIGN.md`: a front end holds only its protocol state).
pub struct SlaveDevice {
    pub(super) desc: &'static DeviceDescription,
    pub(super) coe: Box<CoeServer>,
    pub(super) sii: SiiConfig<'static>,
    pub(super) layout: Option<Layout>,
    pub(super) inputs: Vec<u8>,
    pub(super) next_step: Option<Instant>,
    /// DC synchronisation of the outputs and inputs.
    pub(super) sync: SyncMonitor,
    /// The output buffer waiting for the next SYNC0 event.
    pub(super) pending: Vec<u8>,
    /// SYNC0 configuration (activation, cycle, start) the event grid below belongs to.
    pub(super) sync_config: Option<(u32, u64)>,
    /// System time of the next SYNC0 event to run.
    pub(super) next_sync0_sys: Option<u64>,
    /// Local time of that event (for the runtime's deadline).
    pub(super) next_sync0: Option<Instant>,
    /// Times the synchronisation was lost in Op.
    pub sync_errors: u64,
    /// Output buffers applied to the device (Op).
    pub outputs_applied: u64,
    /// Output buffers ignored (Safe-Op).
    pub outputs_ignored: u64,
    /// Mapped objects the device refused to take.
    pub write_errors: u64,
    /// Times the process-data watchdog expired in Op.
    pub watchdog_expiries: u64,
    /// Until when the master is held by an answer the chain sent late
    /// ([`SlaveChain::answered`](super::SlaveChain::answered)): SYNC0 events up to then do not
    /// count against it.
    master_held_until: Option<Instant>,
    /// When the last output buffer of a DC cycle came (the frame's time), for the warning of a
    /// lost synchronisation.
    pub(super) last_outputs_at: Option<Instant>,
    /// A 1010h "save" whose file the runtime writes, with the reply that waits for it.
    pub(super) saving: Option<SaveInFlight>,
    /// The active errors of a drive on EtherCAT alone, which set its 1001h error register and
    /// its 1003h history as a CANopen node's EMCY producer does (CiA 301 §7.5.2.2, §7.5.2.3;
    /// ETG.1000.6 §5.6.4 takes the CANopen emergency as it is). Its frames are never sent:
    /// the CoE emergencies are.
    pub(super) errors: EmcyProducer,
}

/// A slave with its drive, for the length of one call: the ESC's [`AlHook`].
pub(super) struct Bound<'a> {
    pub(super) dev: &'a mut SlaveDevice,
    pub(super) model: &'a mut Model,
    pub(super) store: Option<&'a ParamStore>,
    pub(super) stored: &'a mut Vec<StoredValue>,
    /// A drive shared with CANopen: its events as the CANopen side took them (it sends them
    /// as EMCY and keeps a copy here for the CoE emergencies).
    pub(super) shared_events: Option<&'a mut VecDeque<DriveEvent>>,
}

impl<'a> Bound<'a> {
    pub(super) fn new(
        dev: &'a mut SlaveDevice,
        drive: &'a mut SlaveDrive,
        buses: &'a mut dyn BusDrives,
    ) -> Option<Self> {
        let station = match drive {
            SlaveDrive::Own(station) => station,
            SlaveDrive::Station { id, bus: None } => buses.in_cell(*id)?,
            SlaveDrive::Station { id, bus: Some(_) } => {
                let (model, store, stored, events) = buses.in_cell(*id)?.coe_parts();
                return Some(Bound {
                    dev,
                    model,
                    store,
                    stored,
                    shared_events: Some(events),
                });
            }
        };
        let (model, store, stored) = station.drive_parts();
        Some(Bound {
            dev,
            model,
            store,
            stored,
            shared_events: None,
        })
    }
}

impl SlaveDevice {
    pub fn new(sii: SiiConfig<'static>, coe: CoeConfig, desc: &'static DeviceDescription) -> Self {
        SlaveDevice {
            desc,
            coe: Box::new(CoeServer::new(desc, coe)),
            sii,
            layout: None,
            inputs: Vec::new(),
            next_step: None,
            sync: SyncMonitor::new(),
            pending: Vec::new(),
            sync_config: None,
            next_sync0_sys: None,
            next_sync0: None,
            sync_errors: 0,
            outputs_applied: 0,
            outputs_ignored: 0,
            write_errors: 0,
            watchdog_expiries: 0,
            master_held_until: None,
            last_outputs_at: None,
            saving: None,
            errors: EmcyProducer::default(),
        }
    }

    /// Whether a 1010h "save" is still writing its file (its CoE reply waits).
    pub fn saving(&self) -> bool {
        self.saving.is_some()
    }

    /// The personality the slave was built for.
    pub fn description(&self) -> &'static DeviceDescription {
        self.desc
    }

    /// The layout in force (Safe-Op and Op).
    pub fn layout(&self) -> Option<&Layout> {
        self.layout.as_ref()
    }

    /// The synchronisation monitor (DC mode).
    pub fn sync_monitor(&self) -> &SyncMonitor {
        &self.sync
    }

    /// CoE counters (requests, aborts, emergencies).
    pub fn coe_counters(&self) -> coe::CoeCounters {
        self.coe.counters()
    }

    /// Safe-Op keeps the layout (inputs go on) but no outputs wait.
    pub(super) fn layout_inputs_only(&mut self) {
        self.pending.clear();
        let limit = self.sync.limit();
        self.sync.reset(limit);
    }
}

impl Bound<'_> {
    /// The device's part of a frame: outputs in, drive to `now`, inputs out (free run); with
    /// SYNC0 the outputs wait for the next event.
    pub(super) fn exchange(&mut self, esc: &mut Esc<'_>, now: Instant) {
        // Events that fell due before this frame run with the outputs of their own cycle.
        self.run_sync0(esc, now);
        self.step(now);
        let state = esc.al_state();
        let dc = self.dev.sync_config.is_some();
        if let Some(out) = esc.process_outputs() {
            if state != AlState::Op {
                self.dev.outputs_ignored += 1;
            } else if dc {
                self.dev.pending.clear();
                self.dev.pending.extend_from_slice(out);
                self.dev.sync.outputs_received();
                self.dev.last_outputs_at = Some(now);
            } else {
                self.apply_outputs(out);
                self.dev.outputs_applied += 1;
                // Free run: the frame is the time base (CMMP-AS §2.11 "without DC").
                self.sync_drive(now);
            }
        }
        if !dc {
            self.post_inputs(esc);
        }
        self.mailbox(esc);
    }

    /// Time passes without a frame: SYNC0 events, the drive, the ESC's watchdog, the inputs
    /// and the mailbox.
    pub(super) fn poll(&mut self, esc: &mut Esc<'_>, now: Instant) {
        self.run_sync0(esc, now);
        self.step(now);
        esc.poll_with(now, self);
        if self.dev.sync_config.is_none() && matches!(esc.al_state(), AlState::SafeOp | AlState::Op)
        {
            self.post_inputs(esc);
        }
        self.mailbox(esc);
    }

    /// The process-data watchdog expired in Op (the master's frames stopped): the device
    /// raises the message its device file names for it (`watchdog_diagnostic`), with that
    /// message's reaction. Its cause ends with the frames' absence being noticed, so a fault
    /// reset clears it once the master is back.
    pub(super) fn watchdog_expired(&mut self) {
        self.dev.watchdog_expiries += 1;
        let number = self.dev.desc.ethercat.and_then(|e| e.watchdog_diagnostic);
        if let Some(drive) = self.model.drive_mut() {
            match number {
                Some(number) => {
                    if drive.raise_diagnostic(number).is_ok() {
                        let _ = drive.clear_diagnostic(number);
                    }
                }
                // Decision: a device that names no message for it (a drive from an EDS)
                // reports CiA 301's 8250h "RPDO timeout" (its process data stopped coming)
                // with the communication bit of the error register, rather than stand in
                // Operation enabled on the last set-point of a slave that takes no more.
                None => {
                    drive.inject_fault(PROCESS_DATA_TIMEOUT, 0x11);
                    drive.clear_fault(PROCESS_DATA_TIMEOUT);
                }
            }
        }
        self.forward_events();
    }

    pub(super) fn step(&mut self, now: Instant) {
        self.dev.next_step = self.model.step(now).map(|t| t.max(now + TICK));
        self.forward_events();
    }
}

/// A slave whose drive is bound only when its ESC calls the hook: a frame passes every slave
/// in every cycle, and the AL hooks run only on a state change, so the drive is not looked up
/// for the frame's pass. A drive that is not in the cell leaves the ESC's own checks alone, as
/// [`ethercat::NoHook`] does.
pub(super) struct Unbound<'a> {
    pub(super) dev: &'a mut SlaveDevice,
    pub(super) drive: &'a mut SlaveDrive,
    pub(super) buses: &'a mut dyn BusDrives,
}

impl AlHook for Unbound<'_> {
    fn check_transition(
        &mut self,
        esc: &Esc<'_>,
        from: AlState,
        to: AlState,
    ) -> Result<(), AlStatusCode> {
        match Bound::new(self.dev, self.drive, self.buses) {
            Some(mut b) => b.check_transition(esc, from, to),
            None => Ok(()),
        }
    }

    fn state_changed(&mut self, esc: &mut Esc<'_>, from: AlState, to: AlState) {
        if let Some(mut b) = Bound::new(self.dev, self.drive, self.buses) {
            b.state_changed(esc, from, to);
        }
    }
}

impl AlHook for Bound<'_> {
    fn check_transition(
        &mut self,
        esc: &Esc<'_>,
        from: AlState,
        to: AlState,
    ) -> Result<(), AlStatusCode> {
        if from == AlState::PreOp && to == AlState::SafeOp {
            let layout = self.compute_layout()?;
            esc.check_process_data(layout.output_bytes, layout.input_bytes)?;
            self.check_sync0(esc)?;
            self.dev.layout = Some(layout);
        }
        if from == AlState::SafeOp && to == AlState::Op {
            // SYNC0 may have been switched on in Safe-Op.
            self.check_sync0(esc)?;
        }
        Ok(())
    }

    fn state_changed(&mut self, esc: &mut Esc<'_>, from: AlState, to: AlState) {
        tracing::debug!(?from, ?to, station = esc.station_address(), "AL state");
        if from == AlState::Op {
            self.dev.layout_inputs_only();
            if esc.al_status_code() == AlStatusCode::SYNC_MANAGER_WATCHDOG {
                self.watchdog_expired();
            }
        }
        if to == AlState::Op {
            // Safe-Op → Op starts the sync error count afresh, with the limit of the moment
            // (the master may have written 10F1h:02 in Pre-Op).
            let limit = self.sync_error_limit();
            self.dev.sync.reset(limit);
        }
        match to {
            AlState::SafeOp | AlState::Op => self.post_inputs(esc),
            AlState::Init | AlState::PreOp | AlState::Bootstrap => self.dev.layout = None,
        }
    }
}

impl SlaveDevice {
    /// As [`SlaveChain::answered`](super::SlaveChain::answered): an answer `delay` late went
    /// out at `answered`.
    pub(super) fn answered(&mut self, delay: Duration, answered: Instant) {
        let Some((cycle, _)) = self.sync_config else {
            return;
        };
        let cycle = Duration::from_nanos(u64::from(cycle)).max(SYNC0_SERVICE_FLOOR);
        if delay >= cycle {
            let until = answered + cycle;
            self.master_held_until = Some(self.master_held_until.map_or(until, |u| u.max(until)));
        }
    }

    /// Whether a late answer held the master back at the SYNC0 event at `at`.
    pub(super) fn held_master_at(&self, at: Instant) -> bool {
        self.master_held_until.is_some_and(|u| at <= u)
    }
}
