//! A station's EtherCAT front end, where its drive is a slave of one of the cell's chains.
//! A drive on a CAN bus as well: the CoE side reaches the very drive the CANopen node serves
//! (what CoE writes SDO reads) and takes a copy of the drive's events for its emergencies. A
//! drive on EtherCAT alone: a station without a CANopen node, whose events the CoE side takes
//! itself.

use std::collections::VecDeque;

use drive::drive::DriveEvent;

use super::Station;
use crate::cell::device_model::Model;
use crate::cell::param_store::{ParamStore, StoredValue};

/// Drive events kept for the CoE side at most (it takes them at its next frame or tick).
const MAX_COE_EVENTS: usize = 64;

impl Station {
    /// What the CoE side of a drive on EtherCAT alone reaches: the model (whose events it
    /// takes itself), where "save" writes, and the set last saved.
    pub fn drive_parts(&mut self) -> (&mut Model, Option<&ParamStore>, &mut Vec<StoredValue>) {
        (&mut self.model, self.store.as_ref(), &mut self.stored)
    }

    /// The drive is an EtherCAT slave of the cell as well: its events are kept for the CoE
    /// emergencies too.
    pub fn serve_coe(&mut self) {
        self.coe_events.get_or_insert_with(VecDeque::new);
    }

    /// What the CoE side of a drive served over EtherCAT as well reaches: the model, where
    /// "save" writes, the set last saved, and the events kept for it.
    pub fn coe_parts(
        &mut self,
    ) -> (
        &mut Model,
        Option<&ParamStore>,
        &mut Vec<StoredValue>,
        &mut VecDeque<DriveEvent>,
    ) {
        let events = self.coe_events.get_or_insert_with(VecDeque::new);
        (
            &mut self.model,
            self.store.as_ref(),
            &mut self.stored,
            events,
        )
    }

    /// A drive event, copied for the CoE emergencies when the drive is served over EtherCAT
    /// as well; the oldest is lost when the CoE side has not taken them.
    pub(super) fn keep_for_coe(&mut self, ev: DriveEvent) {
        let Some(q) = self.coe_events.as_mut() else {
            return;
        };
        let full = q.len() >= MAX_COE_EVENTS;
        if full {
            q.pop_front();
        }
        q.push_back(ev);
        if full {
            tracing::warn!(node = self.node_id(), "CoE event queue full, oldest lost");
        }
    }
}
