//! A Modbus TCP client on one tokio TCP connection: the `no_std` request encoders and the
//! response decoder of [`modbus::client`] around a socket, one request in flight at a time, as
//! a PLC's cyclic exchange runs. `drivetwin fhpp` and the Modbus benchmark use it.
//!
//! Nothing is allocated per request: the request and response ADUs live in two fixed buffers.

use std::io;
use std::time::Duration;

use modbus::client::{self, ClientError, Response};
use modbus::{Exception, Mbap, MAX_ADU_LEN, MBAP_LEN};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// Why a Modbus request got no usable answer.
#[derive(Debug, thiserror::Error)]
pub enum ModbusTcpError {
    #[error("cannot connect to {addr}: {source}")]
    Connect { addr: String, source: io::Error },
    #[error("Modbus connection lost: {0}")]
    Io(#[from] io::Error),
    #[error(
        "the Modbus server closed the connection (a CMMO-ST serves one Modbus client at a time)"
    )]
    Closed,
    #[error("no Modbus response within {0:?}")]
    Timeout(Duration),
    #[error("Modbus exception to function {function:02X}h: {exception}")]
    Exception { function: u8, exception: Exception },
    #[error("malformed Modbus response: {0}")]
    Protocol(&'static str),
}

impl From<ClientError> for ModbusTcpError {
    fn from(e: ClientError) -> Self {
        ModbusTcpError::Protocol(match e {
            ClientError::BufferTooSmall => "buffer too small",
            ClientError::InvalidQuantity => "quantity out of range",
            ClientError::InvalidResponse => "response does not decode",
        })
    }
}

/// One Modbus TCP connection.
pub struct ModbusTcpClient {
    stream: TcpStream,
    transaction: u16,
    unit: u8,
    timeout: Duration,
    tx: [u8; MAX_ADU_LEN],
    rx: [u8; MAX_ADU_LEN],
}

impl ModbusTcpClient {
    /// Connects to `addr` (`host:port`); every later request waits at most `timeout` for its
    /// response.
    pub async fn connect(addr: &str, timeout: Duration) -> Result<Self, ModbusTcpError> {
        let connect = |source| ModbusTcpError::Connect {
            addr: addr.to_string(),
            source,
        };
        let stream = tokio::time::timeout(timeout, TcpStream::connect(addr))
            .await
            .map_err(|_| connect(io::Error::from(io::ErrorKind::TimedOut)))?
            .map_err(connect)?;
        // One small request at a time: Nagle would hold each one back.
        stream.set_nodelay(true).map_err(connect)?;
        Ok(ModbusTcpClient {
            stream,
            transaction: 0,
            unit: 0,
            timeout,
            tx: [0; MAX_ADU_LEN],
            rx: [0; MAX_ADU_LEN],
        })
    }

    /// FC 0x17: writes `values` at `write_address`, then reads `out.len()` registers from
    /// `read_address` into `out`.
    pub async fn read_write(
        &mut self,
        read_address: u16,
        out: &mut [u16],
        write_address: u16,
        values: &[u16],
    ) -> Result<(), ModbusTcpError> {
        let quantity = u16::try_from(out.len()).map_err(|_| ClientError::InvalidQuantity)?;
        let (tid, unit) = self.next_transaction();
        let len = client::read_write_multiple_registers(
            &mut self.tx,
            tid,
            unit,
            read_address,
            quantity,
            write_address,
            values,
        )?;
        match self.transact(len).await? {
            Response::ReadWriteMultipleRegisters(r) if r.len() == out.len() => {
                r.decode_into(out);
                Ok(())
            }
            Response::ReadWriteMultipleRegisters(_) => {
                Err(ModbusTcpError::Protocol("wrong register count"))
            }
            other => Err(unexpected(other)),
        }
    }

    /// FC 0x03: reads `out.len()` registers from `address`.
    pub async fn read_holding(
        &mut self,
        address: u16,
        out: &mut [u16],
    ) -> Result<(), ModbusTcpError> {
        let quantity = u16::try_from(out.len()).map_err(|_| ClientError::InvalidQuantity)?;
        let (tid, unit) = self.next_transaction();
        let len = client::read_holding_registers(&mut self.tx, tid, unit, address, quantity)?;
        match self.transact(len).await? {
            Response::ReadHoldingRegisters(r) if r.len() == out.len() => {
                r.decode_into(out);
                Ok(())
            }
            Response::ReadHoldingRegisters(_) => {
                Err(ModbusTcpError::Protocol("wrong register count"))
            }
            other => Err(unexpected(other)),
        }
    }

    /// FC 0x07: the exception status byte (on a CMMO-ST the active fault number, 0 = none).
    pub async fn exception_status(&mut self) -> Result<u8, ModbusTcpError> {
        let (tid, unit) = self.next_transaction();
        let len = client::read_exception_status(&mut self.tx, tid, unit)?;
        match self.transact(len).await? {
            Response::ReadExceptionStatus(s) => Ok(s),
            other => Err(unexpected(other)),
        }
    }

    fn next_transaction(&mut self) -> (u16, u8) {
        self.transaction = self.transaction.wrapping_add(1);
        (self.transaction, self.unit)
    }

