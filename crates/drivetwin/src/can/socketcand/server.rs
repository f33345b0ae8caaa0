//! The socketcand TCP server: one task per client, each client one node on the [`Bus`].
//!
//! Session states follow socketcand: NO_BUS (after `< hi >`; `open` and the `B` / `C` bus
//! configuration commands) → BCM (default after `open`) ⇄ RAW / CONTROL. Only RAW streams bus
//! frames. BCM jobs and ISO-TP are answered with `< error ... >`; `send` works in BCM and RAW.
//!
//! python-can's client compares each handshake reply with one `recv(256)`, so every reply is
//! its own write, and after the `< ok >` to `rawmode` the server waits
//! [`ServerConfig::stream_delay`] before the first frame, so `< ok >< frame ... >` can never
//! arrive in one segment. Frames sent on the bus in that pause are delivered after it.
//!
//! Bad input never ends the server: a malformed message gets an `< error ... >` reply and the
//! session carries on; an over-long message is dropped with an error reply; a client that
//! asks for the wrong bus is told so and disconnected. Nothing from the wire is indexed
//! unchecked or unwrapped.

use std::io::{self, Write as _};
use std::sync::Arc;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::TcpListener;
use tokio::task::JoinSet;
use tokio::time::{Instant, Interval, MissedTickBehavior};
use tracing::Instrument;

use super::codec::{CodecError, Decoder, Message, Mode, MAX_MESSAGE_LEN};
use crate::can::bus::{Bus, BusFrame, Port};

/// socketcand's registered port.
pub const DEFAULT_PORT: u16 = 29536;

/// Frames written to a client in one write at most, when several are waiting.
const MAX_BATCH: usize = 64;

/// Shortest statistics interval honoured (socketcand polls every 10 ms).
const MIN_STATISTICS_INTERVAL: Duration = Duration::from_millis(10);

#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// The only bus name `open` accepts, e.g. `vcan0`.
    pub channel: String,
    /// Pause between the `< ok >` to `rawmode` and the first streamed frame.
    pub stream_delay: Duration,
    /// Longest accepted message, brackets included.
    pub max_message_len: usize,
    /// Clients served at once; more are sent `< error too many clients >` and closed.
    pub max_clients: usize,
}

impl ServerConfig {
    pub fn new(channel: impl Into<String>) -> ServerConfig {
        ServerConfig {
            channel: channel.into(),
            stream_delay: Duration::from_millis(75),
            max_message_len: MAX_MESSAGE_LEN,
            max_clients: 64,
        }
    }
}

/// Why a client session ended other than by the client closing the connection.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    #[error("connection error: {0}")]
    Io(#[from] io::Error),
    #[error("client asked for a bus that is not served")]
    UnknownChannel,
}

/// Accept clients on `listener` forever, each a node on `bus`, serving bus name `channel`.
///
/// Dropping the returned future (e.g. aborting its task) closes every client session.
pub async fn serve(listener: TcpListener, bus: Bus, channel: impl Into<String>) {
    serve_with(listener, bus, ServerConfig::new(channel)).await
}

/// [`serve`] with explicit settings.
pub async fn serve_with(listener: TcpListener, bus: Bus, config: ServerConfig) {
    let config = Arc::new(config);
    match listener.local_addr() {
        Ok(addr) => tracing::info!(%addr, channel = %config.channel, "socketcand server listening"),
        Err(e) => {
            tracing::info!(error = %e, channel = %config.channel, "socketcand server listening")
        }
    }
    let mut clients = JoinSet::new();
    loop {
        tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((stream, peer)) => {
                    if clients.len() >= config.max_clients {
                        tracing::warn!(%peer, max = config.max_clients, "socketcand: too many clients, refusing");
                        // Best effort, never blocks the accept loop.
                        let _ = stream.try_write(b"< error too many clients >");
                        continue;
                    }
                    if let Err(e) = stream.set_nodelay(true) {
                        tracing::debug!(%peer, error = %e, "could not set TCP_NODELAY");
                    }
                    let bus = bus.clone();
                    let config = Arc::clone(&config);
                    let span = tracing::info_span!("socketcand", %peer);
                    clients.spawn(
                        async move {
                            tracing::info!("client connected");
                            match handle_client(stream, bus, &config).await {
                                Ok(()) => tracing::info!("client disconnected"),
                                Err(e) => tracing::info!(error = %e, "client session ended"),
                            }
                        }
                        .instrument(span),
                    );
                }
                Err(e) => {
                    // E.g. out of file descriptors: back off instead of spinning.
                    tracing::warn!(error = %e, "socketcand: accept failed");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                }
            },
            Some(done) = clients.join_next(), if !clients.is_empty() => {
                if let Err(e) = done {
                    if e.is_panic() {
                        tracing::error!(error = %e, "socketcand client task panicked");
                    }
                }
            }
        }
    }
}

