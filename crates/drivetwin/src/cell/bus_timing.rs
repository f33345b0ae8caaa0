//! The time a cell's CAN bus takes (`bitrate = …` on a `[[bus]]`): every frame, a drive's or
//! an outside client's, waits for the bus, wins or loses the arbitration and occupies the wire
//! for its exact bit time ([`canopen::timed_bus`]); the drives receive it when it has crossed.
//! Counted here: frames, late frames, frames lost to a full transmit queue, the bus load.

use std::time::Duration;

use canopen::timed_bus::{TimedBus, Transmission};
use canopen::CanFrame;
use od::Instant;

/// Frames waiting for the bus at most (every node's transmit queue together): a bus asked for
/// more than it carries for long enough loses frames, as the nodes' queues overflow.
pub const MAX_QUEUED: usize = 1024;

/// The window the bus load is measured over.
pub const LOAD_WINDOW: Duration = Duration::from_millis(500);

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
    /// Bus load of the last complete window ([`LOAD_WINDOW`]; before the first, of the time
    /// so far), percent; more than 100 means more was asked of the bus than it carries (the
    /// queue grows).
    pub load_percent: f64,
    /// The longest wait of a frame for the bus so far.
    pub longest_wait: Duration,
}

/// A cell's bus with its bit time.
pub struct BusTiming {
    bus: TimedBus<MAX_QUEUED>,
    late_after: Duration,
    figures: BusFigures,
    window_start: Instant,
    /// Bit time asked in the current window: frames submitted, each counted once.
    window_asked: u64,
    /// Whether a window has completed (else the load is of the window so far).
    complete: bool,
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
            window_start: Instant::ZERO,
            window_asked: 0,
            complete: false,
        }
    }

    /// `source` (a drive's index, or [`OUTSIDE`]) has `frame` ready at `now`.
    pub fn submit(&mut self, now: Instant, source: u16, frame: CanFrame) {
        self.roll_window(now);
        // Asked of the bus, carried or lost.
        self.window_asked += self.bus.frame_nanos(&frame);
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

    pub fn bitrate(&self) -> u32 {
        self.bus.bitrate()
    }

    /// The figures as of `now`.
    pub fn figures(&mut self, now: Instant) -> BusFigures {
        self.roll_window(now);
        let mut figures = self.figures;
        figures.queued = self.bus.queued();
        if !self.complete {
            figures.load_percent = load(self.window_asked, now.as_nanos());
        }
        figures
    }

    /// Decision: the load of a window is the bit time asked of the bus in it over the
    /// window's length, so an overloaded bus shows more than 100 % (the busy time alone
    /// stops at 100 % and hides by how much the bus is short).
    fn roll_window(&mut self, now: Instant) {
        let window = u64::try_from(LOAD_WINDOW.as_nanos()).unwrap_or(u64::MAX);
        let elapsed = now.as_nanos().saturating_sub(self.window_start.as_nanos());
        if elapsed < window {
            return;
        }
        self.figures.load_percent = load(self.window_asked, elapsed);
        self.complete = true;
        self.window_asked = 0;
        self.window_start = now;
    }
}

/// `asked` ns of bit time in `elapsed` ns, percent.
fn load(asked: u64, elapsed: u64) -> f64 {
    if elapsed == 0 {
        return 0.0;
    }
    // Precision: f64 is exact for these nanosecond counts below 2^53 (104 days).
    asked as f64 * 100.0 / elapsed as f64
}
