//! A station's parameters: the values the cell file commissions, the set stored in its
//! parameter file, and the dictionary as an SDO server writes it (a "save" carried out
//! before the answer).

use od::{AbortCode, ObjectDictionary, StorageRequest};

use crate::cell::device_model::Model;
use crate::cell::param_store::{self, ParamStore, StoreError, StoredValue};
use crate::cell::storage_request::{self, OnRequest, Requesting};

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
pub type Persisting<'a> = Requesting<'a, SaveNow<'a>>;

/// A CANopen node's [`OnRequest`]: the file written before the answer.
pub struct SaveNow<'a> {
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
        Requesting {
            model,
            handler: SaveNow { store, stored },
        }
    }

    /// Carries out a save or restore the dictionary asked for ([`storage_request`]): the
    /// file written before the answer.
    pub fn carry_out(&mut self, req: StorageRequest) -> Result<(), StoreError> {
        self.handler.carry_out(self.model, req)
    }
}

impl SaveNow<'_> {
    fn carry_out(&mut self, model: &mut Model, req: StorageRequest) -> Result<(), StoreError> {
        let Some(save) = storage_request::take(model, self.store, req) else {
            return Ok(());
        };
        let written = save.write_now(model.od());
        storage_request::keep_saved(self.stored, model.od().node_id(), written)
    }
}

impl OnRequest for SaveNow<'_> {
    fn on_request(&mut self, model: &mut Model, req: StorageRequest) -> Result<(), AbortCode> {
        self.carry_out(model, req).map_err(|e| {
            tracing::error!(error = %e, "saving parameters failed");
            AbortCode::CANNOT_STORE
        })
    }
}
