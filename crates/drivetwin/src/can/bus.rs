//! An in-process virtual CAN bus.
//!
//! Every transport (a socketcand client, a SocketCAN bridge) and every drive endpoint holds a
//! [`Port`]. A frame sent on a port reaches every *other* port, never the sender itself, like a
//! SocketCAN RAW socket without `CAN_RAW_RECV_OWN_MSGS`. A [`Tap`] sees every frame, for trace
//! writers and monitors.
//!
//! The hub is a `tokio::sync::broadcast` channel: sending never blocks and never waits for a
//! slow receiver. A receiver that falls more than `capacity` frames behind loses the oldest
//! ones, logs a warning with the count and carries on, as a CAN controller does on overrun.
//! Frames are delivered to every receiver in the order they were sent.

use std::fmt;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

use canopen::CanFrame;
use tokio::sync::broadcast::{self, error::RecvError, error::TryRecvError};

/// Frames a receiver may fall behind before it starts losing frames, when no capacity is given.
pub const DEFAULT_CAPACITY: usize = 4096;

/// Identifies one port on a bus. Port 0 is never handed out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PortId(pub u32);

impl fmt::Display for PortId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "port{}", self.0)
    }
}

/// A frame as it crossed the bus: who sent it and when (wall clock).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BusFrame {
    pub frame: CanFrame,
    pub source: PortId,
    pub timestamp: SystemTime,
}

/// Totals since the bus was created.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BusStats {
    /// Frames sent on the bus by any port.
    pub frames: u64,
    /// Data bytes carried by those frames (remote frames carry none).
    pub bytes: u64,
}

struct Shared {
    tx: broadcast::Sender<BusFrame>,
    /// Serialises stamping and sending, so timestamps never go backwards in delivery order.
    last_stamp: Mutex<SystemTime>,
    next_port: AtomicU32,
    frames: AtomicU64,
    bytes: AtomicU64,
}

impl Shared {
    fn send(&self, source: PortId, frame: CanFrame) -> BusFrame {
        let mut last = self
            .last_stamp
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        // Wall time, but never earlier than the previous frame even if the clock steps back.
        let timestamp = SystemTime::now().max(*last);
        *last = timestamp;
        let bus_frame = BusFrame {
            frame,
            source,
            timestamp,
        };
        // An error only means nobody is listening right now; the frame is lost, as on a bus
        // with no other node.
        let _ = self.tx.send(bus_frame);
        drop(last);
        self.frames.fetch_add(1, Ordering::Relaxed);
        self.bytes
            .fetch_add(frame.payload().len() as u64, Ordering::Relaxed);
        bus_frame
    }
}

/// The bus itself. Cheap to clone; all clones are the same bus.
#[derive(Clone)]
pub struct Bus {
    shared: Arc<Shared>,
}

impl fmt::Debug for Bus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Bus")
            .field("receivers", &self.shared.tx.receiver_count())
            .field("stats", &self.stats())
            .finish()
    }
}

impl Default for Bus {
    fn default() -> Self {
        Bus::new(DEFAULT_CAPACITY)
    }
}

impl Bus {
    /// A bus whose receivers may each fall `capacity` frames behind (at least 1).
    pub fn new(capacity: usize) -> Bus {
        let (tx, _) = broadcast::channel(capacity.max(1));
        Bus {
            shared: Arc::new(Shared {
                tx,
                last_stamp: Mutex::new(SystemTime::UNIX_EPOCH),
                next_port: AtomicU32::new(1),
                frames: AtomicU64::new(0),
                bytes: AtomicU64::new(0),
            }),
        }
    }

    /// Attach a new node. It receives every frame sent after this call by any other port.
    pub fn port(&self) -> Port {
        let id = PortId(self.shared.next_port.fetch_add(1, Ordering::Relaxed));
        Port {
            id,
            rx: self.shared.tx.subscribe(),
            shared: Arc::clone(&self.shared),
        }
    }

    /// A receiver of every frame sent after this call, whatever its source.
    pub fn tap(&self) -> Tap {
        Tap {
            rx: self.shared.tx.subscribe(),
        }
    }

    /// Frame and byte totals since the bus was created.
    pub fn stats(&self) -> BusStats {
        BusStats {
            frames: self.shared.frames.load(Ordering::Relaxed),
            bytes: self.shared.bytes.load(Ordering::Relaxed),
        }
    }
}

/// One node's attachment to the bus.
pub struct Port {
    id: PortId,
    rx: broadcast::Receiver<BusFrame>,
    shared: Arc<Shared>,
}

impl fmt::Debug for Port {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Port").field("id", &self.id).finish()
    }
}

impl Port {
    pub fn id(&self) -> PortId {
        self.id
    }

    /// Put a frame on the bus. Every other port receives it; this one does not.
    /// Returns the frame as stamped by the bus.
    pub fn send(&self, frame: CanFrame) -> BusFrame {
        self.shared.send(self.id, frame)
    }

    /// A cloneable send-only handle with this port's identity, for use from another task.
    pub fn sender(&self) -> PortSender {
        PortSender {
            id: self.id,
            shared: Arc::clone(&self.shared),
        }
    }

    /// The next frame from another port. Waits until one arrives. A port keeps its bus alive,
    /// so this returns `None` only if the bus is gone, which cannot happen while `self` exists;
    /// the `Option` keeps the signature uniform with [`Tap::recv`].
    pub async fn recv(&mut self) -> Option<BusFrame> {
        loop {
            match self.rx.recv().await {
                Ok(f) if f.source == self.id => continue,
                Ok(f) => return Some(f),
                Err(RecvError::Lagged(lost)) => overrun(&self.id.to_string(), lost),
                Err(RecvError::Closed) => return None,
            }
        }
    }

