//! The control handle of a running cell: a typed, thread-safe way in for tests and the web
//! console. It lists the drives, reads and writes their objects through the same object
//! access as every front end (a write is seen at once on the wire), reads the plant and the
//! display, sets inputs and load, and subscribes to samples of the plant.
//!
//! A request goes to the cell loop ([`crate::cell_loop`]) and is carried out there,
//! between two socket events, on the cell's clock; the caller waits for the answer. Samples
//! come on a bounded channel: when the subscriber does not keep up, samples are dropped,
//! never waited for (the loop serves sockets first).

use std::sync::mpsc::{self, Receiver, Sender, SyncSender};
use std::sync::Arc;
use std::time::{Duration, Instant};

use drive::vendors::AnyDrive;
use mio::Waker;
use od::AbortCode;

use crate::cell::modbus_device::ModbusDevice;
use crate::cell::next_turn::NextTurn;

/// Samples waiting for a subscriber before newer ones are dropped.
pub const SAMPLE_QUEUE: usize = 1024;

/// A drive of the cell, as [`ControlHandle::drives`] lists it. Its index is its place in
/// that list: the CAN drives in cell order, then the Modbus drives, then the EtherCAT-only
/// drives (a drive on CANopen and EtherCAT at once is listed once, as a CANopen node).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DriveInfo {
    pub index: usize,
    /// The device file's name (`cmmp-as`, `cmmo-st`, …).
    pub device: &'static str,
    pub product: &'static str,
    pub interface: Interface,
}

/// How the drive is reached from outside the cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interface {
    /// A CANopen node on the cell's bus.
    CanOpen { node: u8 },
    /// FHPP over Modbus TCP.
    ModbusTcp,
    /// An EtherCAT slave only: chain `chain` of the cell, `position` in it (from 0).
    Ethercat { chain: usize, position: usize },
}

/// What the drive's display shows, as its characters read: a 7-segment display (the
/// CMMP-AS's App. B, the CMMO-ST's) or an LED panel's digits with their points (the Kinco
/// CD3 / FD3). Which display a drive has is its vendor's: [`DriveViews::display`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DisplayState {
    text: [u8; DisplayState::MAX],
    len: u8,
}

impl DisplayState {
    /// The most bytes a display's text has (a panel's five digits, each with its point).
    const MAX: usize = 16;

    /// `text` as the display shows it (cut at 16 bytes, on a character).
    pub fn new(text: &str) -> Self {
        let mut end = text.len().min(Self::MAX);
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        let mut buf = [0u8; Self::MAX];
        let bytes = text.as_bytes().get(..end).unwrap_or_default();
        if let Some(b) = buf.get_mut(..end) {
            b.copy_from_slice(bytes);
        }
        DisplayState {
            text: buf,
            len: u8::try_from(end).unwrap_or(0),
        }
    }

    /// The characters shown.
    pub fn text(&self) -> &str {
        self.text
            .get(..usize::from(self.len))
            .and_then(|b| std::str::from_utf8(b).ok())
            .unwrap_or_default()
    }
}

/// What only a drive's vendor can tell the runtime about a CiA 402 drive, handed in by
/// whoever builds the loop ([`crate::cell_loop::FrontEnds::views`]).
#[derive(Debug, Clone, Copy)]
pub struct DriveViews {
    /// What the drive's display shows; `None` for a drive whose manual names no display.
    pub display: fn(&AnyDrive<Vec<u8>>) -> Option<DisplayState>,
}

impl DriveViews {
    /// The engine's display where the drive has one (the CMMP-AS's App. B 7-segment display).
    pub const ENGINE: DriveViews = DriveViews {
        display: |d| d.display().map(|shown| DisplayState::new(&shown.text())),
    };
}

impl Default for DriveViews {
    /// [`DriveViews::ENGINE`].
    fn default() -> Self {
        DriveViews::ENGINE
    }
}

/// Work on one CiA 402 drive in the loop's thread ([`ControlHandle::with_drive`]): it gets
/// the drive, or why there is none, and sends its own answer.
pub type DriveWork = Box<dyn FnOnce(Result<&mut AnyDrive<Vec<u8>>, ControlError>) + Send>;

