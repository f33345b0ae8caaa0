//! The load of a CAN bus over a window: the bit time of the frames asked of it (or seen on
//! it) over the window's length. The cell's timed bus and `drivetwin monitor` measure it the
//! same way, so their figures compare.

use od::Instant;

/// The bit time counted in the window that is running and the load of the last one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadWindow {
    window_nanos: u64,
    start: Instant,
    /// Bit time counted in the running window, ns.
    counted: u64,
    /// Frames counted in the running window.
    frames: u32,
    /// The last complete window: its load (percent) and frames.
    last: Option<(f64, u32)>,
}

impl LoadWindow {
    /// Windows of `window_nanos` (at least 1 ns), the first from `start`.
    pub const fn new(window_nanos: u64, start: Instant) -> Self {
        LoadWindow {
            window_nanos: if window_nanos == 0 { 1 } else { window_nanos },
            start,
            counted: 0,
            frames: 0,
            last: None,
        }
    }

    /// A frame of `nanos` bit time at `now`. Returns the load (percent) and frames of the
    /// window this frame closed, if it closed one.
    pub fn add(&mut self, now: Instant, nanos: u64) -> Option<(f64, u32)> {
        let closed = self.roll(now);
        self.counted = self.counted.saturating_add(nanos);
        self.frames = self.frames.saturating_add(1);
        closed
    }

    /// Closes the running window if `now` is past its end; returns its figures if it did.
    ///
    /// Decision: the load is the bit time over the window's length, so an overloaded bus
    /// shows more than 100 % (the busy time alone stops at 100 % and hides by how much the
    /// bus is short). A window closes at the first event after its end and counts the time
    /// up to it, so a quiet gap lowers the load rather than being skipped.
    pub fn roll(&mut self, now: Instant) -> Option<(f64, u32)> {
        let elapsed = now.as_nanos().saturating_sub(self.start.as_nanos());
        if elapsed < self.window_nanos {
            return None;
        }
        let closed = (percent(self.counted, elapsed), self.frames);
        self.last = Some(closed);
        self.counted = 0;
        self.frames = 0;
        self.start = now;
        Some(closed)
    }

    /// The load of the last complete window; before the first, of the time so far.
    pub fn load_percent(&mut self, now: Instant) -> f64 {
        self.roll(now);
        match self.last {
            Some((load, _)) => load,
            None => percent(
                self.counted,
                now.as_nanos().saturating_sub(self.start.as_nanos()),
            ),
        }
    }
}

/// `counted` ns of bit time in `elapsed` ns, percent.
fn percent(counted: u64, elapsed: u64) -> f64 {
    if elapsed == 0 {
        return 0.0;
    }
    // Precision: f64 is exact for these nanosecond counts below 2^53 (104 days).
    counted as f64 * 100.0 / elapsed as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::time::Duration;

    fn at(ms: u64) -> Instant {
        Instant::ZERO + Duration::from_millis(ms)
    }

    #[test]
    fn a_window_closes_at_the_first_frame_after_its_end() {
        let mut w = LoadWindow::new(500_000_000, Instant::ZERO);
        // 100 frames of 0.5 ms each in the first 500 ms: 10 %.
        for n in 0..100 {
            assert_eq!(w.add(at(n * 5), 500_000), None);
        }
        let (load, frames) = w.add(at(500), 500_000).expect("the first window closed");
        assert!((load - 10.0).abs() < 1e-9, "{load}");
        assert_eq!(frames, 100);
        // The frame that closed it opens the next one.
        assert!((w.load_percent(at(700)) - 10.0).abs() < 1e-9);
        let (load, frames) = w.roll(at(1000)).expect("the second");
        assert!((load - 0.1).abs() < 1e-9, "{load}");
        assert_eq!(frames, 1);
    }

    #[test]
    fn before_the_first_window_the_load_is_of_the_time_so_far() {
        let mut w = LoadWindow::new(500_000_000, Instant::ZERO);
        w.add(at(0), 1_000_000);
        assert!((w.load_percent(at(100)) - 1.0).abs() < 1e-9);
        assert_eq!(
            LoadWindow::new(0, Instant::ZERO).load_percent(Instant::ZERO),
            0.0
        );
    }

    #[test]
    fn more_asked_than_the_bus_carries_shows_above_100() {
        let mut w = LoadWindow::new(1_000_000, Instant::ZERO);
        w.add(at(0), 3_000_000);
        let (load, _) = w.roll(at(1)).expect("closed");
        assert!((load - 300.0).abs() < 1e-9);
    }
}
