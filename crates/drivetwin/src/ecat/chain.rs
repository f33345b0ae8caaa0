//! An EtherCAT chain: emulated slave controllers (ESCs), each with the device behind it, that
//! one Ethernet frame passes in order, as a line of real slaves.
//!
//! Every slave is an [`Esc`] loaded with the SII image of its personality
//! (`ethercat::sii::build_sii`) and a [`SlaveDevice`]: the dictionary and, for a CiA 402
//! personality, the simulated drive and motor, built exactly as the CANopen cell builds them
//! (cell file, motor commissioning, [`Station::with_settings`]).
//!
//! Process data (the manual's extract kept beside the project, `cmmp-as-1-communication.md` §2):
//!
//! * On Pre-Op → Safe-Op the device takes the PDO assignment (1C12h / 1C13h when the
//!   dictionary has them, else the SII defaults 1600h / 1A00h: the CMMP-AS maps its EtherCAT
//!   process data with the CANopen mapping objects 1600h–1603h / 1A00h–1A03h) and computes
//!   the bit layout of SM2 (outputs) and SM3 (inputs) from the mapping entries. A mapping the
//!   dictionary refuses is refused with 0x0025 (outputs) / 0x0024 (inputs); SM2 / SM3 sizes
//!   that do not match it with 0x001D / 0x001E ([`Esc::check_process_data`]).
//! * Free run (no SYNC0): after every frame the newest complete output buffer is written
//!   object by object through [`ObjectAccess::write`] in Op only (Safe-Op ignores set-points,
//!   CMMP-AS §4.2); the drive runs up to the frame's time; the mapped objects are read back
//!   into the input buffer (Safe-Op and Op), which the master reads with its next frame, one
//!   cycle later, as from a real ESC whose PDI runs beside the wire.
//! * Distributed clocks (SYNC0 active, 0x0981 = 03h): the drive's cycle follows SYNC0
//!   (CMMP-AS §2.11: "the current controller is synchronised to the DC clock, and configured
//!   PDOs are evaluated or sent on it"). The output buffer that arrived in a cycle is taken at
//!   the next SYNC0 event and the inputs are latched there; a SYNC0 cycle that differs from
//!   the interpolator cycle 60C2h is refused on Pre-Op → Safe-Op (and Safe-Op → Op) with
//!   0x0036 ("the EtherCAT frame cycle must equal the interpolator cycle tr"). When the
//!   master's cycles stop or fall off the SYNC0 grid ([`SyncMonitor`]) in Op, the slave falls
//!   back to Safe-Op with 0x001A and the drive reports 63-4 "no SYNC in IPO cycle" with a
//!   fault reaction. Events the loop runs a cycle or more after their time (it was held off
//!   its CPU, and the master's frame may wait unread meanwhile) do not count against the
//!   master (docs/decisions.md, "SYNC0 events seen late").
//! * Between frames the cell loop polls the chain at least every [`TICK`], so the drive (and the
//!   ESC's process-data watchdog) runs while the master is silent; in real time up to
//!   [`STEP_GRACE`] later ([`SlaveChain::wake_by`]), so that the loop's wake-up for it falls
//!   between a master's frames, not onto them.
//!
//! * The mailbox speaks CoE ([`ethercat::coe`], the CMMP-AS set of services): after every
//!   frame and every tick the device answers the request waiting in SM0 (or sends the next
//!   fragment or a queued emergency); the drive's errors go out as CoE emergencies.
//!
//! * PDO assignment and mapping are written in Pre-Op only ([`coe::MappingLock`]); the
//!   layout is taken on Pre-Op → Safe-Op.
//!
//! * Stored parameters: with a state directory, 1010h "save" over CoE writes the drive's
//!   file before the answer (as over CANopen) and the next start loads it. The file is written
//!   on a thread of its own (`SaveInFlight`): the reply waits in the device until the file is
//!   synced (0800 0020h if that failed) and the mailbox serves nothing else meanwhile, while the
//!   ESC, hardware on a real slave, goes on answering every frame with its working counter.
//!   Written on the loop thread, two fsyncs under load held the loop for tens of ms and the
//!   master's frames of that time came back late or not at all (`tests/interop/test_kill9.py`
//!   saw pysoem's 1010h write fail with a wrong working counter after ~18 ms).

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::thread::JoinHandle;
use std::time::Duration;

use canopen::emcy::EmcyProducer;
use drive::drive::DriveEvent;
use drive::personality::Fault;
use ethercat::coe::{self, CoeConfig, CoeServer, Emergency};
use ethercat::esc::MAILBOX_MAX;
use ethercat::sii::{self, SiiConfig};
use ethercat::sync_monitor::DEFAULT_SYNC_ERROR_LIMIT;
use ethercat::{AlHook, AlState, AlStatusCode, ClockError, Esc, FrameOutcome, SyncMonitor};
use od::pdo_rules::{check_map_entry, MapEntry};
use od::{
    time::earliest, AbortCode, DeviceDescription, Entry, Instant, ObjectAccess, StorageRequest,
};

use crate::cell::can_cell::CanCell;
use crate::cell::config::{CellFile, ConfigError, DriveSpec};
use crate::cell::device_model::Model;
use crate::cell::param_store::{ParamStore, StoreError, StoredValue};
use crate::cell::station::{Persisting, Station, StationError};
use crate::cell::stations::{StationId, Stations};
use crate::cell::Vendors;

use super::line::{Line, LineError};

/// How often the drives run at least when no frame arrives.
pub const TICK: Duration = Duration::from_millis(1);

/// How late a loop in real time may step a drive that no frame stepped
/// ([`SlaveChain::wake_by`]).
pub const STEP_GRACE: Duration = Duration::from_micros(500);

/// PDO assignment objects (ETG.1000.6): SM2 (RxPDO) and SM3 (TxPDO).
const RX_ASSIGN: u16 = 0x1C12;
const TX_ASSIGN: u16 = 0x1C13;

