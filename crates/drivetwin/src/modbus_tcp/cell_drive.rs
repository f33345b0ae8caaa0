//! A drive served over Modbus TCP as the cell loop ([`crate::cell_loop`]) serves it: its
//! Modbus TCP front end, the state of its one connection (framer, watchdog), reaching the
//! drive by its station's id. The drive (a [`RegisterImage`]: the device, its register map
//! and its cycle on the cell's clock) is a station of the cell once the front end has joined
//! it ([`ModbusDrive::join`]); until then the front end holds it. The loop owns the sockets;
//! this module holds what happens to the bytes and when the device steps.
//!
//! It keeps the rules of the other two servers ([`crate::modbus_tcp::cycle_server`],
//! [`crate::modbus_tcp::server`]): one connection at a time, the watchdog, exceptions, and
//! the ADU handling they share (`server::answer_all_on`). The device steps before a request
//! that finds a cycle due is answered, so an answer shows the device as of now.

use std::io;
use std::net::SocketAddr;
use std::time::Duration;

use od::Instant;

use modbus::{CloseReason, ConnectionEvent, Framer, Watchdog};

use crate::cell::modbus_device::{ModbusDevice, Readout, RegisterImage};
use crate::cell::station::Station;
use crate::cell::stations::{StationId, Stations};
use crate::modbus_tcp::server::{answer_all_on, ModbusConfig};

/// One drive of a cell served over Modbus TCP, with the listener of its server.
pub struct ModbusDrive {
    listener: Option<std::net::TcpListener>,
    drive: Placement,
    config: ModbusConfig,
    connection: Option<ConnectionState>,
}

/// Where the drive is: the front end's own until it joins the cell, then a station.
enum Placement {
    Own(Box<RegisterImage>),
    Station(StationId),
}

struct ConnectionState {
    opened: Instant,
    watchdog: Watchdog,
    framer: Box<Framer>,
}

impl ModbusDrive {
    /// `device` served on `listener` with `config`.
    pub fn new(
        listener: std::net::TcpListener,
        device: Box<dyn ModbusDevice>,
        config: ModbusConfig,
    ) -> ModbusDrive {
        let mut d = ModbusDrive::without_listener(device, config);
        d.listener = Some(listener);
        d
    }

    /// A drive whose Modbus requests come from a script (the virtual clock's runs).
    pub fn without_listener(device: Box<dyn ModbusDevice>, config: ModbusConfig) -> ModbusDrive {
        ModbusDrive {
            listener: None,
            drive: Placement::Own(Box::new(RegisterImage::new(device))),
            config,
            connection: None,
        }
    }

    /// The drive joins `stations` as a station of its own (once): its id.
    pub fn join(&mut self, stations: &mut Stations) -> Option<StationId> {
        if matches!(self.drive, Placement::Own(_)) {
            let next = Placement::Station(StationId::from_index(stations.len()));
            if let Placement::Own(image) = std::mem::replace(&mut self.drive, next) {
                self.drive = Placement::Station(stations.push(Station::register_image(*image)));
            }
        }
        self.station()
    }

    /// Its station, once it has joined the cell.
    pub fn station(&self) -> Option<StationId> {
        match self.drive {
            Placement::Station(id) => Some(id),
            Placement::Own(_) => None,
        }
    }

    /// The drive, in `stations` once it has joined them.
    pub fn image<'a>(&'a self, stations: &'a Stations) -> Option<&'a RegisterImage> {
        match &self.drive {
            Placement::Own(image) => Some(image),
            Placement::Station(id) => stations.station(*id)?.model.register_image(),
        }
    }

