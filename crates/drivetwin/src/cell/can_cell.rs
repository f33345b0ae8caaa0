//! A cell's stations and the CAN buses between them, on one clock: the stations in one list
//! ([`Stations`]), each bus a [`SegmentBus`] that names its stations by id and borrows the
//! list for each call. It is what the virtual clock (`cell_loop::virtual_clock`) and the
//! scenario rig run, as the cell loop runs its list and its buses: an EtherCAT chain joins it
//! (`ecat::chain::SlaveChain::join_cell`), so a drive that is a CANopen node and an EtherCAT
//! slave at once is one station, named by its bus and by its slave.

use canopen::CanFrame;
use od::{time::earliest, Instant};

use super::can_segment::{CanSegment, SegmentBus};
use super::station::Station;
use super::stations::{StationId, Stations};
use super::OnBus;

/// The stations of a cell and its CAN buses (bus `b` is `buses[b]`).
#[derive(Default)]
pub struct CanCell {
    /// Every station: the buses' in bus and segment order, then the chains' own (in the
    /// order they joined).
    pub stations: Stations,
    /// The CAN buses, in the cell file's order.
    pub buses: Vec<SegmentBus>,
}

impl From<CanSegment> for CanCell {
    /// A cell of one bus: its stations are the list, in segment order.
    fn from(segment: CanSegment) -> Self {
        CanCell::from_segments([segment])
    }
}

impl CanCell {
    /// A cell without stations or buses.
    pub fn new() -> Self {
        CanCell::default()
    }

    /// The cell of `segments`, in order: each one's stations join the list (in segment
    /// order) and its bus names them by id there, as the cell loop joins its buses.
    pub fn from_segments(segments: impl IntoIterator<Item = CanSegment>) -> Self {
        let mut cell = CanCell::new();
        for s in segments {
            let (own, bus) = s.into_parts();
            cell.buses.push(bus.join(own, &mut cell.stations));
        }
        cell
    }

    /// `drives` join the list, in order; their ids, for the bus they are on
    /// ([`SegmentBus::new`], then pushed on [`CanCell::buses`]).
    pub fn push_stations(&mut self, drives: Vec<Station>) -> Vec<StationId> {
        drives.into_iter().map(|d| self.stations.push(d)).collect()
    }

    pub fn bus(&self, b: usize) -> Option<&SegmentBus> {
        self.buses.get(b)
    }

    pub fn bus_mut(&mut self, b: usize) -> Option<&mut SegmentBus> {
        self.buses.get_mut(b)
    }

    /// The id of the station at `at` (its bus, its place in the bus's segment order).
    pub fn id_at(&self, at: OnBus) -> Option<StationId> {
        self.buses.get(at.bus)?.member(at.drive)
    }

    /// The station at `at`.
    pub fn station(&self, at: OnBus) -> Option<&Station> {
        self.stations.station(self.id_at(at)?)
    }

    /// The station at `at`.
    pub fn station_mut(&mut self, at: OnBus) -> Option<&mut Station> {
        let id = self.id_at(at)?;
        self.stations.station_mut(id)
    }

    /// The stations of bus `b`, in segment order (none for a bus the cell lacks).
    pub fn on_bus(&self, b: usize) -> impl Iterator<Item = &Station> {
        self.buses
            .get(b)
            .into_iter()
            .flat_map(|bus| bus.stations(&self.stations))
    }

    /// Boots every drive of bus `b`; the boot-up messages go to `out`.
    pub fn boot(&mut self, b: usize, now: Instant, out: &mut Vec<CanFrame>) {
        if let Some(bus) = self.buses.get_mut(b) {
            bus.boot(&mut self.stations, now, out);
        }
    }

    /// A frame from outside on bus `b` ([`SegmentBus::on_frame`]).
    pub fn on_frame(&mut self, b: usize, now: Instant, frame: &CanFrame, out: &mut Vec<CanFrame>) {
        if let Some(bus) = self.buses.get_mut(b) {
            bus.on_frame(&mut self.stations, now, frame, out);
        }
    }

    /// Runs the timers of bus `b` and its drives; the bus's next deadline.
    pub fn poll(&mut self, b: usize, now: Instant, out: &mut Vec<CanFrame>) -> Option<Instant> {
        let bus = self.buses.get_mut(b)?;
        bus.poll(&mut self.stations, now, out)
    }

    /// The next deadline of bus `b` and its drives.
    pub fn deadline_of(&self, b: usize) -> Option<Instant> {
        self.buses.get(b)?.deadline(&self.stations)
    }

    /// The earliest deadline of every bus and its drives.
    pub fn deadline(&self) -> Option<Instant> {
        self.buses
            .iter()
            .fold(None, |acc, b| earliest(acc, b.deadline(&self.stations)))
    }

    /// A local interface (a serial port, a terminal) of the station at `at` reaches its
    /// objects at `now` through `f` ([`SegmentBus::local_access`]); the frames the drive
    /// sends meanwhile go to `out`.
    pub fn local_access(
        &mut self,
        at: OnBus,
        now: Instant,
        out: &mut Vec<CanFrame>,
        f: &mut dyn FnMut(&mut dyn od::ObjectAccess),
    ) {
        if let Some(bus) = self.buses.get_mut(at.bus) {
            bus.local_access(&mut self.stations, at.drive, now, out, f);
        }
    }

    /// Why a drive's load FMU stopped the cell, once one has (the first such station's
    /// error, on a bus or a chain's own).
    pub fn load_failure(&self) -> Option<&crate::cosim::FmuLoadError> {
        self.stations
            .iter()
            .find_map(|d| d.model.drive()?.load_failure())
    }
}