/// Run one client session on any byte stream (a `TcpStream`, or `tokio::io::duplex` in
/// tests) until the client disconnects. Returns `Ok(())` on a clean close by the client.
pub async fn handle_client<S>(
    stream: S,
    bus: Bus,
    config: &ServerConfig,
) -> Result<(), SessionError>
where
    S: AsyncRead + AsyncWrite + Unpin,
{
    let (mut reader, writer) = tokio::io::split(stream);
    let mut session = Session {
        out: writer,
        config,
        bus: &bus,
        port: None,
        mode: None,
        stream_at: None,
        streaming: false,
        statistics: None,
        sent_frames: 0,
        sent_bytes: 0,
        wbuf: Vec::with_capacity(MAX_BATCH * 48),
    };
    session.reply(&Message::Hi).await?;
    let mut decoder = Decoder::with_max_len(config.max_message_len);
    let mut rbuf = vec![0u8; 4096];
    loop {
        while let Some(message) = decoder.next_message() {
            if session.handle(message).await? == Flow::Close {
                return Ok(());
            }
        }
        tokio::select! {
            read = reader.read(&mut rbuf) => {
                let n = read?;
                if n == 0 {
                    return Ok(());
                }
                decoder.push(rbuf.get(..n).unwrap_or(&[]));
            }
            () = sleep_until(session.stream_at), if session.stream_at.is_some() => {
                session.stream_at = None;
                session.streaming = true;
            }
            Some(frame) = recv(&mut session.port), if session.streaming => {
                session.forward(frame).await?;
            }
            () = tick(&mut session.statistics), if session.statistics.is_some() => {
                session.report_statistics().await?;
            }
        }
    }
}

async fn sleep_until(at: Option<Instant>) {
    match at {
        Some(at) => tokio::time::sleep_until(at).await,
        None => std::future::pending().await,
    }
}

async fn recv(port: &mut Option<Port>) -> Option<BusFrame> {
    match port {
        Some(port) => port.recv().await,
        None => None,
    }
}

