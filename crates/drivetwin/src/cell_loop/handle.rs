//! The control handle's side of the cell loop ([`crate::cell::control`]): requests carried
//! out between two socket events, and samples for subscribers.

use std::time::{Duration, Instant};

use super::{CellLoop, SampleSink, Subscription};
use crate::cell::control::{
    BusInfo, Command, ControlError, DriveInfo, Interface, Plant, PlantSample,
};
use crate::cell::device_model::Model;
use crate::cell::stations::StationId;

/// How long after its instant a subscriber's sample may wait for a turn the loop makes
/// anyway (its drives step each millisecond) instead of waking it: browsers on the scope
/// at 1 kHz then add no wake-up. The sample carries the instant it was taken at; one period
/// of the drives' step, so that a 1 kHz subscription loses no sample to the wait.
pub(super) const SAMPLE_RIDE: Duration = Duration::from_millis(1);

impl CellLoop {
    /// Carries out what control handles asked for; whether any asked.
    pub(super) fn control(&mut self, now: Instant) -> bool {
        let mut any = false;
        while let Ok(command) = self.control_rx.try_recv() {
            any = true;
            self.next_turn.taken();
            // A request sees the devices as of the last frame.
            self.settle_chains();
            // A caller that has gone does not need its answer.
            match command {
                Command::Drives(reply) => {
                    let _ = reply.send(self.drive_list());
                }
                Command::Buses(reply) => {
                    let t = self.now(now);
                    let stations = &self.cell.stations;
                    let buses = self
                        .cell
                        .buses
                        .iter_mut()
                        .enumerate()
                        .map(|(index, b)| BusInfo {
                            index,
                            drives: b.members().len(),
                            timing: b.bus_figures(t),
                            node_errors: b
                                .node_faults()
                                .filter(|(_, f)| f.confinement.counters() != (0, 0))
                                .filter_map(|(id, f)| {
                                    let d = stations.station(id)?;
                                    let (tec, rec) = f.confinement.counters();
                                    Some((d.node_id(), f.confinement.state(), tec, rec))
                                })
                                .collect(),
                        })
                        .collect();
                    let _ = reply.send(buses);
                }
                Command::Disturb {
                    bus,
                    node,
                    frames,
                    reply,
                } => {
                    let segment = self.cell.buses.get_mut(bus);
                    let stations = &self.cell.stations;
                    let at = segment.and_then(|c| {
                        let id = c.members().iter().copied().find(|id| {
                            stations.station(*id).is_some_and(|d| d.node_id() == node)
                        })?;
                        Some(c.disturb(id, frames))
                    });
                    let _ = reply.send(match at {
                        Some(true) => Ok(()),
                        _ => Err(ControlError::NoNode { bus, node }),
                    });
                }
                Command::Read {
                    drive,
                    index,
                    sub,
                    reply,
                } => {
                    let _ = reply.send(self.read_object(drive, index, sub));
                }
                Command::Write {
                    drive,
                    index,
                    sub,
                    data,
                    reply,
                } => {
                    let _ = reply.send(self.write_object(drive, index, sub, &data));
                }
                Command::Plant { drive, reply } => {
                    let _ = reply.send(self.sample(drive, now));
                }
                Command::SetInputs {
                    drive,
                    mask,
                    levels,
                    reply,
                } => {
                    let done = match self.cia402_mut(drive) {
                        Ok(d) => {
                            d.force_inputs(mask, levels);
                            Ok(())
                        }
                        Err(e) => Err(e),
                    };
                    let _ = reply.send(done);
                }
                Command::SetLoad {
                    drive,
                    torque_nm,
                    reply,
                } => {
                    let _ = reply.send(self.set_load(drive, torque_nm));
                }
                Command::Subscribe {
                    drive,
                    every,
                    samples,
                    reply,
                } => {
                    let every = every.max(Duration::from_micros(100));
                    let next = first_due(self.origin, every, now);
                    let done = self.sample(drive, now).map(|_| {
                        self.subscriptions.push(Subscription {
                            drive,
                            every,
                            next,
                            objects: Vec::new(),
                            sink: SampleSink::Plant(samples),
                        });
                    });
                    let _ = reply.send(done);
                }
                Command::Diagnostics { drive, reply } => {
                    let _ = reply.send(self.diagnostics(drive));
                }
                Command::SetDiagnostic {
                    drive,
                    number,
                    action,
                    reply,
                } => {
                    let _ = reply.send(self.set_diagnostic(drive, &number, action));
                }
                Command::EthercatLine {
                    chain,
                    action,
                    reply,
                } => {
                    let _ = reply.send(self.ethercat_line(chain, action, now));
                }
                Command::Wire { request, reply } => {
                    let _ = reply.send(self.wire(request, now));
                }
                Command::SubscribeObjects {
                    drive,
                    every,
                    objects,
                    samples,
                    reply,
                } => {
                    let every = every.max(Duration::from_micros(100));
                    let next = first_due(self.origin, every, now);
                    let done = self.sample(drive, now).map(|_| {
                        self.subscriptions.push(Subscription {
                            drive,
                            every,
                            next,
                            objects,
                            sink: SampleSink::Objects(samples),
                        });
                    });
                    let _ = reply.send(done);
                }
                Command::WithDrive { drive, work } => work(self.cia402_mut(drive)),
                Command::WithModbusDevice { drive, work } => match self.target(drive) {
                    Ok(Target::Modbus(device)) => work(Ok(device)),
                    Ok(Target::Can(_)) => work(Err(ControlError::NoPlant(drive))),
                    Err(e) => work(Err(e)),
                },
                Command::SetSupply {
                    drive,
                    millivolts,
                    reply,
                } => {
                    let done = match self.cia402_mut(drive) {
                        Ok(d) => {
                            d.set_dc_link_voltage(millivolts);
                            Ok(())
                        }
                        Err(ControlError::NoPlant(d)) => Err(ControlError::NoSupply(d)),
                        Err(e) => Err(e),
                    };
                    let _ = reply.send(done);
                }
                Command::Physics(r) => {
                    let _ = r.reply.send(self.physics(r.drive, r.change));
                }
                Command::Load(r) => {
                    let _ = r.reply.send(self.load(r.drive, r.change));
                }
                Command::Refusal {
                    drive,
                    request,
                    reply,
                } => {
                    let why = match self.target(drive) {
                        Ok(Target::Can(model)) => {
                            Ok(model.drive_mut().and_then(|d| d.refusal(request)))
                        }
                        Ok(Target::Modbus(_)) => Ok(None),
                        Err(e) => Err(e),
                    };
                    let _ = reply.send(why);
                }
            }
        }
        any
    }

