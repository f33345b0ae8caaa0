//! One CANopen drive of a cell: its dictionary, its CiA 301 stack and its stored parameter
//! set, with the runtime's share of the work (files and resets) done here.

use std::collections::VecDeque;
use std::time::Duration;

use canopen::{CanFrame, Node, NodeEvent};
use drive::drive::{DriveEvent, DriveSettings};
use drive::vendors::festo_cmmp_as::ci_terminal;
use od::{
    time::earliest, AbortCode, Entry, Instant, ObjectAccess, ObjectDictionary, StorageRequest,
};

use crate::cell::device_model::Model;
use crate::cell::param_store::{self, ParamStore, StoreError, StoredValue};

/// How often the runtime steps a drive at least: frames catch the drive up to their own
/// time first, so a coarser step only batches cycles, it never reorders them.
const STEP_PERIOD: Duration = Duration::from_millis(1);

#[derive(Debug, thiserror::Error)]
pub enum StationError {
    #[error("node-ID {0} is outside 1…127 (255 = unconfigured, waiting for LSS)")]
    NodeId(u8),
    #[error("commissioning value {index:04X}h:{sub:02X}h: {what}")]
    Commissioning { index: u16, sub: u8, what: String },
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// A value the cell file sets at power-on, as a commissioning tool would have (before the
/// stored set, which wins).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Commissioning {
    pub index: u16,
    pub sub: u8,
    pub bytes: Vec<u8>,
}

pub struct Station {
    pub model: Model,
    pub node: Node,
    store: Option<ParamStore>,
    stored: Vec<StoredValue>,
    commissioning: Vec<Commissioning>,
    next_step: Option<Instant>,
    /// Served over EtherCAT as well: a copy of each drive event for the CoE emergencies.
    coe_events: Option<VecDeque<DriveEvent>>,
}

/// Drive events kept for the CoE side at most (it takes them at its next frame or tick).
const MAX_COE_EVENTS: usize = 64;

impl Station {
    /// A drive at power-on, not yet booted: defaults, then commissioning values, then the
    /// stored set.
    pub fn new(
        desc: &'static od::DeviceDescription,
        node_id: u8,
        store: Option<ParamStore>,
        commissioning: Vec<Commissioning>,
    ) -> Result<Self, StationError> {
        Self::with_settings(desc, node_id, store, commissioning, None)
    }

    /// As [`Station::new`]; with `settings` a CiA 402 personality gets a simulated drive and
    /// motor behind its dictionary.
    pub fn with_settings(
        desc: &'static od::DeviceDescription,
        node_id: u8,
        store: Option<ParamStore>,
        commissioning: Vec<Commissioning>,
        settings: Option<DriveSettings>,
    ) -> Result<Self, StationError> {
        if !(1..=127).contains(&node_id) && node_id != canopen::lss::UNCONFIGURED {
            return Err(StationError::NodeId(node_id));
        }
        // A node-ID stored by LSS "store configuration" wins over the cell's (CiA 305).
        let node_id = store
            .as_ref()
            .and_then(|s| s.load_lss_node_id())
            .unwrap_or(node_id);
        let od = ObjectDictionary::new(desc, node_id, vec![0; desc.storage_size]).map_err(|e| {
            StationError::Commissioning {
                index: 0,
                sub: 0,
                what: format!("storage {e:?}"),
            }
        })?;
        for c in &commissioning {
            let e = desc
                .entry(c.index, c.sub)
                .ok_or_else(|| StationError::Commissioning {
                    index: c.index,
                    sub: c.sub,
                    what: "no such entry".into(),
                })?;
            let ok = match e.data_type.fixed_size() {
                Some(n) => c.bytes.len() == n,
                None => c.bytes.len() <= e.capacity as usize,
            };
            if !ok {
                return Err(StationError::Commissioning {
                    index: c.index,
                    sub: c.sub,
                    what: format!("{} bytes do not fit {}", c.bytes.len(), e.data_type.name()),
                });
            }
        }
        let stored = match &store {
            Some(s) => s.load()?,
            None => Vec::new(),
        };
        let mut od = od;
        load_all(&mut od, &commissioning, &stored, |_| true);
        Ok(Station {
            model: Model::new(od, settings),
            node: Node::new(node_id, desc.cia301),
            store,
            stored,
            commissioning,
            next_step: None,
            coe_events: None,
        })
    }