async fn tick(interval: &mut Option<Interval>) {
    match interval {
        Some(interval) => {
            interval.tick().await;
        }
        None => std::future::pending().await,
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Flow {
    Continue,
    Close,
}

struct Session<'a, W> {
    out: W,
    config: &'a ServerConfig,
    bus: &'a Bus,
    /// Attached on `open`.
    port: Option<Port>,
    /// `None` until the bus is open (socketcand's NO_BUS state).
    mode: Option<Mode>,
    /// RAW mode: when streaming starts.
    stream_at: Option<Instant>,
    streaming: bool,
    /// CONTROL mode: statistics timer.
    statistics: Option<Interval>,
    sent_frames: u64,
    sent_bytes: u64,
    wbuf: Vec<u8>,
}

impl<W: AsyncWrite + Unpin> Session<'_, W> {
    /// One message, one write: never coalesced with anything else.
    async fn reply(&mut self, message: &Message) -> io::Result<()> {
        self.out.write_all(message.to_string().as_bytes()).await?;
        self.out.flush().await
    }

    async fn error(&mut self, text: &str) -> io::Result<()> {
        self.reply(&Message::Error(text.to_owned())).await
    }

    async fn handle(&mut self, message: Result<Message, CodecError>) -> Result<Flow, SessionError> {
        let message = match message {
            Ok(m) => m,
            Err(e) => {
                tracing::debug!(error = %e, "bad message from client");
                self.error(&e.to_string()).await?;
                return Ok(Flow::Continue);
            }
        };
        tracing::trace!(?message, "from client");
        match (self.mode, message) {
            (_, Message::Echo) => self.reply(&Message::Echo).await?,
            (None, Message::Open(channel)) => {
                if channel != self.config.channel {
                    return self.refuse_channel(&channel).await;
                }
                self.port = Some(self.bus.port());
                self.mode = Some(Mode::Bcm);
                tracing::debug!(%channel, "bus opened");
                self.reply(&Message::Ok).await?;
            }
            (None, Message::BitTiming { channel, .. })
            | (None, Message::ControlModes { channel, .. }) => {
                if channel != self.config.channel {
                    return self.refuse_channel(&channel).await;
                }
                // A virtual bus has no bit timing or controller modes to set.
                self.reply(&Message::Ok).await?;
            }
            (Some(_), Message::Mode(Mode::Isotp)) => {
                self.error("isotp mode not supported").await?;
            }
            (Some(current), Message::Mode(mode)) => {
                if mode != current {
                    self.enter(mode);
                }
                self.reply(&Message::Ok).await?;
                if mode == Mode::Raw && mode != current {
                    self.stream_at = Some(Instant::now() + self.config.stream_delay);
                }
            }
            (Some(Mode::Raw | Mode::Bcm), Message::Send(frame)) => {
                if let Some(port) = &self.port {
                    port.send(frame);
                    self.sent_frames += 1;
                    self.sent_bytes += frame.payload().len() as u64;
                }
            }
            (Some(Mode::Control), Message::Statistics { interval_ms }) => {
                self.statistics = (interval_ms > 0).then(|| {
                    let period =
                        Duration::from_millis(u64::from(interval_ms)).max(MIN_STATISTICS_INTERVAL);
                    let mut interval = tokio::time::interval_at(Instant::now() + period, period);
                    interval.set_missed_tick_behavior(MissedTickBehavior::Delay);
                    interval
                });
            }
            (_, Message::Unsupported(command)) => {
                tracing::debug!(command, "unsupported socketcand command");
                self.error("command not supported").await?;
            }
            (_, other) => {
                tracing::debug!(message = ?other, mode = ?self.mode, "command not valid here");
                self.error("unknown command").await?;
            }
        }
        Ok(Flow::Continue)
    }

    async fn refuse_channel(&mut self, channel: &str) -> Result<Flow, SessionError> {
        tracing::info!(requested = %channel, served = %self.config.channel, "client asked for an unknown bus");
        self.error("could not open bus").await?;
        self.out.shutdown().await.ok();
        Err(SessionError::UnknownChannel)
    }

    /// Leave the current mode for `mode`.
    fn enter(&mut self, mode: Mode) {
        self.mode = Some(mode);
        self.streaming = false;
        self.stream_at = None;
        self.statistics = None;
        if mode == Mode::Raw {
            // Start with the frames sent from now on, not a stale backlog.
            if let Some(port) = &mut self.port {
                port.skip_pending();
            }
        }
    }

    /// Write `first` and whatever else is already waiting, in one write.
    async fn forward(&mut self, first: BusFrame) -> io::Result<()> {
        self.wbuf.clear();
        let mut next = Some(first);
        let mut count = 0;
        while let Some(bus_frame) = next {
            // socketcand does not forward remote frames, and a zero-length frame instead would
            // look like a broken heartbeat to python-canopen: drop them (see anchors.md §3.3).
            if !bus_frame.frame.rtr {
                let message = Message::Frame {
                    frame: bus_frame.frame,
                    timestamp: unix_time(bus_frame.timestamp),
                };
                write!(self.wbuf, "{message}")?;
            }
            count += 1;
            if count >= MAX_BATCH {
                break;
            }
            next = self.port.as_mut().and_then(Port::try_recv);
        }
        if !self.wbuf.is_empty() {
            self.out.write_all(&self.wbuf).await?;
            self.out.flush().await?;
        }
        Ok(())
    }

    async fn report_statistics(&mut self) -> io::Result<()> {
        let bus = self.bus.stats();
        self.reply(&Message::Stat {
            rbytes: bus.bytes.saturating_sub(self.sent_bytes),
            rpackets: bus.frames.saturating_sub(self.sent_frames),
            tbytes: self.sent_bytes,
            tpackets: self.sent_frames,
        })
        .await
    }
}

/// Seconds since the Unix epoch of a bus timestamp (0 for times before it).
pub fn unix_time(t: SystemTime) -> Duration {
    t.duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO)
}

#[cfg(test)]
mod tests {
    use super::*;
    use canopen::CanFrame;
    use tokio::io::DuplexStream;

