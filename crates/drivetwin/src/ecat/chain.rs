//! An EtherCAT chain: emulated slave controllers (ESCs), each with the device behind it, that
//! one Ethernet frame passes in order, as a line of real slaves.
//!
//! Every slave is an [`Esc`] loaded with the SII image of its personality
//! (`ethercat::sii::build_sii`) and a [`SlaveDevice`]: the dictionary and, for a CiA 402
//! personality, the simulated drive and motor, built exactly as the CANopen cell builds them
//! (cell file, motor commissioning,
//! [`Station::with_settings`](crate::cell::station::Station::with_settings)).
//!
//! The chain is slave logic alone (sans-IO): it takes frames and a time and reads no clock,
//! socket or file. What the slaves do is split by concept: process data
//! ([`process_data`](super::process_data)), SYNC0 / DC ([`sync0`](super::sync0)), the
//! mailbox's CoE ([`coe_dispatch`](super::coe_dispatch)), one slave's exchange and AL hooks
//! ([`slave`](super::slave)) and the drive behind it ([`slave_drive`](super::slave_drive)).
//! A 1010h "save" over CoE is written by the runtime: it takes the request
//! ([`take_save`](SlaveChain::take_save)), writes the file and hands the result back
//! ([`saved`](SlaveChain::saved)).

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use ethercat::coe::CoeConfig;
use ethercat::sii::{self, SiiConfig};
use ethercat::{ClockError, Esc, FrameOutcome};
use od::{time::earliest, DeviceDescription, Instant};

use crate::cell::can_cell::CanCell;
use crate::cell::config::{CellFile, ConfigError, DriveSpec};
use crate::cell::device_model::Model;
use crate::cell::param_saver::{SaveJob, SaveResult};
use crate::cell::station::StationError;
use crate::cell::stations::{StationId, Stations};
use crate::cell::Vendors;

use super::line::{Line, LineError};
use super::slave::{Bound, Unbound};

pub use super::frame_tap::{FrameTap, TracedFrame};
pub use super::process_data::{Layout, MapItem};
pub use super::slave::{SlaveDevice, STEP_GRACE, TICK};
pub use super::slave_drive::{own_drive, BusDrives, NoBuses, SlaveDrive};
pub use super::sync0::SYNC0_SERVICE_FLOOR;

/// A 1010h "save" a slave asked for over CoE, for the runtime to carry out; its CoE reply
/// waits until the runtime hands back the result ([`SlaveChain::saved`]).
pub struct SaveRequest {
    /// The slave's position on the chain.
    pub slave: usize,
    pub job: SaveJob,
}

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
            // A drive that is not in the cell: the ESC alone answers.
            let mut hook = Unbound {
                dev,
                drive,
                buses: &mut *buses,
            };
            let o = esc.process_with(now, frame, &mut hook);
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

impl SlaveChain {
    /// A save a slave asked for and the runtime has not taken yet: the runtime writes the
    /// file and hands the result to [`saved`](Self::saved).
    pub fn take_save(&mut self) -> Option<SaveRequest> {
        self.devices
            .iter_mut()
            .enumerate()
            .find_map(|(slave, dev)| {
                let job = dev.saving.as_mut()?.job.take()?;
                Some(SaveRequest { slave, job })
            })
    }

    /// The runtime wrote the file of slave `slave`'s save (`result`): the drive keeps the
    /// stored set and the slave posts its held CoE reply (0800 0020h if the write failed).
    pub fn saved(&mut self, slave: usize, result: SaveResult, buses: &mut dyn BusDrives) {
        let (Some(esc), Some(dev), Some(drive)) = (
            self.escs.get_mut(slave),
            self.devices.get_mut(slave),
            self.drives.get_mut(slave),
        ) else {
            return;
        };
        match Bound::new(dev, drive, buses) {
            Some(mut b) => b.saved(esc, result),
            // The drive left the cell: the mailbox is free again, without a reply.
            None => dev.saving = None,
        }
    }
}
