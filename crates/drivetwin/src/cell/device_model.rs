//! What stands behind a station's dictionary: plain data (a CiA 301 device such as the test
//! bench), a CiA 402 drive with its motor, or a vendor's register-image device stepped on a
//! cycle of its own (the CMMO-ST's FHPP, [`RegisterImage`]). Front ends see each through
//! `ObjectAccess`.

use drive::drive::{Drive, DriveEvent, DriveSettings};
use drive::vendors::{AnyDrive, Cia402};
use od::{AbortCode, Entry, Instant, ObjectAccess, ObjectDictionary};

use crate::cell::modbus_device::RegisterImage;
use crate::cosim::LoadedDrive;

pub enum Model {
    Plain(ObjectDictionary<Vec<u8>>),
    /// A drive, with its load FMU where the cell file gives one.
    Drive(Box<LoadedDrive>),
    /// A vendor's device served with a register image of its own, on its own cycle; the
    /// runtime names no vendor: the device is the vendor folder's `ModbusDevice`.
    RegisterImage(Box<RegisterImage>),
}

/// A CiA 402 drive (`profile = "cia402"` in its device file, checked against 1000h).
pub fn is_cia402(desc: &od::DeviceDescription) -> bool {
    desc.profile == od::Profile::Cia402
}

/// An FHPP device, the CMMO-ST (`profile = "fhpp"` in its device file).
pub fn is_fhpp(desc: &od::DeviceDescription) -> bool {
    desc.profile == od::Profile::Fhpp
}

impl Model {
    /// A drive model when the personality is a CiA 402 device and `settings` are given.
    pub fn new(od: ObjectDictionary<Vec<u8>>, settings: Option<DriveSettings>) -> Self {
        match settings {
            Some(s) if is_cia402(od.description()) => {
                // A drive from its EDS runs the standard CiA 402 vendor with the personality
                // read from its file; a device file's drive, the vendor its name chooses.
                let drive = match crate::cell::eds_drive::personality_of(od.description()) {
                    Some(p) => AnyDrive::Cia402(Drive::with_vendor(od, s, p, Cia402)),
                    None => AnyDrive::new(od, s),
                };
                Model::Drive(Box::new(LoadedDrive::new(drive)))
            }
            _ => Model::Plain(od),
        }
    }

    pub fn od(&self) -> &ObjectDictionary<Vec<u8>> {
        match self {
            Model::Plain(od) => od,
            Model::Drive(d) => d.od(),
            Model::RegisterImage(r) => r.device().od(),
        }
    }

    pub fn od_mut(&mut self) -> &mut ObjectDictionary<Vec<u8>> {
        match self {
            Model::Plain(od) => od,
            Model::Drive(d) => d.od_mut(),
            Model::RegisterImage(r) => r.device_mut().od_mut(),
        }
    }

    pub fn drive(&self) -> Option<&LoadedDrive> {
        match self {
            Model::Drive(d) => Some(d),
            Model::Plain(_) | Model::RegisterImage(_) => None,
        }
    }

    pub fn drive_mut(&mut self) -> Option<&mut LoadedDrive> {
        match self {
            Model::Drive(d) => Some(d),
            Model::Plain(_) | Model::RegisterImage(_) => None,
        }
    }

    /// The register-image device, when the drive is one.
    pub fn register_image(&self) -> Option<&RegisterImage> {
        match self {
            Model::RegisterImage(r) => Some(r),
            Model::Plain(_) | Model::Drive(_) => None,
        }
    }

    /// The register-image device, when the drive is one.
    pub fn register_image_mut(&mut self) -> Option<&mut RegisterImage> {
        match self {
            Model::RegisterImage(r) => Some(r),
            Model::Plain(_) | Model::Drive(_) => None,
        }
    }

    /// Couples the load FMU `mapping` names to the drive's shaft (`[drive.load]`).
    pub fn couple_load(
        &mut self,
        mapping: &crate::cosim::LoadMapping,
        node: u8,
    ) -> Result<(), crate::cosim::FmuLoadError> {
        let Model::Drive(d) = self else {
            return Err(crate::cosim::FmuLoadError::NoShaft {
                fmu: mapping.fmu.display().to_string(),
            });
        };
        d.set_load(crate::cosim::FmuLoad::open(
            mapping,
            None,
            &format!("load{node}"),
        )?);
        Ok(())
    }

    /// Runs the device up to `now`; the next time it wants to run. A register-image device
    /// steps when its own cycle is due.
    pub fn step(&mut self, now: Instant) -> Option<Instant> {
        match self {
            Model::Plain(_) => None,
            Model::Drive(d) => d.step(now),
            Model::RegisterImage(r) => {
                r.step_due(now);
                Some(r.next_cycle())
            }
        }
    }

    /// Values changed under the device (reset, restore): it re-reads what it caches.
    pub fn reload(&mut self) {
        if let Model::Drive(d) = self {
            d.reload();
        }
    }

    pub fn take_event(&mut self) -> Option<DriveEvent> {
        match self {
            Model::Plain(_) | Model::RegisterImage(_) => None,
            Model::Drive(d) => d.take_event(),
        }
    }

    fn access(&self) -> &dyn ObjectAccess {
        match self {
            Model::Plain(od) => od,
            Model::Drive(d) => &***d,
            Model::RegisterImage(r) => r.device().access(),
        }
    }

    fn access_mut(&mut self) -> &mut dyn ObjectAccess {
        match self {
            Model::Plain(od) => od,
            Model::Drive(d) => &mut ***d,
            Model::RegisterImage(r) => r.device_mut().access_mut(),
        }
    }
}

impl ObjectAccess for Model {
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode> {
        self.access().entry(index, sub)
    }
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        self.access().read(index, sub, buf)
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.access_mut().write(index, sub, data)
    }
    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.access_mut().write_internal(index, sub, data)
    }
}
