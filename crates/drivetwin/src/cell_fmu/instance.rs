//! One instance of the cell FMU: the cell file's CANopen drives on the virtual clock
//! ([`VirtualRig`]), stepped by the importer.
//!
//! A `doStep(t, h)` does, in this order: the frames the LS-BUS terminals received go onto
//! their buses at `t` ([`super::can_terminal`]), the inputs set since the last step act at `t`
//! (a load torque as a scenario's `load`, a digital input as its `din`), the timeline's
//! actions due in `[t, t + h)` each at its time, then the cell runs to `t + h` from deadline
//! to deadline as `drivetwin scenario` runs it; the frames that crossed go to the terminals
//! and to the front ends' clients. Times are the clock's nanoseconds (`t` rounded to the
//! nanosecond), so the same inputs at the same times give the same outputs bit for bit, and
//! the same as the scenario with those inputs as its steps.

use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};
use std::time::Duration;

use crate::cell::config::CellFile;
use crate::cell::control::DriveViews;
use crate::cell::Vendors;
use crate::scenario::file::{Action, StepKind};
use crate::scenario::runner::Rig;
use crate::scenario::virtual_rig::{Probe, RigDrive, RigPlace, VirtualRig};
use crate::scenario::Scenario;

use super::can_terminal::CanTerminal;
use super::ethercat_front::EthercatChains;
use super::front_ends::{lock, BusFrame, FrontEnds, Shared, SharedCell};
use super::modbus_front::{self, ModbusFronts};
use super::parameters::{Parameters, Start};
use super::variables::{DriveName, Profile, Role, Variables, DIGITAL_INPUTS};
use super::{CellFmuError, CELL_FILE, ETHERCAT_FILE, TIMELINE_FILE};

/// What the importer set for a drive, and what has acted of it.
#[derive(Debug, Clone)]
struct Inputs {
    /// Set since the inputs last acted (and before the first step, where the load torque
    /// acts): a step looks at the drive's inputs only then, not at its 16 inputs every step.
    pending: bool,
    load_torque: f64,
    /// The load torque that acted last (none before the first step).
    load_applied: Option<f64>,
    din: [Option<bool>; DIGITAL_INPUTS as usize],
    din_applied: [Option<bool>; DIGITAL_INPUTS as usize],
    /// An FHPP drive's reference switch, and the level that acted last.
    reference: Option<bool>,
    reference_applied: Option<bool>,
}

impl Default for Inputs {
    fn default() -> Self {
        Inputs {
            pending: true,
            load_torque: 0.0,
            load_applied: None,
            din: [None; DIGITAL_INPUTS as usize],
            din_applied: [None; DIGITAL_INPUTS as usize],
            reference: None,
            reference_applied: None,
        }
    }
}

/// A cell stepped by an FMI importer.
pub struct CellInstance {
    /// The cell, shared with the front ends' thread.
    shared: SharedCell,
    /// The socketcand servers of the cell file's buses, when it has any.
    front_ends: Option<FrontEnds>,
    /// The Modbus TCP servers of the drives served that way, when it has any.
    modbus_fronts: Option<ModbusFronts>,
    /// The EtherCAT chains of the cell file's slaves, stepped with the rig.
    ethercat: EthercatChains,
    variables: Variables,
    /// Each drive of the variables as the rig knows it, in their order.
    drives: Vec<RigDrive>,
    /// Where each of `drives` is in the rig, found once: its outputs are read there.
    places: Vec<RigPlace>,
    /// The cell file's keys that are FMI parameters, their starts the values the cell was
    /// built with.
    parameters: Parameters,
    /// The timeline's actions in time order, and how many have been done.
    timeline: Vec<(Duration, Action)>,
    done: usize,
    inputs: Vec<Inputs>,
    /// The virtual clock, ns.
    now: u64,
    /// What the drives' displays show.
    views: DriveViews,
    /// The FMI-LS-BUS CAN terminal of each bus.
    pub(super) terminals: Vec<CanTerminal>,
    /// What each drive's display shows, as a C string (NUL-terminated), read from the
    /// drive at the first get of it after a step and emptied by the next step, so that a
    /// step whose displays nobody reads reads none: `fmi3GetString` hands out pointers to
    /// these bytes, which stay where they are (FMI 3.0 §2.2.6.2: valid until the next call
    /// that changes the FMU's state).
    displays: Vec<OnceLock<[u8; DISPLAY_BYTES]>>,
    /// A step's working lists, kept from step to step so that a step allocates nothing once
    /// they have grown to the cell's traffic.
    scratch: StepScratch,
}

/// The lists a `doStep` fills and empties.
#[derive(Debug, Default)]
struct StepScratch {
    /// The frames of the cell's drives that crossed the buses, for the LS-BUS terminals.
    frames: Vec<(usize, Duration, canopen::CanFrame)>,
    /// The ends of the frames from outside (bus, end, frame, acknowledged), in time order.
    outside: Vec<(usize, Duration, canopen::CanFrame, bool)>,
    /// A terminal's frames for its bus.
    to_bus: Vec<canopen::CanFrame>,
    /// What crossed while one of them went onto the bus.
    answers: Vec<(usize, Duration, canopen::CanFrame)>,
}

/// The bytes of a display's text kept for `fmi3GetString`, its NUL included (a display shows
/// at most 16 bytes, `DisplayState`).
const DISPLAY_BYTES: usize = 32;

/// `text` (up to its first NUL, cut to fit) followed by NULs.
fn text_bytes(text: &str) -> [u8; DISPLAY_BYTES] {
    let bytes = text.as_bytes();
    let n = bytes
        .iter()
        .position(|b| *b == 0)
        .unwrap_or(bytes.len())
        .min(DISPLAY_BYTES - 1);
    let mut buffer = [0u8; DISPLAY_BYTES];
    if let (Some(dst), Some(src)) = (buffer.get_mut(..n), bytes.get(..n)) {
        dst.copy_from_slice(src);
    }
    buffer
}

/// The drives' outputs for the values of one get call: the cell locked, and its outputs
/// read anew when a step or a client's frame left them stale ([`Shared::stale`]), at the
/// first value that needs them, and held for the rest of the call (one lock per call, not
/// per value).
struct Outputs<'a> {
    cell: &'a CellInstance,
    guard: Option<MutexGuard<'a, Shared>>,
}

impl Outputs<'_> {
    /// Drive `drive`'s outputs.
    fn of(&mut self, drive: usize) -> Probe {
        let cell = self.cell;
        let shared = self.guard.get_or_insert_with(|| {
            let mut shared = lock(&cell.shared);
            if shared.stale {
                cell.refresh(&mut shared);
            }
            shared
        });
        shared.outputs.get(drive).copied().unwrap_or_default()
    }
}

