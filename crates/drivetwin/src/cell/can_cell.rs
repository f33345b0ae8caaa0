//! A cell's stations and the CAN buses between them, on one clock: the stations in one list
//! ([`Stations`]), each bus a [`SegmentBus`] that names its stations by id and borrows the
//! list for each call. It is what the virtual clock (`cell_loop::virtual_clock`), the
//! scenario rig and the cell loop run (the loop with each bus's transports beside it): an
//! EtherCAT chain joins it
//! (`ecat::chain::SlaveChain::join_cell`), so a drive that is a CANopen node and an EtherCAT
//! slave at once is one station, named by its bus and by its slave.

use canopen::CanFrame;
use od::{time::earliest, Instant};

use super::can_segment::SegmentBus;
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

impl CanCell {
    /// A cell without stations or buses.
    pub fn new() -> Self {
        CanCell::default()
    }

    /// A cell of one instant bus between `drives` (the list, in segment order).
    pub fn one_bus(drives: Vec<Station>) -> Self {
        let mut cell = CanCell::new();
        cell.add_bus(drives);
        cell
    }

    /// A cell of one bus between `drives` that takes the time a real one does at `bitrate`
    /// bit/s ([`SegmentBus::set_bitrate`]).
    pub fn one_timed_bus(
        drives: Vec<Station>,
        bitrate: u32,
        late_after: std::time::Duration,
    ) -> Self {
        let mut cell = CanCell::new();
        let b = cell.add_bus(drives);
        if let Some(bus) = cell.bus_mut(b) {
            bus.set_bitrate(bitrate, late_after);
        }
        cell
    }

    /// A new bus between `drives`, which join the list in order; its index (the last of
    /// [`CanCell::buses`]), without a bit rate: [`CanCell::bus_mut`] sets its timing and plans.
    pub fn add_bus(&mut self, drives: Vec<Station>) -> usize {
        let members = self.push_stations(drives);
        self.buses.push(SegmentBus::new(members));
        self.buses.len() - 1
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

    /// Where station `id` is on the CAN buses (the first bus that names it).
    pub fn place_of(&self, id: StationId) -> Option<OnBus> {
        self.buses.iter().enumerate().find_map(|(bus, b)| {
            let drive = b.position(id)?;
            Some(OnBus { bus, drive })
        })
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

    /// A local interface (a serial port, a terminal) of station `id` reaches its objects at
    /// `now` through `f` ([`SegmentBus::local_access`]); the frames the drive sends meanwhile
    /// go to `out`, for its bus: the index of that bus (none: the station is on no CAN bus,
    /// and what it sends goes nowhere).
    pub fn local_access(
        &mut self,
        id: StationId,
        now: Instant,
        out: &mut Vec<CanFrame>,
        f: &mut dyn FnMut(&mut dyn od::ObjectAccess),
    ) -> Option<usize> {
        match self.place_of(id) {
            Some(at) => {
                let bus = self.buses.get_mut(at.bus)?;
                bus.local_access(&mut self.stations, at.drive, now, out, f);
                Some(at.bus)
            }
            None => {
                if let Some(s) = self.stations.station_mut(id) {
                    s.local_access(now, &mut |_| {}, f);
                }
                None
            }
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
