//! The Modbus TCP server: the async transport around the sans-IO codec of the `modbus`
//! crate. The device behind it is any [`RegisterMap`] shared as `Arc<Mutex<M>>`.
//!
//! Behaviour, with the CMMO-ST manual (GDCP-CMMO-ST-LK-C-HP-ZH) as the reference:
//!
//! - **One Modbus connection at a time** (§4: "最多只能同时进行一种 Modbus TCP 连接", at most one
//!   Modbus TCP connection). The manual does not say what a second client sees. Decision:
//!   it is accepted and closed at once, without a byte (the client reads end-of-file), so a
//!   client fails fast instead of hanging in the listen backlog. The connection being served
//!   is not disturbed. A connection whose client has just closed may still be winding down
//!   when the next client arrives; the server waits up to [`ModbusConfig::handover_grace`]
//!   for it before refusing.
//! - **The connection stays open** until the client closes it, the watchdog expires, or the
//!   server closes it (§4: closed only "on a controller error, on timeout, or by the remote
//!   peer").
//! - **Connection watchdog** ("Node Guard / Timeout", §4.3.4): every complete Modbus message
//!   restarts it, answered or not; when no message arrives within the timeout the server
//!   closes the connection and reports [`CloseReason::WatchdogExpired`] to the map, which
//!   raises "Timeout MODBUS TCP/IP": diagnostic 47h when Modbus held control authority, else
//!   48h (Appendix D). Timeout rules (0 = off, 1…99 ms act as 100 ms, at most 5000 ms) are
//!   [`modbus::watchdog`]'s. The timer starts when the connection opens.
//! - **Every request that is a Modbus TCP ADU is answered**, with the function's response
//!   or an exception response (unknown function code 01, quantities and lengths 03,
//!   addresses 02, device failure 04), and the connection carries on. Bytes that are no
//!   Modbus TCP ADU (a length field outside 2…254, protocol identifier ≠ 0; the Messaging
//!   Implementation Guide discards those) leave the server unable to find the next ADU, so
//!   it answers the ADUs before them and closes the connection
//!   ([`CloseReason::ProtocolError`]). A client that stops half-way through an ADU is closed
//!   by the watchdog, if enabled, or when it closes. Either way the server goes on serving.
//! - **Bounded memory per connection**: a [`Framer`] of two maximal ADUs, a fixed read buffer,
//!   and a response buffer written out after each read; a client that does not read its
//!   responses is dropped after [`ModbusConfig::write_timeout`].
//! - The unit identifier is not checked (Tab. 4.1: "may be ignored") and is echoed.
//!
//! The map is locked for the handling of one request and for each connection event, never
//! across an `await`. A map that panicked (poisoned mutex) is used as it is: the device
//! decides whether its state is still good.
//!
//! The bind address is the caller's (`drivetwin` binds [`DEFAULT_ADDR`] unless told
//! otherwise; 502 is the standard port, which needs privileges).

use std::net::SocketAddr;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use modbus::{
    handle_adu, CloseReason, ConnectionEvent, Framer, RegisterMap, Watchdog, MAX_ADU_LEN,
};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::task::JoinSet;
use tokio::time::Instant;
use tracing::Instrument;

/// Where `drivetwin` listens for Modbus TCP unless told otherwise (loopback, unprivileged).
pub const DEFAULT_ADDR: &str = "127.0.0.1:1502";
/// The registered Modbus TCP port (the CMMO-ST factory setting, §4).
pub const STANDARD_PORT: u16 = 502;

/// Read buffer per connection.
const READ_BUF: usize = 2048;

/// Settings of a Modbus TCP server.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModbusConfig {
    /// Connection watchdog timeout as configured on the device, ms (§4.3.4): 0 = off (the
    /// factory setting: "100 ms, not activated"), 1…99 act as 100, at most 5000.
    pub watchdog_ms: u16,
    /// Longest time writing a response may block before the client is dropped.
    pub write_timeout: Duration,
    /// How long a new client waits for a connection that is closing before it is refused.
    pub handover_grace: Duration,
    /// Spin on the connection instead of sleeping until the kernel wakes the server: the
    /// lowest latency (a controller's fieldbus task never sleeps), at the price of one CPU.
    pub busy_poll: bool,
}

impl Default for ModbusConfig {
    fn default() -> Self {
        ModbusConfig {
            watchdog_ms: 0,
            write_timeout: Duration::from_secs(5),
            handover_grace: Duration::from_millis(50),
            busy_poll: false,
        }
    }
}

impl ModbusConfig {
    /// The default settings with the watchdog set to `ms`.
    pub fn with_watchdog_ms(ms: u16) -> ModbusConfig {
        ModbusConfig {
            watchdog_ms: ms,
            ..ModbusConfig::default()
        }
    }
}