    /// A drive's temperatures and encoder after `change` ([`crate::cell::control::PhysicsChange`]).
    fn physics(
        &mut self,
        drive: usize,
        change: crate::cell::control::PhysicsChange,
    ) -> Result<crate::cell::control::PlantPhysics, ControlError> {
        match self.target(drive)? {
            Target::Can(model) => {
                let d = model.drive_mut().ok_or(ControlError::NoPlant(drive))?;
                crate::cell::control::apply_physics(d, change)
                    .map_err(|switch| ControlError::NoSwitch { drive, switch })
            }
            Target::Modbus(dev) => dev
                .physics(change)
                .map_err(|switch| ControlError::NoSwitch { drive, switch }),
        }
    }

    /// A drive's load FMU after `change` ([`crate::cell::load_control`]): a CiA 402 drive's
    /// plant or a CMMO-ST's, each stepping it with its own cycle.
    fn load(
        &mut self,
        drive: usize,
        change: crate::cell::load_control::LoadChange,
    ) -> Result<crate::cell::load_control::LoadState, crate::cell::load_control::LoadControlError>
    {
        use crate::cell::load_control::{apply, apply_to_modbus_device};
        match self.target(drive)? {
            Target::Can(model) => apply(model, change),
            Target::Modbus(device) => apply_to_modbus_device(device, change),
        }
    }

    fn diagnostics(
        &mut self,
        drive: usize,
    ) -> Result<Vec<crate::cell::diagnostics::DiagnosticState>, ControlError> {
        use crate::cell::diagnostics as diag;
        Ok(match self.target(drive)? {
            Target::Can(model) => diag::list_model(model),
            Target::Modbus(dev) => dev.diagnostics(),
        })
    }