    pub fn od(&self) -> &ObjectDictionary<Vec<u8>> {
        self.model.od()
    }

    /// The drive without its CANopen node (e.g. for an EtherCAT slave): its model, where
    /// its parameters are saved, and the set last saved.
    pub fn into_parts(self) -> (Model, Option<ParamStore>, Vec<StoredValue>) {
        (self.model, self.store, self.stored)
    }

    /// Defaults, commissioning values and the stored set for the indices `filter` selects.
    fn reload(&mut self, filter: impl Fn(u16) -> bool) {
        load_all(
            self.model.od_mut(),
            &self.commissioning,
            &self.stored,
            filter,
        );
        self.model.reload();
    }

    /// The drive is an EtherCAT slave of the cell as well: its events are kept for the CoE
    /// emergencies too.
    pub fn serve_coe(&mut self) {
        self.coe_events.get_or_insert_with(VecDeque::new);
    }

    /// What the CoE side of a drive served over EtherCAT as well reaches: the model, where
    /// "save" writes, the set last saved, and the events kept for it.
    pub fn coe_parts(
        &mut self,
    ) -> (
        &mut Model,
        Option<&ParamStore>,
        &mut Vec<StoredValue>,
        &mut VecDeque<DriveEvent>,
    ) {
        let events = self.coe_events.get_or_insert_with(VecDeque::new);
        (
            &mut self.model,
            self.store.as_ref(),
            &mut self.stored,
            events,
        )
    }

    /// Its CAN controller changed error state: the personality's reaction
    /// ([`crate::cell::bus_faults`]).
    pub fn bus_state_changed(
        &mut self,
        now: Instant,
        t: canbus::fault_confinement::Transition,
        out: &mut dyn FnMut(CanFrame),
    ) {
        use crate::cell::bus_faults::{react, Reaction, COMMUNICATION_REGISTER};
        tracing::warn!(
            node = self.node_id(),
            from = t.from.name(),
            to = t.to.name(),
            "CAN controller"
        );
        let device = self.model.od().description().name;
        for r in react(device, t) {
            match *r {
                Reaction::Raise(code) => {
                    self.node
                        .raise_error(&mut self.model, code, COMMUNICATION_REGISTER, [0; 5])
                }
                Reaction::Clear(code) => self.node.clear_error(&mut self.model, code),
                Reaction::Repeat(code) => self.node.repeat_error(code),
                Reaction::Fault(code) => {
                    if let Some(d) = self.model.drive_mut() {
                        // Raised once; its cause is gone with the bus back, so a fault reset
                        // clears it. Its EMCY is lost with the bus off; `recovered` sends it.
                        d.inject_fault(code, COMMUNICATION_REGISTER);
                        d.clear_fault(code);
                    }
                }
            }
        }
        self.poll(now, out);
    }

    pub fn node_id(&self) -> u8 {
        self.node.node_id()
    }

    /// Power-on finished: boot-up message.
    pub fn boot(&mut self, now: Instant, out: &mut dyn FnMut(CanFrame)) {
        self.model.step(now);
        self.node.boot(now, &self.model, out);
    }

    pub fn on_frame(&mut self, now: Instant, frame: &CanFrame, out: &mut dyn FnMut(CanFrame)) {
        // The drive first runs up to the frame's time, so the frame acts on the right cycle.
        self.model.step(now);
        let (node, mut access) = self.node_and_access();
        node.on_frame(now, frame, &mut access, out);
        self.service(now, out);
    }

    /// One line typed at the drive's CI terminal (CMMP-AS §3.2.3, SDO simulation); its
    /// answer without the line end. Writes follow the SDO rules of the present NMT state.
    pub fn ci_line(
        &mut self,
        now: Instant,
        line: &[u8],
        out: &mut dyn FnMut(CanFrame),
    ) -> ci_terminal::Reply {
        self.model.step(now);
        let (node, access) = self.node_and_access();
        let mut console = Console { node, access, now };
        let reply = ci_terminal::execute(line, &mut console);
        self.service(now, out);
        reply
    }

