//! The socketcand TCP server on tokio: one task per client, each client one node on the [`Bus`];
//! the protocol rules are the sans-IO [`super::session`], shared with the cell loop.
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
use tokio::time::Instant;
use tracing::Instrument;

use super::codec::{Decoder, Message, MAX_MESSAGE_LEN};
use super::session::{Effect, Session, Totals};
use crate::can::bus::{Bus, BusFrame, Port};

/// socketcand's registered port.
pub const DEFAULT_PORT: u16 = 29536;

/// Frames written to a client in one write at most, when several are waiting.
const MAX_BATCH: usize = 64;

/// socketcand clients served at once by default.
pub const DEFAULT_MAX_CLIENTS: usize = 128;

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
            max_clients: DEFAULT_MAX_CLIENTS,
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
    let mut client = Client {
        out: writer,
        bus: &bus,
        port: None,
        session: Session::new(),
        effects: Vec::new(),
        wbuf: Vec::with_capacity(MAX_BATCH * 48),
    };
    client.reply(&Session::HELLO).await?;
    let mut decoder = Decoder::with_max_len(config.max_message_len);
    let mut rbuf = vec![0u8; 4096];
    loop {
        while let Some(message) = decoder.next_message() {
            let Client {
                session, effects, ..
            } = &mut client;
            session.on_message(config, std::time::Instant::now(), message, &mut |e| {
                effects.push(e)
            });
            if client.carry_out().await? == Flow::Close {
                client.out.shutdown().await.ok();
                return Err(SessionError::UnknownChannel);
            }
        }
        let deadline = client.session.deadline().map(Instant::from_std);
        let streaming = client.session.is_streaming();
        tokio::select! {
            read = reader.read(&mut rbuf) => {
                let n = read?;
                if n == 0 {
                    return Ok(());
                }
                decoder.push(rbuf.get(..n).unwrap_or(&[]));
            }
            () = sleep_until(deadline), if deadline.is_some() => {
                let totals = bus.stats();
                let totals = Totals { frames: totals.frames, bytes: totals.bytes };
                let Client { session, effects, .. } = &mut client;
                session.poll(std::time::Instant::now(), totals, &mut |e| effects.push(e));
                client.carry_out().await?;
            }
            Some(frame) = recv(&mut client.port), if streaming => {
                client.forward(frame).await?;
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

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Flow {
    Continue,
    Close,
}

/// A session on an async stream, its node on the [`Bus`] attached on `open`.
struct Client<'a, W> {
    out: W,
    bus: &'a Bus,
    port: Option<Port>,
    session: Session,
    /// What the last message asked for, carried out in order.
    effects: Vec<Effect>,
    wbuf: Vec<u8>,
}

impl<W: AsyncWrite + Unpin> Client<'_, W> {
    /// One message, one write: never coalesced with anything else.
    async fn reply(&mut self, message: &Message) -> io::Result<()> {
        self.out.write_all(message.to_string().as_bytes()).await?;
        self.out.flush().await
    }

    async fn carry_out(&mut self) -> io::Result<Flow> {
        let mut flow = Flow::Continue;
        let effects = std::mem::take(&mut self.effects);
        for effect in &effects {
            match effect {
                Effect::Reply(m) => self.reply(m).await?,
                Effect::Open => self.port = Some(self.bus.port()),
                Effect::SkipPending => {
                    if let Some(port) = &mut self.port {
                        port.skip_pending();
                    }
                }
                Effect::Send(frame) => {
                    if let Some(port) = &self.port {
                        port.send(*frame);
                    }
                }
                Effect::Close => flow = Flow::Close,
            }
        }
        self.effects = effects;
        self.effects.clear();
        Ok(flow)
    }

    /// Write `first` and whatever else is already waiting, in one write.
    async fn forward(&mut self, first: BusFrame) -> io::Result<()> {
        self.wbuf.clear();
        let mut next = Some(first);
        let mut count = 0;
        while let Some(bus_frame) = next {
            if Session::forwards(&bus_frame.frame) {
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