/// Work on one drive served over Modbus TCP in the loop's thread
/// ([`ControlHandle::with_modbus_device`]): it gets the device, or why there is none, and
/// sends its own answer.
pub type ModbusWork = Box<dyn FnOnce(Result<&mut dyn ModbusDevice, ControlError>) + Send>;

/// The plant of one drive at one time of the cell's clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantSample {
    /// The cell's clock.
    pub at: Duration,
    pub plant: Plant,
    pub display: Option<DisplayState>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Plant {
    /// A CiA 402 servo: encoder position (increments), speed, motor current and the digital
    /// inputs as 60FDh shows them.
    Servo {
        position_increments: i64,
        velocity_rpm: f32,
        current_ma: i32,
        digital_inputs: u32,
    },
    /// The CMMO-ST's stepper: position in SI units (`None` before homing), load torque.
    Stepper {
        position_si: Option<f64>,
        load_torque_nm: f64,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ControlError {
    #[error("the cell has stopped")]
    Stopped,
    #[error("no drive {0} in the cell")]
    NoDrive(usize),
    #[error("no node {node} on bus {bus}")]
    NoNode { bus: usize, node: u8 },
    #[error("drive {0} has no simulated plant")]
    NoPlant(usize),
    #[error("refused: {0:?}")]
    Abort(AbortCode),
    /// A diagnostic message that the drive's table does not have, or that was not raised.
    #[error("diagnostic message: {0:?}")]
    Diagnostic(drive::drive::diagnostics::DiagnosticError),
    #[error("drive {0} has no LED panel")]
    NoPanel(usize),
    #[error("drive {0} has no simulated supply (a CiA 402 drive with its motor has one)")]
    NoSupply(usize),
    #[error("drive {drive} has no input with the function {switch}")]
    NoSwitch { drive: usize, switch: &'static str },
}

/// A CAN bus of the cell.
#[derive(Debug, Clone, PartialEq)]
pub struct BusInfo {
    pub index: usize,
    /// Its drives (CANopen nodes of the cell).
    pub drives: usize,
    /// With a bit rate in the cell file: what the bus did (load, late and lost frames).
    pub timing: Option<crate::cell::bus_timing::BusFigures>,
    /// Nodes whose CAN controller counts errors: (node-ID, state, TEC, REC).
    pub node_errors: Vec<(u8, canbus::fault_confinement::ErrorState, u16, u16)>,
}

/// One request to the loop.
pub(crate) enum Command {
    Drives(SyncSender<Vec<DriveInfo>>),
    Buses(SyncSender<Vec<BusInfo>>),
    Disturb {
        bus: usize,
        node: u8,
        frames: u32,
        reply: SyncSender<Result<(), ControlError>>,
    },
    Read {
        drive: usize,
        index: u16,
        sub: u8,
        reply: SyncSender<Result<Vec<u8>, ControlError>>,
    },
    Write {
        drive: usize,
        index: u16,
        sub: u8,
        data: Vec<u8>,
        reply: SyncSender<Result<(), ControlError>>,
    },
    Plant {
        drive: usize,
        reply: SyncSender<Result<PlantSample, ControlError>>,
    },
    SetInputs {
        drive: usize,
        mask: u16,
        levels: u16,
        reply: SyncSender<Result<(), ControlError>>,
    },
    SetLoad {
        drive: usize,
        torque_nm: f64,
        reply: SyncSender<Result<(), ControlError>>,
    },
    Subscribe {
        drive: usize,
        every: Duration,
        samples: SyncSender<PlantSample>,
        reply: SyncSender<Result<(), ControlError>>,
    },
    Diagnostics {
        drive: usize,
        reply: SyncSender<Result<Vec<crate::cell::diagnostics::DiagnosticState>, ControlError>>,
    },
    SetDiagnostic {
        drive: usize,
        number: String,
        action: crate::cell::diagnostics::Action,
        reply: SyncSender<Result<&'static od::Diagnostic, ControlError>>,
    },
    /// A change to an EtherCAT chain's line, or (none) its state
    /// ([`crate::cell::ethercat_line`]).
    EthercatLine {
        chain: usize,
        action: Option<crate::cell::ethercat_line::LineAction>,
        reply: SyncSender<
            Result<
                crate::cell::ethercat_line::LineStatus,
                crate::cell::ethercat_line::LineControlError,
            >,
        >,
    },
    /// Wire faults and traces ([`crate::cell::wire_faults`]).
    Wire {
        request: crate::cell::wire_faults::WireRequest,
        reply: SyncSender<
            Result<crate::cell::wire_faults::WireAnswer, crate::cell::wire_faults::WireError>,
        >,
    },
    SubscribeObjects {
        drive: usize,
        every: Duration,
        objects: Vec<(u16, u8)>,
        samples: SyncSender<ObjectsSample>,
        reply: SyncSender<Result<(), ControlError>>,
    },
    /// Work on a CiA 402 drive (a vendor's own API: the Kinco's LED panel).
    WithDrive {
        drive: usize,
        work: DriveWork,
    },
    /// Work on a drive served over Modbus TCP (a vendor's own API: the CMMO-ST's FHPP).
    WithModbusDevice {
        drive: usize,
        work: ModbusWork,
    },
    /// The drive's supply (DC-link) voltage: `None` is the nominal one.
    SetSupply {
        drive: usize,
        millivolts: Option<u32>,
        reply: SyncSender<Result<(), ControlError>>,
    },
    /// Temperatures, encoder and named switches ([`PhysicsRequest`]).
    Physics(PhysicsRequest),
    /// A drive's load FMU ([`crate::cell::load_control`]).
    Load(crate::cell::load_control::LoadRequest),
    /// Why the drive does not take a request ([`ControlHandle::refusal`]).
    Refusal {
        drive: usize,
        request: drive::drive::refusal::Request,
        reply: SyncSender<Result<Option<drive::drive::refusal::Refusal>, ControlError>>,
    },
}

/// A handle to a running cell; cheap to clone, usable from any thread.
#[derive(Clone)]
pub struct ControlHandle {
    tx: Sender<Command>,
    waker: Arc<Waker>,
    turn: Arc<NextTurn>,
    /// How long a request may wait for a turn the loop makes anyway before it wakes the loop
    /// ([`ControlHandle::riding`]); zero: it always wakes it.
    ride: Duration,
}

impl std::fmt::Debug for ControlHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ControlHandle")
    }
}

impl ControlHandle {
    pub(crate) fn new(tx: Sender<Command>, waker: Arc<Waker>, turn: Arc<NextTurn>) -> Self {
        ControlHandle {
            tx,
            waker,
            turn,
            ride: Duration::ZERO,
        }
    }

    /// This handle, whose requests wait up to `ride` for the loop's next planned turn
    /// instead of waking it ([`NextTurn`]): the console's, whose browsers poll each second
    /// and would otherwise add a wake-up of the loop per object they read. A request still
    /// wakes the loop when no turn is planned by then.
    pub fn riding(&self, ride: Duration) -> ControlHandle {
        ControlHandle {
            ride,
            ..self.clone()
        }
    }

    pub(crate) fn ask<T>(
        &self,
        make: impl FnOnce(SyncSender<T>) -> Command,
    ) -> Result<T, ControlError> {
        let (reply, answer) = mpsc::sync_channel(1);
        self.tx
            .send(make(reply))
            .map_err(|_| ControlError::Stopped)?;
        self.turn.sent();
        if self.ride.is_zero() || !self.turn.comes_within(Instant::now(), self.ride) {
            self.waker.wake().map_err(|_| ControlError::Stopped)?;
        }
        answer.recv().map_err(|_| ControlError::Stopped)
    }

    pub fn drives(&self) -> Result<Vec<DriveInfo>, ControlError> {
        self.ask(Command::Drives)
    }

    /// The cell's CAN buses, with their load where they have a bit rate.
    pub fn buses(&self) -> Result<Vec<BusInfo>, ControlError> {
        self.ask(Command::Buses)
    }

    /// The next `frames` transmissions of node `node` on bus `bus` fail with an error frame
    /// (16: error passive, 32: bus off).
    pub fn disturb(&self, bus: usize, node: u8, frames: u32) -> Result<(), ControlError> {
        self.ask(|reply| Command::Disturb {
            bus,
            node,
            frames,
            reply,
        })?
    }

    /// The value of an object, as its bytes (little-endian, as on CANopen).
    pub fn read(&self, drive: usize, index: u16, sub: u8) -> Result<Vec<u8>, ControlError> {
        self.ask(|reply| Command::Read {
            drive,
            index,
            sub,
            reply,
        })?
    }

    /// Writes an object with the access rules and effects of a fieldbus write.
    pub fn write(
        &self,
        drive: usize,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), ControlError> {
        self.ask(|reply| Command::Write {
            drive,
            index,
            sub,
            data: data.to_vec(),
            reply,
        })?
    }

    pub fn plant(&self, drive: usize) -> Result<PlantSample, ControlError> {
        self.ask(|reply| Command::Plant { drive, reply })?
    }

    /// Drives digital inputs from outside: bit n of `mask` forces DINn to bit n of `levels`.
    pub fn set_inputs(&self, drive: usize, mask: u16, levels: u16) -> Result<(), ControlError> {
        self.ask(|reply| Command::SetInputs {
            drive,
            mask,
            levels,
            reply,
        })?
    }

    /// Why drive `drive` does not take `request` now, with its manual's rule (an input owns
    /// the object, the hardware enables are missing, …); `None`: the drive knows of nothing
    /// in the way (a drive without CiA 402 logic never says).
    pub fn refusal(
        &self,
        drive: usize,
        request: drive::drive::refusal::Request,
    ) -> Result<Option<drive::drive::refusal::Refusal>, ControlError> {
        self.ask(|reply| Command::Refusal {
            drive,
            request,
            reply,
        })?
    }

    /// The load torque on the motor shaft, N·m.
    pub fn set_load(&self, drive: usize, torque_nm: f64) -> Result<(), ControlError> {
        self.ask(|reply| Command::SetLoad {
            drive,
            torque_nm,
            reply,
        })?
    }

    /// Samples of the drive's plant every `every` (at least the loop's own step), until the
    /// receiver is dropped. A subscriber that falls [`SAMPLE_QUEUE`] behind loses samples.
    pub fn subscribe(
        &self,
        drive: usize,
        every: Duration,
    ) -> Result<Receiver<PlantSample>, ControlError> {
        let (samples, rx) = mpsc::sync_channel(SAMPLE_QUEUE);
        self.ask(|reply| Command::Subscribe {
            drive,
            every,
            samples,
            reply,
        })??;
        Ok(rx)
    }

    /// The drive's diagnostic table (its manual's messages) with what is active now.
    pub fn diagnostics(
        &self,
        drive: usize,
    ) -> Result<Vec<crate::cell::diagnostics::DiagnosticState>, ControlError> {
        self.ask(|reply| Command::Diagnostics { drive, reply })?
    }

    /// Raises message `number` ("08-2", "2Fh": as the manual prints it) of drive `drive`: it
    /// reacts as if it had detected it, until [`ControlHandle::clear_diagnostic`].
    pub fn raise_diagnostic(
        &self,
        drive: usize,
        number: &str,
    ) -> Result<&'static od::Diagnostic, ControlError> {
        self.ask(|reply| Command::SetDiagnostic {
            drive,
            number: number.to_owned(),
            action: crate::cell::diagnostics::Action::Raise,
            reply,
        })?
    }

    /// Clears message `number` raised by [`ControlHandle::raise_diagnostic`].
    pub fn clear_diagnostic(
        &self,
        drive: usize,
        number: &str,
    ) -> Result<&'static od::Diagnostic, ControlError> {
        self.ask(|reply| Command::SetDiagnostic {
            drive,
            number: number.to_owned(),
            action: crate::cell::diagnostics::Action::Clear,
            reply,
        })?
    }

    /// Changes EtherCAT chain `chain`'s line (a cable, a slave's power or clock), or with
    /// `None` only reads it ([`crate::cell::ethercat_line`]).
    pub fn ethercat_line(
        &self,
        chain: usize,
        action: Option<crate::cell::ethercat_line::LineAction>,
    ) -> Result<crate::cell::ethercat_line::LineStatus, crate::cell::ethercat_line::LineControlError>
    {
        self.ask(|reply| Command::EthercatLine {
            chain,
            action,
            reply,
        })
        .map_err(|_| crate::cell::ethercat_line::LineControlError::Stopped)?
    }

    /// A wire fault, a trace or a tap on a front end ([`crate::cell::wire_faults`]).
    pub fn wire(
        &self,
        request: crate::cell::wire_faults::WireRequest,
    ) -> Result<crate::cell::wire_faults::WireAnswer, crate::cell::wire_faults::WireError> {
        self.ask(|reply| Command::Wire { request, reply })
            .map_err(|_| crate::cell::wire_faults::WireError::Stopped)?
    }

    /// Samples of the drive's plant and of up to [`MAX_SAMPLED_OBJECTS`] objects every
    /// `every`, read on the loop at the same instant (the scope's "any objects").
    pub fn subscribe_objects(
        &self,
        drive: usize,
        every: Duration,
        objects: &[(u16, u8)],
    ) -> Result<Receiver<ObjectsSample>, ControlError> {
        let (samples, rx) = mpsc::sync_channel(SAMPLE_QUEUE);
        let objects = objects.iter().copied().take(MAX_SAMPLED_OBJECTS).collect();
        self.ask(|reply| Command::SubscribeObjects {
            drive,
            every,
            objects,
            samples,
            reply,
        })??;
        Ok(rx)
    }

    /// Runs `work` on CiA 402 drive `drive` in the loop's thread, between two of its steps,
    /// and returns what it returns: the way to a vendor's own API (the Kinco's LED panel),
    /// which the runtime does not know. `work` gets [`ControlError::NoPlant`] for a drive that
    /// is not a CiA 402 drive with its plant.
    pub fn with_drive<T: Send + 'static>(
        &self,
        drive: usize,
        work: impl FnOnce(Result<&mut AnyDrive<Vec<u8>>, ControlError>) -> Result<T, ControlError>
            + Send
            + 'static,
    ) -> Result<T, ControlError> {
        self.ask(
            |reply: SyncSender<Result<T, ControlError>>| Command::WithDrive {
                drive,
                work: Box::new(move |d| {
                    let _ = reply.send(work(d));
                }),
            },
        )?
    }

    /// Runs `work` on drive `drive` served over Modbus TCP in the loop's thread, between two
    /// of its cycles, and returns what it returns: the way to a vendor's own API on it (the
    /// CMMO-ST's FHPP side), which the runtime does not know
    /// ([`ModbusDevice::as_any_mut`]). `work` gets [`ControlError::NoPlant`] for a drive that
    /// is not served over Modbus TCP.
    pub fn with_modbus_device<T: Send + 'static>(
        &self,
        drive: usize,
        work: impl FnOnce(Result<&mut dyn ModbusDevice, ControlError>) -> Result<T, ControlError>
            + Send
            + 'static,
    ) -> Result<T, ControlError> {
        self.ask(
            |reply: SyncSender<Result<T, ControlError>>| Command::WithModbusDevice {
                drive,
                work: Box::new(move |d| {
                    let _ = reply.send(work(d));
                }),
            },
        )?
    }

    /// The supply of drive `drive` at `millivolts` (`None`: back to the nominal voltage of
    /// its device file): the drive measures it (CMMP-AS 6510h:34, 6079h), its current
    /// controller has that much voltage, and its own supervision reacts (CMMP-AS 02-0 below
    /// 6510h:36 with 6510h:37 = 1).
    pub fn set_supply(&self, drive: usize, millivolts: Option<u32>) -> Result<(), ControlError> {
        self.ask(|reply| Command::SetSupply {
            drive,
            millivolts,
            reply,
        })?
    }
}