    fn set_diagnostic(
        &mut self,
        drive: usize,
        number: &str,
        action: crate::cell::diagnostics::Action,
    ) -> Result<&'static od::Diagnostic, ControlError> {
        use crate::cell::diagnostics as diag;
        match self.target(drive)? {
            Target::Can(model) => diag::set_model(model, number, action),
            Target::Modbus(dev) => dev.set_diagnostic(number, action),
        }
        .map_err(ControlError::Diagnostic)
    }

    /// Samples due to subscribers; a subscriber gone is forgotten, a full one loses the sample.
    /// Named objects are read into the sample's own fixed array: no allocation.
    pub(super) fn samples(&mut self, now: Instant) {
        use crate::cell::control::{ObjectsSample, SampledValue, MAX_SAMPLED_OBJECTS};
        use std::sync::mpsc::TrySendError;
        // Subscriptions of one drive due at one turn (tabs on its scope) share its sample.
        let mut taken: Option<(usize, PlantSample)> = None;
        let mut i = 0;
        while i < self.subscriptions.len() {
            let Some(sub) = self.subscriptions.get(i) else {
                break;
            };
            if sub.next > now {
                i += 1;
                continue;
            }
            let drive = sub.drive;
            let mut wanted = [(0u16, 0u8); MAX_SAMPLED_OBJECTS];
            let n = sub.objects.len().min(MAX_SAMPLED_OBJECTS);
            for (w, o) in wanted.iter_mut().zip(sub.objects.iter()) {
                *w = *o;
            }
            let plant = match taken {
                Some((d, p)) if d == drive => Ok(p),
                _ => self.sample(drive, now),
            };
            if let Ok(p) = plant {
                taken = Some((drive, p));
            }
            let mut values = [SampledValue::default(); MAX_SAMPLED_OBJECTS];
            if plant.is_ok() {
                for (v, (index, sub)) in values.iter_mut().zip(wanted.iter()).take(n) {
                    let mut buf = [0u8; 8];
                    if let Ok(len) = self.read_into(drive, *index, *sub, &mut buf) {
                        v.len = u8::try_from(len).unwrap_or(0);
                        v.bytes = buf;
                    }
                }
            }
            let Some(sub) = self.subscriptions.get_mut(i) else {
                break;
            };
            sub.next = next_due(sub.next, sub.every, now);
            let gone = match (plant, &sub.sink) {
                (Ok(p), SampleSink::Plant(tx)) => {
                    matches!(tx.try_send(p), Err(TrySendError::Disconnected(_)))
                }
                (Ok(plant), SampleSink::Objects(tx)) => matches!(
                    tx.try_send(ObjectsSample { plant, values }),
                    Err(TrySendError::Disconnected(_))
                ),
                (Err(_), _) => true,
            };
            if gone {
                self.subscriptions.swap_remove(i);
            } else {
                i += 1;
            }
        }
    }

    /// The cell's drives as the control handle numbers them, each its station and how it
    /// is reached: the CAN buses' (bus and segment order), then the Modbus drives', then the
    /// chains' own (a drive shared with CANopen is listed with its bus).
    fn drive_stations(&self) -> impl Iterator<Item = (StationId, Interface)> + '_ {
        let stations = &self.cell.stations;
        let can = self.cell.buses.iter().flat_map(|b| {
            b.members().iter().filter_map(|&id| {
                let node = stations.station(id)?.node_id();
                Some((id, Interface::CanOpen { node }))
            })
        });
        let modbus = self
            .modbus
            .iter()
            .filter_map(|m| Some((m.station()?, Interface::ModbusTcp)));
        let ethercat = self.chains.iter().enumerate().flat_map(|(chain, c)| {
            (0..c.chain.len()).filter_map(move |position| {
                let id = c.chain.own_station(position)?;
                Some((id, Interface::Ethercat { chain, position }))
            })
        });
        can.chain(modbus).chain(ethercat)
    }

    fn drive_list(&self) -> Vec<DriveInfo> {
        self.drive_stations()
            .filter_map(|(id, interface)| {
                let desc = self.cell.stations.station(id)?.od().description();
                Some((desc, interface))
            })
            .enumerate()
            .map(|(index, (desc, interface))| DriveInfo {
                index,
                device: desc.name,
                product: desc.product_name,
                interface,
            })
            .collect()
    }

    /// Drive `drive` of the list: its station's model, or its register-image device.
    fn target(&mut self, drive: usize) -> Result<Target<'_>, ControlError> {
        let id = self
            .drive_stations()
            .nth(drive)
            .map(|(id, _)| id)
            .ok_or(ControlError::NoDrive(drive))?;
        let station = self
            .cell
            .stations
            .station_mut(id)
            .ok_or(ControlError::NoDrive(drive))?;
        if station.model.register_image().is_some() {
            return station
                .model
                .register_image_mut()
                .map(|image| Target::Modbus(image.device_mut()))
                .ok_or(ControlError::NoDrive(drive));
        }
        Ok(Target::Can(&mut station.model))
    }

    fn read_object(&mut self, drive: usize, index: u16, sub: u8) -> Result<Vec<u8>, ControlError> {
        let mut buf = [0u8; 256];
        let n = match self.target(drive)? {
            Target::Can(model) => od::ObjectAccess::read(&*model, index, sub, &mut buf),
            Target::Modbus(dev) => dev.read_object(index, sub, &mut buf),
        }
        .map_err(ControlError::Abort)?;
        Ok(buf.get(..n).unwrap_or(&[]).to_vec())
    }

    fn write_object(
        &mut self,
        drive: usize,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), ControlError> {
        match self.target(drive)? {
            Target::Can(model) => od::ObjectAccess::write(model, index, sub, data),
            Target::Modbus(dev) => dev.write_object(index, sub, data),
        }
        .map_err(ControlError::Abort)
    }

    fn cia402_mut(
        &mut self,
        drive: usize,
    ) -> Result<&mut ::drive::vendors::AnyDrive<Vec<u8>>, ControlError> {
        match self.target(drive)? {
            Target::Can(model) => model
                .drive_mut()
                .map(|d| &mut **d)
                .ok_or(ControlError::NoPlant(drive)),
            Target::Modbus(_) => Err(ControlError::NoPlant(drive)),
        }
    }

    fn set_load(&mut self, drive: usize, torque_nm: f64) -> Result<(), ControlError> {
        match self.target(drive)? {
            Target::Can(model) => {
                let d = model.drive_mut().ok_or(ControlError::NoPlant(drive))?;
                d.axis_mut().motor_mut().set_load_torque(torque_nm);
            }
            Target::Modbus(dev) => dev.set_load(torque_nm),
        }
        Ok(())
    }

    fn sample(&mut self, drive: usize, now: Instant) -> Result<PlantSample, ControlError> {
        let at = now.saturating_duration_since(self.origin);
        let views = self.views;
        match self.target(drive)? {
            Target::Can(model) => {
                let inputs = od::ObjectAccess::read_u32(&*model, 0x60FD, 0).unwrap_or(0);
                let Model::Drive(d) = model else {
                    return Err(ControlError::NoPlant(drive));
                };
                let axis = d.axis();
                Ok(PlantSample {
                    at,
                    plant: Plant::Servo {
                        position_increments: axis.position_increments(),
                        velocity_rpm: axis.velocity_rpm(),
                        current_ma: axis.current_ma(),
                        digital_inputs: inputs,
                    },
                    display: (views.display)(d),
                })
            }
            Target::Modbus(dev) => {
                let (plant, display) = dev.plant();
                Ok(PlantSample { at, plant, display })
            }
        }
    }
}

