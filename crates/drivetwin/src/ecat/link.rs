//! Raw Ethernet transport for the EtherCAT chain: a Linux `AF_PACKET` socket bound to one
//! interface and to EtherType 0x88A4, as an EtherCAT slave sits on a wire.
//!
//! The master's frames arrive here, the chain processes them in place and the same frame goes
//! back out of the same interface, as it leaves the last slave of a line towards the master.
//! Two filters keep the chain from processing a frame twice:
//!
//! * our own transmissions come back to a packet socket as `PACKET_OUTGOING` copies: the socket
//!   asks the kernel not to deliver them (`PACKET_IGNORE_OUTGOING`, Linux 4.20+) and
//!   [`EthercatSocket::recv`] drops any that still arrive by their packet type;
//! * a frame whose first source-MAC byte carries the locally-administered bit 0x02 has passed
//!   a slave already (the ESC sets it, `EthernetFrame::mark_returned`): it is on its way back
//!   to the master (e.g. seen through a bridge or another twin on the segment) and is skipped.
//!
//! Two front ends over the same socket: [`EthercatSocket`] for tokio (the master side), and
//! [`SlaveSocket`] for the slave side in the cell loop, which answers a frame as soon as the
//! kernel hands it over, without an async runtime's wake-up in between (the round trip a
//! master measures is the wire latency of the slave).
//!
//! Opening the socket needs `CAP_NET_RAW` (root, or `setcap cap_net_raw+ep`); the socket is
//! Linux's (`sys::packet_socket`).

use std::io;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd, OwnedFd, RawFd};
use std::time::Duration;

use ethercat::frame::{ETHERTYPE_ETHERCAT, SOURCE_MAC_RETURN_BIT};
use tokio::io::unix::AsyncFd;

use crate::sys::packet_socket::{Received, RxRing};

pub use super::MAX_FRAME;

/// Offset of the first source-MAC byte in an Ethernet frame.
const SOURCE_MAC_FIRST: usize = 6;

/// How long [`EthercatSocket::send`] keeps retrying while the interface's TX queue is full.
const TX_QUEUE_FULL_PATIENCE: Duration = Duration::from_millis(10);

/// How long [`SlaveSocket::send`] retries while the TX queue is full: the time a port takes
/// to put the largest frame (1518 bytes, 12 144 bit times) on a 100 Mbit/s wire, after which
/// its transmitter is free again. An ESC forwards a frame as it passes and never holds the
/// ones behind it; a loop that waited longer would hold every other frame, drive step and
/// socket of the cell.
const TX_PORT_BUSY: Duration = Duration::from_nanos(12_144 * 10);

/// A non-blocking raw EtherCAT socket bound to one interface.
#[derive(Debug)]
pub struct EthercatSocket {
    fd: AsyncFd<OwnedFd>,
    interface: String,
}

impl EthercatSocket {
    /// Open an `AF_PACKET` socket for EtherType 0x88A4 on `interface` (e.g. `eth1`, a veth
    /// end). Must be called inside a tokio runtime.
    pub fn open(interface: &str) -> io::Result<EthercatSocket> {
        let fd = crate::sys::fd::register_async(open_raw(interface)?)?;
        Ok(EthercatSocket {
            fd,
            interface: interface.to_owned(),
        })
    }

    pub fn interface(&self) -> &str {
        &self.interface
    }

    /// The next frame from the master into `buf` (at least [`MAX_FRAME`] bytes); returns its
    /// length. Our own transmissions, frames that already passed a slave and frames longer
    /// than `buf` are skipped.
    pub async fn recv(&self, buf: &mut [u8]) -> io::Result<usize> {
        self.recv_where(buf, Want::Requests).await
    }

    /// The next frame on its way back to a master (one that passed a slave: source-MAC bit
    /// 0x02 set), for the master side (`drivetwin ecat`). Requests are skipped.
    pub async fn recv_returned(&self, buf: &mut [u8]) -> io::Result<usize> {
        self.recv_where(buf, Want::Returned).await
    }

    async fn recv_where(&self, buf: &mut [u8], want: Want) -> io::Result<usize> {
        loop {
            let mut guard = self.fd.readable().await?;
            match guard.try_io(|fd| recv_once(fd.get_ref().as_fd(), buf, want)) {
                Ok(Ok(Some(n))) => return Ok(n),
                Ok(Ok(None)) => continue,
                Ok(Err(e)) => return Err(e),
                Err(_would_block) => continue,
            }
        }
    }