/// CiA 301 Tab. 21 "RPDO timeout": the error a drive without a message of its own for an
/// expired process-data watchdog reports ([`Bound::watchdog_expired`]).
const PROCESS_DATA_TIMEOUT: u16 = 0x8250;

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

#[derive(Debug, thiserror::Error)]
pub enum SlaveChainError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Drive(#[from] StationError),
    #[error("{device}: no SII image: {error:?}")]
    Sii {
        device: &'static str,
        error: sii::SiiError,
    },
    #[error("an EtherCAT chain needs at least one slave")]
    Empty,
    #[error(transparent)]
    Line(#[from] LineError),
    #[error(transparent)]
    Eds(#[from] crate::cell::eds_ethercat::EdsEthercatError),
}

/// One mapped object in a process image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MapItem {
    pub index: u16,
    pub sub: u8,
    /// Bit offset in the process image.
    pub offset: usize,
    pub bits: u8,
    /// A dummy entry (RxPDO gap): skipped.
    pub dummy: bool,
}

/// The process-data layout taken on Pre-Op → Safe-Op.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Layout {
    /// SM2, master → device.
    pub outputs: Vec<MapItem>,
    /// SM3, device → master.
    pub inputs: Vec<MapItem>,
    pub output_bytes: u16,
    pub input_bytes: u16,
}

/// The protocol state of one slave behind its ESC: CoE server, process-data layout, SYNC0
/// grid. The drive itself is reached through [`SlaveDrive`], so the same drive may be a
/// CANopen node of the cell as well (`DESIGN.md`: a front end holds only its protocol state).
pub struct SlaveDevice {
    desc: &'static DeviceDescription,
    coe: Box<CoeServer>,
    sii: SiiConfig<'static>,
    layout: Option<Layout>,
    inputs: Vec<u8>,
    next_step: Option<Instant>,
    /// DC synchronisation of the outputs and inputs.
    sync: SyncMonitor,
    /// The output buffer waiting for the next SYNC0 event.
    pending: Vec<u8>,
    /// SYNC0 configuration (activation, cycle, start) the event grid below belongs to.
    sync_config: Option<(u32, u64)>,
    /// System time of the next SYNC0 event to run.
    next_sync0_sys: Option<u64>,
    /// Local time of that event (for the runtime's deadline).
    next_sync0: Option<Instant>,
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
    /// ([`SlaveChain::answered`]): SYNC0 events up to then do not count against it.
    master_held_until: Option<Instant>,
    /// A 1010h "save" whose file is being written, with the reply that waits for it.
    saving: Option<SaveInFlight>,
    /// The active errors of a drive on EtherCAT alone, which set its 1001h error register and
    /// its 1003h history as a CANopen node's EMCY producer does (CiA 301 §7.5.2.2, §7.5.2.3;
    /// ETG.1000.6 §5.6.4 takes the CANopen emergency as it is). Its frames are never sent:
    /// the CoE emergencies are.
    errors: EmcyProducer,
}

/// The thread writing a save's file; its result is the stored set read back.
type SaveJob = JoinHandle<Result<Vec<StoredValue>, StoreError>>;

/// A 1010h "save" over CoE in progress: the file is written and synced on a thread of its own
/// (the stored set read back is its result); the CoE reply waits here until it is done.
struct SaveInFlight {
    job: SaveJob,
    /// 1010h:`sub`, for the abort if the file cannot be written.
    sub: u8,
    /// The mailbox message the CoE server made; posted when the file is written.
    reply: Vec<u8>,
}

/// The drive behind a slave.
pub enum SlaveDrive {
    /// Its own: the station of a drive on EtherCAT alone (no CANopen node), with where 1010h
    /// "save" writes its parameters and the set last saved.
    Own(Box<Station>),
    /// Station `id` of the cell's list: a drive of its own once the chain has joined a cell
    /// ([`SlaveChain::join`]; `bus` none), or a CANopen drive of CAN bus `bus` served over
    /// EtherCAT as well (`allow_unreal_interfaces`): a value written over CoE is the one SDO
    /// reads.
    Station { id: StationId, bus: Option<usize> },
}

/// Where the drives of [`SlaveDrive::Station`] slaves live: the cell's list of stations.
pub trait BusDrives {
    /// Station `id` of the cell's list (none: the chain has not joined a cell).
    fn in_cell(&mut self, _id: StationId) -> Option<&mut Station> {
        None
    }
}

/// A chain without CAN buses: every slave has a drive of its own.
pub struct NoBuses;

impl BusDrives for NoBuses {}

/// The chains that joined a cell ([`SlaveChain::join_cell`]) find their drives in its list.
impl BusDrives for CanCell {
    fn in_cell(&mut self, id: StationId) -> Option<&mut Station> {
        self.stations.station_mut(id)
    }
}

/// A slave with its drive, for the length of one call: the ESC's [`AlHook`].
struct Bound<'a> {
    dev: &'a mut SlaveDevice,
    model: &'a mut Model,
    store: Option<&'a ParamStore>,
    stored: &'a mut Vec<StoredValue>,
    /// A drive shared with CANopen: its events as the CANopen side took them (it sends them
    /// as EMCY and keeps a copy here for the CoE emergencies).
    shared_events: Option<&'a mut VecDeque<DriveEvent>>,
}

