//! A cell's stations and the CAN buses between them, on one clock: the stations in one list
//! ([`Stations`]), each bus a [`SegmentBus`] that names its stations by id and borrows the
//! list for each call. It is what the virtual clock (`cell_loop::virtual_clock`), the
//! scenario rig and the cell loop run (the loop with each bus's transports beside it): an
//! EtherCAT chain joins it
//! (`ecat::chain::SlaveChain::join_cell`), so a drive that is a CANopen node and an EtherCAT
//! slave at once is one station, named by its bus and by its slave. Outside a bus a station
//! is addressed by its [`StationId`] alone; a bus keeps the order of its stations to itself.
//!
//! The cell holds the one timeline of what its cell file plans for its drives
//! ([`super::planned`]), keyed by station, carried out on the cell's clock by what steps the
//! cell ([`CanCell::carry_out_plans`]; a bus's poll carries out the stations' that are due
//! too, for a stepper that only polls the buses).

use canopen::CanFrame;
use od::{time::earliest, Instant};

use super::can_segment::SegmentBus;
use super::diagnostics::Planned;
use super::planned::{self, PlanError, Timeline};
use super::station::Station;
use super::stations::{StationId, Stations};

/// The stations of a cell and its CAN buses (bus `b` is `buses[b]`).
#[derive(Default)]
pub struct CanCell {
    /// Every station: the buses' in bus and segment order, then those that joined after
    /// (the chains' own, the Modbus drives), in the order they joined.
    pub stations: Stations,
    /// The CAN buses, in the cell file's order.
    pub buses: Vec<SegmentBus>,
    /// What the cell file plans for its drives, in time order (those of one time in the
    /// order they were planned).
    plans: Timeline<(StationId, Planned)>,
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

    /// The bus station `id` is on (the first that names it; none: on no CAN bus).
    pub fn bus_of(&self, id: StationId) -> Option<usize> {
        self.buses.iter().position(|b| b.position(id).is_some())
    }

    /// Station `id`.
    pub fn station(&self, id: StationId) -> Option<&Station> {
        self.stations.station(id)
    }

    /// Station `id`.
    pub fn station_mut(&mut self, id: StationId) -> Option<&mut Station> {
        self.stations.station_mut(id)
    }

    /// Plans `what` for `who` at `at` on the cell's clock (after what is planned for the
    /// same time already).
    pub fn plan(&mut self, at: Instant, who: StationId, what: Planned) {
        self.plans.plan(at, (who, what));
    }

    /// Plans a drive's `[[drive.diagnostic]]` and then its plant changes (`[drive.thermal]`,
    /// `[[drive.plant]]`: ms on the cell's clock, the change) for `who`.
    pub fn plan_drive(
        &mut self,
        who: StationId,
        diagnostics: Vec<super::diagnostics::PlannedDiagnostic>,
        physics: Vec<(u64, super::control::PhysicsChange)>,
    ) {
        for p in diagnostics {
            self.plan(Instant::from_millis(p.at_ms), who, Planned::Diagnostic(p));
        }
        for (at_ms, change) in physics {
            self.plan(Instant::from_millis(at_ms), who, Planned::Physics(change));
        }
    }

    /// The time of the first planned change still to come.
    pub fn plans_deadline(&self) -> Option<Instant> {
        self.plans.deadline()
    }

    /// Carries out the changes due by `now`, in time order, each on its station's model (and
    /// the bus the station is on polls at `now`, so its frames go out as the change's own).
    /// A change that cannot be carried out is logged; the cell goes on.
    pub fn carry_out_plans(&mut self, now: Instant) {
        while let Some((who, what)) = self.plans.take_due(now) {
            if let Err(e) = self.carry_out_on(who, now, &what) {
                tracing::warn!(?who, ?what, "planned change: {e}");
            }
        }
    }

    /// The changes due by `now` of the stations a bus's poll steps (a register-image
    /// device's wait for [`CanCell::carry_out_plans`], as its front end steps it).
    fn carry_out_station_plans(&mut self, now: Instant) {
        loop {
            let stations = &self.stations;
            let stepped_here = |(who, _): &(StationId, Planned)| {
                stations
                    .station(*who)
                    .is_none_or(|s| s.model.register_image().is_none())
            };
            let Some((who, what)) = self.plans.take_due_if(now, stepped_here) else {
                break;
            };
            if let Err(e) = self.carry_out_on(who, now, &what) {
                tracing::warn!(?who, ?what, "planned change: {e}");
            }
        }
    }

    /// `what` on station `id` at `now`; its bus polls at `now`.
    fn carry_out_on(
        &mut self,
        id: StationId,
        now: Instant,
        what: &Planned,
    ) -> Result<(), PlanError> {
        let s = self.stations.station_mut(id).ok_or(PlanError::NoDrive)?;
        let done = planned::on_model(&mut s.model, what);
        if let Some(b) = self.bus_of(id) {
            if let Some(bus) = self.buses.get_mut(b) {
                bus.poll_by(now);
            }
        }
        done
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

    /// Runs the timers of bus `b` and its drives, after the stations' planned changes due
    /// by `now`; the bus's next deadline.
    pub fn poll(&mut self, b: usize, now: Instant, out: &mut Vec<CanFrame>) -> Option<Instant> {
        if self.plans.deadline().is_some_and(|d| d <= now) {
            self.carry_out_station_plans(now);
        }
        let bus = self.buses.get_mut(b)?;
        bus.poll(&mut self.stations, now, out)
    }

    /// The next deadline of bus `b` and its drives.
    pub fn deadline_of(&self, b: usize) -> Option<Instant> {
        self.buses.get(b)?.deadline(&self.stations)
    }

    /// The earliest deadline of every bus and its drives, and of the planned changes.
    pub fn deadline(&self) -> Option<Instant> {
        self.buses.iter().fold(self.plans.deadline(), |acc, b| {
            earliest(acc, b.deadline(&self.stations))
        })
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
        match self.bus_of(id) {
            Some(b) => {
                let bus = self.buses.get_mut(b)?;
                bus.local_access(&mut self.stations, id, now, out, f);
                Some(b)
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
