//! A master's connection to a CAN bus: a socketcand server (ours or the real daemon) or a
//! SocketCAN interface.

use std::time::Duration;

use canopen::CanFrame;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use crate::can::socketcand::{Decoder, Message};

#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error("cannot connect to socketcand at {addr}: {source}")]
    Connect {
        addr: String,
        source: std::io::Error,
    },
    #[error("socketcand handshake failed: expected {expected}, got {got}")]
    Handshake { expected: &'static str, got: String },
    #[error("bus connection: {0}")]
    Io(#[from] std::io::Error),
    #[error("the bus connection was closed")]
    Closed,
    #[error("SocketCAN: {0}")]
    SocketCan(String),
}

/// Longer than any server's pause between the rawmode reply and the first streamed frame.
const STREAM_SETTLE: Duration = Duration::from_millis(120);

/// A socketcand client in raw mode.
pub struct SocketcandLink {
    stream: TcpStream,
    decoder: Decoder,
}

impl SocketcandLink {
    /// Connects and performs the handshake `< hi >`, `< open CH >`, `< rawmode >`.
    pub async fn connect(addr: &str, channel: &str) -> Result<Self, LinkError> {
        let stream = tokio::time::timeout(Duration::from_secs(5), TcpStream::connect(addr))
            .await
            .map_err(|_| LinkError::Connect {
                addr: addr.to_string(),
                source: std::io::Error::new(std::io::ErrorKind::TimedOut, "timed out"),
            })?
            .map_err(|source| LinkError::Connect {
                addr: addr.to_string(),
                source,
            })?;
        let _ = stream.set_nodelay(true);
        let mut link = SocketcandLink {
            stream,
            decoder: Decoder::new(),
        };
        link.expect(Message::Hi, "< hi >").await?;
        link.write(&Message::Open(channel.to_string())).await?;
        link.expect(Message::Ok, "< ok >").await?;
        link.write(&Message::Mode(crate::can::socketcand::Mode::Raw))
            .await?;
        link.expect(Message::Ok, "< ok >").await?;
        // A socketcand server streams frames only a moment after the rawmode reply (so the
        // reply is never coalesced); wait that out so short answer timeouts are real.
        tokio::time::sleep(STREAM_SETTLE).await;
        Ok(link)
    }

    async fn write(&mut self, m: &Message) -> Result<(), LinkError> {
        self.stream.write_all(m.to_string().as_bytes()).await?;
        Ok(())
    }

    async fn next_message(&mut self) -> Result<Message, LinkError> {
        let mut buf = [0u8; 1024];
        loop {
            if let Some(m) = self.decoder.next_message() {
                match m {
                    Ok(m) => return Ok(m),
                    Err(e) => tracing::warn!(error = %e, "bad message from socketcand"),
                }
                continue;
            }
            let n = self.stream.read(&mut buf).await?;
            if n == 0 {
                return Err(LinkError::Closed);
            }
            self.decoder.push(buf.get(..n).unwrap_or(&[]));
        }
    }

    async fn expect(&mut self, want: Message, text: &'static str) -> Result<(), LinkError> {
        let got = tokio::time::timeout(Duration::from_secs(5), self.next_message())
            .await
            .map_err(|_| LinkError::Handshake {
                expected: text,
                got: "nothing within 5 s".into(),
            })??;
        if got == want {
            Ok(())
        } else {
            Err(LinkError::Handshake {
                expected: text,
                got: got.to_string(),
            })
        }
    }
}

/// Any link a master command can use.
pub enum Link {
    Socketcand(SocketcandLink),
    SocketCan(crate::can::socketcan::CanSocket),
}

impl Link {
    pub async fn socketcand(addr: &str, channel: &str) -> Result<Self, LinkError> {
        Ok(Link::Socketcand(
            SocketcandLink::connect(addr, channel).await?,
        ))
    }

    /// A SocketCAN interface (real hardware or vcan); elsewhere than on Linux it refuses
    /// ([`crate::sys::socketcan`]).
    pub fn socketcan(interface: &str) -> Result<Self, LinkError> {
        crate::can::socketcan::CanSocket::open(interface)
            .map(Link::SocketCan)
            .map_err(|e| LinkError::SocketCan(format!("{interface}: {e}")))
    }

    pub async fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        match self {
            Link::Socketcand(l) => l.write(&Message::Send(*frame)).await,
            Link::SocketCan(s) => s
                .send(frame)
                .await
                .map_err(|e| LinkError::SocketCan(e.to_string())),
        }
    }

    /// The next frame on the bus.
    pub async fn recv(&mut self) -> Result<CanFrame, LinkError> {
        match self {
            Link::Socketcand(l) => loop {
                match l.next_message().await? {
                    Message::Frame { frame, .. } => return Ok(frame),
                    Message::Error(e) => tracing::warn!(error = %e, "socketcand error"),
                    _ => {}
                }
            },
            Link::SocketCan(s) => s
                .recv()
                .await
                .map_err(|e| LinkError::SocketCan(e.to_string())),
        }
    }
}
