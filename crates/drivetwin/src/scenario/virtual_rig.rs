//! The virtual clock's rig: the CANopen drives of the cell file's buses (`[[bus]]`), stations
//! of one [`CanCell`] as the cell loop holds them, stepped from one deadline to the next as
//! [`crate::cell_loop::virtual_clock::run_virtual`] does, with the scenario's actions between; every
//! frame of the first bus optionally to a trace whose time stamps are the virtual clock's (so
//! two runs give the same file), the trace of that bus's port
//! ([`crate::cell::can_segment::SegmentBus::port`]) as in the cell loop.
//!
//! Decisions: at one instant the planned changes due come first (the cell's timeline,
//! [`CanCell::carry_out_plans`], a CMMO-ST's too), then the Modbus cycles, then the buses
//! in their order, so a run is the same bit for bit; a step's `node` is looked up on the
//! buses in order (the first bus that has it) and reaches that station by its id, a frame,
//! an SDO write, a fault go to the step's `bus`.

use std::path::Path;
use std::time::Duration;

use canopen::CanFrame;
use od::dictionary::stored_read_entry;
use od::{DeviceDescription, Entry, Instant, ObjectAccess, ObjectDictionary};

use super::file::{Action, ScenarioError};
use super::runner::Rig;
use crate::cell::can_cell::CanCell;
use crate::cell::can_segment::SegmentBus;
use crate::cell::config::CellFile;
use crate::cell::link::{At, Link};
use crate::cell::modbus_device::{ModbusDevice, NewModbusDevice};
use crate::cell::station::Station;
use crate::cell::stations::{StationId, Stations};
use crate::cell::Vendors;
use crate::modbus_tcp::cell_drive::ModbusDrive;
use crate::trace::TraceWriter;

/// Steps at one instant before the clock is taken as stuck.
const STUCK: u32 = 10_000;

pub struct VirtualRig {
    /// The stations and the buses between them.
    cell: CanCell,
    now: Instant,
    out: Vec<CanFrame>,
    /// The inputs each station has forced so far: (mask, levels), by station id.
    forced: Vec<(u16, u16)>,
    /// Frames sent and not yet seen, with their bus.
    pending: Vec<(usize, CanFrame)>,
    /// The Modbus TCP front ends of the CMMO-STs (no socket: requests come from the steps),
    /// by the node-ID their cell file gives them; each drive is a station of the cell, stepped
    /// on the same clock.
    modbus: Vec<(u8, ModbusDrive)>,
}

impl VirtualRig {
    /// The CANopen drives of `file`'s buses, booted at 0, its drives' keys read with the
    /// sections of `vendors` (`drivetwin::vendors::VENDORS.runtime`), and its drives served over
    /// Modbus TCP as `vendors.modbus_device` makes them.
    pub fn new(file: &CellFile, vendors: Vendors) -> Result<VirtualRig, ScenarioError> {
        let rig = VirtualRig::new_without_drives_allowed(file, vendors)?;
        if rig.nodes().is_empty() && rig.modbus.is_empty() {
            return Err(ScenarioError::Cell("no drive".into()));
        }
        Ok(rig)
    }