    /// A local interface of the drive (a serial port) reaches its objects at `now`: reads as
    /// they are, writes as SDO downloads of its node (as the CI terminal's); what the drive
    /// sends meanwhile goes to `out`.
    pub fn local_access(
        &mut self,
        now: Instant,
        out: &mut dyn FnMut(CanFrame),
        f: &mut dyn FnMut(&mut dyn ObjectAccess),
    ) {
        self.model.step(now);
        let (node, access) = self.node_and_access();
        let mut console = Console { node, access, now };
        f(&mut console);
        self.service(now, out);
    }

    /// The node, and the dictionary as its SDO server writes it (saves carried out).
    fn node_and_access(&mut self) -> (&mut Node, Persisting<'_>) {
        let Station {
            model,
            node,
            store,
            stored,
            ..
        } = self;
        (node, Persisting::new(model, store.as_ref(), stored))
    }

    pub fn poll(&mut self, now: Instant, out: &mut dyn FnMut(CanFrame)) -> Option<Instant> {
        let next_step = self.model.step(now);
        self.next_step = next_step.map(|t| t.max(now + STEP_PERIOD));
        self.node.poll(now, &mut self.model, out);
        self.service(now, out);
        self.deadline()
    }

    pub fn deadline(&self) -> Option<Instant> {
        earliest(self.node.deadline(), self.next_step)
    }

    /// Carries out what the stack asked for.
    fn service(&mut self, now: Instant, out: &mut dyn FnMut(CanFrame)) {
        // The drive's errors go out as EMCY through the stack (CiA 301 §7.2.7).
        let mut reboot = false;
        while let Some(ev) = self.model.take_event() {
            if let Some(q) = self.coe_events.as_mut() {
                if q.len() >= MAX_COE_EVENTS {
                    q.pop_front();
                    tracing::warn!(
                        node = self.node.node_id(),
                        "CoE event queue full, oldest lost"
                    );
                }
                q.push_back(ev);
            }
            match ev {
                DriveEvent::Error { code, register } => {
                    self.node
                        .raise_error(&mut self.model, code, register, [0; 5])
                }
                DriveEvent::Cleared { code } => self.node.clear_error(&mut self.model, code),
                DriveEvent::Reboot => reboot = true,
            }
        }
        // A storage request left by another path than the SDO server is carried out here.
        if let Some(req) = self.model.od_mut().take_request() {
            let (_, mut access) = self.node_and_access();
            if let Err(e) = access.carry_out(req) {
                tracing::error!(node = self.node_id(), error = %e, "storage request failed");
            }
        }
        if reboot {
            // After a save asked for in the same cycle: the drive restarts from the stored set,
            // as after NMT reset node.
            tracing::info!(node = self.node_id(), "drive reboot");
            self.model.od_mut().set_node_id(self.node.node_id());
            self.reload(|_| true);
            self.node.boot(now, &self.model, out);
        }
        while let Some(ev) = self.node.take_event() {
            match ev {
                NodeEvent::ResetApplication => {
                    self.model.od_mut().set_node_id(self.node.node_id());
                    self.reload(|_| true);
                    self.node.boot(now, &self.model, out);
                }
                NodeEvent::ResetCommunication => {
                    // Decision: CiA 301 reset communication (1000h–1FFFh from the stored set)
                    // for every device, the Nanotec too, whose §2.2 (L465) describes 82h as
                    // 81h (docs/decisions.md).
                    // The node-ID may have changed (LSS): node-relative defaults follow it.
                    self.model.od_mut().set_node_id(self.node.node_id());
                    self.reload(|i| (0x1000..0x2000).contains(&i));
                    self.node.boot(now, &self.model, out);
                }
                NodeEvent::LssStore { node_id } => match &self.store {
                    Some(store) => match store.save_lss_node_id(node_id) {
                        Ok(()) => tracing::info!(node_id, "LSS node-ID stored"),
                        Err(e) => tracing::error!(error = %e, "storing the LSS node-ID failed"),
                    },
                    None => tracing::warn!(
                        node_id,
                        "LSS store without a state directory: kept until the process ends"
                    ),
                },
                NodeEvent::State(s) => {
                    tracing::debug!(node = self.node_id(), state = s.name(), "NMT")
                }
                NodeEvent::Heartbeat(e) => {
                    tracing::warn!(node = self.node_id(), event = ?e, "heartbeat consumer")
                }
                NodeEvent::LifeGuardingLost => {
                    tracing::warn!(
                        node = self.node_id(),
                        "life guarding: no request within the life time"
                    )
                }
                NodeEvent::LifeGuardingResumed => {
                    tracing::info!(node = self.node_id(), "life guarding resumed")
                }
                NodeEvent::Sync => {
                    // The time base of interpolated position mode (CMMP-AS §7.4).
                    if let Some(drive) = self.model.drive_mut() {
                        drive.step(now);
                        drive.sync(now);
                    }
                }
            }
        }
    }
}

