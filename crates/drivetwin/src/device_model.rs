//! What stands behind a node's dictionary: plain data (a CiA 301 device such as the test
//! bench) or a CiA 402 drive with its motor. The stack sees both through `ObjectAccess`.

use drive::drive::{Drive, DriveEvent, DriveSettings};
use od::{AbortCode, Entry, Instant, ObjectAccess, ObjectDictionary};

pub enum Model {
    Plain(ObjectDictionary<Vec<u8>>),
    Drive(Box<Drive<Vec<u8>>>),
}

/// CiA 402 devices announce themselves in 1000h (profile number 402 = 0192h in the low word).
pub fn is_cia402(desc: &od::DeviceDescription) -> bool {
    desc.entry(0x1000, 0)
        .map(|e| e.default.get(..2) == Some(&[0x92, 0x01][..]))
        .unwrap_or(false)
}

/// Whether the personality is an FHPP device (the CMMO-ST): no CiA device profile (1000h
/// reads 0, devices/cmmo-st.toml) and the FHPP parameters (PNU n at object 2000h + n) with
/// PNU 125 "device control".
pub fn is_fhpp(desc: &od::DeviceDescription) -> bool {
    let no_profile = desc
        .entry(0x1000, 0)
        .is_none_or(|e| e.default.iter().all(|b| *b == 0));
    no_profile && desc.object(drive::fhpp::device::pnu_index(125)).is_some()
}

impl Model {
    /// A drive model when the personality is a CiA 402 device and `settings` are given.
    pub fn new(od: ObjectDictionary<Vec<u8>>, settings: Option<DriveSettings>) -> Self {
        match settings {
            Some(s) if is_cia402(od.description()) => Model::Drive(Box::new(Drive::new(od, s))),
            _ => Model::Plain(od),
        }
    }

    pub fn od(&self) -> &ObjectDictionary<Vec<u8>> {
        match self {
            Model::Plain(od) => od,
            Model::Drive(d) => d.od(),
        }
    }

    pub fn od_mut(&mut self) -> &mut ObjectDictionary<Vec<u8>> {
        match self {
            Model::Plain(od) => od,
            Model::Drive(d) => d.od_mut(),
        }
    }

    pub fn drive(&self) -> Option<&Drive<Vec<u8>>> {
        match self {
            Model::Drive(d) => Some(d),
            Model::Plain(_) => None,
        }
    }

    pub fn drive_mut(&mut self) -> Option<&mut Drive<Vec<u8>>> {
        match self {
            Model::Drive(d) => Some(d),
            Model::Plain(_) => None,
        }
    }

    /// Runs the device up to `now`; the next time it wants to run.
    pub fn step(&mut self, now: Instant) -> Option<Instant> {
        match self {
            Model::Plain(_) => None,
            Model::Drive(d) => d.step(now),
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
            Model::Plain(_) => None,
            Model::Drive(d) => d.take_event(),
        }
    }

    fn access(&self) -> &dyn ObjectAccess {
        match self {
            Model::Plain(od) => od,
            Model::Drive(d) => d.as_ref(),
        }
    }

    fn access_mut(&mut self) -> &mut dyn ObjectAccess {
        match self {
            Model::Plain(od) => od,
            Model::Drive(d) => d.as_mut(),
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
