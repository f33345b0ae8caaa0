//! The rig of a running cell: actions through its control handle, frames from a tap on its
//! buses, times on the wall clock from the start of the run (so a live run is as exact as
//! the machine's scheduling, not bit for bit).

use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use canopen::CanFrame;

use super::file::Action;
use super::runner::Rig;
use super::virtual_rig::{expedited_download, unsigned};
use crate::cell::control::{ControlHandle, DriveInfo, Interface};
use crate::cell::wire_faults::{FrontEnd, WireAnswer, WireRequest, TAP_QUEUE};

pub struct LiveRig {
    handle: ControlHandle,
    taps: Vec<(usize, Receiver<(Duration, CanFrame)>)>,
    /// The cell's clock at the start.
    origin: Duration,
    start: Instant,
    drives: Vec<DriveInfo>,
    forced: Vec<(u16, u16)>,
}

impl LiveRig {
    pub fn new(handle: ControlHandle) -> Result<LiveRig, String> {
        let drives = handle.drives().map_err(|e| e.to_string())?;
        let buses = handle.buses().map_err(|e| e.to_string())?;
        let mut taps = Vec::new();
        for b in 0..buses.len() {
            let (frames, rx) = std::sync::mpsc::sync_channel(TAP_QUEUE);
            handle
                .wire(WireRequest::Tap { bus: b, frames })
                .map_err(|e| e.to_string())?;
            taps.push((b, rx));
        }
        let origin = match handle.wire(WireRequest::Now).map_err(|e| e.to_string())? {
            WireAnswer::Now(t) => t,
            _ => Duration::ZERO,
        };
        let forced = vec![(0, 0); drives.len()];
        Ok(LiveRig {
            handle,
            taps,
            origin,
            start: Instant::now(),
            drives,
            forced,
        })
    }

    fn drive(&self, node: Option<u8>) -> Result<&DriveInfo, String> {
        match node {
            None => self
                .drives
                .first()
                .ok_or_else(|| "the cell has no drive".into()),
            Some(n) => self
                .drives
                .iter()
                .find(|d| d.interface == Interface::CanOpen { node: n })
                .ok_or_else(|| format!("no node {n} in the cell")),
        }
    }

    fn encode(info: &DriveInfo, index: u16, sub: u8, value: &str) -> Result<Vec<u8>, String> {
        let desc = crate::cell::eds_drive::by_name(info.device).ok_or("no device description")?;
        let e = desc
            .entry(index, sub)
            .ok_or_else(|| format!("{index:04X}:{sub:02X}: no such object"))?;
        crate::value_text::encode(e.data_type, value)
    }

    fn send(&self, bus: usize, frame: CanFrame) -> Result<(), String> {
        self.handle
            .wire(WireRequest::Send { bus, frame })
            .map(|_| ())
            .map_err(|e| e.to_string())
    }

    fn drain(&self, seen: &mut dyn FnMut(usize, Duration, &CanFrame)) {
        for (b, rx) in &self.taps {
            while let Ok((t, f)) = rx.try_recv() {
                seen(*b, t.saturating_sub(self.origin), &f);
            }
        }
    }
}

impl Rig for LiveRig {
    fn run_until(&mut self, t: Duration, seen: &mut dyn FnMut(usize, Duration, &CanFrame)) {
        let end = self.start + t;
        loop {
            self.drain(seen);
            let now = Instant::now();
            if now >= end {
                break;
            }
            std::thread::sleep((end - now).min(Duration::from_millis(1)));
        }
    }

    fn act(
        &mut self,
        action: &Action,
        seen: &mut dyn FnMut(usize, Duration, &CanFrame),
    ) -> Result<(), String> {
        // Frames the action sends come back through the tap.
        self.drain(seen);
        let err = |e: crate::cell::control::ControlError| e.to_string();
        match action {
            Action::Frame { bus, frame } => self.send(*bus, *frame),
            // Decision: on a live cell the CMMO-ST's Modbus server has its own clients; a
            // scripted request is the virtual clock's.
            Action::Modbus { .. } => {
                Err("modbus_request runs on the virtual clock (drivetwin scenario)".into())
            }
            Action::SdoWrite {
                bus,
                node,
                index,
                sub,
                value,
            } => {
                let info = self.drive(*node)?;
                let Interface::CanOpen { node } = info.interface else {
                    return Err("sdo_write: the drive is no CANopen node".into());
                };
                let bytes = Self::encode(info, *index, *sub, value)?;
                self.send(*bus, expedited_download(node, *index, *sub, &bytes)?)
            }
            Action::Write {
                node,
                index,
                sub,
                value,
            } => {
                let info = self.drive(*node)?;
                let bytes = Self::encode(info, *index, *sub, value)?;
                self.handle
                    .write(info.index, *index, *sub, &bytes)
                    .map_err(err)
            }
            Action::Input { node, din, level } => {
                let i = self.drive(*node)?.index;
                let (mask, levels) = self.forced.get(i).copied().unwrap_or_default();
                let bit = 1u16 << din;
                let forced = (
                    mask | bit,
                    if *level { levels | bit } else { levels & !bit },
                );
                self.handle.set_inputs(i, forced.0, forced.1).map_err(err)?;
                if let Some(f) = self.forced.get_mut(i) {
                    *f = forced;
                }
                Ok(())
            }
            Action::Load { node, torque_nm } => {
                let i = self.drive(*node)?.index;
                self.handle.set_load(i, *torque_nm).map_err(err)
            }
            Action::Physics { node, change } => {
                let i = self.drive(*node)?.index;
                let p = self.handle.physics(i, *change).map_err(err)?;
                // A switch forced by name joins the inputs forced by number.
                if let Some(f) = self.forced.get_mut(i) {
                    *f = p.forced_inputs;
                }
                Ok(())
            }
            Action::Diagnostic {
                node,
                number,
                raise,
            } => {
                let i = self.drive(*node)?.index;
                let done = if *raise {
                    self.handle.raise_diagnostic(i, number)
                } else {
                    self.handle.clear_diagnostic(i, number)
                };
                done.map(|_| ()).map_err(err)
            }
            Action::Fault { bus, fault } => self
                .handle
                .wire(WireRequest::Add {
                    front: FrontEnd::Bus(*bus),
                    fault: *fault,
                })
                .map(|_| ())
                .map_err(|e| e.to_string()),
            Action::ClearFaults { bus } => self
                .handle
                .wire(WireRequest::Clear {
                    front: FrontEnd::Bus(*bus),
                })
                .map(|_| ())
                .map_err(|e| e.to_string()),
            Action::EthercatLine { chain, action } => self
                .handle
                .ethercat_line(*chain, Some(*action))
                .map(|_| ())
                .map_err(|e| e.to_string()),
        }
    }

    fn read(&mut self, node: Option<u8>, index: u16, sub: u8) -> Result<(u64, usize), String> {
        let i = self.drive(node)?.index;
        let bytes = self.handle.read(i, index, sub).map_err(|e| e.to_string())?;
        Ok((unsigned(&bytes), bytes.len()))
    }
}