    /// The next frame from another port if one is already waiting.
    pub fn try_recv(&mut self) -> Option<BusFrame> {
        loop {
            match self.rx.try_recv() {
                Ok(f) if f.source == self.id => continue,
                Ok(f) => return Some(f),
                Err(TryRecvError::Lagged(lost)) => overrun(&self.id.to_string(), lost),
                Err(TryRecvError::Empty | TryRecvError::Closed) => return None,
            }
        }
    }

    /// Forget every frame waiting for this port (e.g. when a client starts listening).
    pub fn skip_pending(&mut self) {
        self.rx = self.rx.resubscribe();
    }
}

/// Send half of a [`Port`]: frames sent here carry the port's id and are not delivered back
/// to that port.
#[derive(Clone)]
pub struct PortSender {
    id: PortId,
    shared: Arc<Shared>,
}

impl fmt::Debug for PortSender {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("PortSender").field("id", &self.id).finish()
    }
}

impl PortSender {
    pub fn id(&self) -> PortId {
        self.id
    }

    pub fn send(&self, frame: CanFrame) -> BusFrame {
        self.shared.send(self.id, frame)
    }
}

/// Receives every frame on the bus, including the sender's id.
#[derive(Debug)]
pub struct Tap {
    rx: broadcast::Receiver<BusFrame>,
}

impl Tap {
    /// The next frame; `None` once every [`Bus`], [`Port`] and [`PortSender`] is dropped.
    pub async fn recv(&mut self) -> Option<BusFrame> {
        loop {
            match self.rx.recv().await {
                Ok(f) => return Some(f),
                Err(RecvError::Lagged(lost)) => overrun("tap", lost),
                Err(RecvError::Closed) => return None,
            }
        }
    }

    /// The next frame if one is already waiting.
    pub fn try_recv(&mut self) -> Option<BusFrame> {
        loop {
            match self.rx.try_recv() {
                Ok(f) => return Some(f),
                Err(TryRecvError::Lagged(lost)) => overrun("tap", lost),
                Err(TryRecvError::Empty | TryRecvError::Closed) => return None,
            }
        }
    }
}

fn overrun(receiver: &str, lost: u64) {
    tracing::warn!(
        receiver,
        lost,
        "CAN bus overrun: receiver too slow, frames lost"
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(id: u16, b: u8) -> CanFrame {
        CanFrame::new(id, &[b]).expect("valid frame")
    }

    #[tokio::test]
    async fn delivers_to_others_not_sender_in_order() {
        let bus = Bus::new(16);
        let mut a = bus.port();
        let mut b = bus.port();
        let mut c = bus.port();
        let mut tap = bus.tap();
        assert_ne!(a.id(), b.id());
        for i in 0..5 {
            a.send(frame(0x100, i));
        }
        b.send(frame(0x200, 9));
        for i in 0..5 {
            let got = b.recv().await.expect("frame");
            assert_eq!(got.frame, frame(0x100, i));
            assert_eq!(got.source, a.id());
        }
        assert!(b.try_recv().is_none(), "no echo of own frame");
        for i in 0..5 {
            assert_eq!(c.recv().await.map(|f| f.frame), Some(frame(0x100, i)));
        }
        assert_eq!(c.recv().await.map(|f| f.frame), Some(frame(0x200, 9)));
        assert_eq!(a.recv().await.map(|f| f.frame), Some(frame(0x200, 9)));
        assert!(a.try_recv().is_none());
        let mut seen = Vec::new();
        while let Some(f) = tap.try_recv() {
            seen.push(f);
        }
        assert_eq!(seen.len(), 6);
        assert!(seen.windows(2).all(|w| w[0].timestamp <= w[1].timestamp));
        assert_eq!(
            bus.stats(),
            BusStats {
                frames: 6,
                bytes: 6
            }
        );
    }

    #[tokio::test]
    async fn sender_handle_keeps_identity() {
        let bus = Bus::default();
        let mut a = bus.port();
        let mut b = bus.port();
        let tx = a.sender();
        tokio::spawn(async move {
            tx.send(frame(0x7, 1));
        })
        .await
        .expect("task");
        assert_eq!(b.recv().await.map(|f| f.source), Some(a.id()));
        assert!(a.try_recv().is_none());
    }

    #[tokio::test]
    async fn lagging_receiver_loses_oldest_and_continues() {
        let bus = Bus::new(4);
        let a = bus.port();
        let mut b = bus.port();
        for i in 0..10 {
            a.send(frame(0x10, i));
        }
        // Only the newest `capacity` frames are left.
        let got: Vec<u8> = std::iter::from_fn(|| b.try_recv())
            .map(|f| f.frame.data[0])
            .collect();
        assert_eq!(got, vec![6, 7, 8, 9]);
        a.send(frame(0x10, 42));
        assert_eq!(b.recv().await.map(|f| f.frame.data[0]), Some(42));
    }

    #[tokio::test]
    async fn skip_pending_drops_backlog() {
        let bus = Bus::new(8);
        let a = bus.port();
        let mut b = bus.port();
        a.send(frame(1, 1));
        b.skip_pending();
        assert!(b.try_recv().is_none());
        a.send(frame(1, 2));
        assert_eq!(b.try_recv().map(|f| f.frame.data[0]), Some(2));
    }

    #[tokio::test]
    async fn tap_closes_when_bus_gone() {
        let bus = Bus::new(8);
        let mut tap = bus.tap();
        drop(bus);
        assert!(tap.recv().await.is_none());
    }
}