/// Accepts Modbus TCP clients on `listener` forever, one at a time, serving `map`.
///
/// Dropping the returned future (e.g. aborting its task) closes the connection being served;
/// the map then gets no `Closed` event.
pub async fn serve<M>(listener: TcpListener, map: Arc<Mutex<M>>, config: ModbusConfig)
where
    M: RegisterMap + Send + ?Sized + 'static,
{
    let config = Arc::new(config);
    match listener.local_addr() {
        Ok(addr) => {
            tracing::info!(%addr, watchdog_ms = config.watchdog_ms, "Modbus TCP server listening")
        }
        Err(e) => tracing::info!(error = %e, "Modbus TCP server listening"),
    }
    // The one connection being served (a JoinSet, so that dropping `serve` aborts it).
    let mut active: JoinSet<()> = JoinSet::new();
    loop {
        tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((stream, peer)) => {
                    if !active.is_empty() && !wait_for_close(&mut active, config.handover_grace).await {
                        tracing::warn!(%peer, "Modbus: one connection at a time, refusing");
                        drop(stream);
                        continue;
                    }
                    if let Err(e) = stream.set_nodelay(true) {
                        tracing::debug!(%peer, error = %e, "could not set TCP_NODELAY");
                    }
                    let map = Arc::clone(&map);
                    let config = Arc::clone(&config);
                    active.spawn(
                        session(stream, peer, map, config)
                            .instrument(tracing::info_span!("modbus", %peer)),
                    );
                }
                Err(e) => {
                    // E.g. out of file descriptors: back off instead of spinning.
                    tracing::warn!(error = %e, "Modbus: accept failed");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                }
            },
            Some(done) = active.join_next(), if !active.is_empty() => log_join(done),
        }
    }
}

/// Waits up to `grace` for the active session to end; `true` if it did.
async fn wait_for_close(active: &mut JoinSet<()>, grace: Duration) -> bool {
    match tokio::time::timeout(grace, active.join_next()).await {
        Ok(Some(done)) => {
            log_join(done);
            true
        }
        Ok(None) => true,
        Err(_) => false,
    }
}

fn log_join(done: Result<(), tokio::task::JoinError>) {
    if let Err(e) = done {
        if e.is_panic() {
            tracing::error!(error = %e, "Modbus session panicked");
        }
    }
}

pub(crate) fn lock<M: ?Sized>(map: &Mutex<M>) -> MutexGuard<'_, M> {
    map.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

async fn session<M>(
    stream: TcpStream,
    peer: SocketAddr,
    map: Arc<Mutex<M>>,
    config: Arc<ModbusConfig>,
) where
    M: RegisterMap + Send + ?Sized,
{
    tracing::info!("client connected");
    lock(&map).connection_event(ConnectionEvent::Opened);
    let reason = run_connection(stream, &map, &config).await;
    match reason {
        CloseReason::Peer => tracing::info!("client disconnected"),
        CloseReason::WatchdogExpired => {
            tracing::warn!(watchdog_ms = config.watchdog_ms, %peer, "Modbus watchdog expired (Timeout MODBUS TCP/IP), connection closed")
        }
        other => tracing::warn!(reason = %other, "connection closed"),
    }
    lock(&map).connection_event(ConnectionEvent::Closed(reason));
}