    /// [`VirtualRig::new`], a rig without a drive of its own allowed: the cell FMU steps its
    /// EtherCAT slaves beside it, and a cell of slaves alone leaves it none.
    pub fn new_without_drives_allowed(
        file: &CellFile,
        vendors: Vendors,
    ) -> Result<VirtualRig, ScenarioError> {
        let cell_err = |e: String| ScenarioError::Cell(e);
        let modbus_device = vendors.modbus_device;
        let specs = file.drives(vendors).map_err(|e| cell_err(e.to_string()))?;
        let rates = file
            .bus_rates(&specs)
            .map_err(|e| cell_err(e.to_string()))?;
        let sections = file.bus.all();
        let mut drives: Vec<Vec<Station>> = sections.iter().map(|_| Vec::new()).collect();
        let mut plans: Vec<Vec<_>> = sections.iter().map(|_| Vec::new()).collect();
        let mut modbus = Vec::new();
        // `[[drive.diagnostic]]`, `[drive.thermal]` and `[[drive.plant]]` of the CMMO-STs.
        let mut modbus_plans = Vec::new();
        for mut spec in specs {
            if let Some(fhpp) = &spec.fhpp {
                modbus_plans.push((
                    modbus.len(),
                    std::mem::take(&mut spec.diagnostics),
                    std::mem::take(&mut spec.physics),
                ));
                modbus.push((
                    spec.node,
                    served(&spec, fhpp, modbus_device).map_err(cell_err)?,
                ));
                continue;
            }
            if !spec.canopen || spec.ethercat.is_some() {
                return Err(cell_err(format!(
                    "drive {} node {}: the virtual clock runs the CANopen drives of the cell's \
                     buses and its CMMO-STs (no EtherCAT)",
                    spec.desc.name, spec.node
                )));
            }
            // Silent on the bus as in `drivetwin run`: CAN off by its switches, or set to
            // another rate than the bus's named `bitrate`.
            let carried = match (&spec.bit_rate, rates.get(spec.bus)) {
                (Some(rate), Some(bus)) => bus.carries(rate),
                _ => true,
            };
            if !spec.on_can().map_err(|e| cell_err(e.to_string()))? || !carried {
                continue;
            }
            let mut d = Station::with_settings(
                spec.desc,
                spec.node,
                None,
                spec.commissioning,
                spec.settings,
            )
            .map_err(|e| cell_err(e.to_string()))?;
            d.couple_load(spec.load.as_ref(), spec.node)
                .map_err(|e| cell_err(e.to_string()))?;
            let (Some(on_bus), Some(p)) = (drives.get_mut(spec.bus), plans.get_mut(spec.bus))
            else {
                return Err(cell_err(format!(
                    "drive node {}: no bus {}",
                    spec.node, spec.bus
                )));
            };
            p.push((
                std::mem::take(&mut spec.diagnostics),
                std::mem::take(&mut spec.physics),
            ));
            on_bus.push(d);
        }
        let mut out = Vec::with_capacity(256);
        let mut cell = CanCell::new();
        for (((d, section), rate), plans) in drives.into_iter().zip(sections).zip(&rates).zip(plans)
        {
            let ids = cell.push_stations(d);
            // `[[drive.diagnostic]]`, `[drive.thermal]` and `[[drive.plant]]` on the virtual
            // clock, by station.
            for (id, (diagnostics, physics)) in ids.iter().zip(plans) {
                cell.plan_drive(*id, diagnostics, physics);
            }
            let bus = SegmentBus::new(ids);
            let mut bus = match rate.bitrate() {
                Some(bitrate) => bus.with_bitrate(bitrate, section.late_after()),
                None => bus,
            };
            for p in &section.disturb {
                bus.plan_disturbance(Instant::from_millis(p.at_ms), p.node, p.frames);
            }
            cell.buses.push(bus);
        }
        // The CMMO-STs join the cell after the buses' drives, each a station of its own.
        for (_, m) in &mut modbus {
            m.join(&mut cell.stations);
            m.open_connection(Instant::ZERO, &mut cell.stations);
        }
        for (k, diagnostics, physics) in modbus_plans {
            match modbus.get(k).and_then(|(_, m)| m.station()) {
                Some(id) => cell.plan_drive(id, diagnostics, physics),
                None => return Err(cell_err(format!("CMMO-ST {k}: not in the cell"))),
            }
        }
        let forced = vec![(0, 0); cell.stations.len()];
        let mut rig = VirtualRig {
            cell,
            now: Instant::ZERO,
            out: Vec::new(),
            forced,
            pending: Vec::new(),
            modbus,
        };
        // Booted in bus order; the boot-up frames wait in `pending` for the first emit.
        for b in 0..rig.cell.buses.len() {
            rig.cell.boot(b, Instant::ZERO, &mut out);
            rig.pending.extend(out.drain(..).map(|f| (b, f)));
        }
        Ok(rig)
    }

    /// Every frame of the first bus into `path` (pcap; `*.log`: candump), stamped with the
    /// virtual clock.
    pub fn trace_to(&mut self, path: &Path) -> std::io::Result<()> {
        let mut file = TraceWriter::create(path, "vcan0")?;
        match self.cell.bus_mut(0) {
            Some(bus) => bus.port_mut().sink_mut().start(Box::new(file)),
            // A cell without a CAN bus: a trace without frames.
            None => file.flush()?,
        }
        Ok(())
    }

