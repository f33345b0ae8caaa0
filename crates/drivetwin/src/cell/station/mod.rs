//! A station: one drive of the cell with all its front ends. The drive (its dictionary and,
//! for a CiA 402 device, its engine and motor: [`Model`]) is stepped on the cell's clock;
//! its front ends reach it through `od::ObjectAccess`: the CANopen node when the drive is on
//! a CAN bus (`canopen_node.rs`), the CI terminal and the serial ports (`local.rs`), the CoE
//! side of an EtherCAT slave (`ethercat.rs`). A drive served over EtherCAT alone is a station
//! without a CANopen node; a vendor's register-image device (the CMMO-ST) is a station
//! without one too, whose Modbus TCP front end (`modbus_tcp::cell_drive`) reaches it by its
//! id and steps it on its own cycle. The runtime's share of the work (parameter files, resets,
//! the drive's events as emergencies) is done here (`parameters.rs`).
//!
//! One type split into files, each an `impl Station` with its own part of the doc.

mod canopen_node;
mod ethercat;
mod local;
mod parameters;

use std::collections::VecDeque;
use std::time::Duration;

use canopen::{CanFrame, Node, NodeEvent};
use drive::drive::{DriveEvent, DriveSettings};
use od::{time::earliest, Instant, ObjectDictionary};

use crate::cell::device_model::Model;
use crate::cell::param_store::{ParamStore, StoreError, StoredValue};
use parameters::load_all;
pub use parameters::{Commissioning, Persisting};

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
    #[error("load: {0}")]
    Load(#[from] crate::cosim::FmuLoadError),
}

/// One drive with all its front ends.
pub struct Station {
    /// The drive: its dictionary, and for a CiA 402 device its engine and motor.
    pub model: Model,
    /// Its CANopen front end, when the drive is on a CAN bus: the CiA 301 node, through which
    /// the CI terminal and the serial ports write as well (none: a drive served over EtherCAT
    /// alone).
    pub canopen: Option<Node>,
    /// Where its parameters are saved (none: kept for the life of the process).
    store: Option<ParamStore>,
    /// The set last saved.
    stored: Vec<StoredValue>,
    /// The values the cell file sets at power-on.
    commissioning: Vec<Commissioning>,
    /// When the drive is stepped next.
    next_step: Option<Instant>,
    /// Its EtherCAT front end's share, when the drive is a slave of a chain as well: a copy
    /// of each drive event for the CoE emergencies.
    coe_events: Option<VecDeque<DriveEvent>>,
}

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

    /// Couples the load FMU of a `[drive.load]` (none: the motor model's own load) to the
    /// drive's shaft, the FMU's instance named for the node.
    pub fn couple_load(
        &mut self,
        load: Option<&crate::cosim::LoadMapping>,
        node: u8,
    ) -> Result<(), StationError> {
        match load {
            Some(load) => Ok(self.model.couple_load(load, node)?),
            None => Ok(()),
        }
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
            canopen: Some(Node::new(node_id, desc.cia301)),
            store,
            stored,
            commissioning,
            next_step: None,
            coe_events: None,
        })
    }

    /// A vendor's register-image device as a station: no CANopen node, its permanent
    /// memory its own; its Modbus TCP front end steps and serves it.
    pub fn register_image(image: crate::cell::modbus_device::RegisterImage) -> Self {
        Station {
            model: Model::RegisterImage(Box::new(image)),
            canopen: None,
            store: None,
            stored: Vec::new(),
            commissioning: Vec::new(),
            next_step: None,
            coe_events: None,
        }
    }

    pub fn od(&self) -> &ObjectDictionary<Vec<u8>> {
        self.model.od()
    }

    /// The drive without its CANopen front end: one served over EtherCAT alone, whose CoE
    /// side takes the drive's events itself.
    pub fn without_canopen(mut self) -> Self {
        self.canopen = None;
        self
    }

    /// Its node-ID: its CANopen node's (LSS may change it), else its dictionary's.
    pub fn node_id(&self) -> u8 {
        match &self.canopen {
            Some(node) => node.node_id(),
            None => self.model.od().node_id(),
        }
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

    /// The node (if the drive is on a CAN bus), and the dictionary as its SDO server writes it
    /// (saves carried out).
    pub(super) fn node_and_access(&mut self) -> (Option<&mut Node>, Persisting<'_>) {
        let Station {
            model,
            canopen,
            store,
            stored,
            ..
        } = self;
        (
            canopen.as_mut(),
            Persisting::new(model, store.as_ref(), stored),
        )
    }

    /// The CANopen node boots (its boot-up message to `out`), if the drive is on a CAN bus.
    fn boot_node(&mut self, now: Instant, out: &mut dyn FnMut(CanFrame)) {
        if let Some(node) = self.canopen.as_mut() {
            node.boot(now, &self.model, out);
        }
    }

    pub fn poll(&mut self, now: Instant, out: &mut dyn FnMut(CanFrame)) -> Option<Instant> {
        let next_step = self.model.step(now);
        self.next_step = next_step.map(|t| t.max(now + STEP_PERIOD));
        if let Some(node) = self.canopen.as_mut() {
            node.poll(now, &mut self.model, out);
        }
        self.service(now, out);
        self.deadline()
    }

    pub fn deadline(&self) -> Option<Instant> {
        earliest(
            self.canopen.as_ref().and_then(Node::deadline),
            self.next_step,
        )
    }

    /// Carries out what the stack asked for.
    pub(super) fn service(&mut self, now: Instant, out: &mut dyn FnMut(CanFrame)) {
        // The drive's errors go out as EMCY through the stack (CiA 301 §7.2.7).
        let mut reboot = false;
        while let Some(ev) = self.model.take_event() {
            self.keep_for_coe(ev);
            match (ev, self.canopen.as_mut()) {
                (DriveEvent::Error { code, register }, Some(node)) => {
                    node.raise_error(&mut self.model, code, register, [0; 5])
                }
                (DriveEvent::Cleared { code }, Some(node)) => {
                    node.clear_error(&mut self.model, code)
                }
                (DriveEvent::Reboot, _) => reboot = true,
                // Without a CANopen node the CoE side reports the drive's errors.
                (DriveEvent::Error { .. } | DriveEvent::Cleared { .. }, None) => {}
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
            let node_id = self.node_id();
            self.model.od_mut().set_node_id(node_id);
            self.reload(|_| true);
            self.boot_node(now, out);
        }
        while let Some(ev) = self.canopen.as_mut().and_then(Node::take_event) {
            match ev {
                NodeEvent::ResetApplication => {
                    let node_id = self.node_id();
                    self.model.od_mut().set_node_id(node_id);
                    self.reload(|_| true);
                    self.boot_node(now, out);
                }
                NodeEvent::ResetCommunication => {
                    // Decision: CiA 301 reset communication (1000h–1FFFh from the stored set)
                    // for every device, the Nanotec too, whose §2.2 (L465) describes 82h as
                    // 81h (docs/decisions.md).
                    // The node-ID may have changed (LSS): node-relative defaults follow it.
                    let node_id = self.node_id();
                    self.model.od_mut().set_node_id(node_id);
                    self.reload(|i| (0x1000..0x2000).contains(&i));
                    self.boot_node(now, out);
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
