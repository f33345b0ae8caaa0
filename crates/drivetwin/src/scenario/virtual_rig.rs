//! The virtual clock's rig: the CANopen drives of the cell file's first bus, stepped from one
//! deadline to the next as [`crate::cell::runtime::run_virtual`] does, with the scenario's
//! actions between; every frame optionally to a trace whose time stamps are the virtual
//! clock's (so two runs give the same file).

use std::path::Path;
use std::time::Duration;

use canopen::CanFrame;
use od::{Instant, ObjectAccess};

use super::file::{Action, ScenarioError};
use super::runner::Rig;
use crate::can::drive::CanDrive;
use crate::cell::config::CellFile;
use crate::cell::Cell;
use crate::trace::TraceWriter;

/// Steps at one instant before the clock is taken as stuck.
const STUCK: u32 = 10_000;

pub struct VirtualRig {
    cell: Cell,
    now: Instant,
    out: Vec<CanFrame>,
    trace: Option<TraceWriter>,
    /// The inputs each drive has forced so far: (mask, levels).
    forced: Vec<(u16, u16)>,
}

impl VirtualRig {
    /// The CANopen drives of `file`'s first bus, booted at 0.
    pub fn new(file: &CellFile) -> Result<VirtualRig, ScenarioError> {
        let cell_err = |e: String| ScenarioError::Cell(e);
        let specs = file.drives().map_err(|e| cell_err(e.to_string()))?;
        let mut drives = Vec::new();
        let mut plans = Vec::new();
        for mut spec in specs {
            if spec.fhpp.is_some() || !spec.canopen || spec.ethercat.is_some() || spec.bus != 0 {
                return Err(cell_err(format!(
                    "drive {} node {}: the virtual clock runs the CANopen drives of the first \
                     bus (no Modbus, EtherCAT or second bus)",
                    spec.desc.name, spec.node
                )));
            }
            let d = CanDrive::with_settings(
                spec.desc,
                spec.node,
                None,
                spec.commissioning,
                spec.settings,
            )
            .map_err(|e| cell_err(e.to_string()))?;
            plans.push((
                std::mem::take(&mut spec.diagnostics),
                std::mem::take(&mut spec.physics),
            ));
            drives.push(d);
        }
        if drives.is_empty() {
            return Err(cell_err("no CANopen drive".into()));
        }
        let forced = vec![(0, 0); drives.len()];
        let bus = file.bus.all().first();
        let mut cell = match bus.and_then(|b| b.timing()) {
            Some((bitrate, late)) => Cell::new(drives).with_bitrate(bitrate, late),
            None => Cell::new(drives),
        };
        for p in bus.map(|b| b.disturb.as_slice()).unwrap_or(&[]) {
            cell.plan_disturbance(Instant::from_millis(p.at_ms), p.node, p.frames);
        }
        // `[[drive.diagnostic]]`, `[drive.thermal]` and `[[drive.plant]]` on the virtual clock.
        for (drive, (diagnostics, physics)) in plans.into_iter().enumerate() {
            for p in diagnostics {
                cell.plan_diagnostic(Instant::from_millis(p.at_ms), drive, p);
            }
            for (at_ms, change) in physics {
                cell.plan_physics(Instant::from_millis(at_ms), drive, change);
            }
        }
        let mut out = Vec::with_capacity(256);
        cell.boot(Instant::ZERO, &mut out);
        Ok(VirtualRig {
            cell,
            now: Instant::ZERO,
            out,
            trace: None,
            forced,
        })
    }

    /// Every frame of the run into `path` (pcap; `*.log`: candump), stamped with the virtual
    /// clock.
    pub fn trace_to(&mut self, path: &Path) -> std::io::Result<()> {
        self.trace = Some(TraceWriter::create(path, "vcan0")?);
        Ok(())
    }

    /// Ends the trace (the file complete).
    pub fn finish(&mut self) -> std::io::Result<()> {
        match self.trace.take() {
            Some(mut w) => w.flush(),
            None => Ok(()),
        }
    }

    /// The frames the drives sent at `now` are on the bus.
    fn emit(&mut self, seen: &mut dyn FnMut(usize, Duration, &CanFrame)) {
        let t = Duration::from_nanos(self.now.as_nanos());
        for f in self.out.drain(..) {
            if let Some(w) = self.trace.as_mut() {
                if let Err(e) = w.write(t, &f) {
                    tracing::error!(error = %e, "writing the trace failed; trace stopped");
                    self.trace = None;
                }
            }
            seen(0, t, &f);
        }
    }

    fn drive(&self, node: Option<u8>) -> Result<usize, String> {
        match node {
            None => Ok(0),
            Some(n) => self
                .cell
                .drives
                .iter()
                .position(|d| d.node_id() == n)
                .ok_or_else(|| format!("no node {n} in the cell")),
        }
    }

    fn encode(&self, i: usize, index: u16, sub: u8, value: &str) -> Result<Vec<u8>, String> {
        let d = self.cell.drives.get(i).ok_or("no drive")?;
        let e = d
            .od()
            .description()
            .entry(index, sub)
            .ok_or_else(|| format!("{index:04X}:{sub:02X}: no such object"))?;
        crate::value_text::encode(e.data_type, value)
    }

    fn bus0(bus: usize) -> Result<(), String> {
        if bus == 0 {
            Ok(())
        } else {
            Err(format!(
                "bus {bus}: the virtual clock runs the first bus only"
            ))
        }
    }
}