    /// The FMI version of the load FMU coupled to node `node`'s drive, if it has one.
    pub fn load_fmi_version(&self, node: u8) -> Option<&'static str> {
        self.cell
            .buses
            .iter()
            .flat_map(|b| b.stations(&self.cell.stations))
            .find(|d| d.node_id() == node)?
            .model
            .drive()?
            .load()
            .map(|l| l.fmi_version())
    }

    /// Ends the trace (the file complete).
    pub fn finish(&mut self) -> std::io::Result<()> {
        match self
            .cell
            .bus_mut(0)
            .and_then(|b| b.port_mut().sink_mut().stop())
        {
            Some(mut w) => w.flush(),
            None => Ok(()),
        }
    }

    /// The frames bus `b`'s drives sent at `now` are on the bus (and those still pending).
    fn emit(&mut self, b: usize, seen: &mut dyn FnMut(usize, Duration, &CanFrame)) {
        // (drained: the list keeps its room, no allocation per frame)
        self.pending.extend(self.out.drain(..).map(|f| (b, f)));
        self.flush(seen);
    }

    fn flush(&mut self, seen: &mut dyn FnMut(usize, Duration, &CanFrame)) {
        let t = Duration::from_nanos(self.now.as_nanos());
        for (b, f) in self.pending.drain(..) {
            if let Some(bus) = self.cell.bus_mut(b) {
                // The bus's port passes every frame; it only traces it.
                bus.port_mut().cross(At::on_clock(self.now), &f);
            }
            seen(b, t, &f);
        }
    }

    /// The bus and the id of the station with node-ID `node` (the first station of the
    /// first bus without one).
    fn drive(&self, node: Option<u8>) -> Result<(usize, StationId), String> {
        (0..self.cell.buses.len())
            .find_map(|b| Some((b, self.drive_on(b, node).ok()?)))
            .ok_or_else(|| match node {
                None => "no drive".to_string(),
                Some(n) => format!("no node {n} in the cell"),
            })
    }

    /// The station with node-ID `node` on bus `bus` (the bus's first without a node).
    fn drive_on(&self, bus: usize, node: Option<u8>) -> Result<StationId, String> {
        let c = self.segment(bus)?;
        let found = c.members().iter().copied().find(|id| {
            node.is_none_or(|n| self.cell.station(*id).is_some_and(|d| d.node_id() == n))
        });
        found.ok_or_else(|| match node {
            None => "no drive".to_string(),
            Some(n) => format!("no node {n} on bus {bus}"),
        })
    }

    /// The CMMO-ST with node-ID `node` (a CANopen node of that number wins).
    fn cmmo_st(&self, node: Option<u8>) -> Option<usize> {
        let cia402 = self.drive(node).is_ok();
        match node {
            None if self.cell.buses.iter().all(|c| c.members().is_empty()) => {
                (!self.modbus.is_empty()).then_some(0)
            }
            Some(n) if !cia402 => self.modbus.iter().position(|(m, _)| *m == n),
            _ => None,
        }
    }

    /// The device of the CMMO-ST at `i` of [`VirtualRig::cmmo_st`].
    fn modbus_device(&mut self, i: usize) -> Option<&mut dyn ModbusDevice> {
        let (_, m) = self.modbus.get_mut(i)?;
        m.device_mut(&mut self.cell.stations)
    }

    fn segment(&self, bus: usize) -> Result<&SegmentBus, String> {
        self.cell
            .bus(bus)
            .ok_or_else(|| format!("bus {bus}: the cell has {} bus(es)", self.cell.buses.len()))
    }

    fn segment_mut(&mut self, bus: usize) -> Result<&mut SegmentBus, String> {
        let n = self.cell.buses.len();
        self.cell
            .bus_mut(bus)
            .ok_or_else(|| format!("bus {bus}: the cell has {n} bus(es)"))
    }

    /// Station `id`.
    fn station(&self, id: StationId) -> Result<&Station, String> {
        self.cell.station(id).ok_or_else(|| "no drive".to_string())
    }

    fn encode(&self, id: StationId, index: u16, sub: u8, value: &str) -> Result<Vec<u8>, String> {
        let d = self.station(id)?;
        let e = d
            .od()
            .description()
            .entry(index, sub)
            .ok_or_else(|| format!("{index:04X}:{sub:02X}: no such object"))?;
        crate::value_text::encode(e.data_type, value)
    }

    fn plant(&mut self, id: StationId) -> Result<&mut drive::vendors::AnyDrive<Vec<u8>>, String> {
        self.cell
            .station_mut(id)
            .and_then(|d| d.model.drive_mut().map(|d| &mut **d))
            .ok_or_else(|| "the drive has no simulated plant".to_string())
    }
}

/// A drive of the rig as an importer addresses it: a CANopen drive by its node-ID, a drive
/// with its own register image (the CMMO-ST) by its place among them in the cell file's
/// order, as it has no node-ID of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RigDrive {
    Node(u8),
    RegisterImage(usize),
}

/// A drive of the rig found once ([`VirtualRig::place`]): a CANopen drive's station with the
/// entries of the words its [`Probe`] shows, or a register-image drive's place among them. An
/// importer that reads every drive after each step reads each at its place, without a search
/// by node-ID or a dictionary lookup.
#[derive(Clone, Copy)]
pub enum RigPlace {
    Station(StationId, Words),
    RegisterImage(usize),
}