    async fn read_some(client: &mut DuplexStream) -> String {
        let mut buf = vec![0u8; 4096];
        let n = tokio::time::timeout(Duration::from_secs(2), client.read(&mut buf))
            .await
            .expect("reply in time")
            .expect("read");
        String::from_utf8_lossy(buf.get(..n).unwrap_or(&[])).into_owned()
    }

    async fn start(
        bus: &Bus,
    ) -> (
        DuplexStream,
        tokio::task::JoinHandle<Result<(), SessionError>>,
    ) {
        let (client, server) = tokio::io::duplex(64 * 1024);
        let bus = bus.clone();
        let task = tokio::spawn(async move {
            let mut config = ServerConfig::new("vcan0");
            config.stream_delay = Duration::from_millis(20);
            handle_client(server, bus, &config).await
        });
        (client, task)
    }

    #[tokio::test]
    async fn full_handshake_over_duplex() {
        let bus = Bus::new(64);
        let (mut c, task) = start(&bus).await;
        assert_eq!(read_some(&mut c).await, "< hi >");
        c.write_all(b"< vcan0 B 500000 875 0 0 0 0 1 0 >")
            .await
            .expect("w");
        assert_eq!(read_some(&mut c).await, "< ok >");
        c.write_all(b"< open vcan0 >").await.expect("w");
        assert_eq!(read_some(&mut c).await, "< ok >");
        c.write_all(b"< controlmode >").await.expect("w");
        assert_eq!(read_some(&mut c).await, "< ok >");
        c.write_all(b"< statistics 10 >").await.expect("w");
        assert!(read_some(&mut c).await.starts_with("< stat 0 0 0 0 >"));
        c.write_all(b"< rawmode >").await.expect("w");
        // Stat reports may still be in flight; read until the ok.
        let mut got = String::new();
        while !got.ends_with("< ok >") {
            got.push_str(&read_some(&mut c).await);
        }
        let node = bus.port();
        node.send(CanFrame::new(0x181, &[1, 2]).expect("f"));
        let text = read_some(&mut c).await;
        assert!(text.starts_with("< frame 181 "), "{text}");
        assert!(text.ends_with(" 0102 >"), "{text}");
        drop(c);
        assert!(task.await.expect("join").is_ok());
    }

    #[tokio::test]
    async fn wrong_channel_is_refused() {
        let bus = Bus::new(8);
        let (mut c, task) = start(&bus).await;
        assert_eq!(read_some(&mut c).await, "< hi >");
        c.write_all(b"< open can9 >").await.expect("w");
        assert_eq!(read_some(&mut c).await, "< error could not open bus >");
        assert!(matches!(
            task.await.expect("join"),
            Err(SessionError::UnknownChannel)
        ));
    }

    #[tokio::test]
    async fn commands_before_open_and_unsupported() {
        let bus = Bus::new(8);
        let (mut c, _task) = start(&bus).await;
        assert_eq!(read_some(&mut c).await, "< hi >");
        c.write_all(b"< rawmode >").await.expect("w");
        assert_eq!(read_some(&mut c).await, "< error unknown command >");
        c.write_all(b"< send 123 0 >").await.expect("w");
        assert_eq!(read_some(&mut c).await, "< error unknown command >");
        c.write_all(b"< echo >").await.expect("w");
        assert_eq!(read_some(&mut c).await, "< echo >");
        c.write_all(b"< open vcan0 >").await.expect("w");
        assert_eq!(read_some(&mut c).await, "< ok >");
        c.write_all(b"< subscribe 0 0 123 >").await.expect("w");
        assert_eq!(read_some(&mut c).await, "< error command not supported >");
        c.write_all(b"< isotpmode >").await.expect("w");
        assert_eq!(
            read_some(&mut c).await,
            "< error isotp mode not supported >"
        );
        c.write_all(b"< open vcan0 >").await.expect("w");
        assert_eq!(read_some(&mut c).await, "< error unknown command >");
        // BCM-mode send works.
        let mut node = bus.port();
        c.write_all(b"< send 123 1 ab >").await.expect("w");
        let got = tokio::time::timeout(Duration::from_secs(2), node.recv())
            .await
            .expect("in time")
            .expect("frame");
        assert_eq!(got.frame, CanFrame::new(0x123, &[0xAB]).expect("f"));
    }
}
