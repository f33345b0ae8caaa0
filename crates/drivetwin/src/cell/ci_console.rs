//! The CI terminal of a drive (the CMMP-AS RS232 debug console, manual §3.2.3) as a TCP
//! service: lines of `?XXXXSU` / `=XXXXSU:W…` in, one answer line each out, ended with CR LF.
//! Bound to loopback only: the console writes any object without authentication.
//!
//! A connection cuts its lines itself and hands each to the cell's runtime, which owns the
//! drives; the runtime answers from the drive's dictionary on its own clock.

use std::net::SocketAddr;

use canopen::ci_terminal::{syntax_error, Cut, LineBuf, LineCutter, Reply};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{mpsc, oneshot};
use tracing::Instrument;

/// One line for drive `drive` (cell order) and where its answer goes.
#[derive(Debug)]
pub struct ConsoleRequest {
    pub drive: usize,
    pub line: LineBuf,
    pub reply: oneshot::Sender<Reply>,
}

/// Lines waiting for the runtime; more wait in the clients' sockets.
pub const QUEUE: usize = 64;

#[derive(Debug, thiserror::Error)]
pub enum ConsoleError {
    #[error("CI terminal address {0:?}: {1}")]
    Address(String, String),
    #[error("CI terminal address {0}: loopback only (the console writes without authentication)")]
    NotLoopback(SocketAddr),
    #[error("CI terminal on {0}: {1}")]
    Bind(String, std::io::Error),
}

/// `addr` as a socket address, if it is a loopback one.
pub fn check_address(addr: &str) -> Result<SocketAddr, ConsoleError> {
    let parsed: SocketAddr = addr
        .parse()
        .map_err(|e: std::net::AddrParseError| ConsoleError::Address(addr.into(), e.to_string()))?;
    if !parsed.ip().is_loopback() {
        return Err(ConsoleError::NotLoopback(parsed));
    }
    Ok(parsed)
}

/// Binds `addr`, which must be a loopback address.
pub async fn bind(addr: &str) -> Result<TcpListener, ConsoleError> {
    TcpListener::bind(check_address(addr)?)
        .await
        .map_err(|e| ConsoleError::Bind(addr.into(), e))
}

/// Serves drive `drive`'s console on `listener` until the runtime goes away.
pub async fn serve(listener: TcpListener, drive: usize, requests: mpsc::Sender<ConsoleRequest>) {
    loop {
        match listener.accept().await {
            Ok((stream, peer)) => {
                let requests = requests.clone();
                let span = tracing::info_span!("ci_terminal", drive, %peer);
                tokio::spawn(
                    async move {
                        tracing::info!("console connected");
                        match connection(stream, drive, requests).await {
                            Ok(()) => tracing::info!("console disconnected"),
                            Err(e) => tracing::info!(error = %e, "console session ended"),
                        }
                    }
                    .instrument(span),
                );
            }
            Err(e) => tracing::warn!(error = %e, "CI terminal: accept failed"),
        }
        if requests.is_closed() {
            break;
        }
    }
}

async fn connection(
    mut stream: TcpStream,
    drive: usize,
    requests: mpsc::Sender<ConsoleRequest>,
) -> std::io::Result<()> {
    let mut lines = LineCutter::default();
    let mut buf = [0u8; 256];
    let mut answer = Vec::with_capacity(64);
    loop {
        let n = stream.read(&mut buf).await?;
        if n == 0 {
            return Ok(());
        }
        answer.clear();
        for &b in buf.get(..n).unwrap_or(&[]) {
            let reply = match lines.push(b) {
                None => continue,
                Some(Cut::TooLong) => syntax_error(),
                Some(Cut::Line(line)) => {
                    let (tx, rx) = oneshot::channel();
                    let req = ConsoleRequest {
                        drive,
                        line,
                        reply: tx,
                    };
                    if requests.send(req).await.is_err() {
                        return Ok(()); // the runtime stopped
                    }
                    match rx.await {
                        Ok(r) => r,
                        Err(_) => return Ok(()),
                    }
                }
            };
            answer.extend_from_slice(reply.as_bytes());
            answer.extend_from_slice(b"\r\n");
        }
        stream.write_all(&answer).await?;
    }
}