/// The dictionary entries of the words a [`Probe`] shows (6041h, 6064h), found once in a
/// drive's description and read as [`ObjectAccess::read`] reads them.
#[derive(Clone, Copy)]
pub struct Words {
    /// The description the entries are of: a dictionary of another reads its own.
    desc: &'static DeviceDescription,
    statusword: Option<&'static Entry>,
    position_actual: Option<&'static Entry>,
}

impl Words {
    /// The entries of 6041h and 6064h in `desc` whose stored bytes are what a read returns
    /// (`None`: refused, or reads as zeros).
    pub fn of(desc: &'static DeviceDescription) -> Words {
        Words {
            desc,
            statusword: stored_read_entry(desc, 0x6041, 0),
            position_actual: stored_read_entry(desc, 0x6064, 0),
        }
    }

    /// The statusword and the position actual value in `od`, as `read_u16` / `read_u32` of
    /// its entries give them (0 for a word the dictionary refuses or holds in another size).
    fn read(&self, od: &ObjectDictionary<Vec<u8>>) -> (u16, i32) {
        if !std::ptr::eq(self.desc, od.description()) {
            return Words::of(od.description()).read(od);
        }
        (
            u16::from_le_bytes(value(od, self.statusword)),
            i32::from_le_bytes(value(od, self.position_actual)),
        )
    }
}

/// The `N` bytes of entry `e` as the dictionary's read gives them (zeros for none or an entry
/// of another size).
fn value<const N: usize>(od: &ObjectDictionary<Vec<u8>>, e: Option<&Entry>) -> [u8; N] {
    e.and_then(|e| <[u8; N]>::try_from(od.raw(e)).ok())
        .unwrap_or([0; N])
}

/// What a drive's plant and device control show at one instant: the quantities a cell shows
/// to an importer that steps it (the cell as an FMU, `drivetwin scenario --samples`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Probe {
    /// The motor shaft's angle, rad (the plant's, not the encoder's quantised reading).
    pub position_rad: f64,
    /// The shaft's angular velocity, rad/s.
    pub velocity_rad_s: f64,
    /// The winding current, A.
    pub current_a: f64,
    /// The statusword (6041h).
    pub statusword: u16,
    /// The position actual value (6064h), in the drive's position units; a drive served with
    /// its own register image: its actual position in its position unit.
    pub position_actual: i32,
    /// A drive served with its own register image: the status bytes of its input telegram
    /// (FHPP: SCON, SPOS, SDIR, actual values); zero for a CiA 402 drive.
    pub status: [u8; 8],
}

impl VirtualRig {
    /// The node-IDs of the CANopen drives, bus by bus in the cell file's order.
    pub fn nodes(&self) -> Vec<u8> {
        self.cell
            .buses
            .iter()
            .flat_map(|b| b.stations(&self.cell.stations).map(|d| d.node_id()))
            .collect()
    }

    /// The node-IDs of the drives served with their own register image (the CMMO-STs), in
    /// the cell file's order.
    pub fn register_image_nodes(&self) -> Vec<u8> {
        self.modbus.iter().map(|(n, _)| *n).collect()
    }

    /// What the display of the `i`-th register-image drive (cell file order) shows (`None`:
    /// no such drive, or no display).
    pub fn register_image_display(&mut self, i: usize) -> Option<String> {
        self.register_image_display_state(i)
            .map(|d| d.text().to_string())
    }

    /// [`VirtualRig::register_image_display`] as the display's state (no text made).
    pub fn register_image_display_state(
        &mut self,
        i: usize,
    ) -> Option<crate::cell::control::DisplayState> {
        self.modbus_device(i)?.plant().1
    }

    /// `action` (a load torque, a switch, an object write, a Modbus request) on the `i`-th
    /// register-image drive, whatever node the action names: a CMMO-ST has no node-ID a
    /// CANopen drive cannot share, so an importer addresses it by its place.
    pub fn act_on_register_image(
        &mut self,
        i: usize,
        action: &Action,
        seen: &mut dyn FnMut(usize, Duration, &CanFrame),
    ) -> Result<(), String> {
        let now = self.now;
        let r = self
            .act_on_modbus(i, action, now)
            .unwrap_or_else(|| Err(format!("the CMMO-ST takes no {action:?}")));
        self.flush(seen);
        r
    }

