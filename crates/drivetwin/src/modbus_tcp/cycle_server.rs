//! The Modbus TCP server run by a device's own cycle thread, as a controller's fieldbus task
//! runs: the thread blocks in `read` on the one connection until a request comes or the
//! device's next cycle is due, answers, and steps the device on time. No readiness
//! notification (epoll) and no runtime sit between the kernel's wake-up and the answer, which
//! is the lowest request latency a sleeping server gets: on a 2-vCPU virtual machine, one CPU,
//! `benches/modbus_loopback.rs` measures p50 6.4 µs per round trip against 7.3 µs through a
//! tokio task, and 6.1…6.4 µs for a bare blocking echo server.
//!
//! It keeps every rule of the async server [`crate::modbus_tcp::server`] (one connection at a
//! time, the second client closed at once, watchdog, exceptions, bounded memory, a client that
//! does not read its answers dropped after the write timeout) and shares its ADU handling
//! (`server::answer_all`). What differs is only when things are looked at:
//!
//! - The device steps at every wake-up that finds a cycle due, before the request that woke
//!   the thread is answered, so an answer always shows the device as of now. A wake-up comes
//!   with a request or with the read timeout (one cycle; the kernel rounds it up to its tick,
//!   4 ms at 250 Hz): when no client talks, the device catches up cycle by cycle (its `step`
//!   runs every missed cycle) up to one kernel tick late, which nobody on the wire can see.
//! - New clients and the watchdog are looked at once per cycle, so a second client is closed
//!   and a silent one timed out within a cycle (plus a kernel tick) of the moment, not at it.
//! - Answers are written without blocking (`MSG_DONTWAIT`); what the socket does not take is
//!   kept, no further request is read until it is gone, and the client is dropped when it has
//!   not taken it within [`ModbusConfig::write_timeout`]. The device goes on stepping.
//!
//! With [`ModbusConfig::busy_poll`] the thread never sleeps: it reads without blocking, again
//! and again.

use std::io::{self, Read};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::os::fd::{AsFd, BorrowedFd};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use modbus::{CloseReason, ConnectionEvent, Framer, RegisterMap, Watchdog, MAX_ADU_LEN};

use crate::modbus_tcp::server::{answer_all, lock, ModbusConfig};

/// Read buffer of the connection.
const READ_BUF: usize = 2048;

/// Serves Modbus TCP clients on `listener`, one at a time, and calls `step` with the present
/// time whenever one or more cycles of `period` are due, on the calling thread, until `stop` is
/// set (looked at at least once per cycle). The connection being served when it stops is
/// closed without a `Closed` event, as the async server does when it is dropped.
pub fn serve<M>(
    listener: TcpListener,
    map: &Mutex<M>,
    config: &ModbusConfig,
    period: Duration,
    stop: &AtomicBool,
    mut step: impl FnMut(Instant),
) where
    M: RegisterMap + ?Sized,
{
    let period = period.max(Duration::from_micros(100));
    if let Err(e) = listener.set_nonblocking(true) {
        tracing::error!(error = %e, "Modbus listener");
        return;
    }
    match listener.local_addr() {
        Ok(addr) => {
            tracing::info!(%addr, watchdog_ms = config.watchdog_ms, "Modbus TCP server listening")
        }
        Err(e) => tracing::info!(error = %e, "Modbus TCP server listening"),
    }
    let mut next_cycle = Instant::now();
    let mut active: Option<Connection> = None;
    let mut rbuf = [0u8; READ_BUF];
    while !stop.load(Ordering::Relaxed) {
        let read = match active.as_mut() {
            Some(conn) => conn.wait(&mut rbuf, config, next_cycle),
            None => {
                sleep_until(next_cycle);
                Ok(0)
            }
        };
        let now = Instant::now();
        let cycle_due = now >= next_cycle;
        if cycle_due {
            // Before the request is answered: the answer shows the device as of now.
            step(now);
            next_cycle = following_cycle(next_cycle, now, period);
        }
        let outcome = match (read, active.as_mut()) {
            (Ok(0), _) | (_, None) => Ok(()),
            (Ok(n), Some(conn)) => conn.answer(rbuf.get(..n).unwrap_or(&[]), map),
            (Err(reason), Some(_)) => Err(reason),
        };
        if let Err(reason) = outcome {
            close(&mut active, map, reason, config);
        }
        if cycle_due {
            if let Some(reason) = active.as_mut().and_then(|c| c.overdue(now, config)) {
                close(&mut active, map, reason, config);
            }
            accept(&listener, &mut active, map, config, period);
        }
    }
}

