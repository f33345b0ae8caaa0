//! The load of a CAN bus over fixed windows: the bit time of the frames asked of it (or seen
//! on it) over the windows' length. The cell's timed bus, its traces and `drivetwin monitor`
//! measure it the same way, so their figures compare.

use od::Instant;

/// Most windows one figure spans ([`LoadWindow::spanning`]).
pub const MAX_SPAN: usize = 8;

/// A window that closed: its load and frames, and the quiet windows (no frame at all) that
/// ended after it, up to the time that closed it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closed {
    /// Bit time over the window's length, percent.
    pub load_percent: f64,
    pub frames: u32,
    /// The window's end.
    pub end: Instant,
    /// Windows after it that ended with no frame.
    pub quiet: u64,
}

/// The bit time counted in the running window and in the last complete ones.
///
/// Decision: windows lie on fixed boundaries of the clock (`start + k × window`), and the
/// time a figure is read never moves them, so steady periodic traffic whose period divides
/// the span of the figure ([`LoadWindow::spanning`]) gives the same figure in every window,
/// whenever it is read. The load is the bit time over the windows' length, so an overloaded
/// bus shows more than 100 % (the busy time alone stops at 100 % and hides by how much the
/// bus is short); a quiet window counts as 0 %, it is not skipped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadWindow {
    window_nanos: u64,
    start: Instant,
    /// The running window's number: it runs from `start + index × window`.
    index: u64,
    /// Bit time counted in the running window, ns.
    counted: u64,
    /// Frames counted in the running window.
    frames: u32,
    /// Bit time of the last complete windows, ns, the newest first.
    recent: [u64; MAX_SPAN],
    /// Windows complete so far.
    complete: u64,
    /// Windows the figure spans, 1 to [`MAX_SPAN`].
    span: usize,
}

impl LoadWindow {
    /// Windows of `window_nanos` (at least 1 ns), the first from `start`; the figure is the
    /// load of the last complete window.
    pub const fn new(window_nanos: u64, start: Instant) -> Self {
        LoadWindow {
            window_nanos: if window_nanos == 0 { 1 } else { window_nanos },
            start,
            index: 0,
            counted: 0,
            frames: 0,
            recent: [0; MAX_SPAN],
            complete: 0,
            span: 1,
        }
    }

    /// The figure ([`LoadWindow::load_percent`]) spans the last `windows` complete windows
    /// (1 to [`MAX_SPAN`]): periodic traffic whose period divides their length shows the same
    /// figure in every window.
    pub const fn spanning(mut self, windows: usize) -> Self {
        self.span = if windows == 0 {
            1
        } else if windows > MAX_SPAN {
            MAX_SPAN
        } else {
            windows
        };
        self
    }

    /// A window's length, ns.
    pub const fn window_nanos(&self) -> u64 {
        self.window_nanos
    }

    /// A frame of `nanos` bit time at `now`. Returns the window its time closed, if it closed
    /// one. A frame dated before the running window (a clock read out of order) counts in it.
    pub fn add(&mut self, now: Instant, nanos: u64) -> Option<Closed> {
        let closed = self.roll(now);
        self.counted = self.counted.saturating_add(nanos);
        self.frames = self.frames.saturating_add(1);
        closed
    }

    /// Closes the running window if it ended by `now` (its end is `now` or earlier); returns
    /// its figures if it did. Reading at any time gives the windows an event would.
    pub fn roll(&mut self, now: Instant) -> Option<Closed> {
        let at = now.as_nanos().saturating_sub(self.start.as_nanos()) / self.window_nanos;
        if at <= self.index {
            return None;
        }
        let closed = Closed {
            load_percent: percent(self.counted, self.window_nanos),
            frames: self.frames,
            end: self.boundary(self.index.saturating_add(1)),
            quiet: at - self.index - 1,
        };
        self.push(self.counted);
        // Quiet windows beyond MAX_SPAN change nothing the ring can still show.
        let shown = closed.quiet.min(MAX_SPAN as u64);
        for _ in 0..shown {
            self.push(0);
        }
        self.complete = self.complete.saturating_add(closed.quiet - shown);
        self.index = at;
        self.counted = 0;
        self.frames = 0;
        Some(closed)
    }

    /// The load over the last complete windows the figure spans (fewer while fewer are
    /// complete; before the first, of the time so far), percent.
    pub fn load_percent(&mut self, now: Instant) -> f64 {
        self.roll(now);
        let n = usize::try_from(self.complete)
            .unwrap_or(usize::MAX)
            .min(self.span);
        if n == 0 {
            let elapsed = now.as_nanos().saturating_sub(self.start.as_nanos());
            return percent(self.counted, elapsed);
        }
        let counted = self
            .recent
            .iter()
            .take(n)
            .fold(0u64, |sum, c| sum.saturating_add(*c));
        percent(counted, self.window_nanos.saturating_mul(n as u64))
    }

    /// The start of window `k`.
    fn boundary(&self, k: u64) -> Instant {
        Instant::from_nanos(
            self.start
                .as_nanos()
                .saturating_add(k.saturating_mul(self.window_nanos)),
        )
    }

