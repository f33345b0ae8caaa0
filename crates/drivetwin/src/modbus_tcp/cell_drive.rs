//! A CMMO-ST as the cell loop ([`crate::cell_loop`]) serves it: the device, its Modbus
//! register map, its FHPP cycle (every millisecond on the cell's clock) and the state of its
//! one Modbus TCP connection (framer, watchdog). The loop owns the sockets; this module holds
//! what happens to the bytes and when the device steps.
//!
//! It keeps the rules of the other two servers ([`crate::modbus_tcp::cycle_server`],
//! [`crate::modbus_tcp::server`]): one connection at a time, the watchdog, exceptions, and
//! the ADU handling they share (`server::answer_all`). The device steps before a request that
//! finds a cycle due is answered, so an answer shows the device as of now.

use std::io;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use od::Instant;

use modbus::{CloseReason, ConnectionEvent, Framer, RegisterMap, Watchdog};

use crate::cell::param_store::ParamStore;
use crate::modbus_tcp::fhpp::{keep_memory, FhppModbus, SharedDevice, CYCLE};
use crate::modbus_tcp::server::{answer_all, lock, ModbusConfig};

/// One CMMO-ST of a cell, with the listener of its Modbus TCP server.
pub struct ModbusDrive {
    listener: Option<std::net::TcpListener>,
    device: SharedDevice,
    map: Mutex<FhppModbus>,
    config: ModbusConfig,
    store: Option<ParamStore>,
    generation: u32,
    next_cycle: Instant,
    connection: Option<ConnectionState>,
}

struct ConnectionState {
    opened: Instant,
    watchdog: Watchdog,
    framer: Box<Framer>,
}

impl ModbusDrive {
    /// `device` served on `listener` with `config`; its permanent memory kept in `store`.
    pub fn new(
        listener: std::net::TcpListener,
        device: SharedDevice,
        config: ModbusConfig,
        store: Option<ParamStore>,
    ) -> ModbusDrive {
        let mut d = ModbusDrive::without_listener(device, config, store);
        d.listener = Some(listener);
        d
    }

    /// A drive whose Modbus requests come from a script (the virtual clock's runs).
    pub fn without_listener(
        device: SharedDevice,
        config: ModbusConfig,
        store: Option<ParamStore>,
    ) -> ModbusDrive {
        // One cycle before the first client: the input telegram shows the power-on state
        // (SCON 10h, SPOS 04h) from the very first request.
        lock(&device).step(od::Instant::ZERO);
        let generation = lock(&device).permanent_memory().generation();
        let map = Mutex::new(FhppModbus::new(Arc::clone(&device)));
        ModbusDrive {
            listener: None,
            device,
            map,
            config,
            store,
            generation,
            next_cycle: Instant::ZERO,
            connection: None,
        }
    }

    pub fn device(&self) -> &SharedDevice {
        &self.device
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
        {
            let mut dev = lock(&self.device);
            dev.step(now);
            if let Some(store) = &self.store {
                keep_memory(&dev, store, &mut self.generation);
            }
        }
        // Cycles missed while the thread was not scheduled are not made up here: `step` itself
        // runs every cycle up to `now`.
        let next = self.next_cycle + CYCLE;
        self.next_cycle = if next > now { next } else { now + CYCLE };
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
        lock(&self.map).connection_event(ConnectionEvent::Opened);
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
        answer_all(&mut c.framer, bytes, &self.map, out, || {
            watchdog.on_message(now_ms)
        })
    }

    /// The connection ended for `reason`: the device is told.
    pub fn close_connection_because(&mut self, reason: CloseReason) {
        if self.connection.take().is_some() {
            lock(&self.map).connection_event(ConnectionEvent::Closed(reason));
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