/// The cycle after `due` that is still ahead of `now` (cycles missed while the thread was not
/// scheduled are not made up: `step` itself runs every cycle up to `now`).
fn following_cycle(due: Instant, now: Instant, period: Duration) -> Instant {
    let next = due + period;
    if next > now {
        next
    } else {
        now + period
    }
}

fn sleep_until(at: Instant) {
    let now = Instant::now();
    if at > now {
        std::thread::sleep(at - now);
    }
}

/// Takes a waiting client: served when no other is, else closed at once without a byte
/// (the CMMO-ST's one-connection rule, see [`crate::modbus_tcp::server`]). A served connection
/// whose client has already closed it gives way to the new one.
fn accept<M>(
    listener: &TcpListener,
    active: &mut Option<Connection>,
    map: &Mutex<M>,
    config: &ModbusConfig,
    period: Duration,
) where
    M: RegisterMap + ?Sized,
{
    loop {
        let (stream, peer) = match listener.accept() {
            Ok(accepted) => accepted,
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => return,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => {
                // E.g. out of file descriptors: try again next cycle.
                tracing::warn!(error = %e, "Modbus: accept failed");
                return;
            }
        };
        if active.as_ref().is_some_and(Connection::peer_has_closed) {
            close(active, map, CloseReason::Peer, config);
        }
        if active.is_some() {
            tracing::warn!(%peer, "Modbus: one connection at a time, refusing");
            drop(stream);
            continue;
        }
        match Connection::open(stream, peer, config, period) {
            Ok(conn) => {
                tracing::info!(%peer, "client connected");
                lock(map).connection_event(ConnectionEvent::Opened);
                *active = Some(conn);
            }
            Err(e) => tracing::warn!(%peer, error = %e, "Modbus: cannot set up the connection"),
        }
    }
}

fn close<M>(
    active: &mut Option<Connection>,
    map: &Mutex<M>,
    reason: CloseReason,
    config: &ModbusConfig,
) where
    M: RegisterMap + ?Sized,
{
    let Some(conn) = active.take() else {
        return;
    };
    let peer = conn.peer;
    match reason {
        CloseReason::Peer => tracing::info!(%peer, "client disconnected"),
        CloseReason::WatchdogExpired => tracing::warn!(
            watchdog_ms = config.watchdog_ms,
            %peer,
            "Modbus watchdog expired (Timeout MODBUS TCP/IP), connection closed"
        ),
        other => tracing::warn!(%peer, reason = %other, "connection closed"),
    }
    drop(conn);
    lock(map).connection_event(ConnectionEvent::Closed(reason));
}

/// The connection being served.
struct Connection {
    stream: TcpStream,
    peer: SocketAddr,
    origin: Instant,
    watchdog: Watchdog,
    framer: Box<Framer>,
    /// Answers not yet taken by the socket.
    pending: Vec<u8>,
    /// Since when `pending` has waited for the socket to take it.
    stalled_since: Option<Instant>,
}

impl Connection {
    /// Reads block for at most `period` (the device's cycle), or not at all when spinning.
    fn open(
        stream: TcpStream,
        peer: SocketAddr,
        config: &ModbusConfig,
        period: Duration,
    ) -> io::Result<Self> {
        stream.set_nonblocking(config.busy_poll)?;
        if !config.busy_poll {
            stream.set_read_timeout(Some(period))?;
        }
        if let Err(e) = stream.set_nodelay(true) {
            tracing::debug!(%peer, error = %e, "could not set TCP_NODELAY");
        }
        let mut watchdog = Watchdog::new(config.watchdog_ms);
        watchdog.start(0);
        Ok(Connection {
            stream,
            peer,
            origin: Instant::now(),
            watchdog,
            framer: Box::new(Framer::new()),
            pending: Vec::with_capacity(4 * MAX_ADU_LEN),
            stalled_since: None,
        })
    }