    /// Where drive `drive` is, found once for the reads that follow ([`VirtualRig::probe_at`]):
    /// a CANopen drive's station (as [`VirtualRig::probe`] finds it by its node-ID, the first
    /// bus that has it), with its words' entries; a register-image drive's place.
    pub fn place(&self, drive: RigDrive) -> Result<RigPlace, String> {
        match drive {
            RigDrive::Node(n) => match self.cmmo_st(Some(n)) {
                Some(i) => Ok(RigPlace::RegisterImage(i)),
                None => {
                    let (_, id) = self.drive(Some(n))?;
                    let words = Words::of(self.station(id)?.od().description());
                    Ok(RigPlace::Station(id, words))
                }
            },
            RigDrive::RegisterImage(i) => Ok(RigPlace::RegisterImage(i)),
        }
    }

    /// The plant and words now of the drive at `place` (`None`: no simulated plant there).
    pub fn probe_at(&self, place: &RigPlace) -> Option<Probe> {
        match place {
            RigPlace::Station(id, words) => {
                Probe::of_model_with(&self.cell.station(*id)?.model, words)
            }
            RigPlace::RegisterImage(i) => self.register_image_probe(*i),
        }
    }

    /// The engine of the CANopen drive at `place` (its plant and device control), if it has
    /// one.
    pub fn drive_model_at(&self, place: &RigPlace) -> Option<&drive::vendors::AnyDrive<Vec<u8>>> {
        match place {
            RigPlace::Station(id, _) => self.cell.station(*id)?.model.drive().map(|d| &**d),
            RigPlace::RegisterImage(_) => None,
        }
    }

    /// Drive `drive`'s plant and words now.
    pub fn probe_drive(&self, drive: RigDrive) -> Result<Probe, String> {
        match drive {
            RigDrive::Node(n) => self.probe(n),
            RigDrive::RegisterImage(i) => self
                .register_image_probe(i)
                .ok_or_else(|| format!("no register-image drive {i}")),
        }
    }

    fn register_image_probe(&self, i: usize) -> Option<Probe> {
        let (_, m) = self.modbus.get(i)?;
        let r = m.readout(&self.cell.stations)?;
        Some(Probe {
            position_rad: r.position_rad,
            velocity_rad_s: r.velocity_rad_s,
            current_a: r.current_a,
            statusword: 0,
            position_actual: r.position_actual,
            status: r.status,
        })
    }

    /// Each bus's bit rate, in the cell file's order (none: the instant bus).
    pub fn bus_bitrates(&self) -> Vec<Option<u32>> {
        self.cell
            .buses
            .iter()
            .map(SegmentBus::timed_bitrate)
            .collect()
    }

    /// The engine of node `node`'s drive (its plant and device control), if it has one.
    pub fn drive_model(&self, node: u8) -> Option<&drive::vendors::AnyDrive<Vec<u8>>> {
        let (_, id) = self.drive(Some(node)).ok()?;
        self.cell.station(id)?.model.drive().map(|d| &**d)
    }

    /// Bus `bus` keeps the frames from outside that cross it ([`crate::cell::can_segment::SegmentBus::report_outside_frames`]).
    pub fn report_outside_frames(&mut self, bus: usize) {
        if let Some(c) = self.cell.bus_mut(bus) {
            c.report_outside_frames();
        }
    }

    /// The frames from outside that crossed bus `bus` since the last call: end of frame,
    /// frame, and whether a drive received it.
    pub fn take_outside_frames(
        &mut self,
        bus: usize,
    ) -> impl Iterator<Item = (Instant, CanFrame, bool)> + '_ {
        self.cell
            .bus_mut(bus)
            .into_iter()
            .flat_map(SegmentBus::take_outside_frames)
    }

    /// Whether `frame` from outside, put on bus `bus` now, would wait for the bus.
    pub fn would_wait(&self, bus: usize, frame: &CanFrame) -> bool {
        self.cell
            .bus(bus)
            .is_some_and(|c| c.would_wait(self.now, frame))
    }

    /// How many drives the rig serves over Modbus TCP (the CMMO-STs), in the cell file's order.
    pub fn modbus_drives(&self) -> usize {
        self.modbus.len()
    }

    /// The Modbus TCP front end of the `i`-th drive served over Modbus TCP (cell file
    /// order), with the cell's stations, where its drive is: the cell FMU's Modbus TCP front
    /// end opens its connections on it and passes it the client's bytes.
    pub fn modbus_drive_mut(&mut self, i: usize) -> Option<(&mut ModbusDrive, &mut Stations)> {
        let (_, m) = self.modbus.get_mut(i)?;
        Some((m, &mut self.cell.stations))
    }

    /// How many CANopen drives bus `bus` has (0 for a bus it does not have).
    pub fn drives_on(&self, bus: usize) -> usize {
        self.cell.bus(bus).map_or(0, |c| c.members().len())
    }

    /// The time the rig has run to.
    pub fn now(&self) -> Instant {
        self.now
    }

    /// Drive `node`'s plant and words now.
    pub fn probe(&self, node: u8) -> Result<Probe, String> {
        if let Some(p) = self
            .cmmo_st(Some(node))
            .and_then(|i| self.register_image_probe(i))
        {
            return Ok(p);
        }
        let (_, id) = self.drive(Some(node))?;
        let station = self.station(id)?;
        Probe::of_model(&station.model)
            .ok_or_else(|| format!("node {node}: the drive has no simulated plant"))
    }
}