impl CellInstance {
    /// The cell of `resources/cell.toml`, with the actions of `resources/timeline.toml` when
    /// there is one, booted at 0, its buses' socketcand servers open ([`FrontEnds`]).
    pub fn from_resources(
        resources: &Path,
        vendors: Vendors,
    ) -> Result<CellInstance, CellFmuError> {
        CellInstance::from_resources_with(resources, vendors, &[])
    }

    /// [`CellInstance::from_resources`] with the parameters `set` (value reference, value),
    /// written into the cell file before the cell is built ([`Parameters::apply`]).
    pub fn from_resources_with(
        resources: &Path,
        vendors: Vendors,
        set: &[(u32, f64)],
    ) -> Result<CellInstance, CellFmuError> {
        let cell_path = resources.join(CELL_FILE);
        let mut cell = CellFile::load(&cell_path).map_err(|e| CellFmuError::Cell(e.to_string()))?;
        let ethercat_path = resources.join(ETHERCAT_FILE);
        let ethercat_if = match std::fs::read_to_string(&ethercat_path) {
            Ok(text) => Some(text.trim().to_string()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(source) => {
                return Err(CellFmuError::Io {
                    path: ethercat_path,
                    source,
                })
            }
        };
        let ethercat_if = ethercat_if.as_deref();
        if !set.is_empty() {
            // The parameters as the description declares them: those of the file as written.
            let (rest, ethercat) = EthercatChains::split(&cell, vendors, ethercat_if)?;
            let rig = VirtualRig::new_without_drives_allowed(&rest, vendors)
                .map_err(|e| CellFmuError::Cell(e.to_string()))?;
            let steppers = register_image_sections(&cell, vendors)?;
            parameters_of(&rig, &rig.nodes(), &steppers, &ethercat)
                .apply(&mut cell, vendors, set)?;
        }
        let timeline_path = resources.join(TIMELINE_FILE);
        let timeline = if timeline_path.exists() {
            let text =
                std::fs::read_to_string(&timeline_path).map_err(|source| CellFmuError::Io {
                    path: timeline_path.clone(),
                    source,
                })?;
            Some(
                Scenario::parse(&text, TIMELINE_FILE, None)
                    .map_err(|e| CellFmuError::Timeline(e.to_string()))?,
            )
        } else {
            None
        };
        let mut instance =
            CellInstance::with_ethercat(&cell, timeline.as_ref(), vendors, ethercat_if)?;
        instance.front_ends = FrontEnds::open(&cell, &instance.shared)?;
        let servers = modbus_front::addresses(&cell, vendors)?;
        instance.modbus_fronts = ModbusFronts::open(&servers, &instance.shared)?;
        instance.ethercat.open(&instance.shared)?;
        Ok(instance)
    }

    /// `cell`, with `timeline`'s actions (its expectations are not checked here), its front
    /// ends closed (they open in [`CellInstance::from_resources`], the FMU's instance).
    pub fn new(
        cell: &CellFile,
        timeline: Option<&Scenario>,
        vendors: Vendors,
    ) -> Result<CellInstance, CellFmuError> {
        CellInstance::with_ethercat(cell, timeline, vendors, None)
    }

    /// [`CellInstance::new`] with `ethercat_if` the chain of the EtherCAT slaves that name
    /// none, as `drivetwin run --ethercat IFNAME` gives it
    /// ([`crate::cell::interfaces::resolve_ethercat_chains`]).
    pub fn with_ethercat(
        cell: &CellFile,
        timeline: Option<&Scenario>,
        vendors: Vendors,
        ethercat_if: Option<&str>,
    ) -> Result<CellInstance, CellFmuError> {
        let views = vendors.views;
        // The EtherCAT slaves form chains of their own; the rest is the virtual rig's.
        let (rest, ethercat) = EthercatChains::split(cell, vendors, ethercat_if)?;
        let rig = VirtualRig::new_without_drives_allowed(&rest, vendors)
            .map_err(|e| CellFmuError::Cell(e.to_string()))?;
        let register_image = register_image_sections(cell, vendors)?;
        if register_image.len() != rig.modbus_drives() {
            return Err(CellFmuError::Cell(format!(
                "{} CMMO-ST section(s), {} served",
                register_image.len(),
                rig.modbus_drives()
            )));
        }
        let nodes = rig.nodes();
        let drives: Vec<RigDrive> = nodes
            .iter()
            .map(|n| RigDrive::Node(*n))
            .chain((0..register_image.len()).map(RigDrive::RegisterImage))
            .collect();
        let places = drives
            .iter()
            .map(|d| rig.place(*d))
            .collect::<Result<Vec<_>, _>>()
            .map_err(CellFmuError::Cell)?;
        let variables = Variables::with_profiles(
            nodes
                .iter()
                .map(|n| (DriveName::Node(*n), Profile::Cia402))
                .chain(
                    register_image
                        .iter()
                        .map(|(k, _)| (DriveName::Section(*k), Profile::Fhpp)),
                )
                .chain(
                    ethercat
                        .places()
                        .into_iter()
                        .map(|k| (DriveName::Section(k), Profile::Cia402)),
                )
                .collect(),
        )?;
        let parameters = parameters_of(&rig, &nodes, &register_image, &ethercat);
        let timeline = timeline
            .map(|s| {
                s.steps
                    .iter()
                    .filter_map(|(at, k)| match k {
                        StepKind::Act(a) => Some((*at, a.clone())),
                        StepKind::Expect { .. } => None,
                    })
                    .collect()
            })
            .unwrap_or_default();
        let mut rig = rig;
        let terminals: Vec<CanTerminal> = rig
            .bus_bitrates()
            .into_iter()
            .map(CanTerminal::new)
            .collect();
        for bus in 0..terminals.len() {
            rig.report_outside_frames(bus);
        }
        // The rig's drives, then the EtherCAT slaves' drives.
        let n = variables.names.len();
        let shared = Arc::new(Mutex::new(Shared {
            rig,
            outbox: Vec::new(),
            stale: true,
            outputs: vec![Probe::default(); n],
        }));
        let instance = CellInstance {
            shared,
            front_ends: None,
            modbus_fronts: None,
            ethercat,
            variables,
            drives,
            places,
            parameters,
            timeline,
            done: 0,
            inputs: vec![Inputs::default(); n],
            now: 0,
            views,
            terminals,
            displays: (0..n).map(|_| OnceLock::new()).collect(),
            scratch: StepScratch::default(),
        };
        Ok(instance)
    }

    /// The FMU's variables.
    pub fn variables(&self) -> &Variables {
        &self.variables
    }

    /// The EtherCAT chains: each one's interface and its number of slaves.
    pub fn ethercat_chains(&self) -> Vec<(String, usize)> {
        self.ethercat.chains()
    }

    /// The cell file's keys that are FMI parameters.
    pub fn parameters(&self) -> &Parameters {
        &self.parameters
    }

    /// The virtual clock, s.
    pub fn time(&self) -> f64 {
        Duration::from_nanos(self.now).as_secs_f64()
    }

    /// The addresses of the front ends' servers, with their bus.
    pub fn front_end_addresses(&self) -> &[(usize, std::net::SocketAddr)] {
        self.front_ends.as_ref().map_or(&[], |f| f.addresses())
    }

    /// The addresses of the Modbus TCP servers, with the drive's place among the drives
    /// served over Modbus TCP.
    pub fn modbus_addresses(&self) -> &[(usize, std::net::SocketAddr)] {
        self.modbus_fronts.as_ref().map_or(&[], |f| f.addresses())
    }

    /// The drives' outputs for one get call, the cell not locked yet.
    fn outputs(&self) -> Outputs<'_> {
        Outputs {
            cell: self,
            guard: None,
        }
    }

