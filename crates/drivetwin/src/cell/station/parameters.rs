//! A station's parameters: the values the cell file commissions, the set stored in its
//! parameter file, and the dictionary as an SDO server writes it (a "save" carried out
//! before the answer).

use od::{AbortCode, Entry, ObjectAccess, ObjectDictionary, StorageRequest};

use crate::cell::device_model::Model;
use crate::cell::param_store::{self, ParamStore, StoreError, StoredValue};

/// A value the cell file sets at power-on, as a commissioning tool would have (before the
/// stored set, which wins).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Commissioning {
    pub index: u16,
    pub sub: u8,
    pub bytes: Vec<u8>,
}

/// Defaults, then commissioning values, then the stored set, for the indices `filter` selects.
pub(super) fn load_all(
    od: &mut ObjectDictionary<Vec<u8>>,
    commissioning: &[Commissioning],
    stored: &[StoredValue],
    filter: impl Fn(u16) -> bool,
) {
    od.load_defaults(|e| filter(e.index));
    let desc = od.description();
    for c in commissioning {
        if filter(c.index) {
            if let Some(e) = desc.entry(c.index, c.sub) {
                od.store(e, &c.bytes);
            }
        }
    }
    param_store::apply(od, stored, &filter);
}

/// The dictionary as the SDO server (CANopen or CoE) sees it: a "save" (1010h) is carried
/// out before the answer, so a file that cannot be written gets the abort CiA 301 and the
/// CMMP-AS manual give for a faulty store access (0800 0020h) instead of a confirmation.
pub struct Persisting<'a> {
    model: &'a mut Model,
    store: Option<&'a ParamStore>,
    stored: &'a mut Vec<StoredValue>,
}

impl<'a> Persisting<'a> {
    /// `model` with its parameters saved to `store` (none: kept for the life of the process);
    /// `stored` is the set last saved, kept up to date.
    pub fn new(
        model: &'a mut Model,
        store: Option<&'a ParamStore>,
        stored: &'a mut Vec<StoredValue>,
    ) -> Self {
        Persisting {
            model,
            store,
            stored,
        }
    }

    /// Carries out a save or restore the dictionary asked for.
    pub fn carry_out(&mut self, req: StorageRequest) -> Result<(), StoreError> {
        match req {
            StorageRequest::Save { sub } => {
                let node = self.model.od().node_id();
                match self.store {
                    Some(store) => {
                        store.save(self.model.od(), sub)?;
                        *self.stored = store.load()?;
                        tracing::info!(node, path = %store.path().display(), "parameters saved");
                    }
                    None => {
                        tracing::warn!(node, "save accepted, but the cell has no state directory")
                    }
                }
            }
            // CMMP-AS §5.1: "load" copies the defaults into the current set (the dictionary
            // did); the application set in flash stays until the next "save".
            StorageRequest::Restore { sub } => {
                self.model.reload();
                tracing::info!(node = self.model.od().node_id(), sub, "defaults restored");
                // Nanotec §11.25: the defaults are written to EEPROM at once, so the next
                // power-on or NMT reset starts from them (2005h, 2009h kept).
                if self
                    .model
                    .od()
                    .description()
                    .cia301
                    .restore_writes_stored_set
                {
                    self.carry_out(StorageRequest::Save { sub })?;
                }
            }
        }
        Ok(())
    }
}

impl ObjectAccess for Persisting<'_> {
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode> {
        self.model.entry(index, sub)
    }
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        self.model.read(index, sub, buf)
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.model.write(index, sub, data)?;
        if let Some(req) = self.model.od_mut().take_request() {
            self.carry_out(req).map_err(|e| {
                tracing::error!(error = %e, "saving parameters failed");
                AbortCode::CANNOT_STORE
            })?;
        }
        Ok(())
    }
    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.model.write_internal(index, sub, data)
    }
}