impl<'a> Bound<'a> {
    fn new(
        dev: &'a mut SlaveDevice,
        drive: &'a mut SlaveDrive,
        buses: &'a mut dyn BusDrives,
    ) -> Option<Self> {
        match drive {
            SlaveDrive::Own(station) => {
                let (model, store, stored) = station.drive_parts();
                Some(Bound {
                    dev,
                    model,
                    store,
                    stored,
                    shared_events: None,
                })
            }
            SlaveDrive::Station { id, bus: None } => {
                let (model, store, stored) = buses.in_cell(*id)?.drive_parts();
                Some(Bound {
                    dev,
                    model,
                    store,
                    stored,
                    shared_events: None,
                })
            }
            SlaveDrive::Station { id, bus: Some(_) } => {
                let (model, store, stored, events) = buses.in_cell(*id)?.coe_parts();
                Some(Bound {
                    dev,
                    model,
                    store,
                    stored,
                    shared_events: Some(events),
                })
            }
        }
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
    fn layout_inputs_only(&mut self) {
        self.pending.clear();
        let limit = self.sync.limit();
        self.sync.reset(limit);
    }
}

impl Bound<'_> {
    /// The PDO assignment of SM2 or SM3: 1C12h / 1C13h from the dictionary when it has
    /// them, else the SII's defaults.
    fn assignment(&self, rx: bool) -> Result<Vec<u16>, ()> {
        let index = if rx { RX_ASSIGN } else { TX_ASSIGN };
        let model: &Model = self.model;
        if model.entry(index, 0).is_err() {
            let d = if rx {
                self.dev.sii.rx_assigned
            } else {
                self.dev.sii.tx_assigned
            };
            return Ok(d.to_vec());
        }
        let count = read_unsigned(model, index, 0).ok_or(())?;
        (1..=count)
            .map(|sub| {
                let sub = u8::try_from(sub).map_err(|_| ())?;
                read_unsigned(model, index, sub)
                    .and_then(|v| u16::try_from(v).ok())
                    .ok_or(())
            })
            .collect()
    }

    /// The items of one direction from the current mapping objects, and the bit length.
    fn map(&self, rx: bool) -> Result<(Vec<MapItem>, usize), ()> {
        let model: &Model = self.model;
        let desc = model.od().description();
        let mut items = Vec::new();
        let mut offset = 0usize;
        for pdo in self.assignment(rx)? {
            let count = read_unsigned(model, pdo, 0).ok_or(())?;
            for sub in 1..=count {
                let sub = u8::try_from(sub).map_err(|_| ())?;
                let v = read_unsigned(model, pdo, sub).ok_or(())?;
                let v = u32::try_from(v).map_err(|_| ())?;
                if v == 0 {
                    continue;
                }
                check_map_entry(desc, !rx, v).map_err(|_| ())?;
                let m = MapEntry::from_u32(v);
                items.push(MapItem {
                    index: m.index,
                    sub: m.sub,
                    offset,
                    bits: m.bits,
                    dummy: m.is_dummy(),
                });
                offset += usize::from(m.bits);
            }
        }
        Ok((items, offset))
    }

    /// The layout the current dictionary gives, or the AL status code that refuses it.
    fn compute_layout(&self) -> Result<Layout, AlStatusCode> {
        let (outputs, out_bits) = self
            .map(true)
            .map_err(|()| AlStatusCode::INVALID_OUTPUT_MAPPING)?;
        let (inputs, in_bits) = self
            .map(false)
            .map_err(|()| AlStatusCode::INVALID_INPUT_MAPPING)?;
        Ok(Layout {
            outputs,
            inputs,
            output_bytes: u16::try_from(out_bits.div_ceil(8))
                .map_err(|_| AlStatusCode::INVALID_OUTPUT_MAPPING)?,
            input_bytes: u16::try_from(in_bits.div_ceil(8))
                .map_err(|_| AlStatusCode::INVALID_INPUT_MAPPING)?,
        })
    }

    /// Writes the mapped objects of an output buffer into the device.
    fn apply_outputs(&mut self, data: &[u8]) {
        let Some(layout) = &self.dev.layout else {
            return;
        };
        let mut value = [0u8; 8];
        for item in layout.outputs.iter().filter(|i| !i.dummy) {
            let n = usize::from(item.bits).div_ceil(8);
            let Some(v) = value.get_mut(..n) else {
                continue;
            };
            get_bits(data, item.offset, item.bits, v);
            if self.model.write(item.index, item.sub, v).is_err() {
                self.dev.write_errors += 1;
            }
        }
    }

    /// Reads the mapped objects into the input buffer and hands it to the ESC.
    fn post_inputs(&mut self, esc: &mut Esc<'_>) {
        let dev = &mut *self.dev;
        let Some(layout) = &dev.layout else {
            return;
        };
        dev.inputs.clear();
        dev.inputs.resize(usize::from(layout.input_bytes), 0);
        let mut value = [0u8; 8];
        for item in &layout.inputs {
            value.fill(0);
            // A value that cannot be read leaves zeros, as a real PDI would leave stale data.
            let _ = self.model.read(item.index, item.sub, &mut value);
            set_bits(&mut dev.inputs, item.offset, item.bits, &value);
        }
        if !dev.inputs.is_empty() {
            let _ = esc.set_inputs(&dev.inputs);
        }
    }