    /// The values of `vrs` into `values`, read by `read` under one lock of the cell: what an
    /// `fmi3Get…` call of several value references costs once, not per value. The first
    /// unknown value reference ends the call with its error.
    fn get_many<T>(
        &self,
        vrs: &[u32],
        values: &mut [T],
        read: impl Fn(&Self, u32, &mut Outputs<'_>) -> Result<T, CellFmuError>,
    ) -> Result<(), CellFmuError> {
        if values.len() < vrs.len() {
            return Err(CellFmuError::TooFewValues {
                given: values.len(),
                needed: vrs.len(),
            });
        }
        let mut outputs = self.outputs();
        for (vr, slot) in vrs.iter().zip(values) {
            *slot = read(self, *vr, &mut outputs)?;
        }
        Ok(())
    }

    /// Every drive's outputs read anew: the rig's drives, then the EtherCAT slaves' (the
    /// chains' lock taken inside the cell's, as the EtherCAT front end takes them).
    fn refresh(&self, shared: &mut Shared) {
        shared.refresh(&self.places);
        let rig_drives = self.places.len();
        if let Some(slaves) = shared.outputs.get_mut(rig_drives..) {
            self.ethercat.probe_into(slaves);
        }
    }

    fn find(&self, vr: u32) -> Result<(usize, Role), CellFmuError> {
        // The error is made only when there is one: its drop is not free on every get.
        match self.variables.find(vr) {
            Some(found) => Ok(found),
            None => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn get_float64(&self, vr: u32) -> Result<f64, CellFmuError> {
        self.float64(vr, &mut self.outputs())
    }

    /// [`CellInstance::get_float64`] of each of `vrs`, under one lock.
    pub fn get_float64s(&self, vrs: &[u32], values: &mut [f64]) -> Result<(), CellFmuError> {
        self.get_many(vrs, values, Self::float64)
    }

    fn float64(&self, vr: u32, outputs: &mut Outputs<'_>) -> Result<f64, CellFmuError> {
        if super::parameters::is_parameter(vr) {
            return self
                .parameters
                .find(vr)
                .map(|p| p.start)
                .ok_or(CellFmuError::UnknownVariable(vr));
        }
        match self.find(vr)? {
            (drive, Role::LoadTorque) => Ok(self.inputs.get(drive).map_or(0.0, |i| i.load_torque)),
            (drive, Role::Position) => Ok(outputs.of(drive).position_rad),
            (drive, Role::Velocity) => Ok(outputs.of(drive).velocity_rad_s),
            (drive, Role::Current) => Ok(outputs.of(drive).current_a),
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn set_float64(&mut self, vr: u32, value: f64) -> Result<(), CellFmuError> {
        match self.find(vr)? {
            (drive, Role::LoadTorque) => {
                if let Some(i) = self.inputs.get_mut(drive) {
                    i.load_torque = value;
                    i.pending = true;
                }
                Ok(())
            }
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn get_boolean(&self, vr: u32) -> Result<bool, CellFmuError> {
        if let Some(on) = self.bus_notifications(vr) {
            return Ok(on);
        }
        match self.find(vr)? {
            (drive, Role::ReferenceSwitch) => Ok(self
                .inputs
                .get(drive)
                .and_then(|i| i.reference)
                .unwrap_or(false)),
            (drive, Role::DigitalInput(k)) => Ok(self
                .inputs
                .get(drive)
                .and_then(|i| i.din.get(usize::from(k)).copied().flatten())
                .unwrap_or(false)),
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn set_boolean(&mut self, vr: u32, value: bool) -> Result<(), CellFmuError> {
        if self.set_bus_notifications(vr, value) {
            return Ok(());
        }
        match self.find(vr)? {
            (drive, Role::ReferenceSwitch) => {
                if let Some(i) = self.inputs.get_mut(drive) {
                    i.reference = Some(value);
                    i.pending = true;
                }
                Ok(())
            }
            (drive, Role::DigitalInput(k)) => {
                if let Some(i) = self.inputs.get_mut(drive) {
                    if let Some(slot) = i.din.get_mut(usize::from(k)) {
                        *slot = Some(value);
                        i.pending = true;
                    }
                }
                Ok(())
            }
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    /// An FHPP drive's status byte (SCON, SPOS).
    pub fn get_uint8(&self, vr: u32) -> Result<u8, CellFmuError> {
        self.uint8(vr, &mut self.outputs())
    }

    /// [`CellInstance::get_uint8`] of each of `vrs`, under one lock.
    pub fn get_uint8s(&self, vrs: &[u32], values: &mut [u8]) -> Result<(), CellFmuError> {
        self.get_many(vrs, values, Self::uint8)
    }

    fn uint8(&self, vr: u32, outputs: &mut Outputs<'_>) -> Result<u8, CellFmuError> {
        match self.find(vr)? {
            (drive, Role::Scon) => Ok(outputs.of(drive).status[0]),
            (drive, Role::Spos) => Ok(outputs.of(drive).status[1]),
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn get_uint16(&self, vr: u32) -> Result<u16, CellFmuError> {
        self.uint16(vr, &mut self.outputs())
    }

    /// [`CellInstance::get_uint16`] of each of `vrs`, under one lock.
    pub fn get_uint16s(&self, vrs: &[u32], values: &mut [u16]) -> Result<(), CellFmuError> {
        self.get_many(vrs, values, Self::uint16)
    }

    fn uint16(&self, vr: u32, outputs: &mut Outputs<'_>) -> Result<u16, CellFmuError> {
        match self.find(vr)? {
            (drive, Role::Statusword) => Ok(outputs.of(drive).statusword),
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn get_int32(&self, vr: u32) -> Result<i32, CellFmuError> {
        self.int32(vr, &mut self.outputs())
    }

    /// [`CellInstance::get_int32`] of each of `vrs`, under one lock.
    pub fn get_int32s(&self, vrs: &[u32], values: &mut [i32]) -> Result<(), CellFmuError> {
        self.get_many(vrs, values, Self::int32)
    }

    fn int32(&self, vr: u32, outputs: &mut Outputs<'_>) -> Result<i32, CellFmuError> {
        match self.find(vr)? {
            (drive, Role::PositionActual) => Ok(outputs.of(drive).position_actual),
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    pub fn get_string(&self, vr: u32) -> Result<String, CellFmuError> {
        Ok(self.display(vr)?.to_string_lossy().into_owned())
    }

    /// A display's text as of the last step, in the instance's own bytes (no copy): read
    /// from the drive at the first get of it after a step, valid until the next step, and
    /// always at the same address.
    pub fn display(&self, vr: u32) -> Result<&std::ffi::CStr, CellFmuError> {
        match self.find(vr)? {
            (drive, Role::Display) => self
                .displays
                .get(drive)
                .map(|shown| shown.get_or_init(|| self.display_text(drive)))
                .and_then(|b| std::ffi::CStr::from_bytes_until_nul(b).ok())
                .ok_or(CellFmuError::UnknownVariable(vr)),
            _ => Err(CellFmuError::UnknownVariable(vr)),
        }
    }

    /// What drive `drive`'s display shows now, NUL-terminated (the chains' lock taken inside
    /// the cell's, as in [`CellInstance::refresh`]).
    fn display_text(&self, drive: usize) -> [u8; DISPLAY_BYTES] {
        let mut shared = lock(&self.shared);
        let display = self.views.display;
        let shown = match self.places.get(drive) {
            Some(RigPlace::RegisterImage(i)) => shared.rig.register_image_display_state(*i),
            Some(place) => shared.rig.drive_model_at(place).and_then(display),
            None => drive.checked_sub(self.places.len()).and_then(|slave| {
                self.ethercat
                    .with_drive(slave, |m| m.drive().and_then(|d| display(d)))
            }),
        };
        text_bytes(shown.as_ref().map_or("", |s| s.text()))
    }

    /// `fmi3DoStep(t, h)`: the inputs act at `t`, the timeline's actions in `[t, t + h)`, the
    /// cell runs to `t + h`.
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), CellFmuError> {
        let start = nanos(t)?;
        let end = nanos(t + h)?;
        if start != self.now {
            return Err(CellFmuError::NotAtTime {
                given: t,
                at: self.time(),
            });
        }
        let shared = Arc::clone(&self.shared);
        let mut guard = lock(&shared);
        let Shared { rig, outbox, .. } = &mut *guard;
        // The bus's frames go to the LS-BUS terminals, and to the front ends' clients when
        // there are any.
        let collect = self.front_ends.is_some();
        let StepScratch {
            frames,
            outside,
            to_bus,
            answers,
        } = &mut self.scratch;
        frames.clear();
        outside.clear();
        Self::put_terminal_frames_on_bus(rig, &mut self.terminals, to_bus, answers, frames)?;
        let mut seen = |bus: usize, at: Duration, frame: &canopen::CanFrame| {
            frames.push((bus, at, *frame));
            if collect {
                outbox.push(BusFrame {
                    bus,
                    at,
                    frame: *frame,
                });
            }
        };
        Self::apply_inputs(rig, &self.drives, &mut self.inputs, &mut seen)?;
        Self::apply_slave_inputs(
            &self.ethercat,
            &self.variables,
            self.drives.len(),
            &mut self.inputs,
        )?;
        while let Some((at, action)) = self.timeline.get(self.done) {
            let at_ns = u64::try_from(at.as_nanos()).unwrap_or(u64::MAX);
            if at_ns >= end {
                break;
            }
            if at_ns > self.now {
                self.ethercat.run_until(rig, *at, &mut seen);
            }
            // A refused action is the timeline's mistake, as in a scenario's report: logged.
            if let Err(e) = rig.act(action, &mut seen) {
                tracing::warn!(at = ?at, "timeline action refused: {e}");
            }
            self.done += 1;
        }
        self.ethercat
            .run_until(rig, Duration::from_nanos(end), &mut seen);
        for bus in 0..self.terminals.len() {
            outside.extend(
                rig.take_outside_frames(bus)
                    .map(|(at, f, acked)| (bus, Duration::from_nanos(at.as_nanos()), f, acked)),
            );
        }
        // (a stable sort: its scratch is on the stack up to a step's worth of frames)
        outside.sort_by_key(|(_, at, _, _)| *at);
        Self::terminals_saw(&mut self.terminals, frames, outside);
        self.now = end;
        let stopped = rig.stopped();
        // The outputs and the displays are read at the importer's first get of them after
        // the step, if any.
        guard.stale = true;
        drop(guard);
        for shown in &mut self.displays {
            shown.take();
        }
        if let Some(f) = &self.front_ends {
            f.wake();
        }
        if let Some(f) = &self.modbus_fronts {
            f.wake();
        }
        match stopped {
            Some(why) => Err(CellFmuError::Stopped {
                at: self.time(),
                why,
            }),
            None => Ok(()),
        }
    }

    /// The frames the LS-BUS terminals received go onto their buses now, from outside the
    /// cell's drives; the other frames that cross meanwhile (a drive's boot-up) go to `seen`.
    fn put_terminal_frames_on_bus(
        rig: &mut VirtualRig,
        terminals: &mut [CanTerminal],
        to_bus: &mut Vec<canopen::CanFrame>,
        got: &mut Vec<(usize, Duration, canopen::CanFrame)>,
        seen: &mut Vec<(usize, Duration, canopen::CanFrame)>,
    ) -> Result<(), CellFmuError> {
        for (bus, t) in terminals.iter_mut().enumerate() {
            t.take_to_bus_into(to_bus);
            for frame in to_bus.drain(..) {
                // FMI-LS-BUS §4.4.1.4 "Arbitration": a frame that cannot start at once has
                // lost the arbitration (or waits for the busy bus): kept by the bus model,
                // or, with DISCARD_AND_NOTIFY, discarded and answered.
                if t.discards_on_arbitration_lost() && rig.would_wait(bus, &frame) {
                    t.arbitration_lost(&frame);
                    continue;
                }
                t.sent(frame);
                got.clear();
                rig.act(&Action::Frame { bus, frame }, &mut |b, at, f| {
                    got.push((b, at, *f))
                })
                .map_err(|e| CellFmuError::Cell(format!("bus {bus}: LS-BUS frame: {e}")))?;
                // The frame itself, as the rig reports it, is not an answer.
                if let Some(i) = got.iter().position(|(b, _, f)| *b == bus && *f == frame) {
                    got.remove(i);
                }
                seen.append(got);
            }
        }
        Ok(())
    }

    /// The inputs of the EtherCAT slaves' drives set since the last step act now, as
    /// [`CellInstance::apply_inputs`] makes them act on the rig's drives.
    fn apply_slave_inputs(
        ethercat: &EthercatChains,
        variables: &Variables,
        first: usize,
        inputs: &mut [Inputs],
    ) -> Result<(), CellFmuError> {
        for (slave, i) in inputs.iter_mut().skip(first).enumerate() {
            if !i.pending {
                continue;
            }
            // Named only for an error: no text made per step.
            let name = || {
                variables
                    .name(first + slave)
                    .map(|n| n.to_string())
                    .unwrap_or_default()
            };
            if i.load_applied != Some(i.load_torque) {
                ethercat
                    .set_load_torque(slave, i.load_torque)
                    .map_err(|e| CellFmuError::Cell(format!("{}: load torque: {e}", name())))?;
                i.load_applied = Some(i.load_torque);
            }
            for (k, (want, applied)) in i.din.iter().zip(i.din_applied.iter_mut()).enumerate() {
                let (Some(level), false) = (*want, *want == *applied) else {
                    continue;
                };
                let din = u8::try_from(k).unwrap_or(0);
                ethercat
                    .force_input(slave, din, level)
                    .map_err(|e| CellFmuError::Cell(format!("{}: din{din}: {e}", name())))?;
                *applied = Some(level);
            }
            i.pending = false;
        }
        Ok(())
    }

    fn apply_inputs(
        rig: &mut VirtualRig,
        drives: &[RigDrive],
        inputs: &mut [Inputs],
        seen: &mut dyn FnMut(usize, Duration, &canopen::CanFrame),
    ) -> Result<(), CellFmuError> {
        for (drive, i) in drives.iter().zip(inputs.iter_mut()) {
            if !i.pending {
                continue;
            }
            // A CANopen drive by its node-ID, a CMMO-ST by its place (its `node` may be a
            // CANopen drive's as well).
            let node = match drive {
                RigDrive::Node(n) => Some(*n),
                RigDrive::RegisterImage(_) => None,
            };
            let who = || match drive {
                RigDrive::Node(n) => format!("node {n}"),
                RigDrive::RegisterImage(k) => format!("CMMO-ST {k}"),
            };
            let act =
                |rig: &mut VirtualRig,
                 action: &Action,
                 seen: &mut dyn FnMut(usize, Duration, &canopen::CanFrame)| {
                    match drive {
                        RigDrive::Node(_) => rig.act(action, seen),
                        RigDrive::RegisterImage(k) => rig.act_on_register_image(*k, action, seen),
                    }
                };
            if i.load_applied != Some(i.load_torque) {
                let torque_nm = i.load_torque;
                act(rig, &Action::Load { node, torque_nm }, seen)
                    .map_err(|e| CellFmuError::Cell(format!("{}: load torque: {e}", who())))?;
                i.load_applied = Some(torque_nm);
            }
            if let (Some(level), false) = (i.reference, i.reference == i.reference_applied) {
                let change = crate::cell::control::PhysicsChange::Switch(
                    drive::drive::named_switches::NamedSwitch::Home,
                    Some(level),
                );
                act(rig, &Action::Physics { node, change }, seen)
                    .map_err(|e| CellFmuError::Cell(format!("{}: reference switch: {e}", who())))?;
                i.reference_applied = Some(level);
            }
            for (k, (want, applied)) in i.din.iter().zip(i.din_applied.iter_mut()).enumerate() {
                let (Some(level), false) = (*want, *want == *applied) else {
                    continue;
                };
                let din = u8::try_from(k).unwrap_or(0);
                act(rig, &Action::Input { node, din, level }, seen)
                    .map_err(|e| CellFmuError::Cell(format!("{}: din{din}: {e}", who())))?;
                *applied = Some(level);
            }
            i.pending = false;
        }
        Ok(())
    }
}

/// The indexes of `cell`'s `[[drive]]` sections whose drives have their own register image
/// (the CMMO-STs), in the file's order (the virtual rig serves them in that order), each with
/// the stepper it is built with.
fn register_image_sections(
    cell: &CellFile,
    vendors: Vendors,
) -> Result<Vec<(usize, drive::stepper::StepperData)>, CellFmuError> {
    Ok(cell
        .drives(vendors)
        .map_err(|e| CellFmuError::Cell(e.to_string()))?
        .iter()
        .enumerate()
        .filter_map(|(k, s)| s.fhpp.as_ref().map(|f| (k, f.settings.stepper)))
        .collect())
}

/// The parameters of the table's drives: the rig's CANopen drives `nodes`, its CMMO-STs
/// `register_image`, then the EtherCAT slaves' drives, whose `[drive.motor]` keys are those of
/// the same device on CANopen.
fn parameters_of(
    rig: &VirtualRig,
    nodes: &[u8],
    register_image: &[(usize, drive::stepper::StepperData)],
    ethercat: &EthercatChains,
) -> Parameters {
    let slaves = ethercat.places().into_iter().enumerate().map(|(slave, k)| {
        let start = ethercat.with_drive(slave, |m| Start::of_drive(m.drive().map(|d| &**d)));
        (DriveName::Section(k), start)
    });
    Parameters::of(rig, nodes, register_image, slaves)
}

/// Seconds as the clock's nanoseconds.
fn nanos(seconds: f64) -> Result<u64, CellFmuError> {
    let ns = (seconds * 1e9).round();
    if !ns.is_finite() || ns < 0.0 || ns > u64::MAX as f64 {
        return Err(CellFmuError::BadTime(seconds));
    }
    Ok(ns as u64)
}

#[cfg(test)]
mod tests {
    use std::io::{BufRead, BufReader, Write};
    use std::net::TcpStream;

    use super::*;

    /// Each parameter's name and start value.
    fn starts(cell: &CellInstance) -> Vec<(String, f64)> {
        cell.parameters()
            .list
            .iter()
            .map(|p| (p.name(), p.start))
            .collect()
    }

    /// The next `< … >` message of a socketcand server.
    fn message(r: &mut BufReader<TcpStream>) -> String {
        let mut m = Vec::new();
        r.read_until(b'>', &mut m).unwrap();
        String::from_utf8(m).unwrap().trim().to_string()
    }

    /// The value reference of the variable named `name`.
    fn vr(cell: &CellInstance, name: &str) -> u32 {
        cell.variables()
            .all()
            .find(|v| v.name() == name)
            .map(|v| v.value_reference)
            .unwrap_or_else(|| panic!("no variable {name}"))
    }

    #[test]
    fn an_ethercat_slave_alone_has_a_drives_variables_named_by_its_place() {
        let cell: CellFile = toml::from_str(
            "[[bus]]\nsocketcand = \"\"\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 2\nethercat = \"dtnone0\"\n",
        )
        .unwrap();
        let mut cell = CellInstance::new(&cell, None, crate::vendors::VENDORS.runtime).unwrap();
        let names: Vec<String> = cell.variables().all().map(|v| v.name()).collect();
        assert!(names.contains(&"node1.position".to_string()), "{names:?}");
        for role in [
            "load_torque",
            "din0",
            "din15",
            "position",
            "velocity",
            "current",
        ] {
            assert!(
                names.contains(&format!("drive1.{role}")),
                "{role}: {names:?}"
            );
        }
        for role in ["statusword", "position_actual", "display"] {
            assert!(
                names.contains(&format!("drive1.{role}")),
                "{role}: {names:?}"
            );
        }
        // The slave's drive steps on the FMU's clock: its statusword is the power-on one
        // (switch on disabled, CiA 402 §6.3.1), its display its own.
        cell.do_step(0.0, 0.05).unwrap();
        let sw = cell.get_uint16(vr(&cell, "drive1.statusword")).unwrap();
        assert_eq!(sw & 0x4F, 0x40, "{sw:#06x}");
        assert_eq!(
            cell.get_string(vr(&cell, "drive1.display")).unwrap(),
            cell.get_string(vr(&cell, "node1.display")).unwrap()
        );
        // A load torque set on the slave's drive acts at the next step, on its shaft alone.
        cell.set_float64(vr(&cell, "drive1.load_torque"), 0.01)
            .unwrap();
        cell.set_boolean(vr(&cell, "drive1.din3"), true).unwrap();
        cell.do_step(0.05, 0.05).unwrap();
        assert_eq!(
            cell.get_float64(vr(&cell, "drive1.load_torque")).unwrap(),
            0.01
        );
        assert!(cell.get_boolean(vr(&cell, "drive1.din3")).unwrap());
        let (mask, levels) = cell
            .ethercat
            .with_drive(0, |m| Some(m.drive()?.forced_inputs()))
            .unwrap();
        assert_eq!((mask & 8, levels & 8), (8, 8), "din3 forced high");
        let torque = cell
            .ethercat
            .with_drive(0, |m| Some(m.drive()?.axis().motor().data().load_torque))
            .unwrap();
        assert_eq!(torque, 0.01);
    }

    #[test]
    fn outputs_are_read_at_the_first_get_after_a_step_in_one_pass_and_not_without_a_get() {
        let file: CellFile = toml::from_str(
            "[[bus]]\nsocketcand = \"\"\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n[drive.motor]\nbrake_holding_torque = 0.0\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 2\n",
        )
        .unwrap();
        let mut cell = CellInstance::new(&file, None, crate::vendors::VENDORS.runtime).unwrap();
        let position = vr(&cell, "node1.position");
        cell.do_step(0.0, 1e-3).unwrap();
        assert_eq!(cell.get_float64(position).unwrap(), 0.0);
        assert!(!lock(&cell.shared).stale);
        // A load torque turns the free shaft; steps without a get leave the outputs unread.
        cell.set_float64(vr(&cell, "node1.load_torque"), 0.05)
            .unwrap();
        for k in 1..20 {
            cell.do_step(f64::from(k) * 1e-3, 1e-3).unwrap();
            let shared = lock(&cell.shared);
            assert!(shared.stale);
            assert_eq!(shared.outputs[0].position_rad, 0.0, "read at step {k}");
        }
        // The first get reads every drive's outputs; the next ones read none.
        let turned = cell.get_float64(position).unwrap();
        assert!(turned < -1e-4, "{turned}");
        assert!(!lock(&cell.shared).stale);
        let read = lock(&cell.shared).outputs.clone();
        assert_eq!(read[0].position_rad, turned);
        assert_eq!(
            cell.get_uint16(vr(&cell, "node2.statusword")).unwrap(),
            read[1].statusword
        );
        assert!(!lock(&cell.shared).stale);
    }

    /// An input the importer sets acts at the next step's start and not before; a step
    /// after it looks at no drive's inputs until the importer sets one again.
    #[test]
    fn an_input_set_between_steps_acts_at_the_next_step() {
        let mut cell = two_drives();
        let forced = |cell: &CellInstance| {
            lock(&cell.shared)
                .rig
                .drive_model(2)
                .map(|d| d.forced_inputs())
        };
        cell.do_step(0.0, 1e-3).unwrap();
        assert!(cell.inputs.iter().all(|i| !i.pending));
        assert_eq!(forced(&cell), Some((0, 0)));
        cell.set_boolean(vr(&cell, "node2.din3"), true).unwrap();
        assert!(cell.inputs[1].pending && !cell.inputs[0].pending);
        assert_eq!(forced(&cell), Some((0, 0)), "not before the step");
        cell.do_step(1e-3, 1e-3).unwrap();
        assert_eq!(forced(&cell), Some((1 << 3, 1 << 3)));
        assert!(!cell.inputs[1].pending);
        // The same level again acts no more; another level acts at the next step.
        cell.set_boolean(vr(&cell, "node2.din3"), true).unwrap();
        cell.do_step(2e-3, 1e-3).unwrap();
        assert_eq!(forced(&cell), Some((1 << 3, 1 << 3)));
        cell.set_boolean(vr(&cell, "node2.din3"), false).unwrap();
        cell.do_step(3e-3, 1e-3).unwrap();
        assert_eq!(forced(&cell), Some((1 << 3, 0)));
        assert!(cell.inputs.iter().all(|i| !i.pending));
    }

    /// Two CMMP-AS on one bus, the first one's shaft free.
    fn two_drives() -> CellInstance {
        let file: CellFile = toml::from_str(
            "[[bus]]\nsocketcand = \"\"\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n[drive.motor]\nbrake_holding_torque = 0.0\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 2\n",
        )
        .unwrap();
        CellInstance::new(&file, None, crate::vendors::VENDORS.runtime).unwrap()
    }

    #[test]
    fn a_display_is_read_at_its_first_get_after_a_step_and_not_without_one() {
        let mut cell = two_drives();
        let (first, second) = (vr(&cell, "node1.display"), vr(&cell, "node2.display"));
        for k in 0..10 {
            cell.do_step(f64::from(k) * 1e-3, 1e-3).unwrap();
            assert!(cell.displays.iter().all(|d| d.get().is_none()), "step {k}");
        }
        // The first get reads that drive's display alone, as the drive shows it now.
        let shown = cell.display(first).unwrap().to_owned();
        assert!(!shown.is_empty());
        assert_eq!(cell.displays[0].get().copied(), Some(cell.display_text(0)));
        assert!(cell.displays[1].get().is_none());
        let address = cell.display(first).unwrap().as_ptr().addr();
        assert_eq!(cell.display(second).unwrap(), shown.as_c_str());
        // A step empties them; the text comes back at the same address.
        cell.do_step(0.01, 1e-3).unwrap();
        assert!(cell.displays.iter().all(|d| d.get().is_none()));
        assert_eq!(cell.display(first).unwrap().as_ptr().addr(), address);
        assert!(cell.get_float64(first).is_err(), "a display is no Float64");
    }

    #[test]
    fn a_get_of_several_values_gives_what_a_get_of_each_gives_under_one_read_of_the_outputs() {
        let mut cell = two_drives();
        let torque = vr(&cell, "node1.load_torque");
        cell.set_float64(torque, 0.05).unwrap();
        for k in 0..20 {
            cell.do_step(f64::from(k) * 1e-3, 1e-3).unwrap();
        }
        let floats = [
            vr(&cell, "node1.position"),
            torque,
            vr(&cell, "node2.velocity"),
            vr(&cell, "node1.velocity"),
            vr(&cell, "node1.current"),
        ];
        let mut many = [f64::NAN; 5];
        cell.get_float64s(&floats, &mut many).unwrap();
        assert!(!lock(&cell.shared).stale);
        let one: Vec<f64> = floats
            .iter()
            .map(|v| cell.get_float64(*v).unwrap())
            .collect();
        assert_eq!(many.to_vec(), one);
        assert!(many[0] < -1e-4 && many[1] == 0.05, "{many:?}");
        let words = [vr(&cell, "node2.statusword"), vr(&cell, "node1.statusword")];
        let mut sw = [0u16; 2];
        cell.get_uint16s(&words, &mut sw).unwrap();
        assert_eq!(
            sw,
            [
                cell.get_uint16(words[0]).unwrap(),
                cell.get_uint16(words[1]).unwrap()
            ]
        );
        let mut actual = [0i32; 1];
        cell.get_int32s(&[vr(&cell, "node1.position_actual")], &mut actual)
            .unwrap();
        assert_eq!(
            actual[0],
            cell.get_int32(vr(&cell, "node1.position_actual")).unwrap()
        );
        // A value reference of another type ends the call with its error; so does too little
        // room for the values.
        let wrong = [floats[0], words[0]];
        assert!(matches!(
            cell.get_float64s(&wrong, &mut [0.0; 2]),
            Err(CellFmuError::UnknownVariable(v)) if v == words[0]
        ));
        assert!(matches!(
            cell.get_float64s(&floats, &mut [0.0; 4]),
            Err(CellFmuError::TooFewValues {
                given: 4,
                needed: 5
            })
        ));
    }

    #[test]
    fn an_ethercat_slave_without_its_chain_is_on_the_interface_given_as_drivetwin_run_takes_it() {
        let vendors = crate::vendors::VENDORS.runtime;
        let file: CellFile = toml::from_str(
            "[[bus]]\nsocketcand = \"\"\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 2\ninterfaces = [\"ethercat\"]\n",
        )
        .unwrap();
        // Without an interface: refused, naming both ways to give one.
        let e = CellInstance::new(&file, None, vendors)
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("ethercat = \"IFNAME\"") && e.contains("--ethercat"),
            "{e}"
        );
        // With one, the slave is on its chain, as with `ethercat = "dtnone0"` in the file.
        let mut cell = CellInstance::with_ethercat(&file, None, vendors, Some("dtnone0")).unwrap();
        assert_eq!(cell.ethercat_chains(), [("dtnone0".to_string(), 1)]);
        let named: CellFile = toml::from_str(
            "[[bus]]\nsocketcand = \"\"\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 2\nethercat = \"dtnone0\"\n",
        )
        .unwrap();
        let named = CellInstance::new(&named, None, vendors).unwrap();
        assert_eq!(cell.variables(), named.variables());
        cell.do_step(0.0, 0.01).unwrap();
        let sw = cell.get_uint16(vr(&cell, "drive1.statusword")).unwrap();
        assert_eq!(sw & 0x4F, 0x40, "{sw:#06x}");
        // A cell file that names no interfaces: every drive is on the chain instead of CAN.
        let whole: CellFile = toml::from_str(
            "[[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n[[drive]]\ndevice = \"cmmp-as\"\nnode = 2\n",
        )
        .unwrap();
        let whole = CellInstance::with_ethercat(&whole, None, vendors, Some("dtnone0")).unwrap();
        assert_eq!(whole.ethercat_chains(), [("dtnone0".to_string(), 2)]);
        let names: Vec<String> = whole.variables().all().map(|v| v.name()).collect();
        assert!(!names.iter().any(|n| n.starts_with("node")), "{names:?}");
        // The example of 64 slaves on one chain, as `drivetwin run --ethercat` takes it.
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/ethercat-64.toml");
        let example = CellFile::load(&path).unwrap();
        let example =
            CellInstance::with_ethercat(&example, None, vendors, Some("dtnone0")).unwrap();
        assert_eq!(example.ethercat_chains(), [("dtnone0".to_string(), 64)]);
    }

    #[test]
    fn the_fmus_resources_give_the_chain_of_the_slaves_that_name_none() {
        let dir = std::env::temp_dir().join(format!("cell-fmu-ecat-if-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            dir.join(CELL_FILE),
            "[[drive]]\ndevice = \"cmmp-as\"\nnode = 1\ninterfaces = [\"ethercat\"]\n",
        )
        .unwrap();
        let vendors = crate::vendors::VENDORS.runtime;
        let e = CellInstance::from_resources(&dir, vendors)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("--ethercat"), "{e}");
        // With the interface `drivetwin fmu --ethercat` packs, the instance opens its chain's
        // socket on it: here an interface that does not exist, named in the refusal.
        std::fs::write(dir.join(ETHERCAT_FILE), "dtnone0\n").unwrap();
        let e = CellInstance::from_resources(&dir, vendors)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("dtnone0") && !e.contains("--ethercat"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_cell_of_ethercat_slaves_alone_is_an_fmu_with_their_variables_and_parameters() {
        let file: CellFile = toml::from_str(
            "[[drive]]\ndevice = \"cmmp-as\"\nnode = 1\nethercat = \"dtnone0\"\n\
             [[drive]]\ndevice = \"cmmp-as\"\nnode = 2\nethercat = \"dtnone0\"\n\
             [drive.motor]\ninertia = 4e-5\nbrake_holding_torque = 0.0\n",
        )
        .unwrap();
        let vendors = crate::vendors::VENDORS.runtime;
        let mut cell = CellInstance::new(&file, None, vendors).unwrap();
        let names: Vec<String> = cell.variables().all().map(|v| v.name()).collect();
        assert!(
            names.contains(&"drive0.statusword".to_string()),
            "{names:?}"
        );
        assert!(names.contains(&"drive1.position".to_string()), "{names:?}");
        assert!(!names.iter().any(|n| n.starts_with("node")), "{names:?}");
        assert_eq!(cell.ethercat_chains(), [("dtnone0".to_string(), 2)]);
        // (no holding brake: a load torque turns the shaft of a drive at power-on)
        // The slaves' [drive.motor] keys are parameters as a CANopen drive's, named by place.
        let p = starts(&cell);
        assert!(
            p.contains(&("drive0.motor.inertia".to_string(), 3e-5)),
            "{p:?}"
        );
        assert!(
            p.contains(&("drive1.motor.inertia".to_string(), 4e-5)),
            "{p:?}"
        );
        // doStep advances the slaves' drives: a load torque turns the second one's free shaft.
        cell.set_float64(vr(&cell, "drive1.load_torque"), 0.05)
            .unwrap();
        for k in 0..20 {
            cell.do_step(f64::from(k) * 1e-3, 1e-3).unwrap();
        }
        assert_eq!(cell.time(), 0.02);
        let sw = cell.get_uint16(vr(&cell, "drive0.statusword")).unwrap();
        assert_eq!(sw & 0x4F, 0x40, "{sw:#06x}");
        // (a load torque acts towards negative rotation)
        assert!(cell.get_float64(vr(&cell, "drive1.position")).unwrap() < -1e-3);
        assert_eq!(cell.get_float64(vr(&cell, "drive0.position")).unwrap(), 0.0);
        // A parameter set is the slave's key: the heavier shaft turns less in the same time.
        let inertia = cell
            .parameters()
            .list
            .iter()
            .find(|p| p.name() == "drive1.motor.inertia")
            .map(|p| p.value_reference)
            .unwrap();
        let mut set = file.clone();
        cell.parameters()
            .apply(&mut set, vendors, &[(inertia, 4e-4)])
            .unwrap();
        let mut heavy = CellInstance::new(&set, None, vendors).unwrap();
        heavy
            .set_float64(vr(&heavy, "drive1.load_torque"), 0.05)
            .unwrap();
        for k in 0..20 {
            heavy.do_step(f64::from(k) * 1e-3, 1e-3).unwrap();
        }
        let turned = |c: &CellInstance| c.get_float64(vr(c, "drive1.position")).unwrap().abs();
        assert!(turned(&heavy) < turned(&cell) / 5.0);
        // No drive at all is still refused.
        let none: CellFile = toml::from_str("[[bus]]\nsocketcand = \"\"\n").unwrap();
        assert!(matches!(
            CellInstance::new(&none, None, vendors).err(),
            Some(CellFmuError::NoDrive)
        ));
    }

    #[test]
    fn a_nanotec_steppers_keys_are_its_stepper_section_and_its_parameters() {
        let vendors = crate::vendors::VENDORS.runtime;
        let file: CellFile = toml::from_str(
            "[[bus]]\nsocketcand = \"\"\n[[drive]]\ndevice = \"nanotec-pd4n\"\nnode = 5\n\
             [drive.stepper]\nload_inertia = 2e-5\nholding_torque = 0.8\n",
        )
        .unwrap();
        let cell = CellInstance::new(&file, None, vendors).unwrap();
        let p = starts(&cell);
        assert!(
            p.contains(&("node5.stepper.load_inertia".to_string(), 2e-5)),
            "{p:?}"
        );
        assert!(
            p.contains(&("node5.stepper.holding_torque".to_string(), 0.8)),
            "{p:?}"
        );
        assert!(!p.iter().any(|(n, _)| n.contains(".motor.")), "{p:?}");
        // A servo motor's shaft key on a stepper is refused by name, never ignored.
        let servo: CellFile = toml::from_str(
            "[[bus]]\nsocketcand = \"\"\n[[drive]]\ndevice = \"nanotec-pd4n\"\nnode = 5\n\
             [drive.motor]\ninertia = 2e-5\n",
        )
        .unwrap();
        let e = CellInstance::new(&servo, None, vendors)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("motor.inertia"), "{e}");
        // The stepper's mode is the drive's object, not a key.
        let mode: CellFile = toml::from_str(
            "[[drive]]\ndevice = \"nanotec-smci47s\"\nnode = 5\n\
             [drive.stepper]\nmode = \"open-loop\"\n",
        )
        .unwrap();
        let e = mode.drives(vendors).err().unwrap().to_string();
        assert!(e.contains("2001h"), "{e}");
    }

    #[test]
    fn a_cmmo_st_at_a_canopen_drives_node_id_is_named_by_its_place_and_turns_alone() {
        // The CMMO-ST without a `node`: the default 1, the CMMP-AS's as well.
        let cell: CellFile = toml::from_str(
            "[[bus]]\nsocketcand = \"\"\n[[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n\
             [[drive]]\ndevice = \"cmmo-st\"\n",
        )
        .unwrap();
        let mut fmu = CellInstance::new(&cell, None, crate::vendors::VENDORS.runtime).unwrap();
        let vr: std::collections::HashMap<String, u32> = fmu
            .variables()
            .all()
            .map(|v| (v.name(), v.value_reference))
            .collect();
        assert!(vr.contains_key("node1.statusword"));
        assert!(vr.contains_key("drive1.scon"));
        assert!(!vr.contains_key("node1.scon"));
        // Its load torque (towards negative rotation) turns its free shaft, not the CMMP-AS's.
        fmu.set_float64(vr["drive1.load_torque"], 0.1).unwrap();
        for k in 0..20 {
            fmu.do_step(f64::from(k) * 1e-3, 1e-3).unwrap();
        }
        assert!(fmu.get_float64(vr["drive1.position"]).unwrap() < -0.05);
        assert!(fmu.get_float64(vr["node1.position"]).unwrap().abs() < 1e-9);
        assert_eq!(fmu.get_uint8(vr["drive1.scon"]).unwrap() & 0x10, 0x10);
        // Its reference switch, forced by the importer, reaches the CMMO-ST.
        fmu.set_boolean(vr["drive1.reference_switch"], true)
            .unwrap();
        fmu.do_step(0.02, 1e-3).unwrap();
        assert!(fmu.get_string(vr["drive1.display"]).is_ok());
    }

    #[test]
    fn a_socketcand_client_is_answered_between_steps_at_the_clocks_time() {
        let dir = std::env::temp_dir().join(format!("cell-fmu-front-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            dir.join(CELL_FILE),
            "[[bus]]\nsocketcand = \"127.0.0.1:0\"\nbitrate = \"instant\"\n[[drive]]\ndevice = \"cmmp-as\"\nnode = 1\n",
        )
        .unwrap();
        let mut cell = CellInstance::from_resources(&dir, crate::vendors::VENDORS.runtime).unwrap();
        let (bus, addr) = cell.front_end_addresses()[0];
        assert_eq!(bus, 0);
        let stream = TcpStream::connect(addr).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        let mut w = stream.try_clone().unwrap();
        let mut r = BufReader::new(stream);
        assert_eq!(message(&mut r), "< hi >");
        w.write_all(b"< open vcan0 >").unwrap();
        assert_eq!(message(&mut r), "< ok >");
        w.write_all(b"< rawmode >").unwrap();
        assert_eq!(message(&mut r), "< ok >");
        cell.do_step(0.0, 0.01).unwrap();
        // SDO upload of 1018h:01 (CiA 301 §7.2.4.3.6) between two steps: on the instant bus,
        // answered at once, at 10 ms.
        w.write_all(b"< send 601 8 40 18 10 01 00 00 00 00 >")
            .unwrap();
        let answer = loop {
            let m = message(&mut r);
            if m.starts_with("< frame 581 ") {
                break m;
            }
        };
        assert!(
            answer.starts_with("< frame 581 0.010000 43181001"),
            "{answer}"
        );
        drop(w);
        drop(cell);
        assert!(
            TcpStream::connect(addr).is_err(),
            "the server closes with its instance"
        );
        std::fs::remove_dir_all(&dir).ok();
    }
}
