//! The master side of the Kinco RS232 telegrams (Kinco CD3 / FD3 manual ch. 10, the codec
//! `drive::vendors::kinco::rs232`): one 10-byte telegram out, one 10-byte answer in, over a serial
//! port (a real drive on a USB adapter, or a twin's pty link). Blocking: a command-line tool.
//!
//! Decisions: bytes that come before the answer (a ring's echo of the telegram, §2.1
//! multi-point; noise) are skipped: the answer is the first 10 bytes from the station that
//! pass the checksum and name the object asked for. Stale input is flushed before each
//! telegram, as public Kinco drivers do.

use std::path::Path;
use std::time::{Duration, Instant};

use drive::vendors::kinco::rs232::{Request, Response, Telegram, TELEGRAM_LEN};
use od::AbortCode;

use crate::serial::pty::{Port, PortError};

#[derive(Debug, thiserror::Error)]
pub enum KincoError {
    #[error(transparent)]
    Port(#[from] PortError),
    #[error("serial port: {0}")]
    Io(#[from] std::io::Error),
    #[error("no answer from station {station} within {timeout_ms} ms")]
    Timeout { station: u8, timeout_ms: u128 },
    #[error("{index:04X}h:{sub:02X}h: error {code}")]
    Abort {
        index: u16,
        sub: u8,
        code: AbortCode,
    },
}

/// A serial port to Kinco drives.
pub struct KincoMaster {
    port: Port,
    timeout: Duration,
}

impl KincoMaster {
    /// Opens `path` at `baud` bit/s (8N1); each answer is awaited at most `timeout`.
    pub fn open(path: &Path, baud: u32, timeout: Duration) -> Result<Self, KincoError> {
        Ok(KincoMaster {
            port: Port::device(path, baud)?,
            timeout,
        })
    }

    /// Sends `request` to `station`; its answer.
    pub fn exchange(&mut self, station: u8, request: Request) -> Result<Response, KincoError> {
        let mut junk = [0u8; 256];
        while self.port.read(&mut junk)? > 0 {}
        let t = request.emit(station);
        let mut sent = 0;
        let start = Instant::now();
        while sent < t.len() {
            sent += self.port.write(t.get(sent..).unwrap_or(&[]));
            if start.elapsed() > self.timeout {
                return Err(self.timeout_error(station));
            }
        }
        let (index, sub) = request.index();
        let mut window: Vec<u8> = Vec::with_capacity(64);
        loop {
            let left = self.timeout.saturating_sub(start.elapsed());
            if left.is_zero() || !self.port.wait_readable(left)? {
                return Err(self.timeout_error(station));
            }
            let mut buf = [0u8; 64];
            let n = self.port.read(&mut buf)?;
            window.extend_from_slice(buf.get(..n).unwrap_or(&[]));
            // The first 10 bytes at any offset that are this station's answer.
            let mut at = 0;
            while let Some(candidate) = window.get(at..at + TELEGRAM_LEN) {
                if let Ok(tg) = Telegram::try_from(candidate) {
                    if let Some(r) = Response::parse(&tg, station) {
                        if response_index(&r) == (index, sub) {
                            return Ok(r);
                        }
                    }
                }
                at += 1;
            }
        }
    }

    fn timeout_error(&self, station: u8) -> KincoError {
        KincoError::Timeout {
            station,
            timeout_ms: self.timeout.as_millis(),
        }
    }

    /// Reads an object: its little-endian bytes (1, 2 or 4).
    pub fn read(&mut self, station: u8, index: u16, sub: u8) -> Result<Vec<u8>, KincoError> {
        match self.exchange(station, Request::Read { index, sub })? {
            Response::Read { data, len, .. } => Ok(data.get(..len).unwrap_or(&[]).to_vec()),
            Response::Error { code, .. } => Err(KincoError::Abort { index, sub, code }),
            Response::Written { .. } => Err(KincoError::Abort {
                index,
                sub,
                code: AbortCode::COMMAND_SPECIFIER,
            }),
        }
    }

    /// Writes an object of `data.len()` bytes (1, 2 or 4).
    pub fn write(
        &mut self,
        station: u8,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), KincoError> {
        let mut d = [0u8; 4];
        for (slot, b) in d.iter_mut().zip(data) {
            *slot = *b;
        }
        let request = Request::Write {
            index,
            sub,
            data: d,
            len: data.len().min(4),
        };
        match self.exchange(station, request)? {
            Response::Written { .. } => Ok(()),
            Response::Error { code, .. } => Err(KincoError::Abort { index, sub, code }),
            Response::Read { .. } => Err(KincoError::Abort {
                index,
                sub,
                code: AbortCode::COMMAND_SPECIFIER,
            }),
        }
    }
}

fn response_index(r: &Response) -> (u16, u8) {
    match *r {
        Response::Written { index, sub }
        | Response::Read { index, sub, .. }
        | Response::Error { index, sub, .. } => (index, sub),
    }
}