/// Objects one subscription may name at most.
pub const MAX_SAMPLED_OBJECTS: usize = 8;

/// One object's value in an [`ObjectsSample`]: its bytes (little-endian, as on CANopen), or
/// `len` 0 when it could not be read at that sample or is longer than 8 bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SampledValue {
    pub len: u8,
    pub bytes: [u8; 8],
}

impl SampledValue {
    pub fn get(&self) -> Option<&[u8]> {
        (self.len > 0).then(|| self.bytes.get(..usize::from(self.len)))?
    }
}

/// The plant and named objects of one drive at one time of the cell's clock (no allocation
/// in the loop: a fixed array).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectsSample {
    pub plant: PlantSample,
    /// In the order the subscription named them; the rest `len` 0.
    pub values: [SampledValue; MAX_SAMPLED_OBJECTS],
}

/// The plant's physics of one drive that its own supervision watches: temperatures and the
/// encoder (`drive::thermal`, `drive::encoder_fault`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantPhysics {
    pub ambient_c: f64,
    /// The motor winding, °C.
    pub motor_c: f64,
    /// The power (output) stage, °C.
    pub power_stage_c: f64,
    pub encoder: drive::encoder_fault::EncoderFault,
    /// The inputs forced from outside (mask, levels; bit n = DINn), named switches included.
    pub forced_inputs: (u16, u16),
}

