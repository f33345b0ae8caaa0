//! The jerk-free profile (6086h = 2, CMMP-AS §7.3): the trapezoid's position set-points
//! through a moving average. Averaging positions over a window T turns each acceleration
//! step into a ramp of length T (limited jerk), keeps the end position exact, and delays the
//! profile by T/2.

/// Longest window in set-points (at a 500 µs position cycle: 0.5 s).
pub const MAX_WINDOW: usize = 1000;

#[derive(Debug, Clone)]
pub struct Smoother {
    buf: [f64; MAX_WINDOW],
    len: usize,
    head: usize,
    /// Sum of the set-points in the window relative to `base`, so long runs keep precision.
    sum: f64,
    base: f64,
}

impl Default for Smoother {
    fn default() -> Self {
        Smoother {
            buf: [0.0; MAX_WINDOW],
            len: 1,
            head: 0,
            sum: 0.0,
            base: 0.0,
        }
    }
}

impl Smoother {
    /// Restarts at rest at `position` with a window of `len` set-points (1 = no smoothing).
    pub fn reset(&mut self, position: f64, len: usize) {
        self.len = len.clamp(1, MAX_WINDOW);
        self.base = position;
        self.head = 0;
        self.sum = 0.0;
        for v in self.buf.iter_mut().take(self.len) {
            *v = 0.0;
        }
    }

    pub fn window(&self) -> usize {
        self.len
    }

    /// Feeds one set-point, returns the smoothed one.
    pub fn push(&mut self, position: f64) -> f64 {
        if self.len == 1 {
            return position;
        }
        let x = position - self.base;
        if let Some(slot) = self.buf.get_mut(self.head) {
            self.sum += x - *slot;
            *slot = x;
        }
        self.head = (self.head + 1) % self.len;
        self.base + self.sum / self.len as f64
    }

    /// Whether the output has caught up with a constant input `position`.
    pub fn settled(&self, position: f64) -> bool {
        if self.len == 1 {
            return true;
        }
        let x = position - self.base;
        self.buf.iter().take(self.len).all(|v| *v == x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_becomes_s_curve_and_ends_exactly() {
        let mut s = Smoother::default();
        s.reset(0.0, 10);
        let mut out = [0.0f64; 40];
        for (i, o) in out.iter_mut().enumerate() {
            let input = if i < 20 { i as f64 } else { 20.0 };
            *o = s.push(input);
        }
        assert_eq!(out[39], 20.0);
        assert!(s.settled(20.0));
        // Velocity changes gradually at the start (no step in velocity).
        let v1 = out[1] - out[0];
        let v5 = out[5] - out[4];
        assert!(v1 < v5);
    }

    #[test]
    fn window_one_passes_through() {
        let mut s = Smoother::default();
        s.reset(5.0, 1);
        assert_eq!(s.push(7.5), 7.5);
    }
}