impl CellLoop {
    /// An object's value into `buf` (an object longer than `buf` is an error).
    fn read_into(
        &mut self,
        drive: usize,
        index: u16,
        sub: u8,
        buf: &mut [u8],
    ) -> Result<usize, ControlError> {
        match self.target(drive)? {
            Target::Can(model) => od::ObjectAccess::read(&*model, index, sub, buf),
            Target::Modbus(dev) => dev.read_object(index, sub, buf),
        }
        .map_err(ControlError::Abort)
    }
}

enum Target<'a> {
    Can(&'a mut Model),
    Modbus(&'a mut dyn crate::cell::modbus_device::ModbusDevice),
}

/// The loop's deadline `at` with the subscribers' next sample `sample`: the sample rides on a
/// turn due within [`SAMPLE_RIDE`] after it; the loop wakes for it only when none is.
pub(super) fn with_samples(at: Option<Instant>, sample: Option<Instant>) -> Option<Instant> {
    match (at, sample) {
        (Some(a), Some(s)) if a <= s + SAMPLE_RIDE => Some(a),
        (Some(a), Some(s)) => Some(a.min(s)),
        (a, s) => a.or(s),
    }
}

/// The first sample time of a subscription: the next multiple of its period on the cell's
/// clock. Subscriptions of one period (five browser tabs on a scope at 1 kHz) are then due at
/// the same instants and served in one wake-up of the loop, instead of one wake-up each at the
/// phase each happened to subscribe at.
fn first_due(origin: Instant, every: Duration, now: Instant) -> Instant {
    let since = now.saturating_duration_since(origin).as_nanos();
    let period = every.as_nanos().max(1);
    let periods = since.div_ceil(period);
    let at =
        Duration::from_nanos(u64::try_from(periods.saturating_mul(period)).unwrap_or(u64::MAX));
    origin.checked_add(at).unwrap_or(now)
}

/// The next sample time of a subscription: one period after the last due time, so that the
/// loop's lateness does not stretch the period (1 kHz stays 1 kHz); after a stall of more
/// than a period the missed samples are skipped, not sent in a burst, and the next stays on
/// the subscription's grid of periods ([`first_due`]).
fn next_due(due: Instant, every: Duration, now: Instant) -> Instant {
    let next = due + every;
    if next > now {
        return next;
    }
    let behind = now.saturating_duration_since(next).as_nanos();
    let period = every.as_nanos().max(1);
    let skipped = behind / period + 1;
    let ahead =
        Duration::from_nanos(u64::try_from(skipped.saturating_mul(period)).unwrap_or(u64::MAX));
    next.checked_add(ahead).unwrap_or(now + every)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sample_rides_on_a_turn_due_soon_after_it() {
        let t0 = Instant::now();
        let us = Duration::from_micros;
        // The drives step 300 µs after the sample is due: no wake-up of its own.
        assert_eq!(
            with_samples(Some(t0 + us(300)), Some(t0)),
            Some(t0 + us(300))
        );
        // A turn before the sample is the loop's next turn anyway.
        assert_eq!(with_samples(Some(t0), Some(t0 + us(300))), Some(t0));
        // Nothing due within SAMPLE_RIDE: the loop wakes for the sample.
        assert_eq!(with_samples(Some(t0 + us(1500)), Some(t0)), Some(t0));
        assert_eq!(with_samples(None, Some(t0)), Some(t0));
        assert_eq!(with_samples(Some(t0), None), Some(t0));
    }

    #[test]
    fn a_late_sample_does_not_stretch_the_period() {
        let t0 = Instant::now();
        let ms = Duration::from_millis(1);
        // Served 60 µs late: the next is still due at 2 ms.
        assert_eq!(
            next_due(t0 + ms, ms, t0 + ms + Duration::from_micros(60)),
            t0 + 2 * ms
        );
        // Served 5 ms late: the missed ones are skipped.
        assert_eq!(next_due(t0 + ms, ms, t0 + 6 * ms), t0 + 7 * ms);
        // Served 5.3 ms late: skipped up to the grid's next instant, not 1 ms after `now`.
        let late = t0 + 6 * ms + Duration::from_micros(300);
        assert_eq!(next_due(t0 + ms, ms, late), t0 + 7 * ms);
    }

    #[test]
    fn subscriptions_of_one_period_share_their_due_times() {
        let origin = Instant::now();
        let ms = Duration::from_millis(1);
        let us = Duration::from_micros(1);
        // Tabs that subscribed at 3.2 ms, 3.9 ms and 4.0 ms are all first due at 4 ms.
        for at in [3200 * us, 3900 * us, 4 * ms] {
            assert_eq!(first_due(origin, ms, origin + at), origin + 4 * ms);
        }
        // Each is then due on the same grid, late or not.
        let mut a = first_due(origin, ms, origin + 3200 * us);
        let mut b = first_due(origin, ms, origin + 3900 * us);
        for now in [4 * ms + 30 * us, 5 * ms + 700 * us, 9 * ms + 100 * us] {
            a = next_due(a, ms, origin + now);
            b = next_due(b, ms, origin + now);
            assert_eq!(a, b);
            assert_eq!(a.duration_since(origin).as_nanos() % ms.as_nanos(), 0);
        }
        // A 2 ms subscription lands on every other of the 1 ms instants.
        assert_eq!(
            first_due(origin, 2 * ms, origin + 3200 * us),
            origin + 4 * ms
        );
    }
}
