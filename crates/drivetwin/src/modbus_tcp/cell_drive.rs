//! A drive served over Modbus TCP as the cell loop ([`crate::cell_loop`]) serves it: the
//! device ([`ModbusDevice`], its register map and its cycle on the cell's clock) and the
//! state of its one Modbus TCP connection (framer, watchdog). The loop owns the sockets; this
//! module holds what happens to the bytes and when the device steps.
//!
//! It keeps the rules of the other two servers ([`crate::modbus_tcp::cycle_server`],
//! [`crate::modbus_tcp::server`]): one connection at a time, the watchdog, exceptions, and
//! the ADU handling they share (`server::answer_all`). The device steps before a request that
//! finds a cycle due is answered, so an answer shows the device as of now.

use std::io;
use std::net::SocketAddr;
use std::sync::Mutex;
use std::time::Duration;

use od::Instant;

use modbus::{CloseReason, ConnectionEvent, Framer, Watchdog};

use crate::cell::modbus_device::ModbusDevice;
use crate::modbus_tcp::server::{answer_all, lock, ModbusConfig};

/// One drive of a cell served over Modbus TCP, with the listener of its server.
pub struct ModbusDrive {
    listener: Option<std::net::TcpListener>,
    device: Mutex<Box<dyn ModbusDevice>>,
    cycle: Duration,
    config: ModbusConfig,
    next_cycle: Instant,
    connection: Option<ConnectionState>,
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
    pub fn without_listener(
        mut device: Box<dyn ModbusDevice>,
        config: ModbusConfig,
    ) -> ModbusDrive {
        // One cycle before the first client: the registers show the power-on state (the
        // CMMO-ST's SCON 10h, SPOS 04h) from the very first request.
        device.step(od::Instant::ZERO);
        let cycle = device.cycle();
        ModbusDrive {
            listener: None,
            device: Mutex::new(device),
            cycle,
            config,
            next_cycle: Instant::ZERO,
            connection: None,
        }
    }

    /// The device, for the control handle and the scenario rig.
    pub fn device_mut(&mut self) -> &mut dyn ModbusDevice {
        let device = self.device.get_mut().unwrap_or_else(|p| p.into_inner());
        &mut **device
    }

    /// The device's shaft, current and status now.
    pub fn readout(&self) -> crate::cell::modbus_device::Readout {
        lock(&self.device).readout()
    }

    /// Why the device's load stopped it, once it has.
    pub fn load_failure(&self) -> Option<String> {
        lock(&self.device).load_failure().map(|e| e.to_string())
    }

    /// Its device file.
    pub fn description(&self) -> &'static od::DeviceDescription {
        lock(&self.device).description()
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

    /// When the device's next cycle is due, on the cell's clock.
    pub fn next_cycle(&self) -> Instant {
        self.next_cycle
    }

    /// Steps the device when a cycle is due, and looks at the watchdog: `true` when the
    /// connection has just been closed by it.
    pub fn cycle(&mut self, now: Instant) -> bool {
        if now < self.next_cycle {
            return false;
        }
        self.device_mut().step(now);
        // Cycles missed while the thread was not scheduled are not made up here: `step` itself
        // runs every cycle up to `now`.
        let next = self.next_cycle + self.cycle;
        self.next_cycle = if next > now { next } else { now + self.cycle };
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
            self.close_connection_because(CloseReason::WatchdogExpired);
        }
        expired
    }

    /// A client is now the one connection.
    pub fn open_connection(&mut self, now: Instant) {
        let mut watchdog = Watchdog::new(self.config.watchdog_ms);
        watchdog.start(0);
        self.connection = Some(ConnectionState {
            opened: now,
            watchdog,
            framer: Box::new(Framer::new()),
        });
        self.device_mut().connection_event(ConnectionEvent::Opened);
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
    ) -> Result<(), CloseReason> {
        let Some(c) = self.connection.as_mut() else {
            return Ok(());
        };
        let now_ms = ms(now, c.opened);
        let watchdog = &mut c.watchdog;
        answer_all(&mut c.framer, bytes, &self.device, out, || {
            watchdog.on_message(now_ms)
        })
    }

    /// The connection ended for `reason`: the device is told.
    pub fn close_connection_because(&mut self, reason: CloseReason) {
        if self.connection.take().is_some() {
            self.device_mut()
                .connection_event(ConnectionEvent::Closed(reason));
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