impl Rig for VirtualRig {
    fn run_until(&mut self, t: Duration, seen: &mut dyn FnMut(usize, Duration, &CanFrame)) {
        let end = Instant::from_nanos(u64::try_from(t.as_nanos()).unwrap_or(u64::MAX));
        self.emit(seen);
        let mut stuck = 0u32;
        while let Some(wake) = self.cell.deadline().filter(|w| *w <= end) {
            // A deadline that does not move would spin forever: give up loudly instead.
            stuck = if wake <= self.now { stuck + 1 } else { 0 };
            if stuck > STUCK {
                tracing::error!(at = ?self.now, "virtual clock stuck on a deadline that does not advance");
                break;
            }
            self.now = wake.max(self.now);
            self.cell.poll(self.now, &mut self.out);
            self.emit(seen);
        }
        self.now = end.max(self.now);
    }

    fn act(
        &mut self,
        action: &Action,
        seen: &mut dyn FnMut(usize, Duration, &CanFrame),
    ) -> Result<(), String> {
        let now = self.now;
        let result = match action {
            Action::Frame { bus, frame } => {
                Self::bus0(*bus)?;
                self.out.push(*frame);
                self.emit(seen);
                self.cell.on_frame(now, frame, &mut self.out);
                Ok(())
            }
            Action::SdoWrite {
                bus,
                node,
                index,
                sub,
                value,
            } => {
                Self::bus0(*bus)?;
                let i = self.drive(*node)?;
                let bytes = self.encode(i, *index, *sub, value)?;
                let node = self.cell.drives.get(i).map_or(0, |d| d.node_id());
                let frame = expedited_download(node, *index, *sub, &bytes)?;
                self.out.push(frame);
                self.emit(seen);
                self.cell.on_frame(now, &frame, &mut self.out);
                Ok(())
            }
            Action::Write {
                node,
                index,
                sub,
                value,
            } => {
                let i = self.drive(*node)?;
                let bytes = self.encode(i, *index, *sub, value)?;
                let mut result = Ok(());
                self.cell.local_access(i, now, &mut self.out, &mut |a| {
                    result = a.write(*index, *sub, &bytes);
                });
                result.map_err(|code| {
                    format!(
                        "{index:04X}:{sub:02X} refused: SDO abort {:#010X} ({})",
                        code.0,
                        code.description().unwrap_or("unknown")
                    )
                })
            }
            Action::Input { node, din, level } => {
                let i = self.drive(*node)?;
                let (mask, levels) = self.forced.get(i).copied().unwrap_or_default();
                let bit = 1u16 << din;
                let forced = (
                    mask | bit,
                    if *level { levels | bit } else { levels & !bit },
                );
                let d = self
                    .cell
                    .drives
                    .get_mut(i)
                    .and_then(|d| d.model.drive_mut())
                    .ok_or("the drive has no simulated inputs")?;
                d.force_inputs(forced.0, forced.1);
                if let Some(f) = self.forced.get_mut(i) {
                    *f = forced;
                }
                Ok(())
            }
            Action::Load { node, torque_nm } => {
                let i = self.drive(*node)?;
                let d = self
                    .cell
                    .drives
                    .get_mut(i)
                    .and_then(|d| d.model.drive_mut())
                    .ok_or("the drive has no simulated motor")?;
                d.axis_mut().motor_mut().set_load_torque(*torque_nm);
                Ok(())
            }
            Action::Physics { node, change } => {
                let i = self.drive(*node)?;
                let d = self
                    .cell
                    .drives
                    .get_mut(i)
                    .and_then(|d| d.model.drive_mut())
                    .ok_or("the drive has no simulated plant")?;
                crate::cell::control::apply_physics(d, *change)
                    .map_err(|s| format!("the drive has no input with the function {s}"))?;
                if let crate::cell::control::PhysicsChange::Switch(..) = change {
                    // A switch forced by name joins the inputs forced by number.
                    if let Some(f) = self.forced.get_mut(i) {
                        *f = d.forced_inputs();
                    }
                }
                Ok(())
            }
            Action::Diagnostic {
                node,
                number,
                raise,
            } => {
                let i = self.drive(*node)?;
                let done = if *raise {
                    self.cell.raise_diagnostic(i, number)
                } else {
                    self.cell.clear_diagnostic(i, number)
                };
                done.map(|_| ()).map_err(|e| e.to_string())
            }
            Action::Fault { bus, fault } => {
                Self::bus0(*bus)?;
                self.cell
                    .add_wire_fault(now, *fault)
                    .map(|_| ())
                    .map_err(|e| e.to_string())
            }
            Action::ClearFaults { bus } => {
                Self::bus0(*bus)?;
                self.cell.clear_wire_faults();
                Ok(())
            }
        };
        self.emit(seen);
        result
    }

    fn read(&mut self, node: Option<u8>, index: u16, sub: u8) -> Result<(u64, usize), String> {
        let i = self.drive(node)?;
        let d = self.cell.drives.get(i).ok_or("no drive")?;
        let mut buf = [0u8; 8];
        let n = d
            .model
            .read(index, sub, &mut buf)
            .map_err(|code| format!("{index:04X}:{sub:02X}: SDO abort {:#010X}", code.0))?;
        Ok((unsigned(buf.get(..n).unwrap_or(&[])), n))
    }
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
