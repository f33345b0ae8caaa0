//! A drive the cell serves over Modbus TCP with a register image of its vendor's own (the
//! FHPP telegrams of a Festo CMMO-ST), stepped on a cycle of its own: what the runtime needs
//! of it, declared here and implemented in the vendor's folder
//! (`drivetwin::vendors::MODBUS_DEVICE`), which the binary and the test rigs hand in.
//!
//! In a cell the device is a station's drive ([`crate::cell::device_model::Model::RegisterImage`],
//! a [`RegisterImage`]: the device and its cycle on the cell's clock). Its Modbus TCP front
//! end ([`crate::modbus_tcp`]) reaches it by the station's id, serves its [`RegisterMap`] and
//! steps it;
//! the control handle reads and writes its objects, its diagnostics and its plant as it does
//! a CiA 402 drive's; a vendor's own API on it (the CMMO-ST's FHPP console) goes through
//! [`crate::cell::control::ControlHandle::with_modbus_device`] and
//! [`ModbusDevice::as_any_mut`].

use std::any::Any;
use std::time::Duration;

use drive::drive::diagnostics::DiagnosticError;
use modbus::{ConformityLevel, ConnectionEvent, Exception, ReadDeviceIdCode, RegisterMap};
use od::{AbortCode, Diagnostic, Instant, ObjectAccess, ObjectDictionary};

use crate::cell::config::DriveSpec;
use crate::cell::control::{DisplayState, PhysicsChange, Plant, PlantPhysics};
use crate::cell::diagnostics::{Action, DiagnosticState};
use crate::cell::param_store::ParamStore;
use crate::cosim::{FmuLoad, FmuLoadError};

/// A drive served over Modbus TCP: its register map, its cycle, and what the console asks of
/// it. Every method runs on the thread that serves it, between two requests.
pub trait ModbusDevice: RegisterMap + Send {
    /// Its device file.
    fn description(&self) -> &'static od::DeviceDescription;

    /// Its dictionary, as it stores it.
    fn od(&self) -> &ObjectDictionary<Vec<u8>>;

    /// Its dictionary, as it stores it.
    fn od_mut(&mut self) -> &mut ObjectDictionary<Vec<u8>>;

    /// Its objects as a front end reads and writes them (the device's own write rules).
    fn access(&self) -> &dyn ObjectAccess;

    /// Its objects as a front end reads and writes them (the device's own write rules).
    fn access_mut(&mut self) -> &mut dyn ObjectAccess;

    /// How often it steps (its cycle on the cell's clock).
    fn cycle(&self) -> Duration;

    /// Runs its cycles up to `now`, and keeps what it stores permanently.
    fn step(&mut self, now: Instant);

