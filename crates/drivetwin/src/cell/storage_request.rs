//! What a storage request does to a drive's dictionary and its stored set, whichever front
//! end it came from (CiA 301 §7.5.2.13 1010h "store parameters", §7.5.2.14 1011h "restore
//! default parameters"). A CANopen node's SDO server carries it out before its answer
//! ([`Persisting`](crate::cell::station::Persisting)); an EtherCAT slave's CoE server hands
//! the write to the runtime and answers once the file is written (`ecat::coe_dispatch`).
//! Both take the request here ([`take`]) and keep the set the file holds afterwards
//! ([`keep_saved`]); they differ only in when the file is written.

use od::{AbortCode, Forwarding, ObjectAccess, ObjectDictionary, StorageRequest};

use crate::cell::device_model::Model;
use crate::cell::param_saver::{SaveJob, SaveResult};
use crate::cell::param_store::{ParamStore, StoreError, StoredValue};

/// The save a storage request asks for: the object written (1010h, or 1011h where a restore
/// writes the stored set too), its sub-index (the parameter groups), and the drive's file.
pub struct Save<'s> {
    pub index: u16,
    pub sub: u8,
    pub store: &'s ParamStore,
}

impl Save<'_> {
    /// Writes the file from `od` now and reads the stored set back (atomically, as
    /// [`SaveJob::run`]).
    pub fn write_now(&self, od: &ObjectDictionary<Vec<u8>>) -> SaveResult {
        crate::cell::param_saver::write(self.store, od, self.sub)
    }

    /// The write for the runtime to carry out, of a copy of `od` as it is now (`on_loop`: on
    /// its loop, for a drive whose CANopen node writes the same file).
    pub fn job(&self, od: &ObjectDictionary<Vec<u8>>, on_loop: bool) -> SaveJob {
        SaveJob::new(self.store.clone(), od.clone(), self.sub, on_loop)
    }
}

/// The dictionary takes `req`; returns the save it asks for, if any. A save stores the values
/// as they are. A restore loads the defaults into the current set at once (CMMP-AS §5.1: the
/// application set in flash stays until the next "save") and is stored only where the device
/// writes them to its memory at once (Nanotec §11.25: the next power-on or NMT reset starts
/// from them). Without a state directory nothing is stored: the values live as long as the
/// process.
pub fn take<'s>(
    model: &mut Model,
    store: Option<&'s ParamStore>,
    req: StorageRequest,
) -> Option<Save<'s>> {
    let node = model.od().node_id();
    let (index, sub) = match req {
        StorageRequest::Save { sub } => (0x1010, sub),
        StorageRequest::Restore { sub } => {
            model.reload();
            tracing::info!(node, sub, "defaults restored");
            if !model.od().description().cia301.restore_writes_stored_set {
                return None;
            }
            (0x1011, sub)
        }
    };
    match store {
        Some(store) => Some(Save { index, sub, store }),
        None => {
            tracing::warn!(node, "save accepted, but the cell has no state directory");
            None
        }
    }
}

/// A save written (`result`): `stored` becomes the set read back from the file, which a reset
/// of the drive loads; a write that failed leaves it as it was and is returned.
pub fn keep_saved(
    stored: &mut Vec<StoredValue>,
    node: u8,
    result: SaveResult,
) -> Result<(), StoreError> {
    *stored = result?;
    tracing::info!(node, "parameters saved");
    Ok(())
}

/// What a front end does with a storage request a write raised: carry it out before the
/// answer ([`Persisting`](crate::cell::station::Persisting)) or leave it for the runtime
/// (the CoE server's).
pub trait OnRequest {
    /// `req` was written to `model`'s dictionary; an error is the write's answer.
    fn on_request(&mut self, model: &mut Model, req: StorageRequest) -> Result<(), AbortCode>;
}

/// A drive's dictionary as an SDO server (CANopen or CoE) writes it: every access goes to the
/// model, and a storage request a write raises goes to the front end's [`OnRequest`].
pub struct Requesting<'a, H> {
    pub model: &'a mut Model,
    pub handler: H,
}

impl<H: OnRequest> Forwarding for Requesting<'_, H> {
    type Inner = Model;

    fn inner(&self) -> &Model {
        self.model
    }
    fn inner_mut(&mut self) -> &mut Model {
        self.model
    }

    fn on_write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.model.write(index, sub, data)?;
        if let Some(req) = self.model.od_mut().take_request() {
            self.handler.on_request(self.model, req)?;
        }
        Ok(())
    }
}
