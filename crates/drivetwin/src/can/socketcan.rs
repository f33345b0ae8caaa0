//! Linux SocketCAN transport: a raw `AF_CAN` socket on a real or virtual (`vcan`) interface,
//! and a bridge between it and the in-process [`Bus`].
//!
//! The socket is a plain `CAN_RAW` socket with the kernel defaults: it does not receive its
//! own frames (so the bridge cannot loop), other sockets on the same host do see them, no
//! CAN FD and no error frames. Frames are exchanged as the 16-byte `struct can_frame`, whose
//! identifier is in host byte order. The socket is Linux's (`sys::socketcan`).

use std::io;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd, OwnedFd, RawFd};
use std::time::Duration;

use canopen::CanFrame;
use tokio::io::unix::AsyncFd;

use crate::can::bus::{Bus, Port};

const CAN_EFF_FLAG: u32 = 0x8000_0000;
const CAN_RTR_FLAG: u32 = 0x4000_0000;
const CAN_ERR_FLAG: u32 = 0x2000_0000;
/// `sizeof(struct can_frame)`.
const CAN_MTU: usize = 16;

/// How long [`CanSocket::send`] keeps retrying while the interface's TX queue is full.
const TX_QUEUE_FULL_PATIENCE: Duration = Duration::from_millis(100);

/// The `struct can_frame` bytes of `frame` (identifier in host byte order, data zero padded).
pub fn encode_can_frame(frame: &CanFrame) -> [u8; CAN_MTU] {
    let mut id = if frame.extended {
        (frame.id & CanFrame::MAX_EXTENDED_ID) | CAN_EFF_FLAG
    } else {
        frame.id & CanFrame::MAX_STANDARD_ID
    };
    if frame.rtr {
        id |= CAN_RTR_FLAG;
    }
    let mut out = [0u8; CAN_MTU];
    let [i0, i1, i2, i3] = id.to_ne_bytes();
    // can_id, can_dlc, 3 bytes of padding, then the data (payload() holds at most 8 bytes).
    let head = [i0, i1, i2, i3, frame.len.min(8), 0, 0, 0];
    for (dst, src) in out.iter_mut().zip(head.iter().chain(frame.payload())) {
        *dst = *src;
    }
    out
}

/// The frame in `struct can_frame` bytes, or `None` for an error frame or a wrong size.
pub fn decode_can_frame(bytes: &[u8]) -> Option<CanFrame> {
    let bytes: &[u8; CAN_MTU] = bytes.try_into().ok()?;
    let (head, rest) = bytes.split_first_chunk::<4>()?;
    let raw_id = u32::from_ne_bytes(*head);
    if raw_id & CAN_ERR_FLAG != 0 {
        return None;
    }
    let extended = raw_id & CAN_EFF_FLAG != 0;
    let rtr = raw_id & CAN_RTR_FLAG != 0;
    let id = raw_id
        & if extended {
            CanFrame::MAX_EXTENDED_ID
        } else {
            CanFrame::MAX_STANDARD_ID
        };
    let len = rest.first().copied().unwrap_or(0).min(8);
    let mut data = [0u8; 8];
    if !rtr {
        data.copy_from_slice(rest.get(4..12)?);
        // Keep bytes beyond `len` zero, whatever the driver left there.
        for b in data.iter_mut().skip(usize::from(len)) {
            *b = 0;
        }
    }
    Some(CanFrame {
        id,
        extended,
        rtr,
        len,
        data,
    })
}

/// A non-blocking raw CAN socket bound to one interface.
#[derive(Debug)]
pub struct CanSocket {
    fd: AsyncFd<OwnedFd>,
    interface: String,
}

impl CanSocket {
    /// Open a `CAN_RAW` socket on `interface` (e.g. `can0`, `vcan0`). Must be called inside a
    /// tokio runtime.
    pub fn open(interface: &str) -> io::Result<CanSocket> {
        let fd = crate::sys::fd::register_async(crate::sys::socketcan::open(interface)?)?;
        Ok(CanSocket {
            fd,
            interface: interface.to_owned(),
        })
    }

    pub fn interface(&self) -> &str {
        &self.interface
    }