    /// Transmit one frame. While the interface's TX queue is full (`ENOBUFS`) it retries for
    /// up to 10 ms, then returns that error (the master sees a lost frame, as on a wire).
    pub async fn send(&self, frame: &[u8]) -> io::Result<()> {
        let deadline = tokio::time::Instant::now() + TX_QUEUE_FULL_PATIENCE;
        loop {
            let mut guard = self.fd.writable().await?;
            match guard.try_io(|fd| send_once(fd.get_ref().as_fd(), frame)) {
                Ok(Ok(())) => return Ok(()),
                Ok(Err(e)) if is_queue_full(&e) && tokio::time::Instant::now() < deadline => {
                    drop(guard);
                    tokio::task::yield_now().await;
                }
                Ok(Err(e)) => return Err(e),
                Err(_would_block) => continue,
            }
        }
    }
}

/// A non-blocking `AF_PACKET` socket for EtherType 0x88A4 bound to `interface`, with the
/// outgoing copies switched off where the kernel can (also for tools that drive the wire
/// themselves, such as the round-trip benchmark's master).
pub fn open_raw(interface: &str) -> io::Result<OwnedFd> {
    crate::sys::packet_socket::open(interface, ETHERTYPE_ETHERCAT)
}

/// The raw socket of a chain in the cell loop: the loop waits for it with the cell's other
/// sockets (mio) and reads it until it would block; an answer is sent at once.
///
/// Frames are read from a receive ring shared with the kernel
/// (`sys::packet_socket::RxRing`) where one can be set up: the answer's path then
/// has the poll's wake-up and the `send` as its only system calls, as a blocking echo has.
/// Without one (another OS, a kernel that refuses) each frame is a `recvfrom`.
#[derive(Debug)]
pub struct SlaveSocket {
    // Declared before the socket: the ring is unmapped before the socket closes.
    ring: Option<RxRing>,
    fd: OwnedFd,
    interface: String,
    /// When the last frame read reached the socket, as the kernel stamped it.
    arrived: Option<std::time::SystemTime>,
}

impl SlaveSocket {
    /// Open the socket on `interface` (see [`EthercatSocket::open`]).
    pub fn open(interface: &str) -> io::Result<SlaveSocket> {
        let fd = open_raw(interface)?;
        let ring = match RxRing::new(fd.as_fd()) {
            Ok(ring) => Some(ring),
            Err(e) => {
                tracing::debug!(interface, error = %e, "no receive ring: a recvfrom per frame");
                None
            }
        };
        let socket = SlaveSocket {
            ring,
            fd,
            interface: interface.to_owned(),
            arrived: None,
        };
        if socket.ring.is_some() {
            // What came before the ring waits in the socket's queue, where the ring's reader
            // does not look: such frames are old, and dropped.
            let mut buf = [0u8; MAX_FRAME];
            while recv_once(socket.fd.as_fd(), &mut buf, Want::Requests).is_ok() {}
        }
        Ok(socket)
    }

    pub fn interface(&self) -> &str {
        &self.interface
    }

    /// Whether a frame waits in the receive ring, without a system call: `None` without a
    /// ring (then only a read tells).
    pub fn frame_waits(&self) -> Option<bool> {
        self.ring.as_ref().map(RxRing::ready)
    }

    /// One read: `Ok(Some(len))` a request from the master in `buf`, `Ok(None)` a frame to
    /// skip (our own, or one on its way back); `WouldBlock` when nothing waits.
    pub fn try_recv(&mut self, buf: &mut [u8]) -> io::Result<Option<usize>> {
        match &mut self.ring {
            Some(ring) => match ring.recv(buf) {
                Some(received) => {
                    self.arrived = received
                        .arrived
                        .and_then(|d| std::time::UNIX_EPOCH.checked_add(d));
                    Ok(request(received, buf, Want::Requests))
                }
                None => Err(io::ErrorKind::WouldBlock.into()),
            },
            None => {
                self.arrived = None;
                recv_once(self.fd.as_fd(), buf, Want::Requests)
            }
        }
    }

    /// When the frame [`try_recv`](Self::try_recv) read last reached the socket (the
    /// kernel's stamp, wall-clock time), where the receive ring tells: a frame that waited
    /// while the reader was busy or off its CPU arrived before it was read.
    pub fn arrived(&self) -> Option<std::time::SystemTime> {
        self.arrived
    }

