//! A faulted position encoder: what the drive reads when the encoder cable is pulled or the
//! signal is disturbed. The motor turns as before; only the drive's reading of it changes,
//! and the drive's own supervision finds the fault from that reading.
//!
//! * Disconnected: the reading stands still at the last value read (no more counts); the
//!   encoder evaluation reports the lost signal (CMMP-AS 08-0, Kinco "Encoder not
//!   connected", CMMO-ST 06h).
//! * Noisy: each reading is off by up to ± `amplitude` increments (count errors from a
//!   disturbed signal). Decision: the noise is a fixed xorshift sequence, so the same run
//!   gives the same readings bit for bit (no RNG); the drive reports it as a signal error
//!   once it is beyond the plausibility limit [`PLAUSIBLE_NOISE`].
//!
//! The fault is an offset added to the true reading, refreshed once per logic cycle: no
//! allocation, a few integer operations.

/// What is wrong with the encoder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EncoderFault {
    #[default]
    Connected,
    /// The cable is broken: no signal.
    Disconnected,
    /// Each reading off by up to ± `amplitude` internal increments.
    Noisy { amplitude: u32 },
}

/// Decision (CHOSEN): a disturbance larger than 1/64 revolution (1024 of the 65536
/// internal increments) between two readings is beyond what the motor can move in one
/// cycle at its rated speed, so the drive's plausibility check calls it an encoder error;
/// smaller noise only roughens the reading.
pub const PLAUSIBLE_NOISE: u32 = 1024;

/// The encoder between the shaft and the drive's reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Encoder {
    fault: EncoderFault,
    /// The reading when the cable broke.
    frozen: Option<i64>,
    /// xorshift32 state of the noise.
    noise: u32,
    /// What the reading is off by now.
    error: i64,
}

impl Default for Encoder {
    fn default() -> Self {
        Encoder {
            fault: EncoderFault::Connected,
            frozen: None,
            noise: 0x2545_F491,
            error: 0,
        }
    }
}

impl Encoder {
    pub fn fault(&self) -> EncoderFault {
        self.fault
    }

    /// Faults the encoder (or repairs it: [`EncoderFault::Connected`]).
    pub fn set_fault(&mut self, fault: EncoderFault) {
        if fault != EncoderFault::Disconnected {
            self.frozen = None;
        }
        if fault == EncoderFault::Connected {
            self.error = 0;
        }
        self.fault = fault;
    }

    /// What the reading is off by (add it to the true reading).
    #[inline]
    pub fn error(&self) -> i64 {
        self.error
    }

    /// Whether the drive's encoder evaluation sees a fault: no signal, or noise beyond the
    /// plausibility limit.
    pub fn signal_lost(&self) -> bool {
        self.fault == EncoderFault::Disconnected
    }

    /// Noise beyond [`PLAUSIBLE_NOISE`].
    pub fn implausible(&self) -> bool {
        matches!(self.fault, EncoderFault::Noisy { amplitude } if amplitude > PLAUSIBLE_NOISE)
    }

    /// One reading of `true_position` (increments): the error for it from now on.
    #[inline]
    pub fn update(&mut self, true_position: i64) {
        self.error = match self.fault {
            EncoderFault::Connected => 0,
            EncoderFault::Disconnected => {
                let at = *self.frozen.get_or_insert(true_position);
                at.wrapping_sub(true_position)
            }
            EncoderFault::Noisy { amplitude } => {
                let mut x = self.noise;
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                self.noise = x;
                let span = u64::from(amplitude) * 2 + 1;
                (u64::from(x) % span) as i64 - i64::from(amplitude)
            }
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_broken_cable_freezes_the_reading() {
        let mut e = Encoder::default();
        e.update(100);
        assert_eq!(e.error(), 0);
        e.set_fault(EncoderFault::Disconnected);
        e.update(100);
        e.update(5000);
        assert_eq!(5000 + e.error(), 100);
        assert!(e.signal_lost());
        e.set_fault(EncoderFault::Connected);
        e.update(6000);
        assert_eq!(e.error(), 0);
        assert!(!e.signal_lost());
    }

    #[test]
    fn noise_stays_within_its_amplitude_and_repeats() {
        let mut a = Encoder::default();
        let mut b = Encoder::default();
        a.set_fault(EncoderFault::Noisy { amplitude: 50 });
        b.set_fault(EncoderFault::Noisy { amplitude: 50 });
        let mut seen_nonzero = false;
        for i in 0..1000 {
            a.update(i);
            b.update(i);
            assert!(a.error().abs() <= 50);
            assert_eq!(a.error(), b.error());
            seen_nonzero |= a.error() != 0;
        }
        assert!(seen_nonzero);
        assert!(!a.implausible());
        a.set_fault(EncoderFault::Noisy {
            amplitude: PLAUSIBLE_NOISE + 1,
        });
        assert!(a.implausible());
    }
}