/// Serves one connection until it ends; the stream is closed when this returns.
async fn run_connection<M>(
    mut stream: TcpStream,
    map: &Mutex<M>,
    config: &ModbusConfig,
) -> CloseReason
where
    M: RegisterMap + Send + ?Sized,
{
    let origin = Instant::now();
    let now_ms = || u64::try_from(origin.elapsed().as_millis()).unwrap_or(u64::MAX);
    let mut watchdog = Watchdog::new(config.watchdog_ms);
    watchdog.start(0);
    let mut framer = Box::new(Framer::new());
    let mut rbuf = vec![0u8; READ_BUF];
    // Responses to the ADUs of one read, written together; at most one per 8 bytes read.
    let mut wbuf: Vec<u8> = Vec::with_capacity(4 * MAX_ADU_LEN);
    loop {
        let deadline = watchdog
            .deadline_ms()
            .map(|ms| origin + Duration::from_millis(ms));
        let read = if config.busy_poll {
            spin_read(&stream, &mut rbuf, deadline).await
        } else {
            tokio::select! {
                read = stream.read(&mut rbuf) => Some(read),
                () = sleep_until(deadline) => None,
            }
        };
        let n = match read {
            Some(Ok(0)) => return CloseReason::Peer,
            Some(Ok(n)) => n,
            Some(Err(e)) => {
                tracing::debug!(error = %e, "read failed");
                return CloseReason::Peer;
            }
            None => {
                if watchdog.poll(now_ms()) {
                    return CloseReason::WatchdogExpired;
                }
                continue;
            }
        };
        let failure = answer_all(
            &mut framer,
            rbuf.get(..n).unwrap_or(&[]),
            map,
            &mut wbuf,
            || watchdog.on_message(now_ms()),
        )
        .err();
        if !wbuf.is_empty() {
            // Fast path: the socket buffer takes the answer at once (no timer to arm); the
            // timed write only for what it did not take.
            let done = match stream.try_write(&wbuf) {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => 0,
                Err(e) => {
                    tracing::debug!(error = %e, "write failed");
                    return CloseReason::Peer;
                }
            };
            let rest = wbuf.get(done..).unwrap_or(&[]);
            let written = if rest.is_empty() {
                Ok(Ok(()))
            } else {
                tokio::time::timeout(config.write_timeout, stream.write_all(rest)).await
            };
            wbuf.clear();
            match written {
                Ok(Ok(())) => {}
                Ok(Err(e)) => {
                    tracing::debug!(error = %e, "write failed");
                    return CloseReason::Peer;
                }
                Err(_) => return CloseReason::Transport,
            }
        }
        if let Some(reason) = failure {
            return reason;
        }
    }
}

/// Answers every complete ADU of `bytes` (with what `framer` held before), appending the
/// responses to `out` and calling `on_message` for each ADU; the ADUs before a byte stream
/// that is no Modbus TCP are answered, then the connection is to be closed (the error).
/// Shared by both transports ([`serve`] and [`crate::modbus_tcp::cycle_server`]); `map` is
/// locked for each ADU.
pub(crate) fn answer_all<M>(
    framer: &mut Framer,
    bytes: &[u8],
    map: &Mutex<M>,
    out: &mut Vec<u8>,
    on_message: impl FnMut(),
) -> Result<(), CloseReason>
where
    M: RegisterMap + ?Sized,
{
    answer_each(framer, bytes, out, on_message, |adu, response| {
        handle_adu(adu, &mut *lock(map), response)
    })
}

/// As [`answer_all`] on a map the caller holds (the cell loop's, a station's drive).
pub(crate) fn answer_all_on<M>(
    framer: &mut Framer,
    bytes: &[u8],
    map: &mut M,
    out: &mut Vec<u8>,
    on_message: impl FnMut(),
) -> Result<(), CloseReason>
where
    M: RegisterMap + ?Sized,
{
    answer_each(framer, bytes, out, on_message, |adu, response| {
        handle_adu(adu, map, response)
    })
}

fn answer_each(
    framer: &mut Framer,
    mut bytes: &[u8],
    out: &mut Vec<u8>,
    mut on_message: impl FnMut(),
    mut handle: impl FnMut(&[u8], &mut [u8]) -> Result<usize, modbus::AduError>,
) -> Result<(), CloseReason> {
    let mut response = [0u8; MAX_ADU_LEN];
    while !bytes.is_empty() {
        let taken = framer.push(bytes);
        bytes = bytes.get(taken..).unwrap_or(&[]);
        loop {
            match framer.next_adu() {
                Ok(Some(adu)) => {
                    on_message();
                    match handle(adu, &mut response) {
                        Ok(len) => out.extend_from_slice(response.get(..len).unwrap_or(&[])),
                        Err(e) => {
                            tracing::warn!(error = %e, "not a Modbus TCP ADU");
                            return Err(CloseReason::ProtocolError);
                        }
                    }
                }
                Ok(None) => break,
                Err(e) => {
                    tracing::warn!(error = %e, "not a Modbus TCP stream");
                    return Err(CloseReason::ProtocolError);
                }
            }
        }
    }
    Ok(())
}

/// Reads by trying again and again (yielding to the runtime's other tasks in between) until
/// data comes, the connection fails, or `deadline` passes (`None`).
async fn spin_read(
    stream: &TcpStream,
    buf: &mut [u8],
    deadline: Option<Instant>,
) -> Option<std::io::Result<usize>> {
    loop {
        match stream.try_read(buf) {
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if deadline.is_some_and(|d| Instant::now() >= d) {
                    return None;
                }
                std::hint::spin_loop();
                tokio::task::yield_now().await;
            }
            r => return Some(r),
        }
    }
}

async fn sleep_until(at: Option<Instant>) {
    match at {
        Some(at) => tokio::time::sleep_until(at).await,
        None => std::future::pending().await,
    }
}