    fn now_ms(&self, now: Instant) -> u64 {
        u64::try_from(now.saturating_duration_since(self.origin).as_millis()).unwrap_or(u64::MAX)
    }

    /// Waits for a request until about `until` (blocking read with the cycle as timeout, one
    /// non-blocking try when spinning): the bytes read (0: none yet) or why the connection
    /// ended. While answers are pending it waits for the socket to take them instead.
    fn wait(
        &mut self,
        buf: &mut [u8],
        config: &ModbusConfig,
        until: Instant,
    ) -> Result<usize, CloseReason> {
        if !self.pending.is_empty() {
            wait_writable(self.stream.as_fd(), until);
            return self.flush().map(|()| 0);
        }
        match self.stream.read(buf) {
            Ok(0) => Err(CloseReason::Peer),
            Ok(n) => Ok(n),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock
                        | io::ErrorKind::TimedOut
                        | io::ErrorKind::Interrupted
                ) =>
            {
                if config.busy_poll {
                    std::hint::spin_loop();
                }
                Ok(0)
            }
            Err(e) => {
                tracing::debug!(error = %e, "read failed");
                Err(CloseReason::Peer)
            }
        }
    }

    /// Answers the complete ADUs of `bytes` and hands the answers to the socket.
    fn answer<M>(&mut self, bytes: &[u8], map: &Mutex<M>) -> Result<(), CloseReason>
    where
        M: RegisterMap + ?Sized,
    {
        let now_ms = self.now_ms(Instant::now());
        let watchdog = &mut self.watchdog;
        let handled = answer_all(&mut self.framer, bytes, map, &mut self.pending, || {
            watchdog.on_message(now_ms)
        });
        // The answers before a broken stream still go out.
        let flushed = self.flush();
        handled.and(flushed)
    }

    /// Writes what the socket takes now without blocking; the rest stays pending.
    fn flush(&mut self) -> Result<(), CloseReason> {
        while !self.pending.is_empty() {
            match crate::sys::tcp::send_nonblocking(self.stream.as_fd(), &self.pending) {
                Ok(n) => {
                    self.pending.drain(..n.min(self.pending.len()));
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    self.stalled_since.get_or_insert_with(Instant::now);
                    return Ok(());
                }
                Err(e) => {
                    tracing::debug!(error = %e, "write failed");
                    return Err(CloseReason::Peer);
                }
            }
        }
        self.stalled_since = None;
        Ok(())
    }

    /// The watchdog expired, or the client has not taken its answers for too long.
    fn overdue(&mut self, now: Instant, config: &ModbusConfig) -> Option<CloseReason> {
        if self.watchdog.poll(self.now_ms(now)) {
            return Some(CloseReason::WatchdogExpired);
        }
        self.stalled_since
            .filter(|since| now.saturating_duration_since(*since) >= config.write_timeout)
            .map(|_| CloseReason::Transport)
    }

    /// Whether the client has closed its end (end of file waiting, nothing else).
    fn peer_has_closed(&self) -> bool {
        let mut byte = [0u8; 1];
        match crate::sys::tcp::peek_nonblocking(self.stream.as_fd(), &mut byte) {
            Ok(n) => n == 0,
            Err(e) => !matches!(
                e.kind(),
                io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
            ),
        }
    }
}

/// Waits until `fd` takes more data or `until` passes.
fn wait_writable(fd: BorrowedFd<'_>, until: Instant) {
    let ms = until
        .saturating_duration_since(Instant::now())
        .as_millis()
        .clamp(1, 1000);
    let wait = Duration::from_millis(u64::try_from(ms).unwrap_or(1000));
    let _ = crate::sys::fd::wait(fd, crate::sys::fd::Readiness::Writable, wait);
}