    /// One more complete window, of `counted` ns bit time.
    fn push(&mut self, counted: u64) {
        self.recent.rotate_right(1);
        if let Some(newest) = self.recent.first_mut() {
            *newest = counted;
        }
        self.complete = self.complete.saturating_add(1);
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
    extern crate std;

    use super::*;
    use core::time::Duration;
    use std::vec::Vec;

    fn at(ms: u64) -> Instant {
        Instant::ZERO + Duration::from_millis(ms)
    }

    fn at_us(us: u64) -> Instant {
        Instant::ZERO + Duration::from_micros(us)
    }

    #[test]
    fn windows_close_on_fixed_boundaries() {
        let mut w = LoadWindow::new(500_000_000, Instant::ZERO);
        // 100 frames of 0.5 ms each in the first 500 ms: 10 %.
        for n in 0..100 {
            assert_eq!(w.add(at(n * 5), 500_000), None);
        }
        let c = w.add(at(500), 500_000).expect("the first window closed");
        assert!((c.load_percent - 10.0).abs() < 1e-9, "{c:?}");
        assert_eq!((c.frames, c.end, c.quiet), (100, at(500), 0));
        // Read in the running window: the last complete one.
        assert!((w.load_percent(at(700)) - 10.0).abs() < 1e-9);
        // The next frame comes 1.2 s later: the second window ends at 1000 ms, whatever
        // closed it, and the one from 1000 to 1500 ms is quiet.
        let c = w.add(at(1700), 500_000).expect("the second");
        assert!((c.load_percent - 0.1).abs() < 1e-9, "{c:?}");
        assert_eq!((c.frames, c.end, c.quiet), (1, at(1000), 1));
        assert_eq!(w.load_percent(at(1999)), 0.0, "the quiet window");
        let c = w.roll(at(2000)).expect("the fourth");
        assert!((c.load_percent - 0.1).abs() < 1e-9, "{c:?}");
        assert_eq!((c.end, c.quiet), (at(2000), 0));
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
        let c = w.roll(at(1)).expect("closed");
        assert!((c.load_percent - 300.0).abs() < 1e-9);
    }

    /// A pseudo-random read time in each 100 ms (xorshift, fixed seed): reads at arbitrary
    /// times, the same for every run.
    fn read_times(until_ms: u64) -> impl Iterator<Item = Instant> {
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        (0..until_ms / 100).map(move |k| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            at_us(k * 100_000 + x % 100_000)
        })
    }

    /// Frames of `nanos` every `period_ms` from `phase_us`, and reads at arbitrary times in
    /// between: the figure each read gives, from `from_ms` on.
    fn figures(
        mut w: LoadWindow,
        period_ms: u64,
        phase_us: u64,
        nanos: u64,
        from_ms: u64,
    ) -> Vec<f64> {
        let until = 20_000;
        let mut frames = (0..)
            .map(|k| at_us(phase_us + k * period_ms * 1000))
            .peekable();
        let mut seen = Vec::new();
        for read in read_times(until) {
            while let Some(&t) = frames.peek() {
                if t > read {
                    break;
                }
                w.add(t, nanos);
                frames.next();
            }
            let load = w.load_percent(read);
            if read >= at(from_ms) {
                seen.push(load);
            }
        }
        seen
    }

    /// The cell's bus at rest: a heartbeat (454 µs of bits) every 1000 ms, read every 100 ms
    /// or so at arbitrary times. One 500 ms window alternates 0.09 % and 0 %; a figure over
    /// two windows shows the same 0.045 % at every read.
    #[test]
    fn a_heartbeat_read_at_arbitrary_times_shows_one_figure() {
        let w = LoadWindow::new(500_000_000, Instant::ZERO).spanning(2);
        let seen = figures(w, 1000, 2_345, 454_000, 1000);
        assert!(seen.len() > 150);
        for load in &seen {
            assert!((load - 0.0454).abs() < 1e-9, "{seen:?}");
        }
        // One window alone is honest about each window, and flickers.
        let single = figures(
            LoadWindow::new(500_000_000, Instant::ZERO),
            1000,
            2_345,
            454_000,
            1000,
        );
        assert!(single.contains(&0.0));
        assert!(single.iter().any(|l| (l - 0.0908).abs() < 1e-9));
    }

    /// SYNCs every 10 ms and TPDOs every 250 ms, at phases that do not fall on a boundary:
    /// the same figure at every read, for every phase, once the traffic has run through the
    /// two windows the figure spans.
    #[test]
    fn periodic_traffic_gives_the_same_figure_in_every_window() {
        for phase_us in [0, 1, 4_999, 123_456, 249_999] {
            for (period_ms, nanos, expect) in [(10, 408_000, 4.08), (250, 1_000_000, 0.4)] {
                let w = LoadWindow::new(500_000_000, Instant::ZERO).spanning(2);
                let seen = figures(w, period_ms, phase_us, nanos, 1500);
                for load in &seen {
                    assert!(
                        (load - expect).abs() < 1e-9,
                        "period {period_ms} ms, phase {phase_us} µs: {load}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_long_quiet_gap_empties_the_figure_and_is_counted() {
        let mut w = LoadWindow::new(500_000_000, Instant::ZERO).spanning(2);
        w.add(at(100), 5_000_000);
        assert!(
            (w.load_percent(at(999)) - 1.0).abs() < 1e-9,
            "one window complete"
        );
        // The read closed the first window; the frame an hour later closes the second (empty)
        // and counts the quiet ones after it.
        let c = w.add(at(3_600_000), 1).expect("closed");
        assert_eq!((c.frames, c.end, c.quiet), (0, at(1000), 7_198));
        assert_eq!(w.load_percent(at(3_600_000)), 0.0);
    }
}
