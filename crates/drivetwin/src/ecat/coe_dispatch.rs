//! The mailbox's CoE dispatch ([`ethercat::coe`], the CMMP-AS set of services): after every
//! frame and every tick the device answers the request waiting in SM0 (or sends the next
//! fragment or a queued emergency); the drive's errors go out as CoE emergencies.
//!
//! Stored parameters: a "save" (1010h, or a restore 1011h that writes the stored set) is
//! confirmed once its file is written, as over CANopen (CiA 301; 0800 0020h when it cannot be
//! written). The slave writes no file itself: it takes a copy of the dictionary as it is, holds
//! the CoE reply and asks the runtime for the write ([`SlaveChain::take_save`]); the runtime
//! hands the result back ([`SlaveChain::saved`]) and the reply goes out then. Meanwhile the
//! mailbox serves nothing else, while the ESC, hardware on a real slave, goes on answering
//! every frame with its working counter (a save's two fsyncs under load take tens of
//! milliseconds: written in the frame's path they made pysoem's frames of that time come back
//! late, `tests/interop/test_kill9.py`). What a save or restore does to the dictionary and the
//! stored set is decided where a CANopen node's is ([`storage_request`]); only the moment of
//! the write differs.
//!
//! [`SlaveChain::take_save`]: super::chain::SlaveChain::take_save
//! [`SlaveChain::saved`]: super::chain::SlaveChain::saved

use drive::drive::DriveEvent;
use ethercat::coe::{self, Emergency};
use ethercat::esc::MAILBOX_MAX;
use ethercat::Esc;
use od::{AbortCode, StorageRequest};

use crate::cell::device_model::Model;
use crate::cell::param_saver::{SaveJob, SaveResult};
use crate::cell::param_store::ParamStore;
use crate::cell::storage_request::{self, OnRequest, Requesting};

use super::process_data::read_unsigned;
use super::slave::Bound;

/// A save asked for over CoE whose file the runtime writes; the CoE reply waits here.
pub(super) struct SaveInFlight {
    /// The write the runtime has not taken yet
    /// ([`SlaveChain::take_save`](super::chain::SlaveChain::take_save)).
    pub(super) job: Option<SaveJob>,
    /// The object written (1010h or 1011h) and its sub-index, for the abort if the file
    /// cannot be written.
    index: u16,
    sub: u8,
    /// The mailbox message the CoE server made; posted when the file is written (none for a
    /// save asked for by another path than the mailbox).
    reply: Vec<u8>,
}

/// The write a storage request asks for ([`storage_request::take`]), for the runtime to carry
/// out (`on_loop`: on its loop, for a drive whose CANopen node writes the same file), with the
/// object (1010h / 1011h) and sub-index asked.
fn ask(
    model: &mut Model,
    store: Option<&ParamStore>,
    on_loop: bool,
    req: StorageRequest,
) -> Option<(SaveJob, u16, u8)> {
    let save = storage_request::take(model, store, req)?;
    Some((save.job(model.od(), on_loop), save.index, save.sub))
}

/// The CoE server's [`OnRequest`]: a storage request (1010h / 1011h) is taken out and left in
/// `asked` for the slave to hand to the runtime.
struct SaveLater<'a> {
    store: Option<&'a ParamStore>,
    on_loop: bool,
    asked: Option<(SaveJob, u16, u8)>,
}

impl OnRequest for SaveLater<'_> {
    fn on_request(&mut self, model: &mut Model, req: StorageRequest) -> Result<(), AbortCode> {
        self.asked = ask(model, self.store, self.on_loop, req);
        Ok(())
    }
}