/// Carries out `change` on a CiA 402 drive; `Err` names a switch no input has.
pub fn apply_physics(
    d: &mut drive::vendors::AnyDrive<Vec<u8>>,
    change: PhysicsChange,
) -> Result<PlantPhysics, &'static str> {
    match change {
        PhysicsChange::None => {}
        PhysicsChange::Ambient(c) => d.set_ambient_temperature(c),
        PhysicsChange::Encoder(f) => d.set_encoder_fault(f),
        PhysicsChange::Thermal(t) => d.set_thermal_data(t),
        PhysicsChange::Switch(s, on) => {
            d.set_switch(s, on).ok_or(s.name())?;
        }
    }
    let w = d.plant_watch();
    Ok(PlantPhysics {
        ambient_c: w.thermal.ambient_c(),
        motor_c: w.thermal.motor_c(),
        power_stage_c: w.thermal.stage_c(),
        encoder: w.encoder.fault(),
        forced_inputs: d.forced_inputs(),
    })
}

/// A change of the plant's physics ([`ControlHandle::physics`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum PhysicsChange {
    /// Nothing: read only.
    #[default]
    None,
    /// The ambient temperature, °C.
    Ambient(f64),
    /// The encoder faulted or repaired.
    Encoder(drive::encoder_fault::EncoderFault),
    /// The thermal figures (time constants, rises).
    Thermal(drive::thermal::ThermalData),
    /// A limit or home switch by name: actuated, released, or back to the travel (`None`).
    Switch(drive::drive::named_switches::NamedSwitch, Option<bool>),
}