    /// The drive, in `stations` once it has joined them.
    pub fn image_mut<'a>(
        &'a mut self,
        stations: &'a mut Stations,
    ) -> Option<&'a mut RegisterImage> {
        image_in(&mut self.drive, stations)
    }

    /// The device, for the control handle and the scenario rig.
    pub fn device_mut<'a>(
        &'a mut self,
        stations: &'a mut Stations,
    ) -> Option<&'a mut dyn ModbusDevice> {
        self.image_mut(stations).map(RegisterImage::device_mut)
    }

    /// The device's shaft, current and status now.
    pub fn readout(&self, stations: &Stations) -> Option<Readout> {
        self.image(stations).map(|i| i.device().readout())
    }

    /// Why the device's load stopped it, once it has.
    pub fn load_failure(&self, stations: &Stations) -> Option<String> {
        self.image(stations)?
            .device()
            .load_failure()
            .map(|e| e.to_string())
    }

    /// Its device file.
    pub fn description(&self, stations: &Stations) -> Option<&'static od::DeviceDescription> {
        self.image(stations).map(|i| i.device().description())
    }

    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.listener.as_ref().and_then(|l| l.local_addr().ok())
    }

    /// The listener, for the loop to register (once).
    pub(crate) fn take_listener(&mut self) -> io::Result<mio::net::TcpListener> {
        let l = self
            .listener
            .take()
            .ok_or_else(|| io::Error::other("Modbus listener already taken"))?;
        l.set_nonblocking(true)?;
        Ok(mio::net::TcpListener::from_std(l))
    }

    /// When the device's next cycle is due, on the cell's clock (none: the drive is not in
    /// `stations`).
    pub fn next_cycle(&self, stations: &Stations) -> Option<Instant> {
        self.image(stations).map(RegisterImage::next_cycle)
    }

    /// Steps the device when a cycle is due, and looks at the watchdog: `true` when the
    /// connection has just been closed by it.
    pub fn cycle(&mut self, now: Instant, stations: &mut Stations) -> bool {
        let stepped = self
            .image_mut(stations)
            .is_some_and(|image| image.step_due(now));
        if !stepped {
            return false;
        }
        let expired = match self.connection.as_mut() {
            Some(c) => {
                let ms = ms(now, c.opened);
                c.watchdog.poll(ms)
            }
            None => false,
        };
        if expired {
            tracing::warn!(
                watchdog_ms = self.config.watchdog_ms,
                "Modbus watchdog expired (Timeout MODBUS TCP/IP), connection closed"
            );
            self.close_connection_because(CloseReason::WatchdogExpired, stations);
        }
        expired
    }

    /// A client is now the one connection.
    pub fn open_connection(&mut self, now: Instant, stations: &mut Stations) {
        let mut watchdog = Watchdog::new(self.config.watchdog_ms);
        watchdog.start(0);
        self.connection = Some(ConnectionState {
            opened: now,
            watchdog,
            framer: Box::new(Framer::new()),
        });
        if let Some(device) = self.device_mut(stations) {
            device.connection_event(ConnectionEvent::Opened);
        }
    }

    /// Whether a connection is open (the watchdog or an error may have closed it).
    pub fn has_connection(&self) -> bool {
        self.connection.is_some()
    }

    /// Answers the complete ADUs of `bytes` into `out`; an error: close the connection.
    pub fn answer(
        &mut self,
        bytes: &[u8],
        now: Instant,
        out: &mut Vec<u8>,
        stations: &mut Stations,
    ) -> Result<(), CloseReason> {
        let ModbusDrive {
            drive, connection, ..
        } = self;
        let Some(c) = connection.as_mut() else {
            return Ok(());
        };
        let Some(image) = image_in(drive, stations) else {
            return Ok(());
        };
        let now_ms = ms(now, c.opened);
        let watchdog = &mut c.watchdog;
        answer_all_on(&mut c.framer, bytes, image.device_mut(), out, || {
            watchdog.on_message(now_ms)
        })
    }

    /// The connection ended for `reason`: the device is told.
    pub fn close_connection_because(&mut self, reason: CloseReason, stations: &mut Stations) {
        if self.connection.take().is_some() {
            if let Some(device) = self.device_mut(stations) {
                device.connection_event(ConnectionEvent::Closed(reason));
            }
        }
    }

    /// The loop stops: the connection goes without a `Closed` event, as the other servers do
    /// when they are dropped.
    pub(crate) fn close_connection(&mut self) {
        self.connection = None;
    }

    /// Longest a client may leave answers unread (`ModbusConfig::write_timeout`).
    pub fn write_timeout(&self) -> Duration {
        self.config.write_timeout
    }
}

fn ms(now: Instant, since: Instant) -> u64 {
    now.as_nanos().saturating_sub(since.as_nanos()) / 1_000_000
}

/// The drive `drive` places, in `stations` once it has joined them.
fn image_in<'a>(
    drive: &'a mut Placement,
    stations: &'a mut Stations,
) -> Option<&'a mut RegisterImage> {
    match drive {
        Placement::Own(image) => Some(image),
        Placement::Station(id) => stations.station_mut(*id)?.model.register_image_mut(),
    }
}