    /// Transmit one frame, retrying for up to `TX_PORT_BUSY` (121 µs) while the TX queue is full;
    /// then the frame is lost, as on a congested line. The retries spin: a thread that slept
    /// between them could wake milliseconds later on a loaded machine, holding the loop.
    pub fn send(&self, frame: &[u8]) -> io::Result<()> {
        // The clock is read only once the queue turns out full: not on every answer's path.
        let mut deadline = None;
        loop {
            match send_once(self.fd.as_fd(), frame) {
                Err(e) if is_queue_full(&e) || e.kind() == io::ErrorKind::WouldBlock => {
                    let now = std::time::Instant::now();
                    if now >= *deadline.get_or_insert(now + TX_PORT_BUSY) {
                        return Err(e);
                    }
                    std::hint::spin_loop();
                }
                r => return r,
            }
        }
    }
}

/// The chain's end of its link ([`crate::cell::link::FrontLink`]): a master's frame is
/// taken in as it came, and the answer goes out on the wire at once. A send that fails is
/// logged, never stops the chain.
impl crate::cell::link::FrontLink for SlaveSocket {
    type In = [u8];
    type Out = [u8];

    fn receive(&mut self, _: crate::cell::link::At, _: &[u8]) -> crate::cell::wire_faults::Verdict {
        crate::cell::wire_faults::Verdict::Pass
    }

    fn transmit(
        &mut self,
        _: crate::cell::link::At,
        frame: &[u8],
    ) -> crate::cell::wire_faults::Verdict {
        use crate::cell::wire_faults::Verdict;
        match self.send(frame) {
            Ok(()) => Verdict::Pass,
            Err(e) if is_queue_full(&e) || e.kind() == io::ErrorKind::WouldBlock => {
                tracing::warn!(interface = self.interface(), "TX queue full, frame lost");
                Verdict::Lost
            }
            Err(e) => {
                tracing::error!(interface = self.interface(), error = %e, "EtherCAT send failed");
                Verdict::Lost
            }
        }
    }
}

impl AsRawFd for SlaveSocket {
    fn as_raw_fd(&self) -> RawFd {
        self.fd.as_raw_fd()
    }
}

/// The TX queue of the interface is full.
pub fn is_queue_full(e: &io::Error) -> bool {
    crate::sys::fd::is_queue_full(e)
}

/// Whether a received frame is a request for the chain: not one that already passed a slave
/// (source MAC bit 0x02 set by the ESC).
pub fn is_request(frame: &[u8]) -> bool {
    frame
        .get(SOURCE_MAC_FIRST)
        .is_some_and(|b| b & SOURCE_MAC_RETURN_BIT == 0)
}

/// Which frames a receiver takes: the slave side takes requests, the master side replies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Want {
    Requests,
    Returned,
}

/// One `recvfrom`: `Some(len)` for a frame to process, `None` for one to skip.
fn recv_once(fd: BorrowedFd<'_>, buf: &mut [u8], want: Want) -> io::Result<Option<usize>> {
    let received = crate::sys::packet_socket::recv(fd, buf)?;
    Ok(request(received, buf, want))
}

/// `Some(len)` for a frame `buf` received that is to be processed, `None` for one to skip.
fn request(received: Received, buf: &[u8], want: Want) -> Option<usize> {
    let n = received.len;
    if received.outgoing || n > buf.len() {
        return None;
    }
    let take = |f: &&[u8]| match want {
        Want::Requests => is_request(f),
        Want::Returned => f.len() > SOURCE_MAC_FIRST && !is_request(f),
    };
    buf.get(..n).filter(take).map(|_| n)
}

fn send_once(fd: BorrowedFd<'_>, frame: &[u8]) -> io::Result<()> {
    let n = crate::sys::packet_socket::send(fd, frame)?;
    if n != frame.len() {
        return Err(io::Error::new(
            io::ErrorKind::WriteZero,
            "short EtherCAT frame write",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn returned_frames_are_not_requests() {
        let mut f = [0u8; 60];
        f[SOURCE_MAC_FIRST] = 0x01; // SOEM's primary MAC 01:01:01:01:01:01
        assert!(is_request(&f));
        f[SOURCE_MAC_FIRST] = 0x03; // the same after a slave
        assert!(!is_request(&f));
        assert!(!is_request(&f[..4]));
    }

    #[tokio::test]
    async fn open_missing_interface_fails() {
        let err = EthercatSocket::open("nosuchecat9").expect_err("no such interface");
        assert_eq!(err.kind(), io::ErrorKind::NotFound);
        assert!(EthercatSocket::open("bad\0name").is_err());
    }
}