    /// The next classic CAN frame from the interface (error and CAN FD frames are skipped).
    pub async fn recv(&self) -> io::Result<CanFrame> {
        loop {
            let mut guard = self.fd.readable().await?;
            match guard.try_io(|fd| read_once(fd.get_ref().as_fd())) {
                Ok(Ok(Some(frame))) => return Ok(frame),
                Ok(Ok(None)) => continue,
                Ok(Err(e)) => return Err(e),
                Err(_would_block) => continue,
            }
        }
    }

    /// Transmit one frame. While the interface's TX queue is full (`ENOBUFS`) it retries for
    /// up to 100 ms, then returns that error.
    pub async fn send(&self, frame: &CanFrame) -> io::Result<()> {
        let bytes = encode_can_frame(frame);
        let deadline = tokio::time::Instant::now() + TX_QUEUE_FULL_PATIENCE;
        loop {
            let mut guard = self.fd.writable().await?;
            match guard.try_io(|fd| write_once(fd.get_ref().as_fd(), &bytes)) {
                Ok(Ok(())) => return Ok(()),
                Ok(Err(e)) if is_queue_full(&e) && tokio::time::Instant::now() < deadline => {
                    drop(guard);
                    tokio::time::sleep(Duration::from_millis(1)).await;
                }
                Ok(Err(e)) => return Err(e),
                Err(_would_block) => continue,
            }
        }
    }
}

/// A non-blocking raw CAN socket for a poll loop (the cell loop registers its descriptor).
#[derive(Debug)]
pub struct RawCanSocket {
    fd: OwnedFd,
    interface: String,
}

impl RawCanSocket {
    /// Open a `CAN_RAW` socket on `interface`, non-blocking.
    pub fn open(interface: &str) -> io::Result<RawCanSocket> {
        Ok(RawCanSocket {
            fd: crate::sys::socketcan::open(interface)?,
            interface: interface.to_owned(),
        })
    }

    pub fn interface(&self) -> &str {
        &self.interface
    }

    pub fn as_raw_fd(&self) -> RawFd {
        self.fd.as_raw_fd()
    }

    /// One received frame; `Ok(None)` for a frame that is not classic CAN (skipped);
    /// `WouldBlock` when nothing waits.
    pub fn try_recv(&self) -> io::Result<Option<CanFrame>> {
        read_once(self.fd.as_fd())
    }

    /// Transmit one frame now, or fail (`ENOBUFS`: the TX queue is full, the frame is lost
    /// as a controller drops it).
    pub fn try_send(&self, frame: &CanFrame) -> io::Result<()> {
        write_once(self.fd.as_fd(), &encode_can_frame(frame))
    }
}

fn is_queue_full(e: &io::Error) -> bool {
    crate::sys::fd::is_queue_full(e)
}

fn read_once(fd: BorrowedFd<'_>) -> io::Result<Option<CanFrame>> {
    // Room for a CAN FD frame (72 bytes) so an FD frame is read whole and then skipped.
    let mut buf = [0u8; 72];
    let n = crate::sys::fd::read(fd, &mut buf)?;
    Ok(buf.get(..n).and_then(decode_can_frame))
}

fn write_once(fd: BorrowedFd<'_>, bytes: &[u8; CAN_MTU]) -> io::Result<()> {
    let n = crate::sys::fd::write(fd, bytes)?;
    if n != bytes.len() {
        return Err(io::Error::new(
            io::ErrorKind::WriteZero,
            "short CAN frame write",
        ));
    }
    Ok(())
}

/// Move frames both ways between `socket` and `port` until the socket fails (e.g. the
/// interface goes down). A frame the interface cannot queue is dropped with a warning, as a
/// CAN controller drops frames when its TX buffer is full.
pub async fn bridge(socket: CanSocket, mut port: Port) -> io::Result<()> {
    tracing::info!(interface = %socket.interface(), port = %port.id(), "SocketCAN bridge up");
    loop {
        tokio::select! {
            received = socket.recv() => {
                port.send(received?);
            }
            Some(bus_frame) = port.recv() => {
                match socket.send(&bus_frame.frame).await {
                    Ok(()) => {}
                    Err(e) if is_queue_full(&e) => {
                        tracing::warn!(interface = %socket.interface(), "SocketCAN TX queue full, frame dropped");
                    }
                    Err(e) => return Err(e),
                }
            }
        }
    }
}

/// Open `interface` and bridge it to `bus` (see [`bridge`]).
pub async fn bridge_interface(interface: &str, bus: &Bus) -> io::Result<()> {
    let socket = CanSocket::open(interface)?;
    bridge(socket, bus.port()).await
}