impl Bound<'_> {
    /// Serves the mailbox once (CoE) when it has something to do ([`coe::due`]), then what
    /// the dictionary asked for (1010h / 1011h); a save in progress holds the mailbox.
    pub(super) fn mailbox(&mut self, esc: &mut Esc<'_>) {
        if self.dev.saving.is_some() {
            return;
        }
        // A drive shared with CANopen: its node writes the file on the loop, so this slave's
        // saves are written there too (one writer of the file).
        let on_loop = self.shared_events.is_some();
        if coe::due(esc, &self.dev.coe) {
            self.serve(esc, on_loop);
            if self.dev.saving.is_some() {
                return;
            }
        }
        // A storage request left by another path than the SDO server is asked for here.
        if let Some(req) = self.model.od_mut().take_request() {
            if let Some((job, index, sub)) = ask(self.model, self.store, on_loop, req) {
                self.dev.saving = Some(SaveInFlight {
                    job: Some(job),
                    index,
                    sub,
                    reply: Vec::new(),
                });
            }
        }
    }

    /// The CoE server's turn ([`coe::serve`]): the reply it makes is posted, or held with the
    /// save its request asked for. Apart from [`mailbox`](Self::mailbox), which runs in every
    /// cycle, with the send buffer it needs.
    #[inline(never)]
    fn serve(&mut self, esc: &mut Esc<'_>, on_loop: bool) {
        let mut out = [0u8; MAILBOX_MAX];
        let mut access = Requesting {
            model: self.model,
            handler: SaveLater {
                store: self.store,
                on_loop,
                asked: None,
            },
        };
        let n = coe::serve(esc, &mut self.dev.coe, &mut access, &mut out);
        let asked = access.handler.asked.take();
        let reply = n.and_then(|n| out.get(..n)).unwrap_or(&[]);
        match asked {
            Some((job, index, sub)) => {
                self.dev.saving = Some(SaveInFlight {
                    job: Some(job),
                    index,
                    sub,
                    reply: reply.to_vec(),
                });
            }
            None if !reply.is_empty() => {
                let _ = esc.mailbox_write(reply);
            }
            None => {}
        }
    }

    /// The runtime wrote the file of the save in progress (`result`): the stored set is the
    /// one read back, and the held reply goes out (the abort 0800 0020h if the file could not
    /// be written); the mailbox is free again.
    pub(super) fn saved(&mut self, esc: &mut Esc<'_>, result: SaveResult) {
        let Some(SaveInFlight {
            index,
            sub,
            mut reply,
            ..
        }) = self.dev.saving.take()
        else {
            return;
        };
        let node = self.model.od().node_id();
        if let Err(error) = storage_request::keep_saved(self.stored, node, result) {
            // CiA 301 / CMMP-AS: a store that failed is refused with 0800 0020h.
            tracing::error!(node, %error, "saving parameters failed");
            if !reply.is_empty() {
                reply.truncate(ethercat::mailbox::HEADER_LEN);
                reply.resize(ethercat::mailbox::HEADER_LEN + 10, 0);
                if let Some(p) = reply.get_mut(ethercat::mailbox::HEADER_LEN..) {
                    let _ = coe::abort::encode(p, index, sub, AbortCode::CANNOT_STORE);
                }
                if let Some(len) = reply.get_mut(..2) {
                    len.copy_from_slice(&10u16.to_le_bytes());
                }
            }
        }
        // A master that took the mailbox down (Init) meanwhile gets no reply.
        if reply.len() > ethercat::mailbox::HEADER_LEN && esc.mailbox_running() {
            let _ = esc.mailbox_write(&reply);
        }
    }

    /// The drive's events as CoE emergencies. Called after every step of the drive, which
    /// has none in nearly every cycle: the look for one stays small (inlined where it is
    /// called), an event is handled apart.
    #[inline]
    pub(super) fn forward_events(&mut self) {
        // A shared drive's events are taken by its CANopen side, which keeps a copy here.
        while let Some(ev) = match self.shared_events.as_deref_mut() {
            Some(q) => q.pop_front(),
            None => self.model.take_event(),
        } {
            self.forward_event(ev);
        }
    }

    /// One event of the drive: the error register and history of a drive on EtherCAT alone,
    /// and the CoE emergency.
    #[inline(never)]
    fn forward_event(&mut self, ev: DriveEvent) {
        if self.shared_events.is_none() {
            // A shared drive's CANopen side keeps 1001h and 1003h; one on EtherCAT alone
            // keeps them here.
            let errors = &mut self.dev.errors;
            match ev {
                DriveEvent::Error { code, register } => {
                    errors.raise(self.model, code, register, [0; 5])
                }
                DriveEvent::Cleared { code } => errors.clear(self.model, code),
                DriveEvent::Reboot => {}
            }
            errors.reset_communication();
        }
        // CiA 402 errors as CoE emergencies (ETG.1000.6 §5.6.4, the CANopen EMCY layout).
        let emcy = match ev {
            // A reboot is the CANopen side's (no EtherCAT drive asks for one).
            DriveEvent::Reboot => return,
            DriveEvent::Error { code, register } => Emergency::new(code, register, [0; 5]),
            // "Error reset": code 0000h with the error register that remains.
            DriveEvent::Cleared { .. } => {
                let model: &Model = self.model;
                let register = read_unsigned(model, 0x1001, 0).unwrap_or(0);
                Emergency::new(0, u8::try_from(register).unwrap_or(0), [0; 5])
            }
        };
        if self.dev.coe.queue_emergency(emcy).is_err() {
            tracing::warn!(event = ?ev, "emergency queue full");
        }
    }
}
