//! CAN fault confinement (ISO 11898-1 §12): a node's transmit and receive error counters and
//! its error state. A transmit error costs 8, a receive error 1; every frame sent or received
//! without error gives one back. Above 127 the node is error passive; a transmit counter above
//! 255 takes it off the bus (bus off) until it has seen 128 times 11 recessive bits.
//!
//! Sans-IO: the runtime reports what happened to the node's frames and asks for the state.

use od::Instant;

use crate::frame_time::bits_to_nanos;

/// Error passive above this count.
pub const PASSIVE_LIMIT: u16 = 127;
/// Bus off above this transmit error count.
pub const BUS_OFF_LIMIT: u16 = 255;
/// Bus-off recovery: 128 occurrences of 11 consecutive recessive bits.
pub const RECOVERY_BITS: u32 = 128 * 11;
/// An error frame: error flag (6) with the others' superposed flags (up to 6 more), the
/// delimiter (8) and the intermission (3), at most.
pub const ERROR_FRAME_BITS: u32 = 6 + 6 + 8 + 3;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorState {
    Active,
    Passive,
    BusOff,
}

impl ErrorState {
    pub fn name(self) -> &'static str {
        match self {
            ErrorState::Active => "error active",
            ErrorState::Passive => "error passive",
            ErrorState::BusOff => "bus off",
        }
    }
}

/// A change of error state, for the device's reaction (EMCY, fault).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Transition {
    pub from: ErrorState,
    pub to: ErrorState,
}

/// One node's error counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultConfinement {
    tec: u16,
    rec: u16,
    state: ErrorState,
    /// Bus off: when the node may take part again.
    back_at: Option<Instant>,
}

impl Default for FaultConfinement {
    fn default() -> Self {
        FaultConfinement {
            tec: 0,
            rec: 0,
            state: ErrorState::Active,
            back_at: None,
        }
    }
}

impl FaultConfinement {
    pub fn state(&self) -> ErrorState {
        self.state
    }

    /// Transmit and receive error counters.
    pub fn counters(&self) -> (u16, u16) {
        (self.tec, self.rec)
    }

    /// Whether the node takes part on the bus (sends and receives).
    pub fn on_bus(&self) -> bool {
        self.state != ErrorState::BusOff
    }

    /// A frame of this node failed (error frame) at `now` on a bus of `bitrate` bit/s.
    pub fn transmit_error(&mut self, now: Instant, bitrate: u32) -> Option<Transition> {
        if self.state == ErrorState::BusOff {
            return None;
        }
        self.tec = self.tec.saturating_add(8);
        if self.tec > BUS_OFF_LIMIT {
            self.back_at = Some(Instant::from_nanos(
                now.as_nanos() + bits_to_nanos(RECOVERY_BITS, bitrate),
            ));
        }
        self.update()
    }

    /// A frame of this node crossed the bus.
    pub fn transmit_ok(&mut self) -> Option<Transition> {
        self.tec = self.tec.saturating_sub(1);
        self.update()
    }

    /// The node saw an error frame while receiving.
    pub fn receive_error(&mut self) -> Option<Transition> {
        if self.state == ErrorState::BusOff {
            return None;
        }
        // ISO 11898-1: the receive counter is not increased beyond what takes it passive.
        self.rec = self.rec.saturating_add(1).min(PASSIVE_LIMIT + 1);
        self.update()
    }

    /// The node received a frame without error.
    pub fn receive_ok(&mut self) -> Option<Transition> {
        if self.rec > PASSIVE_LIMIT {
            // ISO 11898-1 §12.1.4.2 rule 8: back to a value between 119 and 127.
            self.rec = 119;
        } else {
            self.rec = self.rec.saturating_sub(1);
        }
        self.update()
    }

    /// When a bus-off node will be back on the bus.
    pub fn deadline(&self) -> Option<Instant> {
        self.back_at
    }

    /// The recovery of a bus-off node is due by `now`.
    pub fn poll(&mut self, now: Instant) -> Option<Transition> {
        match self.back_at {
            Some(t) if t <= now => {
                self.back_at = None;
                self.tec = 0;
                self.rec = 0;
                self.update()
            }
            _ => None,
        }
    }

    fn update(&mut self) -> Option<Transition> {
        let to = if self.back_at.is_some() {
            ErrorState::BusOff
        } else if self.tec > PASSIVE_LIMIT || self.rec > PASSIVE_LIMIT {
            ErrorState::Passive
        } else {
            ErrorState::Active
        };
        let from = self.state;
        self.state = to;
        (from != to).then_some(Transition { from, to })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sixteen_transmit_errors_make_a_node_passive_and_thirty_two_take_it_off_the_bus() {
        let mut fc = FaultConfinement::default();
        let t = Instant::from_millis(10);
        for _ in 0..15 {
            assert_eq!(fc.transmit_error(t, 125_000), None);
        }
        // TEC 128 > 127.
        assert_eq!(
            fc.transmit_error(t, 125_000),
            Some(Transition {
                from: ErrorState::Active,
                to: ErrorState::Passive
            })
        );
        for _ in 16..31 {
            assert_eq!(fc.transmit_error(t, 125_000), None);
        }
        // TEC 256 > 255.
        assert_eq!(
            fc.transmit_error(t, 125_000),
            Some(Transition {
                from: ErrorState::Passive,
                to: ErrorState::BusOff
            })
        );
        assert!(!fc.on_bus());
        // 1408 bits at 125 kbit/s = 11.264 ms.
        let back = Instant::from_nanos(t.as_nanos() + 11_264_000);
        assert_eq!(fc.deadline(), Some(back));
        assert_eq!(fc.poll(Instant::from_nanos(back.as_nanos() - 1)), None);
        assert_eq!(
            fc.poll(back),
            Some(Transition {
                from: ErrorState::BusOff,
                to: ErrorState::Active
            })
        );
        assert_eq!(fc.counters(), (0, 0));
    }

    #[test]
    fn good_frames_bring_a_passive_node_back() {
        let mut fc = FaultConfinement::default();
        for _ in 0..16 {
            fc.transmit_error(Instant::ZERO, 500_000);
        }
        assert_eq!(fc.state(), ErrorState::Passive);
        assert_eq!(
            fc.transmit_ok(),
            Some(Transition {
                from: ErrorState::Passive,
                to: ErrorState::Active
            })
        );
        let mut rx = FaultConfinement::default();
        for _ in 0..200 {
            rx.receive_error();
        }
        assert_eq!((rx.state(), rx.counters()), (ErrorState::Passive, (0, 128)));
        assert_eq!(rx.receive_ok().map(|t| t.to), Some(ErrorState::Active));
        assert_eq!(rx.counters(), (0, 119));
    }
}