/// Whether a network interface with this name exists (e.g. to skip tests without `vcan0`).
pub fn interface_exists(interface: &str) -> bool {
    crate::sys::net_interface::exists(interface)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn can_frame_layout_round_trip() {
        let std = CanFrame::new(0x605, &[0x40, 0x18, 0x10, 0x01]).expect("frame");
        let bytes = encode_can_frame(&std);
        assert_eq!(bytes.get(..4), Some(&0x605u32.to_ne_bytes()[..]));
        assert_eq!(bytes.get(4..8), Some(&[4, 0, 0, 0][..]));
        assert_eq!(
            bytes.get(8..),
            Some(&[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0][..])
        );
        assert_eq!(decode_can_frame(&bytes), Some(std));

        let ext = CanFrame::with_id(0x1ABC_DEF0, true, &[1, 2, 3, 4, 5, 6, 7, 8]).expect("frame");
        let bytes = encode_can_frame(&ext);
        assert_eq!(
            bytes.get(..4),
            Some(&(0x1ABC_DEF0u32 | CAN_EFF_FLAG).to_ne_bytes()[..])
        );
        assert_eq!(decode_can_frame(&bytes), Some(ext));

        let rtr = CanFrame::remote(0x705, 1);
        let bytes = encode_can_frame(&rtr);
        assert_eq!(
            bytes.get(..4),
            Some(&(0x705 | CAN_RTR_FLAG).to_ne_bytes()[..])
        );
        assert_eq!(decode_can_frame(&bytes), Some(rtr));
    }

    #[test]
    fn decode_rejects_error_frames_and_bad_sizes() {
        let mut bytes = [0u8; CAN_MTU];
        bytes[..4].copy_from_slice(&(CAN_ERR_FLAG | 0x4).to_ne_bytes());
        assert_eq!(decode_can_frame(&bytes), None);
        assert_eq!(decode_can_frame(&[0u8; 72]), None);
        assert_eq!(decode_can_frame(&[]), None);
        // A DLC above 8 is clamped and stray bytes beyond `len` are cleared.
        let mut odd = [0xFFu8; CAN_MTU];
        odd[..4].copy_from_slice(&0x123u32.to_ne_bytes());
        odd[4] = 2;
        let frame = decode_can_frame(&odd).expect("frame");
        assert_eq!(frame, CanFrame::new(0x123, &[0xFF, 0xFF]).expect("frame"));
        odd[4] = 15;
        assert_eq!(decode_can_frame(&odd).map(|f| f.len), Some(8));
    }

    #[tokio::test]
    async fn open_missing_interface_fails() {
        let err = CanSocket::open("nosuchcan9").expect_err("no such interface");
        assert_eq!(err.kind(), io::ErrorKind::NotFound);
        assert!(CanSocket::open("bad\0name").is_err());
        assert!(!interface_exists("nosuchcan9"));
    }

    #[tokio::test]
    async fn vcan0_bridge() {
        if !interface_exists("vcan0") {
            println!(
                "SKIPPED: no vcan0 interface (ip link add dev vcan0 type vcan && ip link set up vcan0)"
            );
            return;
        }
        let bus = Bus::new(64);
        let mut node = bus.port();
        let bridge_task = tokio::spawn({
            let bus = bus.clone();
            async move { bridge_interface("vcan0", &bus).await }
        });
        let peer = CanSocket::open("vcan0").expect("open vcan0");
        // Give the bridge time to bind before traffic starts.
        tokio::time::sleep(Duration::from_millis(100)).await;

        let from_wire = CanFrame::new(0x181, &[1, 2, 3]).expect("frame");
        peer.send(&from_wire).await.expect("send on vcan0");
        let got = tokio::time::timeout(Duration::from_secs(2), node.recv())
            .await
            .expect("frame reaches the bus in time")
            .expect("frame");
        assert_eq!(got.frame, from_wire);

        let from_bus = CanFrame::with_id(0x18FF_0001, true, &[9]).expect("frame");
        node.send(from_bus);
        let got = tokio::time::timeout(Duration::from_secs(2), peer.recv())
            .await
            .expect("frame reaches vcan0 in time")
            .expect("recv");
        assert_eq!(got, from_bus);
        bridge_task.abort();
    }
}