/// Defaults, then commissioning values, then the stored set, for the indices `filter` selects.
fn load_all(
    od: &mut ObjectDictionary<Vec<u8>>,
    commissioning: &[Commissioning],
    stored: &[StoredValue],
    filter: impl Fn(u16) -> bool,
) {
    od.load_defaults(|e| filter(e.index));
    let desc = od.description();
    for c in commissioning {
        if filter(c.index) {
            if let Some(e) = desc.entry(c.index, c.sub) {
                od.store(e, &c.bytes);
            }
        }
    }
    param_store::apply(od, stored, &filter);
}

/// The dictionary as the SDO server (CANopen or CoE) sees it: a "save" (1010h) is carried
/// out before the answer, so a file that cannot be written gets the abort CiA 301 and the
/// CMMP-AS manual give for a faulty store access (0800 0020h) instead of a confirmation.
pub struct Persisting<'a> {
    model: &'a mut Model,
    store: Option<&'a ParamStore>,
    stored: &'a mut Vec<StoredValue>,
}

impl<'a> Persisting<'a> {
    /// `model` with its parameters saved to `store` (none: kept for the life of the process);
    /// `stored` is the set last saved, kept up to date.
    pub fn new(
        model: &'a mut Model,
        store: Option<&'a ParamStore>,
        stored: &'a mut Vec<StoredValue>,
    ) -> Self {
        Persisting {
            model,
            store,
            stored,
        }
    }

    /// Carries out a save or restore the dictionary asked for.
    pub fn carry_out(&mut self, req: StorageRequest) -> Result<(), StoreError> {
        match req {
            StorageRequest::Save { sub } => {
                let node = self.model.od().node_id();
                match self.store {
                    Some(store) => {
                        store.save(self.model.od(), sub)?;
                        *self.stored = store.load()?;
                        tracing::info!(node, path = %store.path().display(), "parameters saved");
                    }
                    None => {
                        tracing::warn!(node, "save accepted, but the cell has no state directory")
                    }
                }
            }
            // CMMP-AS §5.1: "load" copies the defaults into the current set (the dictionary
            // did); the application set in flash stays until the next "save".
            StorageRequest::Restore { sub } => {
                self.model.reload();
                tracing::info!(node = self.model.od().node_id(), sub, "defaults restored");
                // Nanotec §11.25: the defaults are written to EEPROM at once, so the next
                // power-on or NMT reset starts from them (2005h, 2009h kept).
                if self
                    .model
                    .od()
                    .description()
                    .cia301
                    .restore_writes_stored_set
                {
                    self.carry_out(StorageRequest::Save { sub })?;
                }
            }
        }
        Ok(())
    }
}

impl ObjectAccess for Persisting<'_> {
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode> {
        self.model.entry(index, sub)
    }
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        self.model.read(index, sub, buf)
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.model.write(index, sub, data)?;
        if let Some(req) = self.model.od_mut().take_request() {
            self.carry_out(req).map_err(|e| {
                tracing::error!(error = %e, "saving parameters failed");
                AbortCode::CANNOT_STORE
            })?;
        }
        Ok(())
    }
    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.model.write_internal(index, sub, data)
    }
}

/// The CI terminal's view of a drive: reads as they are, writes as SDO downloads of its node.
struct Console<'a> {
    node: &'a mut Node,
    access: Persisting<'a>,
    now: Instant,
}

impl ObjectAccess for Console<'_> {
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode> {
        self.access.entry(index, sub)
    }
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        self.access.read(index, sub, buf)
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.node
            .local_write(self.now, index, sub, data, &mut self.access)
    }
    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.access.write_internal(index, sub, data)
    }
}