/// A request of the plant's physics to the loop (appended to [`Command`] through
/// [`Command::Physics`]).
pub(crate) struct PhysicsRequest {
    pub drive: usize,
    pub change: PhysicsChange,
    pub reply: SyncSender<Result<PlantPhysics, ControlError>>,
}

impl ControlHandle {
    /// The plant's temperatures and encoder after `change` (see [`PhysicsChange`]).
    pub fn physics(
        &self,
        drive: usize,
        change: PhysicsChange,
    ) -> Result<PlantPhysics, ControlError> {
        self.ask(|reply| {
            Command::Physics(PhysicsRequest {
                drive,
                change,
                reply,
            })
        })?
    }

    /// The ambient temperature of drive `drive` and its motor, °C: motor and power stage
    /// heat or cool towards it; the drive's supervision raises its manual's temperature
    /// messages.
    pub fn set_ambient(&self, drive: usize, celsius: f64) -> Result<PlantPhysics, ControlError> {
        self.physics(drive, PhysicsChange::Ambient(celsius))
    }

    /// Faults (or repairs) the encoder of drive `drive`.
    pub fn set_encoder_fault(
        &self,
        drive: usize,
        fault: drive::encoder_fault::EncoderFault,
    ) -> Result<PlantPhysics, ControlError> {
        self.physics(drive, PhysicsChange::Encoder(fault))
    }

    /// Actuates (`Some(true)`), releases (`Some(false)`) or gives back to the travel (`None`)
    /// a limit or home switch by name; it is forced on the input its function is on.
    pub fn set_switch(
        &self,
        drive: usize,
        switch: drive::drive::named_switches::NamedSwitch,
        actuated: Option<bool>,
    ) -> Result<PlantPhysics, ControlError> {
        self.physics(drive, PhysicsChange::Switch(switch, actuated))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A display's text comes back as given; a text longer than any display's is cut on a
    /// character, never inside one.
    #[test]
    fn a_display_keeps_its_text_cut_on_a_character() {
        assert_eq!(DisplayState::new("-E081-").text(), "-E081-");
        assert_eq!(DisplayState::new("F.0.0.1.2.").text(), "F.0.0.1.2.");
        assert_eq!(DisplayState::new("").text(), "");
        let long = "0123456789abcde°";
        assert_eq!(long.len(), 17);
        assert_eq!(DisplayState::new(long).text(), "0123456789abcde");
    }
}
