//! The CiA 402 statusword (6041h) decoded for people: its state and each bit by name.

use drive::device_control::State;

/// Bit names of 6041h, CMMP-AS §6.1.5 Tab. 6.7 (CiA 402 §6.3.2); bits 12 and 13 depend on
/// the mode of operation, so both meanings are named.
pub const BITS: [&str; 16] = [
    "ready to switch on",
    "switched on",
    "operation enabled",
    "fault",
    "voltage enabled",
    "quick stop",
    "switch on disabled",
    "warning",
    "manufacturer specific (8)",
    "remote",
    "target reached",
    "internal limit active",
    "set-point acknowledge / speed 0 / homing attained",
    "following error / homing error",
    "manufacturer specific (14)",
    "manufacturer specific (15)",
];

/// The state the statusword shows (CMMP-AS Tab. 6.6, CiA 402 Tab. 30), `None` for a
/// combination no state has.
pub fn state(sw: u16) -> Option<State> {
    // Decision: 000Fh is FAULT REACTION ACTIVE in CiA 402, but a CMMP-AS without 6510h:F0
    // bit 7 shows FAULT itself as 000Fh (CMMP-AS Tab. 6.6 footnote); the reaction lasts
    // milliseconds, so a console that sees 000Fh shows FAULT, the state a person must act on.
    const BY_MASK: [(u16, u16, State); 8] = [
        (0x4F, 0x00, State::NotReadyToSwitchOn),
        (0x4F, 0x40, State::SwitchOnDisabled),
        (0x6F, 0x21, State::ReadyToSwitchOn),
        (0x6F, 0x23, State::SwitchedOn),
        (0x6F, 0x27, State::OperationEnabled),
        (0x6F, 0x07, State::QuickStopActive),
        (0x4F, 0x0F, State::Fault),
        (0x4F, 0x08, State::Fault),
    ];
    BY_MASK
        .iter()
        .find(|(mask, value, _)| sw & mask == *value)
        .map(|(_, _, s)| *s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_state_reads_back_from_its_own_bits() {
        for s in [
            State::NotReadyToSwitchOn,
            State::SwitchOnDisabled,
            State::ReadyToSwitchOn,
            State::SwitchedOn,
            State::OperationEnabled,
            State::QuickStopActive,
            State::Fault,
        ] {
            // With voltage-enabled and remote set, as a running drive shows them.
            assert_eq!(state(s.statusword_bits(true) | 0x0210), Some(s), "{s:?}");
        }
        assert_eq!(
            state(0x0F),
            Some(State::Fault),
            "CMMP-AS FAULT without 6510h:F0 bit 7"
        );
        assert_eq!(state(0x0637), Some(State::OperationEnabled));
        assert_eq!(state(0x0025), None, "no state has bits 0 and 2 without 1");
    }
}
