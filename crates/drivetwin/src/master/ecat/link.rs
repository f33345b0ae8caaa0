//! How the EtherCAT master's frames reach the chain: a round trip of one frame.

use std::io;
use std::time::Duration;

use ethercat::master::reply_datagram;

/// One frame out, the same frame back (processed by every slave of the line).
///
/// `async fn` in a trait: the master is generic over concrete links on one task and never
/// needs a `Send` bound, so the lint's concern does not apply.
#[allow(async_fn_in_trait)]
pub trait FrameLink {
    /// Sends `frame` (a whole Ethernet frame) and waits up to `timeout` for the reply to
    /// it, the returned frame whose first datagram has index `index`, which replaces
    /// `frame`. `Ok(false)`: nothing came back in time.
    async fn round_trip(
        &mut self,
        frame: &mut [u8],
        index: u8,
        timeout: Duration,
    ) -> io::Result<bool>;
}

/// The raw `AF_PACKET` socket of [`crate::ecat::link`], on the master's side of the wire;
/// elsewhere than on Linux it does not open ([`crate::sys::packet_socket`]).
#[derive(Debug)]
pub struct SocketLink {
    socket: crate::ecat::link::EthercatSocket,
    rx: Vec<u8>,
}

impl SocketLink {
    /// Opens `interface` (needs `CAP_NET_RAW`); inside a tokio runtime.
    pub fn open(interface: &str) -> io::Result<Self> {
        Ok(SocketLink {
            socket: crate::ecat::link::EthercatSocket::open(interface)?,
            rx: vec![0; crate::ecat::link::MAX_FRAME],
        })
    }
}

impl FrameLink for SocketLink {
    async fn round_trip(
        &mut self,
        frame: &mut [u8],
        index: u8,
        timeout: Duration,
    ) -> io::Result<bool> {
        self.socket.send(frame).await?;
        let deadline = tokio::time::Instant::now() + timeout;
        loop {
            let n = match tokio::time::timeout_at(deadline, self.socket.recv_returned(&mut self.rx))
                .await
            {
                Err(_elapsed) => return Ok(false),
                Ok(r) => r?,
            };
            // A slave returns the bytes it got (ESC reference §1.1); a real NIC pads a short frame
            // to 60 bytes on the way, so the reply may be longer. A shorter one, or a late reply to
            // an earlier request with another index, is not ours.
            let Some(reply) = self.rx.get(..n).and_then(|r| r.get(..frame.len())) else {
                continue;
            };
            if reply_datagram(reply, index).is_some() {
                frame.copy_from_slice(reply);
                return Ok(true);
            }
        }
    }
}