    /// An object's value into `buf` (its length), through the device's object access.
    fn read_object(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode>;

    /// Writes an object through the device's object access.
    fn write_object(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;

    /// Its diagnostic table (its manual's messages) with what is active now.
    fn diagnostics(&self) -> Vec<DiagnosticState>;

    /// Raises or clears message `number` as the manual prints it.
    fn set_diagnostic(
        &mut self,
        number: &str,
        action: Action,
    ) -> Result<&'static Diagnostic, DiagnosticError>;

    /// Its plant's physics after `change`; `Err` names a switch it has no input for.
    fn physics(&mut self, change: PhysicsChange) -> Result<PlantPhysics, &'static str>;

    /// The load torque on its motor, Nm.
    fn set_load(&mut self, torque_nm: f64);

    /// Its plant and display as the console samples them.
    fn plant(&self) -> (Plant, Option<DisplayState>);

    /// Its shaft, current and status now, as an importer that steps the cell reads them (the
    /// cell FMU's outputs).
    fn readout(&self) -> Readout;

    /// Couples `load` to its shaft from the next cycle on, in place of any other (and of an
    /// error a former one stopped it with); `None` uncouples it. Refused (and nothing
    /// changes) when the load drives a switch the device has no input for.
    fn couple_load(&mut self, load: Option<FmuLoad>) -> Result<(), FmuLoadError>;

    /// Why its load stopped it, once it has (it steps no more).
    fn load_failure(&self) -> Option<&FmuLoadError>;

    /// The load FMU coupled to its shaft, if any.
    fn load(&self) -> Option<&FmuLoad>;

    /// The vendor's own type, for the vendor's own API.
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

/// A register-image device as a station's drive: the device and when its next cycle is due on
/// the cell's clock.
pub struct RegisterImage {
    device: Box<dyn ModbusDevice>,
    cycle: Duration,
    next_cycle: Instant,
}

impl RegisterImage {
    /// `device` after one cycle at zero: its registers show the power-on state (the
    /// CMMO-ST's SCON 10h, SPOS 04h) from the very first request.
    pub fn new(mut device: Box<dyn ModbusDevice>) -> Self {
        device.step(Instant::ZERO);
        let cycle = device.cycle();
        RegisterImage {
            device,
            cycle,
            next_cycle: Instant::ZERO,
        }
    }

    pub fn device(&self) -> &dyn ModbusDevice {
        &*self.device
    }

    pub fn device_mut(&mut self) -> &mut dyn ModbusDevice {
        &mut *self.device
    }

    /// When its next cycle is due.
    pub fn next_cycle(&self) -> Instant {
        self.next_cycle
    }

    /// Steps the device when a cycle is due by `now`: whether it stepped. Cycles missed
    /// while the stepper was not scheduled are not made up here: the device's `step` itself
    /// runs every cycle up to `now`.
    pub fn step_due(&mut self, now: Instant) -> bool {
        if now < self.next_cycle {
            return false;
        }
        self.device.step(now);
        let next = self.next_cycle + self.cycle;
        self.next_cycle = if next > now { next } else { now + self.cycle };
        true
    }
}

/// What a drive served with its own register image shows an importer at one instant.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Readout {
    /// The motor shaft's angle, rad (the plant's, not the encoder's reading).
    pub position_rad: f64,
    /// The shaft's angular velocity, rad/s.
    pub velocity_rad_s: f64,
    /// The winding current, A.
    pub current_a: f64,
    /// The status bytes of its input telegram (FHPP: SCON, SPOS, SDIR, actual values).
    pub status: [u8; 8],
    /// The actual position, in the device's position unit.
    pub position_actual: i32,
}

/// The boxed device is its register map, so that the servers, which take any
/// [`RegisterMap`], serve it as they serve the device.
impl RegisterMap for Box<dyn ModbusDevice> {
    fn read(&mut self, address: u16, out: &mut [u16]) -> Result<(), Exception> {
        (**self).read(address, out)
    }

    fn write(&mut self, address: u16, values: &[u16]) -> Result<(), Exception> {
        (**self).write(address, values)
    }

    fn read_write(
        &mut self,
        read_address: u16,
        out: &mut [u16],
        write_address: u16,
        values: &[u16],
    ) -> Result<(), Exception> {
        (**self).read_write(read_address, out, write_address, values)
    }

    fn exception_status(&mut self) -> Result<u8, Exception> {
        (**self).exception_status()
    }

    fn device_id(&self, object: u8) -> Option<&[u8]> {
        (**self).device_id(object)
    }

    fn conformity_level(&self, requested: ReadDeviceIdCode) -> ConformityLevel {
        (**self).conformity_level(requested)
    }

    fn connection_event(&mut self, event: ConnectionEvent) {
        (**self).connection_event(event)
    }
}

/// A device of a cell file's drive at power-on, as [`NewModbusDevice`] makes it.
pub struct PoweredOn {
    pub device: Box<dyn ModbusDevice>,
    /// Why its permanent memory was not taken (it runs on its factory settings).
    pub memory_error: Option<String>,
}

/// Makes the device of the drive `spec` names at power-on (its dictionary with the cell
/// file's commissioning values and settings), its permanent memory kept in `store`; `None`
/// for a drive that is not served this way.
pub type NewModbusDevice =
    fn(spec: &DriveSpec, store: Option<ParamStore>) -> Option<Result<PoweredOn, NewDeviceError>>;

/// Why a drive's Modbus device could not be made.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NewDeviceError {
    #[error("dictionary storage too small")]
    Storage,
    #[error("load: {0}")]
    Load(String),
}