impl Probe {
    /// A CiA 402 drive's plant and words now (`None`: a dictionary without a plant).
    pub fn of_model(model: &crate::cell::device_model::Model) -> Option<Probe> {
        model.drive()?;
        Probe::of_model_with(model, &Words::of(model.od().description()))
    }

    /// [`Probe::of_model`] with the words' entries found beforehand.
    pub fn of_model_with(model: &crate::cell::device_model::Model, words: &Words) -> Option<Probe> {
        let d = model.drive()?;
        let shaft = d.shaft();
        let current_a = match d.stepper() {
            Some(s) => s.current_a(),
            None => d.axis().motor().current(),
        };
        let (statusword, position_actual) = words.read(model.od());
        Some(Probe {
            position_rad: shaft.angle_rad,
            velocity_rad_s: shaft.velocity_rad_s,
            current_a,
            statusword,
            position_actual,
            status: [0; 8],
        })
    }
}

impl Rig for VirtualRig {
    fn stopped(&self) -> Option<String> {
        self.cell
            .load_failure()
            .map(|e| format!("load: {e}"))
            .or_else(|| {
                self.modbus.iter().find_map(|(node, m)| {
                    m.load_failure(&self.cell.stations)
                        .map(|e| format!("node {node}: load: {e}"))
                })
            })
    }

    fn run_until(&mut self, t: Duration, seen: &mut dyn FnMut(usize, Duration, &CanFrame)) {
        let end = Instant::from_nanos(u64::try_from(t.as_nanos()).unwrap_or(u64::MAX));
        self.flush(seen);
        let mut stuck = 0u32;
        loop {
            let wake = (0..self.cell.buses.len())
                .filter_map(|b| self.cell.deadline_of(b))
                .chain(self.cell.plans_deadline())
                .chain(
                    self.modbus
                        .iter()
                        .filter_map(|(_, m)| m.next_cycle(&self.cell.stations)),
                )
                .min()
                .filter(|w| *w <= end);
            let Some(wake) = wake else {
                break;
            };
            // A deadline that does not move would spin forever: give up loudly instead.
            stuck = if wake <= self.now { stuck + 1 } else { 0 };
            if stuck > STUCK {
                tracing::error!(at = ?self.now, "virtual clock stuck on a deadline that does not advance");
                break;
            }
            self.now = wake.max(self.now);
            // The planned changes first, then the Modbus cycles, then the buses in order (as
            // `run_virtual_mixed`).
            self.cell.carry_out_plans(self.now);
            for (_, m) in &mut self.modbus {
                m.cycle(self.now, &mut self.cell.stations);
            }
            for b in 0..self.cell.buses.len() {
                let now = self.now;
                let mut out = std::mem::take(&mut self.out);
                if self.cell.deadline_of(b).is_some_and(|d| d <= now) {
                    self.cell.poll(b, now, &mut out);
                }
                self.out = out;
                self.emit(b, seen);
            }
        }
        self.now = end.max(self.now);
    }