    /// Sends the request ADU in `tx[..len]` and waits for the response with its transaction
    /// identifier; returns the decoded response PDU.
    async fn transact(&mut self, len: usize) -> Result<Response<'_>, ModbusTcpError> {
        let request = self
            .tx
            .get(..len)
            .ok_or(ModbusTcpError::Protocol("request too long"))?;
        let timeout = self.timeout;
        let stream = &mut self.stream;
        let rx = &mut self.rx;
        let tid = self.transaction;
        let pdu_len = tokio::time::timeout(timeout, async {
            stream.write_all(request).await.map_err(link_error)?;
            read_response(stream, rx, tid).await
        })
        .await
        .map_err(|_| ModbusTcpError::Timeout(timeout))??;
        let pdu = self
            .rx
            .get(MBAP_LEN..MBAP_LEN + pdu_len)
            .ok_or(ModbusTcpError::Protocol("response too long"))?;
        match Response::parse(pdu)? {
            Response::Exception(e) => Err(ModbusTcpError::Exception {
                function: e.function,
                exception: e.exception,
            }),
            r => Ok(r),
        }
    }
}

/// Reads ADUs into `rx` until the one answering `tid` arrives (a stale answer to a request
/// that timed out is skipped); returns its PDU length.
async fn read_response(
    stream: &mut TcpStream,
    rx: &mut [u8; MAX_ADU_LEN],
    tid: u16,
) -> Result<usize, ModbusTcpError> {
    loop {
        let (head, body) = rx.split_at_mut(MBAP_LEN);
        read_exact(stream, head).await?;
        let mbap = Mbap::parse(head).ok_or(ModbusTcpError::Protocol("short header"))?;
        let pdu_len = usize::from(mbap.length)
            .checked_sub(1)
            .filter(|n| (1..=body.len()).contains(n))
            .ok_or(ModbusTcpError::Protocol("length field out of range"))?;
        if mbap.protocol_id != 0 {
            return Err(ModbusTcpError::Protocol("protocol identifier is not 0"));
        }
        let pdu = body
            .get_mut(..pdu_len)
            .ok_or(ModbusTcpError::Protocol("length field out of range"))?;
        read_exact(stream, pdu).await?;
        if mbap.transaction_id == tid {
            return Ok(pdu_len);
        }
    }
}

async fn read_exact(stream: &mut TcpStream, buf: &mut [u8]) -> Result<(), ModbusTcpError> {
    stream.read_exact(buf).await.map(drop).map_err(link_error)
}

/// End of stream, or a reset because the server closed with our request unread: closed.
fn link_error(e: io::Error) -> ModbusTcpError {
    match e.kind() {
        io::ErrorKind::UnexpectedEof
        | io::ErrorKind::ConnectionReset
        | io::ErrorKind::BrokenPipe
        | io::ErrorKind::ConnectionAborted => ModbusTcpError::Closed,
        _ => ModbusTcpError::Io(e),
    }
}

fn unexpected(_: Response<'_>) -> ModbusTcpError {
    ModbusTcpError::Protocol("the response answers another function")
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::net::TcpListener;

    /// A server that answers one FC 0x17 request with fixed registers, checking the request
    /// bytes (FHPP-MB-03 cycle 2, fhpp §8.2 b: the direct-mode start telegram), then an FC 0x07
    /// request (FHPP-MB-05) with an exception.
    #[tokio::test]
    async fn fc17_request_bytes_and_response() {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let server = tokio::spawn(async move {
            let (mut s, _) = listener.accept().await.unwrap();
            let mut req = [0u8; 7 + 18];
            s.read_exact(&mut req).await.unwrap();
            let pdu = [
                0x17, 0, 0, 0, 4, 0, 0, 0, 4, 8, 0x43, 0x03, 0x00, 0x64, 0x00, 0x00, 0x27, 0x10,
            ];
            assert_eq!(&req[..7], &[0, 1, 0, 0, 0, 0x13, 0]);
            assert_eq!(&req[7..], &pdu);
            // A stale answer first (another transaction), then the real one.
            s.write_all(&[0, 9, 0, 0, 0, 3, 0, 0x87, 0x01])
                .await
                .unwrap();
            s.write_all(&[
                0, 1, 0, 0, 0, 0x0B, 0, 0x17, 8, 0x53, 0x03, 0, 0, 0, 0, 0, 5,
            ])
            .await
            .unwrap();
            let mut req = [0u8; 8];
            s.read_exact(&mut req).await.unwrap();
            assert_eq!(req, [0, 2, 0, 0, 0, 2, 0, 0x07]);
            s.write_all(&[0, 2, 0, 0, 0, 3, 0, 0x87, 0x04])
                .await
                .unwrap();
        });
        let mut c = ModbusTcpClient::connect(&addr, Duration::from_secs(2))
            .await
            .unwrap();
        let mut out = [0u16; 4];
        c.read_write(0, &mut out, 0, &[0x4303, 0x0064, 0x0000, 0x2710])
            .await
            .unwrap();
        assert_eq!(out, [0x5303, 0, 0, 5]);
        match c.exception_status().await {
            Err(ModbusTcpError::Exception {
                function: 0x07,
                exception: Exception::ServerDeviceFailure,
            }) => {}
            other => panic!("{other:?}"),
        }
        server.await.unwrap();
        // The server is gone: the next request sees the closed connection.
        assert!(matches!(
            c.exception_status().await,
            Err(ModbusTcpError::Closed | ModbusTcpError::Io(_))
        ));
    }
}