    /// The device's part of a frame: outputs in, drive to `now`, inputs out (free run); with
    /// SYNC0 the outputs wait for the next event.
    fn exchange(&mut self, esc: &mut Esc<'_>, now: Instant) {
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
    fn poll(&mut self, esc: &mut Esc<'_>, now: Instant) {
        self.run_sync0(esc, now);
        self.step(now);
        esc.poll_with(now, self);
        if self.dev.sync_config.is_none() && matches!(esc.al_state(), AlState::SafeOp | AlState::Op)
        {
            self.post_inputs(esc);
        }
        self.mailbox(esc);
    }

    /// Runs the SYNC0 events due at `now`: the drive steps to each event, takes the outputs
    /// of the cycle and latches its inputs; a lost synchronisation in Op falls back to
    /// Safe-Op with 0x001A.
    fn run_sync0(&mut self, esc: &mut Esc<'_>, now: Instant) {
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
                self.sync_lost(esc);
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
    fn sync_error_limit(&self) -> u16 {
        let model: &Model = self.model;
        read_unsigned(model, SYNC_ERROR_SETTINGS, SYNC_ERROR_COUNTER_LIMIT)
            .map_or(DEFAULT_SYNC_ERROR_LIMIT, |v| {
                u16::try_from(v).unwrap_or(u16::MAX)
            })
    }

    /// A SYNC for the drive (interpolated position mode's time base).
    fn sync_drive(&mut self, at: Instant) {
        if let Some(drive) = self.model.drive_mut() {
            drive.sync(at);
        }
        self.forward_events();
    }

    /// The master's cycles stopped or left the SYNC0 grid.
    fn sync_lost(&mut self, esc: &mut Esc<'_>) {
        self.dev.sync_errors += 1;
        tracing::warn!(
            station = esc.station_address(),
            missed = self.dev.sync.missed,
            // The SYNC0 events since the last output buffer, and the buffers taken in Op:
            // whether the master's frames stopped or came off the grid.
            without_outputs = self.dev.sync.since_outputs(),
            sync0_events = self.dev.sync.events,
            outputs_applied = self.dev.outputs_applied,
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

    /// The process-data watchdog expired in Op (the master's frames stopped): the device
    /// raises the message its device file names for it (`watchdog_diagnostic`), with that
    /// message's reaction. Its cause ends with the frames' absence being noticed, so a fault
    /// reset clears it once the master is back.
    fn watchdog_expired(&mut self) {
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

    /// SYNC0 on and its cycle differs from the interpolator cycle: 0x0036.
    fn check_sync0(&self, esc: &Esc<'_>) -> Result<(), AlStatusCode> {
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

    /// Serves the mailbox once (CoE), then what the dictionary asked for (1010h / 1011h).
    fn mailbox(&mut self, esc: &mut Esc<'_>) {
        if !self.finish_save(esc) {
            return;
        }
        if self.shared_events.is_some() {
            // A drive shared with CANopen saves as its CANopen side does (before the answer):
            // one writer of its file.
            let mut access = Persisting::new(self.model, self.store, self.stored);
            coe::pump(esc, &mut self.dev.coe, &mut access);
        } else {
            let mut out = [0u8; MAILBOX_MAX];
            let mut access = Deferring {
                model: self.model,
                store: self.store,
                stored: self.stored,
                started: None,
            };
            let n = coe::serve(esc, &mut self.dev.coe, &mut access, &mut out);
            let started = access.started.take();
            let reply = n.and_then(|n| out.get(..n)).unwrap_or(&[]);
            match started {
                Some((job, sub)) => {
                    self.dev.saving = Some(SaveInFlight {
                        job,
                        sub,
                        reply: reply.to_vec(),
                    })
                }
                None if !reply.is_empty() => {
                    let _ = esc.mailbox_write(reply);
                }
                None => {}
            }
        }
        // A storage request left by another path than the SDO server is carried out here.
        if let Some(req) = self.model.od_mut().take_request() {
            let mut access = Persisting::new(self.model, self.store, self.stored);
            if let Err(e) = access.carry_out(req) {
                tracing::error!(error = %e, "storage request failed");
            }
        }
    }

    /// Posts the reply of a save whose file is written (or the abort 0800 0020h if it could
    /// not be); whether the mailbox is free to serve the next message.
    fn finish_save(&mut self, esc: &mut Esc<'_>) -> bool {
        if !self
            .dev
            .saving
            .as_ref()
            .is_some_and(|s| s.job.is_finished())
        {
            return self.dev.saving.is_none();
        }
        let Some(SaveInFlight {
            job,
            sub,
            mut reply,
        }) = self.dev.saving.take()
        else {
            return true;
        };
        let node = self.model.od().node_id();
        let failed = match job.join() {
            Ok(Ok(stored)) => {
                *self.stored = stored;
                tracing::info!(node, "parameters saved");
                None
            }
            Ok(Err(e)) => Some(e.to_string()),
            Err(_) => Some("the writer thread panicked".to_owned()),
        };
        if let Some(error) = failed {
            // CiA 301 / CMMP-AS: a store that failed is refused with 0800 0020h.
            tracing::error!(node, error, "saving parameters failed");
            reply.truncate(ethercat::mailbox::HEADER_LEN);
            reply.resize(ethercat::mailbox::HEADER_LEN + 10, 0);
            if let Some(p) = reply.get_mut(ethercat::mailbox::HEADER_LEN..) {
                let _ = coe::abort::encode(p, 0x1010, sub, AbortCode::CANNOT_STORE);
            }
            if let Some(len) = reply.get_mut(..2) {
                len.copy_from_slice(&10u16.to_le_bytes());
            }
        }
        // A master that took the mailbox down (Init) meanwhile gets no reply.
        if reply.len() > ethercat::mailbox::HEADER_LEN && esc.mailbox_running() {
            let _ = esc.mailbox_write(&reply);
        }
        true
    }

    fn step(&mut self, now: Instant) {
        self.dev.next_step = self.model.step(now).map(|t| t.max(now + TICK));
        self.forward_events();
    }

    /// The drive's events as CoE emergencies.
    fn forward_events(&mut self) {
        loop {
            // A shared drive's events are taken by its CANopen side, which keeps a copy here.
            let ev = match self.shared_events.as_deref_mut() {
                Some(q) => q.pop_front(),
                None => self.model.take_event(),
            };
            let Some(ev) = ev else {
                break;
            };
            if self.shared_events.is_none() {
                // A shared drive's CANopen side keeps 1001h and 1003h; one on EtherCAT alone
                // keeps them here.
                let errors = &mut self.dev.errors;
                match ev {
                    DriveEvent::Error { code, register } => {
                        errors.raise(self.model, code, register, [0; 5])
                    }
                    DriveEvent::Cleared { code } => errors.clear(self.model, code),
                    DriveEvent::Reboot => {}
                }
                errors.reset_communication();
            }
            // CiA 402 errors as CoE emergencies (ETG.1000.6 §5.6.4, the CANopen EMCY layout).
            let emcy = match ev {
                // A reboot is the CANopen side's (no EtherCAT drive asks for one).
                DriveEvent::Reboot => continue,
                DriveEvent::Error { code, register } => Emergency::new(code, register, [0; 5]),
                // "Error reset": code 0000h with the error register that remains.
                DriveEvent::Cleared { .. } => {
                    let model: &Model = self.model;
                    let register = read_unsigned(model, 0x1001, 0).unwrap_or(0);
                    Emergency::new(0, u8::try_from(register).unwrap_or(0), [0; 5])
                }
            };
            if self.dev.coe.queue_emergency(emcy).is_err() {
                tracing::warn!(event = ?ev, "emergency queue full");
            }
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

fn read_unsigned(dev: &dyn ObjectAccess, index: u16, sub: u8) -> Option<u64> {
    let mut b = [0u8; 8];
    let n = dev.read(index, sub, &mut b).ok()?;
    (n <= 8).then(|| u64::from_le_bytes(b))
}

/// Copies `bits` bits from `src` at bit offset `offset` into `dst` (LSB first).
fn get_bits(src: &[u8], offset: usize, bits: u8, dst: &mut [u8]) {
    dst.fill(0);
    for i in 0..usize::from(bits) {
        let s = offset + i;
        let bit = src.get(s / 8).map(|b| (b >> (s % 8)) & 1).unwrap_or(0);
        if let Some(d) = dst.get_mut(i / 8) {
            *d |= bit << (i % 8);
        }
    }
}

/// Copies the low `bits` bits of `src` into `dst` at bit offset `offset` (LSB first).
fn set_bits(dst: &mut [u8], offset: usize, bits: u8, src: &[u8]) {
    for i in 0..usize::from(bits) {
        let bit = src.get(i / 8).map(|b| (b >> (i % 8)) & 1).unwrap_or(0);
        let d = offset + i;
        if let Some(b) = dst.get_mut(d / 8) {
            *b = (*b & !(1 << (d % 8))) | (bit << (d % 8));
        }
    }
}

/// The SII image of a personality, built once per process.
pub fn sii_image(
    desc: &'static DeviceDescription,
    cfg: &SiiConfig<'static>,
) -> Result<&'static [u8], SlaveChainError> {
    type Cache = Vec<(&'static str, SiiConfig<'static>, &'static [u8])>;
    static CACHE: Mutex<Cache> = Mutex::new(Vec::new());
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, _, image)) = cache.iter().find(|(n, c, _)| *n == desc.name && c == cfg) {
        return Ok(image);
    }
    let mut buf = vec![0u8; sii::DEFAULT_IMAGE_SIZE];
    sii::build_sii(desc, cfg, &mut buf).map_err(|error| SlaveChainError::Sii {
        device: desc.name,
        error,
    })?;
    // One image per personality and configuration for the life of the process.
    let image: &'static [u8] = Box::leak(buf.into_boxed_slice());
    cache.push((desc.name, *cfg, image));
    Ok(image)
}

/// The chain: `escs[i]` with `devices[i]` and `drives[i]`, in wire order.
pub struct SlaveChain {
    escs: Vec<Esc<'static>>,
    devices: Vec<SlaveDevice>,
    drives: Vec<SlaveDrive>,
    /// What each drive of its own is built from again when its slave is powered on.
    specs: Vec<Option<DriveSpec>>,
    /// Where the drives store their parameters.
    state_dir: Option<PathBuf>,
    /// Cables pulled and slaves switched off ([`Line`]).
    line: Line,
    /// Frames processed (EtherCAT or not).
    pub frames: u64,
}

impl SlaveChain {
    /// Why the load FMU of a drive of its own stopped the chain, once one has (as
    /// [`crate::cell::can_cell::CanCell::load_failure`]; a drive of a CAN bus is its bus's).
    pub fn load_failure(&self) -> Option<&crate::cosim::FmuLoadError> {
        self.drives.iter().find_map(|d| match d {
            SlaveDrive::Own(station) => station.model.drive()?.load_failure(),
            SlaveDrive::Station { .. } => None,
        })
    }

    /// The chain joins a cell: the stations of its own drives move to the end of `cell`, in
    /// wire order, and every slave names its station by id there (a CAN bus's station it
    /// names by id from the start).
    pub fn join(&mut self, cell: &mut Stations) {
        self.drives = std::mem::take(&mut self.drives)
            .into_iter()
            .map(|d| match d {
                SlaveDrive::Own(station) => SlaveDrive::Station {
                    id: cell.push(*station),
                    bus: None,
                },
                joined @ SlaveDrive::Station { .. } => joined,
            })
            .collect();
    }

    /// The chain joins `cell` as it joins a cell loop ([`join`](Self::join)): its own
    /// drives become stations of the cell's list, and a slave whose drive is a CANopen node
    /// of one of the cell's buses names that station by id.
    pub fn join_cell(&mut self, cell: &mut CanCell) {
        self.join(&mut cell.stations);
    }

    /// One slave per drive of the cell file, in file order, its keys read with the sections
    /// of `vendors`. Node-IDs only name the drives; EtherCAT addresses them by position and
    /// station address.
    pub fn from_cell_file(file: &CellFile, vendors: Vendors) -> Result<Self, SlaveChainError> {
        Self::new(file.drives(vendors)?)
    }

    /// As [`from_cell_file`](Self::from_cell_file), each drive's parameters stored under
    /// `state_dir` (1010h "save"; loaded at power-on).
    pub fn with_state_dir(
        file: &CellFile,
        vendors: Vendors,
        state_dir: Option<&Path>,
    ) -> Result<Self, SlaveChainError> {
        Self::with_stores(file.drives(vendors)?, state_dir)
    }

    pub fn new(specs: Vec<DriveSpec>) -> Result<Self, SlaveChainError> {
        Self::with_stores(specs, None)
    }

    /// A chain of drives of their own, each built from its spec.
    pub fn with_stores(
        specs: Vec<DriveSpec>,
        state_dir: Option<&Path>,
    ) -> Result<Self, SlaveChainError> {
        if specs.is_empty() {
            return Err(SlaveChainError::Empty);
        }
        let mut chain = SlaveChain::empty();
        chain.state_dir = state_dir.map(Path::to_path_buf);
        for mut spec in specs {
            spec.desc = crate::cell::eds_drive::on_ethercat(spec.desc)?;
            let desc = spec.desc;
            let drive = own_drive(spec.clone(), state_dir)?;
            chain.push(desc, drive)?;
            if let Some(last) = chain.specs.last_mut() {
                *last = Some(spec);
            }
        }
        Ok(chain)
    }

    /// A chain without slaves yet.
    pub fn empty() -> Self {
        SlaveChain {
            escs: Vec::new(),
            devices: Vec::new(),
            drives: Vec::new(),
            specs: Vec::new(),
            state_dir: None,
            line: Line::default(),
            frames: 0,
        }
    }

    /// Appends a slave of personality `desc` with `drive` behind it.
    pub fn push(
        &mut self,
        desc: &'static DeviceDescription,
        drive: SlaveDrive,
    ) -> Result<(), SlaveChainError> {
        let cfg = SiiConfig::from_description(desc);
        let image = sii_image(desc, &cfg)?;
        self.escs.push(Esc::with_sii(image));
        self.devices.push(SlaveDevice::new(
            cfg,
            CoeConfig::from_description(desc),
            desc,
        ));
        self.drives.push(drive);
        self.specs.push(None);
        self.show_line();
        Ok(())
    }

    pub fn len(&self) -> usize {
        self.escs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.escs.is_empty()
    }

    pub fn esc(&self, i: usize) -> Option<&Esc<'static>> {
        self.escs.get(i)
    }

    /// The protocol state of slave `i`.
    pub fn device(&self, i: usize) -> Option<&SlaveDevice> {
        self.devices.get(i)
    }

    /// The drive of slave `i` when it is its own (not a CANopen drive's) and the chain holds
    /// it (it has not joined a cell).
    pub fn model(&self, i: usize) -> Option<&Model> {
        match self.drives.get(i)? {
            SlaveDrive::Own(station) => Some(&station.model),
            SlaveDrive::Station { .. } => None,
        }
    }

    pub fn model_mut(&mut self, i: usize) -> Option<&mut Model> {
        match self.drives.get_mut(i)? {
            SlaveDrive::Own(station) => Some(&mut station.model),
            SlaveDrive::Station { .. } => None,
        }
    }

    /// The station of slave `i` in the cell's list when its drive is its own (not a CANopen
    /// drive's) and the chain has joined a cell ([`join`](Self::join)).
    pub fn own_station(&self, i: usize) -> Option<StationId> {
        match self.drives.get(i)? {
            SlaveDrive::Station { id, bus: None } => Some(*id),
            _ => None,
        }
    }

    /// Whether a slave's drive is a CANopen drive of the cell as well.
    pub fn has_bus_drives(&self) -> bool {
        self.drives
            .iter()
            .any(|d| matches!(d, SlaveDrive::Station { bus: Some(_), .. }))
    }

    /// Whether a slave's drive is a CANopen drive of bus `bus` as well.
    pub fn has_drives_on_bus(&self, bus: usize) -> bool {
        self.drives.iter().any(|d| match d {
            SlaveDrive::Station { bus: b, .. } => *b == Some(bus),
            SlaveDrive::Own(_) => false,
        })
    }

    /// What stands behind slave `i`.
    pub fn drive(&self, i: usize) -> Option<&SlaveDrive> {
        self.drives.get(i)
    }

    /// Power-on: the drives start their clocks.
    pub fn boot(&mut self, now: Instant) {
        self.boot_with(now, &mut NoBuses);
    }

    /// Power-on, the drives of [`SlaveDrive::Station`] slaves found in `buses`.
    pub fn boot_with(&mut self, now: Instant, buses: &mut dyn BusDrives) {
        for (dev, drive) in self.devices.iter_mut().zip(self.drives.iter_mut()) {
            if let Some(mut b) = Bound::new(dev, drive, buses) {
                b.step(now);
            }
        }
    }

    /// A frame from the master, processed in place through every slave in order; then each
    /// device exchanges its process data. Send the frame back when
    /// [`FrameOutcome::forward`] says so.
    pub fn on_frame(&mut self, now: Instant, frame: &mut [u8]) -> FrameOutcome {
        self.on_frame_with(now, frame, &mut NoBuses)
    }

    /// As [`on_frame`](Self::on_frame), the drives of [`SlaveDrive::Station`] slaves found in
    /// `buses`.
    pub fn on_frame_with(
        &mut self,
        now: Instant,
        frame: &mut [u8],
        buses: &mut dyn BusDrives,
    ) -> FrameOutcome {
        let outcome = self.pass_with(now, frame, buses);
        self.exchange_with(now, buses);
        outcome
    }

    /// The frame's own part of [`on_frame_with`](Self::on_frame_with): it passes every slave
    /// in order and is complete when this returns, so it can go back out before the devices
    /// exchange their process data. A real ESC processes the frame on the fly, and the
    /// device's firmware reads the outputs through the PDI after the frame has passed: the
    /// inputs a frame carries are those the device posted before it.
    pub fn pass_with(
        &mut self,
        now: Instant,
        frame: &mut [u8],
        buses: &mut dyn BusDrives,
    ) -> FrameOutcome {
        self.frames += 1;
        // The frame returns from the last slave it reaches (its port 1 loop closed).
        let reach = self.line.reach(self.escs.len());
        if reach == 0 {
            return FrameOutcome::Unreturned;
        }
        let mut first = None;
        let slaves = self
            .escs
            .iter_mut()
            .zip(self.devices.iter_mut().zip(self.drives.iter_mut()))
            .take(reach);
        for (esc, (dev, drive)) in slaves {
            let o = match Bound::new(dev, drive, buses) {
                Some(mut hook) => esc.process_with(now, frame, &mut hook),
                // A drive that is not in the cell: the ESC alone answers.
                None => esc.process(now, frame),
            };
            first.get_or_insert(o);
            if !o.forward() {
                break;
            }
        }
        first.unwrap_or(FrameOutcome::Processed { datagrams: 0 })
    }

    /// The devices' part after a frame passed ([`pass_with`](Self::pass_with)): each takes
    /// its outputs, its drive runs to `now`, it posts its inputs and serves its mailbox.
    pub fn exchange_with(&mut self, now: Instant, buses: &mut dyn BusDrives) {
        // Only the slaves the frame reached ([`pass_with`](Self::pass_with)) take outputs.
        let reach = self.line.reach(self.escs.len());
        let slaves = self
            .escs
            .iter_mut()
            .zip(self.devices.iter_mut().zip(self.drives.iter_mut()))
            .take(reach);
        for (esc, (dev, drive)) in slaves {
            if let Some(mut b) = Bound::new(dev, drive, buses) {
                b.exchange(esc, now);
            }
        }
    }

    /// Time passes without a frame: drives run, ESC watchdogs are checked, inputs refreshed.
    /// Returns the next deadline.
    pub fn poll(&mut self, now: Instant) -> Option<Instant> {
        self.poll_with(now, &mut NoBuses)
    }

    /// As [`poll`](Self::poll), the drives of [`SlaveDrive::Station`] slaves found in `buses`.
    pub fn poll_with(&mut self, now: Instant, buses: &mut dyn BusDrives) -> Option<Instant> {
        let line = &self.line;
        let slaves = self
            .escs
            .iter_mut()
            .zip(self.devices.iter_mut().zip(self.drives.iter_mut()))
            .enumerate()
            .filter(|(i, _)| line.powered(*i));
        for (_, (esc, (dev, drive))) in slaves {
            match Bound::new(dev, drive, buses) {
                Some(mut b) => b.poll(esc, now),
                None => {
                    esc.poll(now);
                }
            }
        }
        self.deadline()
    }

    /// Whether a device's step or SYNC0 event falls due by `now`: the inputs a frame reads
    /// are those the device posted by the time it arrives, so what fell due before it runs
    /// first.
    pub fn due(&self, now: Instant) -> bool {
        self.deadline().is_some_and(|at| at <= now)
    }

    pub fn deadline(&self) -> Option<Instant> {
        self.devices
            .iter()
            .enumerate()
            .filter(|(i, _)| self.line.powered(*i))
            .fold(None, |acc, (_, d)| {
                earliest(earliest(acc, d.next_step), d.next_sync0)
            })
    }

    /// By when a loop in real time wakes for the chain (its wait; what is due stays
    /// [`deadline`](Self::deadline)): a SYNC0 event at its time, a device's step up to
    /// [`STEP_GRACE`] after it. Every frame steps the devices it reaches and moves their next
    /// step a [`TICK`] on, so under a master that sends every [`TICK`] the step would fall
    /// due just as the next frame comes: the loop would wake for it when the frame arrives
    /// (or re-arm its timer at every frame). With the grace it wakes, if at all, between two
    /// frames; a master that stops finds its drives stepped every [`TICK`] + [`STEP_GRACE`].
    pub fn wake_by(&self) -> Option<Instant> {
        self.devices
            .iter()
            .enumerate()
            .filter(|(i, _)| self.line.powered(*i))
            .fold(None, |acc, (_, d)| {
                let step = d.next_step.map(|t| t + STEP_GRACE);
                earliest(earliest(acc, step), d.next_sync0)
            })
    }

    /// The line's physical state: cable, power.
    pub fn line(&self) -> &Line {
        &self.line
    }

    /// The cable behind `after` slaves pulled (0: the master's own): frames return from slave
    /// `after`, the slaves behind it see none (their watchdogs expire, their drives react).
    pub fn pull_cable(&mut self, after: usize) -> Result<(), LineError> {
        self.line.pull_cable(after, self.escs.len())?;
        self.show_line();
        Ok(())
    }

    /// The pulled cable plugged back: the slaves behind it see frames again, in the state
    /// their watchdogs left them.
    pub fn plug_cable(&mut self) {
        self.line.plug_cable();
        self.show_line();
    }

    /// Every slave's DL status shows the links of its ports 0 and 1 as the line has them.
    fn show_line(&mut self) {
        let len = self.escs.len();
        for (i, esc) in self.escs.iter_mut().enumerate() {
            esc.set_port_link(0, self.line.linked(i, len));
            esc.set_port_link(1, self.line.linked(i + 1, len));
        }
    }

    /// Slave `position` switched off: it and every slave behind it drop off the line; its
    /// drive stops.
    pub fn power_off(&mut self, position: usize) -> Result<(), LineError> {
        self.line.set_power(position, false, self.escs.len())?;
        self.show_line();
        Ok(())
    }

    /// Slave `position` switched on at `now`: its ESC starts from its reset values (AL Init,
    /// no station address), its drive boots from its cell-file spec and stored parameters as
    /// at power-on. A drive that is a CANopen node of the cell as well keeps running (its power
    /// is the CAN side's); its ESC alone restarts.
    pub fn power_on(
        &mut self,
        position: usize,
        now: Instant,
        buses: &mut dyn BusDrives,
    ) -> Result<(), SlaveChainError> {
        let len = self.escs.len();
        if !self.line.set_power(position, true, len)? {
            return Ok(());
        }
        let (Some(esc), Some(dev)) = (self.escs.get_mut(position), self.devices.get_mut(position))
        else {
            return Ok(());
        };
        let desc = dev.desc;
        let clock = esc.clock_error();
        let cfg = SiiConfig::from_description(desc);
        *esc = Esc::with_sii(sii_image(desc, &cfg)?);
        // The oscillator is the board's: it runs off nominal as before.
        esc.set_clock_error(now, clock);
        *dev = SlaveDevice::new(cfg, CoeConfig::from_description(desc), desc);
        self.show_line();
        if let (Some(Some(spec)), Some(drive)) =
            (self.specs.get(position), self.drives.get_mut(position))
        {
            let fresh = own_drive(spec.clone(), self.state_dir.as_deref())?;
            match (drive, fresh) {
                // A station of the cell's list is built again in its place there.
                (SlaveDrive::Station { id, bus: None }, SlaveDrive::Own(station)) => {
                    if let Some(slot) = buses.in_cell(*id) {
                        *slot = *station;
                    }
                }
                (drive, fresh) => *drive = fresh,
            }
        }
        if let (Some(dev), Some(drive)) = (
            self.devices.get_mut(position),
            self.drives.get_mut(position),
        ) {
            if let Some(mut b) = Bound::new(dev, drive, buses) {
                b.step(now);
            }
        }
        Ok(())
    }

    /// Slave `position`'s local clock runs off nominal from `now` on (drift, jitter).
    pub fn set_clock_error(
        &mut self,
        position: usize,
        now: Instant,
        error: ClockError,
    ) -> Result<(), LineError> {
        let len = self.escs.len();
        let esc = self
            .escs
            .get_mut(position)
            .ok_or(LineError::NoSlave { position, len })?;
        esc.set_clock_error(now, error);
        Ok(())
    }

    /// The answer to a frame that reached the chain at `arrived` went out at `answered`
    /// (real time: the loop may have been held off its CPU meanwhile). A master waits for
    /// each answer before it sends its next frame (SOEM's send / receive, a PLC's task), so
    /// an answer a SYNC0 cycle or more late holds the master's next outputs back: the SYNC0
    /// events until one cycle after the answer find none through the chain's delay, which a
    /// device, answering as the frame passes, never causes. They count as events seen late
    /// (docs/decisions.md, "SYNC0 events seen late"); a master that stops is found by the
    /// events after them.
    pub fn answered(&mut self, arrived: Instant, answered: Instant) {
        let delay = answered.saturating_since(arrived);
        if delay < SYNC0_SERVICE_FLOOR {
            return;
        }
        for dev in &mut self.devices {
            dev.answered(delay, answered);
        }
    }
}

impl SlaveDevice {
    /// As [`SlaveChain::answered`]: an answer `delay` late went out at `answered`.
    fn answered(&mut self, delay: Duration, answered: Instant) {
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
    fn held_master_at(&self, at: Instant) -> bool {
        self.master_held_until.is_some_and(|u| at <= u)
    }
}

/// A drive on EtherCAT alone built from its spec: a station without a CANopen node, built as
/// a CAN bus's stations are (cell file, motor commissioning, stored set).
pub fn own_drive(spec: DriveSpec, state_dir: Option<&Path>) -> Result<SlaveDrive, SlaveChainError> {
    let settings = spec.settings.map(|mut s| {
        // CSP (6060h = 8) exists only over EtherCAT.
        s.ethercat = true;
        s
    });
    let store = state_dir.map(|d| ParamStore::new(d, spec.desc.name, spec.node));
    let mut drive =
        Station::with_settings(spec.desc, spec.node, store, spec.commissioning, settings)?;
    drive.couple_load(spec.load.as_ref(), spec.node)?;
    Ok(SlaveDrive::Own(Box::new(drive.without_canopen())))
}

/// The dictionary as the CoE server sees it: as [`Persisting`], but a "save" with a file
/// starts writing it on a thread of its own (`started`) instead of holding the loop; the
/// caller holds the reply until it is done.
struct Deferring<'a> {
    model: &'a mut Model,
    store: Option<&'a ParamStore>,
    stored: &'a mut Vec<StoredValue>,
    started: Option<(SaveJob, u8)>,
}

impl ObjectAccess for Deferring<'_> {
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode> {
        self.model.entry(index, sub)
    }
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        self.model.read(index, sub, buf)
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.model.write(index, sub, data)?;
        match (self.model.od_mut().take_request(), self.store) {
            (Some(StorageRequest::Save { sub }), Some(store)) => {
                // The values as they are now; the file is written after.
                let text = store.save_text(self.model.od(), sub);
                let store = store.clone();
                let job = std::thread::Builder::new()
                    .name("parameter-save".into())
                    .spawn(move || {
                        store.write_text(&text)?;
                        store.load()
                    })
                    .map_err(|e| {
                        tracing::error!(error = %e, "no thread to save the parameters");
                        AbortCode::CANNOT_STORE
                    })?;
                self.started = Some((job, sub));
            }
            (Some(req), _) => Persisting::new(self.model, self.store, self.stored)
                .carry_out(req)
                .map_err(|e| {
                    tracing::error!(error = %e, "saving parameters failed");
                    AbortCode::CANNOT_STORE
                })?,
            (None, _) => {}
        }
        Ok(())
    }
    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.model.write_internal(index, sub, data)
    }
}

/// A copy of a frame for the trace, with the wall-clock time it was seen.
#[derive(Debug, Clone)]
pub struct TracedFrame {
    pub at: std::time::SystemTime,
    pub frame: Vec<u8>,
}

/// Where the runtime sends the frames it sees (`--trace`): each request as it came in and
/// each processed frame as it went back. A full queue drops the copy, never the frame.
pub type FrameTap = std::sync::mpsc::SyncSender<TracedFrame>;

/// A chain's frames copied to the trace's queue: the copy is stamped with the wall clock when
/// it is taken (read only while tracing), as the pcap beside other captures wants.
impl crate::cell::tracer::TraceSink<[u8]> for Option<FrameTap> {
    fn write(&mut self, _: crate::cell::link::At, frame: &[u8]) {
        if let Some(tap) = self {
            let copy = TracedFrame {
                at: std::time::SystemTime::now(),
                frame: frame.to_vec(),
            };
            if tap.try_send(copy).is_err() {
                tracing::warn!("trace queue full, a frame copy is lost");
            }
        }
    }
}
