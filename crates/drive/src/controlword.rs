//! The controlword 6040h (CiA 402 §6.3.2): bits
//! 0–3 and 7 command the device control state machine, 4–6, 8 and 9 belong to the mode.

use crate::bit_word::bit_word;

bit_word! {
    /// 6040h controlword.
    Controlword {
        /// Bit 0 switch on.
        SWITCH_ON = 0x0001;
        /// Bit 1 enable voltage.
        ENABLE_VOLTAGE = 0x0002;
        /// Bit 2 quick stop, active low: 0 = quick stop.
        QUICK_STOP = 0x0004;
        /// Bit 3 enable operation.
        ENABLE_OPERATION = 0x0008;
        /// Bit 4: PP new set-point, HM homing operation start, IP enable ip mode.
        NEW_SET_POINT = 0x0010;
        /// Bit 5 (PP): change set immediately.
        CHANGE_SET_IMMEDIATELY = 0x0020;
        /// Bit 6 (PP): 0 absolute, 1 relative target.
        RELATIVE = 0x0040;
        /// Bit 7 fault reset (rising edge).
        FAULT_RESET = 0x0080;
        /// Bit 8 halt.
        HALT = 0x0100;
        /// Bit 9 (PP): change on set-point (CiA 402 v3).
        CHANGE_ON_SET_POINT = 0x0200;
    }
}

impl Controlword {
    /// Bit 4 under its homing name (homing operation start).
    pub const HOMING_START: Controlword = Controlword::NEW_SET_POINT;
    /// Bit 4 under its interpolated-position name (enable ip mode).
    pub const ENABLE_IP_MODE: Controlword = Controlword::NEW_SET_POINT;
    /// The command bits 0–3 of the state machine.
    pub const COMMAND: Controlword = Controlword(0x000F);

    // The commands of CiA 402 Tab. 28, named as ethercrab's ds402 names them.
    /// Shutdown (transitions 2, 6, 8): 0110b.
    pub const SHUTDOWN: Controlword = Controlword(0x0006);
    /// Switch on (transition 3): 0111b.
    pub const SWITCH_ON_CMD: Controlword = Controlword(0x0007);
    /// Enable operation (transition 4): 1111b.
    pub const ENABLE_OPERATION_CMD: Controlword = Controlword(0x000F);
}

/// The controlwords written since the device control last ran, in the order their writes
/// were confirmed ([`ConfirmedWrites`] of 16).
///
/// **Decision** (DESIGN "a confirmed write has been taken"): every acknowledged write of 6040h
/// reaches the state machine, in order, at the drive's next logic cycle. A master that waits
/// for each answer before the next write can then never outrun the drive: 06h, 07h, 0Fh
/// written within one cycle run transitions 2, 3 and 4 as they do on the real bus, where the
/// next write cannot arrive before the device has answered (and so taken) the one before.
/// CiA 402 §6.3 drives the state machine by the commands the master sends, not by samples of
/// the object; the vendors' manuals print no sampling rule (they all describe the commands
/// in sequence).
pub type ControlwordQueue = ConfirmedWrites<u16, 16>;

/// Values written since their consumer last ran, oldest first: only changes are kept (a
/// cyclic RPDO or telegram repeating one value adds nothing), and more changes than the queue
/// holds (a flood no master waiting for answers can send) keep the newest, as a sampled value
/// would have lost the oldest anyway.
#[derive(Debug, Clone, Default)]
pub struct ConfirmedWrites<T, const N: usize> {
    values: heapless::Deque<T, N>,
}

impl<T: Copy + PartialEq, const N: usize> ConfirmedWrites<T, N> {
    /// Changes kept between two runs of the consumer.
    pub const CAPACITY: usize = N;

    /// A confirmed write of `value`; `previous` is what the object held before it.
    pub fn push(&mut self, value: T, previous: T) {
        let last = self.values.back().copied().unwrap_or(previous);
        if value == last {
            return;
        }
        if self.values.is_full() {
            self.values.pop_front();
        }
        let _ = self.values.push_back(value);
    }

    /// The oldest write not yet taken.
    pub fn pop(&mut self) -> Option<T> {
        self.values.pop_front()
    }

    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::ControlwordQueue;

    #[test]
    fn keeps_changes_in_order_and_drops_repeats() {
        let mut q = ControlwordQueue::default();
        for cw in [0x00, 0x00, 0x80, 0x06, 0x06, 0x07, 0x0F, 0x0F] {
            q.push(cw, 0x00);
        }
        let got: heapless::Vec<u16, 32> = core::iter::from_fn(|| q.pop()).collect();
        assert_eq!(got.as_slice(), [0x80, 0x06, 0x07, 0x0F]);
    }

    #[test]
    fn a_flood_keeps_the_newest() {
        let mut q = ControlwordQueue::default();
        for cw in 1..=40u16 {
            q.push(cw, 0);
        }
        let got: heapless::Vec<u16, 32> = core::iter::from_fn(|| q.pop()).collect();
        assert_eq!(got.len(), ControlwordQueue::CAPACITY);
        assert_eq!(got.last(), Some(&40));
        assert_eq!(got.first(), Some(&(41 - ControlwordQueue::CAPACITY as u16)));
    }
}