    fn act(
        &mut self,
        action: &Action,
        seen: &mut dyn FnMut(usize, Duration, &CanFrame),
    ) -> Result<(), String> {
        let now = self.now;
        if let Some(r) = self.act_cmmo_st(action, now) {
            self.flush(seen);
            return r;
        }
        let on: usize;
        let result = match action {
            Action::Frame { bus, frame } => {
                on = *bus;
                self.segment(*bus)?;
                self.out.push(*frame);
                self.emit(*bus, seen);
                let mut out = std::mem::take(&mut self.out);
                self.cell.on_frame(*bus, now, frame, &mut out);
                self.out = out;
                Ok(())
            }
            Action::SdoWrite {
                bus,
                node,
                index,
                sub,
                value,
            } => {
                on = *bus;
                let id = self.drive_on(*bus, *node)?;
                let bytes = self.encode(id, *index, *sub, value)?;
                let node = self.station(id).map_or(0, |d| d.node_id());
                let frame = expedited_download(node, *index, *sub, &bytes)?;
                self.out.push(frame);
                self.emit(*bus, seen);
                let mut out = std::mem::take(&mut self.out);
                self.cell.on_frame(*bus, now, &frame, &mut out);
                self.out = out;
                Ok(())
            }
            Action::Write {
                node,
                index,
                sub,
                value,
            } => {
                let (b, id) = self.drive(*node)?;
                on = b;
                let bytes = self.encode(id, *index, *sub, value)?;
                let mut result = Ok(());
                let mut out = std::mem::take(&mut self.out);
                self.cell.local_access(id, now, &mut out, &mut |a| {
                    result = a.write(*index, *sub, &bytes);
                });
                self.out = out;
                result.map_err(|code| {
                    format!(
                        "{index:04X}:{sub:02X} refused: SDO abort {:#010X} ({})",
                        code.0,
                        code.description().unwrap_or("unknown")
                    )
                })
            }
            Action::Input { node, din, level } => {
                let (b, id) = self.drive(*node)?;
                on = b;
                let (mask, levels) = self.forced.get(id.index()).copied().unwrap_or_default();
                let bit = 1u16 << din;
                let forced = (
                    mask | bit,
                    if *level { levels | bit } else { levels & !bit },
                );
                self.plant(id)
                    .map_err(|_| "the drive has no simulated inputs".to_string())?
                    .force_inputs(forced.0, forced.1);
                if let Some(f) = self.forced.get_mut(id.index()) {
                    *f = forced;
                }
                Ok(())
            }
            Action::Load { node, torque_nm } => {
                let (b, id) = self.drive(*node)?;
                on = b;
                self.plant(id)
                    .map_err(|_| "the drive has no simulated motor".to_string())?
                    .axis_mut()
                    .motor_mut()
                    .set_load_torque(*torque_nm);
                Ok(())
            }
            Action::Physics { node, change } => {
                let (b, id) = self.drive(*node)?;
                on = b;
                let d = self.plant(id)?;
                crate::cell::control::apply_physics(d, *change)
                    .map_err(|s| format!("the drive has no input with the function {s}"))?;
                let now_forced = d.forced_inputs();
                if let crate::cell::control::PhysicsChange::Switch(..) = change {
                    // A switch forced by name joins the inputs forced by number.
                    if let Some(f) = self.forced.get_mut(id.index()) {
                        *f = now_forced;
                    }
                }
                Ok(())
            }
            Action::Diagnostic {
                node,
                number,
                raise,
            } => {
                let (b, id) = self.drive(*node)?;
                on = b;
                let done = if *raise {
                    self.cell.raise_diagnostic(id, number)
                } else {
                    self.cell.clear_diagnostic(id, number)
                };
                done.map(|_| ()).map_err(|e| e.to_string())
            }
            Action::Fault { bus, fault } => {
                on = *bus;
                self.segment_mut(*bus)?
                    .add_wire_fault(now, *fault)
                    .map(|_| ())
                    .map_err(|e| e.to_string())
            }
            Action::ClearFaults { bus } => {
                on = *bus;
                self.segment_mut(*bus)?.clear_wire_faults();
                Ok(())
            }
            // Answered by `act_cmmo_st` when the node is a CMMO-ST.
            Action::Modbus { .. } => return Err("no CMMO-ST with that node".into()),
            // Decision: the virtual rig's cell has CAN buses only; a chain's line is a live
            // cell's (a scenario posted to its console, `POST /api/scenarios`).
            Action::EthercatLine { .. } => {
                return Err("ethercat_line runs on a live cell with an EtherCAT chain".into())
            }
        };
        self.emit(on, seen);
        result
    }

    fn read(&mut self, node: Option<u8>, index: u16, sub: u8) -> Result<(u64, usize), String> {
        if let Some(dev) = self.cmmo_st(node).and_then(|i| self.modbus_device(i)) {
            let mut buf = [0u8; 8];
            let n = dev
                .read_object(index, sub, &mut buf)
                .map_err(|code| format!("{index:04X}:{sub:02X}: abort {:#010X}", code.0))?;
            return Ok((unsigned(buf.get(..n).unwrap_or(&[])), n));
        }
        let (_, id) = self.drive(node)?;
        let d = self.station(id)?;
        let mut buf = [0u8; 8];
        let n = d
            .model
            .read(index, sub, &mut buf)
            .map_err(|code| format!("{index:04X}:{sub:02X}: SDO abort {:#010X}", code.0))?;
        Ok((unsigned(buf.get(..n).unwrap_or(&[])), n))
    }
}

