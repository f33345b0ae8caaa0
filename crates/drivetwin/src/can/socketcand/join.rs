//! Joining another socketcand server as a client (`--socketcand-join ADDR`): the cell's bus is then
//! that server's bus, so one plant larger than a process runs on several processes or machines over
//! the existing protocol (the notes on open-source systems kept beside the project, §3.3):
//! `< hi >`, `< open CH >`, `< rawmode >`, then frames both ways.

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use super::{Decoder, Message, Mode};

/// How long the connection and each step of the handshake may take.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);

#[derive(Debug, thiserror::Error)]
pub enum JoinError {
    #[error("socketcand server {addr}: {source}")]
    Io { addr: String, source: io::Error },
    #[error("socketcand server {addr}: expected {expected}, got {got}")]
    Handshake {
        addr: String,
        expected: &'static str,
        got: String,
    },
}

/// Connects to the server at `addr`, opens `channel` in raw mode; the stream is ready for
/// frames (blocking, as the caller hands it to its poll loop).
pub fn join(addr: &str, channel: &str) -> Result<TcpStream, JoinError> {
    let io_err = |source| JoinError::Io {
        addr: addr.to_owned(),
        source,
    };
    let target = addr
        .to_socket_addrs()
        .map_err(io_err)?
        .next()
        .ok_or_else(|| io_err(io::Error::new(io::ErrorKind::NotFound, "no address")))?;
    let mut stream = TcpStream::connect_timeout(&target, HANDSHAKE_TIMEOUT).map_err(io_err)?;
    let _ = stream.set_nodelay(true);
    stream
        .set_read_timeout(Some(HANDSHAKE_TIMEOUT))
        .map_err(io_err)?;
    let mut decoder = Decoder::new();
    let mut expect = |stream: &mut TcpStream, want: Message, text: &'static str| {
        let got = next_message(stream, &mut decoder).map_err(io_err)?;
        if got == want {
            Ok(())
        } else {
            Err(JoinError::Handshake {
                addr: addr.to_owned(),
                expected: text,
                got: got.to_string(),
            })
        }
    };
    expect(&mut stream, Message::Hi, "< hi >")?;
    write!(stream, "{}", Message::Open(channel.to_owned())).map_err(io_err)?;
    expect(&mut stream, Message::Ok, "< ok >")?;
    write!(stream, "{}", Message::Mode(Mode::Raw)).map_err(io_err)?;
    expect(&mut stream, Message::Ok, "< ok >")?;
    stream.set_read_timeout(None).map_err(io_err)?;
    Ok(stream)
}

fn next_message(stream: &mut TcpStream, decoder: &mut Decoder) -> io::Result<Message> {
    let deadline = Instant::now() + HANDSHAKE_TIMEOUT;
    let mut buf = [0u8; 256];
    loop {
        match decoder.next_message() {
            Some(Ok(m)) => return Ok(m),
            Some(Err(e)) => return Err(io::Error::new(io::ErrorKind::InvalidData, e.to_string())),
            None => {}
        }
        if Instant::now() > deadline {
            return Err(io::Error::new(io::ErrorKind::TimedOut, "no answer"));
        }
        // One byte at a time past the handshake would be slow; messages here are short and
        // the server sends nothing else before `< ok >` of rawmode.
        let n = stream.read(&mut buf)?;
        if n == 0 {
            return Err(io::Error::new(io::ErrorKind::UnexpectedEof, "closed"));
        }
        decoder.push(buf.get(..n).unwrap_or(&[]));
    }
}
