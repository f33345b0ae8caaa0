//! The time a cell's CAN bus takes (`bitrate = …` on a `[[bus]]`): every frame, a drive's or
//! an outside client's, waits for the bus, wins or loses the arbitration and occupies the wire
//! for its exact bit time ([`canbus::timed_bus`]); the drives receive it when it has crossed.
//! Counted here: frames, late frames, frames lost to a full transmit queue, the bus load.

use std::time::Duration;

use canbus::bus_load::LoadWindow;
use canbus::timed_bus::{TimedBus, Transmission};
use canopen::CanFrame;
use od::Instant;

/// Frames waiting for the bus at most (every node's transmit queue together): a bus asked for
/// more than it carries for long enough loses frames, as the nodes' queues overflow.
pub const MAX_QUEUED: usize = 1024;

/// The window the bus load is measured over, on fixed boundaries of the cell's clock.
pub const LOAD_WINDOW: Duration = Duration::from_millis(500);

/// Windows the cell's load figure spans (1 s): the usual periods of a CANopen bus at rest (a
/// 1000 ms heartbeat, 100 to 500 ms event timers, SYNC cycles) divide it, so steady traffic
/// shows one figure, not one window with a heartbeat and the next without.
pub const LOAD_FIGURE_WINDOWS: usize = 2;

/// Source number of frames from outside the cell (clients, SocketCAN, injected).
pub const OUTSIDE: u16 = u16::MAX;

/// What the bus did so far.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BusFigures {
    pub bitrate: u32,
    /// Frames that crossed the bus.
    pub frames: u64,
    /// Of these, frames that waited longer than the late limit for the bus.
    pub late: u64,
    /// Frames lost: the transmit queues were full.
    pub dropped: u64,
    /// Frames waiting now.
    pub queued: usize,
    /// Bus load of the last complete windows ([`LOAD_FIGURE_WINDOWS`] of [`LOAD_WINDOW`];
    /// before the first, of the time so far), percent; more than 100 means more was asked of
    /// the bus than it carries (the queue grows).
    pub load_percent: f64,
    /// The longest wait of a frame for the bus so far.
    pub longest_wait: Duration,
}

/// A cell's bus with its bit time.
pub struct BusTiming {
    bus: TimedBus<MAX_QUEUED>,
    late_after: Duration,
    figures: BusFigures,
    /// Bit time asked of the bus: frames submitted, each counted once, carried or lost.
    load: LoadWindow,
}

impl BusTiming {
    /// A bus at `bitrate` bit/s; a frame that waits longer than `late_after` counts as late.
    pub fn new(bitrate: u32, late_after: Duration) -> Self {
        BusTiming {
            bus: TimedBus::new(bitrate),
            late_after,
            figures: BusFigures {
                bitrate: bitrate.max(1),
                ..BusFigures::default()
            },
            load: LoadWindow::new(
                u64::try_from(LOAD_WINDOW.as_nanos()).unwrap_or(u64::MAX),
                Instant::ZERO,
            )
            .spanning(LOAD_FIGURE_WINDOWS),
        }
    }

    /// `source` (a drive's index, or [`OUTSIDE`]) has `frame` ready at `now`.
    pub fn submit(&mut self, now: Instant, source: u16, frame: CanFrame) {
        self.load.add(now, self.bus.frame_nanos(&frame));
        match self.bus.submit(now, source, frame) {
            Ok(()) => {}
            Err(_) => {
                self.figures.dropped += 1;
                tracing::debug!(id = frame.id, "CAN transmit queues full, frame lost");
            }
        }
    }

    /// The next frame that has crossed the bus by `now`, in bus order.
    pub fn poll(&mut self, now: Instant) -> Option<Transmission> {
        let tx = self.bus.poll(now)?;
        self.figures.frames += 1;
        let waited = Duration::from_nanos(tx.queued_nanos());
        if waited > self.late_after {
            self.figures.late += 1;
        }
        self.figures.longest_wait = self.figures.longest_wait.max(waited);
        Some(tx)
    }

    pub fn deadline(&self) -> Option<Instant> {
        self.bus.deadline()
    }

    /// Whether `frame`, ready at `now`, would wait for the bus (busy, or a waiting frame wins
    /// the arbitration).
    pub fn would_wait(&self, now: Instant, frame: &CanFrame) -> bool {
        self.bus.would_wait(now, frame)
    }

    pub fn bitrate(&self) -> u32 {
        self.bus.bitrate()
    }

    /// The figures as of `now`.
    pub fn figures(&mut self, now: Instant) -> BusFigures {
        let mut figures = self.figures;
        figures.queued = self.bus.queued();
        figures.load_percent = self.load.load_percent(now);
        figures
    }
}