impl VirtualRig {
    /// An action addressed to a CMMO-ST (`None`: not one of its actions or not a CMMO-ST).
    fn act_cmmo_st(&mut self, action: &Action, now: Instant) -> Option<Result<(), String>> {
        let node = match action {
            Action::Write { node, .. }
            | Action::Diagnostic { node, .. }
            | Action::Physics { node, .. }
            | Action::Load { node, .. } => *node,
            Action::Modbus { node, .. } => *node,
            _ => return None,
        };
        let Some(i) = self.cmmo_st(node) else {
            return match action {
                Action::Modbus { .. } => Some(Err("no CMMO-ST with that node".into())),
                _ => None,
            };
        };
        self.act_on_modbus(i, action, now)
    }

    /// `action` on the `i`-th CMMO-ST (`None`: an action it does not take).
    fn act_on_modbus(
        &mut self,
        i: usize,
        action: &Action,
        now: Instant,
    ) -> Option<Result<(), String>> {
        let stations = &mut self.cell.stations;
        let Some((_, m)) = self.modbus.get_mut(i) else {
            return Some(Err(format!("no CMMO-ST {i}")));
        };
        if let Action::Modbus { request, .. } = action {
            let mut answer = Vec::new();
            return Some(
                m.answer(request, now, &mut answer, stations)
                    .map_err(|e| format!("Modbus connection closed: {e:?}")),
            );
        }
        let Some(d) = m.device_mut(stations) else {
            return Some(Err(format!("CMMO-ST {i}: not in the cell")));
        };
        Some(match action {
            Action::Write {
                index, sub, value, ..
            } => {
                let e = d.description().entry(*index, *sub);
                match e {
                    None => Err(format!("{index:04X}:{sub:02X}: no such object")),
                    Some(e) => crate::value_text::encode(e.data_type, value).and_then(|bytes| {
                        d.write_object(*index, *sub, &bytes).map_err(|code| {
                            format!("{index:04X}:{sub:02X} refused: {:#010X}", code.0)
                        })
                    }),
                }
            }
            Action::Diagnostic { number, raise, .. } => {
                use crate::cell::diagnostics::Action;
                let action = if *raise { Action::Raise } else { Action::Clear };
                d.set_diagnostic(number, action)
                    .map(|_| ())
                    .map_err(|e| format!("{e:?}"))
            }
            Action::Physics { change, .. } => d
                .physics(*change)
                .map(drop)
                .map_err(|switch| format!("the CMMO-ST has no input with the function {switch}")),
            Action::Load { torque_nm, .. } => {
                d.set_load(*torque_nm);
                Ok(())
            }
            _ => return None,
        })
    }
}

/// A drive served over Modbus TCP as `drivetwin run` makes it (its dictionary with the cell
/// file's values), served by scripted Modbus requests.
fn served(
    spec: &crate::cell::config::DriveSpec,
    fhpp: &crate::cell::config::FhppSpec,
    modbus_device: NewModbusDevice,
) -> Result<ModbusDrive, String> {
    let device = modbus_device(spec, None)
        .ok_or_else(|| format!("drive {}: not served over Modbus TCP", spec.desc.name))?
        .map_err(|e| e.to_string())?
        .device;
    let mut config = crate::modbus_tcp::server::ModbusConfig::default();
    if let Some(ms) = fhpp.watchdog_ms {
        config.watchdog_ms = ms;
    }
    Ok(ModbusDrive::without_listener(device, config))
}

/// Little-endian bytes as a number (at most 8).
pub fn unsigned(bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .take(8)
        .rev()
        .fold(0u64, |acc, b| (acc << 8) | u64::from(*b))
}

/// An expedited SDO download to `node` (CiA 301 §7.2.4.3.3: 2Fh/2Bh/27h/23h for 1…4 bytes).
pub fn expedited_download(node: u8, index: u16, sub: u8, data: &[u8]) -> Result<CanFrame, String> {
    let n = data.len();
    if !(1..=4).contains(&n) {
        return Err(format!(
            "{index:04X}:{sub:02X}: an expedited SDO carries 1 to 4 bytes, not {n}"
        ));
    }
    let cs = 0x23 | (((4 - n) as u8) << 2);
    let [lo, hi] = index.to_le_bytes();
    let mut payload = [cs, lo, hi, sub, 0, 0, 0, 0];
    for (slot, b) in payload.iter_mut().skip(4).zip(data) {
        *slot = *b;
    }
    CanFrame::new(0x600 + u16::from(node), &payload).map_err(|e| format!("{e:?}"))
}
