//! The drive behind a slave: its own (a drive on EtherCAT alone), or a station of the cell's
//! list, which may be a CANopen node of one of the cell's buses as well.

use std::path::Path;

use crate::cell::can_cell::CanCell;
use crate::cell::config::DriveSpec;
use crate::cell::param_store::ParamStore;
use crate::cell::station::Station;
use crate::cell::stations::StationId;

#[cfg(doc)]
use super::chain::SlaveChain;
use super::chain::SlaveChainError;

/// The drive behind a slave.
pub enum SlaveDrive {
    /// Its own: the station of a drive on EtherCAT alone (no CANopen node), with where 1010h
    /// "save" writes its parameters and the set last saved.
    Own(Box<Station>),
    /// Station `id` of the cell's list: a drive of its own once the chain has joined a cell
    /// ([`SlaveChain::join`]; `bus` none), or a CANopen drive of CAN bus `bus` served over
    /// EtherCAT as well (`allow_unreal_interfaces`): a value written over CoE is the one SDO
    /// reads.
    Station { id: StationId, bus: Option<usize> },
}

/// Where the drives of [`SlaveDrive::Station`] slaves live: the cell's list of stations.
pub trait BusDrives {
    /// Station `id` of the cell's list (none: the chain has not joined a cell).
    fn in_cell(&mut self, _id: StationId) -> Option<&mut Station> {
        None
    }
}

/// A chain without CAN buses: every slave has a drive of its own.
pub struct NoBuses;

impl BusDrives for NoBuses {}

/// The chains that joined a cell ([`SlaveChain::join_cell`]) find their drives in its list.
impl BusDrives for CanCell {
    fn in_cell(&mut self, id: StationId) -> Option<&mut Station> {
        self.stations.station_mut(id)
    }
}

/// A drive on EtherCAT alone built from its spec: a station without a CANopen node, built as
/// a CAN bus's stations are (cell file, motor commissioning, stored set).
pub fn own_drive(spec: DriveSpec, state_dir: Option<&Path>) -> Result<SlaveDrive, SlaveChainError> {
    let settings = spec.settings.map(|mut s| {
        // CSP (6060h = 8) exists only over EtherCAT.
        s.ethercat = true;
        s
    });
    let store = state_dir.map(|d| ParamStore::new(d, spec.desc.name, spec.node));
    let mut drive =
        Station::with_settings(spec.desc, spec.node, store, spec.commissioning, settings)?;
    drive.couple_load(spec.load.as_ref(), spec.node)?;
    Ok(SlaveDrive::Own(Box::new(drive.without_canopen())))
}
