//! The statusword 6041h (CiA 402 §6.3.3): bits 0–3, 5, 6 show the device control state, the
//! others the drive and the mode; the manufacturer-specific bits 8, 14 and 15 are the
//! personality's.

use crate::bit_word::bit_word;
use crate::device_control::State;

bit_word! {
    /// 6041h statusword.
    Statusword {
        /// Bit 0 ready to switch on.
        READY_TO_SWITCH_ON = 0x0001;
        /// Bit 1 switched on.
        SWITCHED_ON = 0x0002;
        /// Bit 2 operation enabled.
        OPERATION_ENABLED = 0x0004;
        /// Bit 3 fault.
        FAULT = 0x0008;
        /// Bit 4 voltage enabled.
        VOLTAGE_ENABLED = 0x0010;
        /// Bit 5 quick stop (1 = not active).
        QUICK_STOP = 0x0020;
        /// Bit 6 switch on disabled.
        SWITCH_ON_DISABLED = 0x0040;
        /// Bit 7 warning.
        WARNING = 0x0080;
        /// Bit 8: manufacturer-specific (the personality gives it its meaning).
        BIT_8 = 0x0100;
        /// Bit 9 remote.
        REMOTE = 0x0200;
        /// Bit 10 target reached.
        TARGET_REACHED = 0x0400;
        /// Bit 11 internal limit active.
        INTERNAL_LIMIT_ACTIVE = 0x0800;
        /// Bit 12, mode-specific: PP set-point acknowledge, PV speed zero, HM homing attained,
        /// IP ip mode active, CSP following the command value.
        OPERATION_MODE_SPECIFIC_12 = 0x1000;
        /// Bit 13, mode-specific: following error (PP, IP, CSP), homing error (HM).
        OPERATION_MODE_SPECIFIC_13 = 0x2000;
        /// Bit 14, manufacturer-specific.
        MANUFACTURER_14 = 0x4000;
        /// Bit 15, manufacturer-specific.
        MANUFACTURER_15 = 0x8000;
    }
}

impl Statusword {
    /// PP set-point acknowledge (bit 12).
    pub const SET_POINT_ACKNOWLEDGE: Statusword = Statusword::OPERATION_MODE_SPECIFIC_12;
    /// PP, IP, CSP following error (bit 13).
    pub const FOLLOWING_ERROR: Statusword = Statusword::OPERATION_MODE_SPECIFIC_13;
    /// HM homing attained (bit 12).
    pub const HOMING_ATTAINED: Statusword = Statusword::OPERATION_MODE_SPECIFIC_12;
    /// HM homing error (bit 13).
    pub const HOMING_ERROR: Statusword = Statusword::OPERATION_MODE_SPECIFIC_13;
    /// IP ip mode active (bit 12).
    pub const IP_MODE_ACTIVE: Statusword = Statusword::OPERATION_MODE_SPECIFIC_12;
    /// PV speed zero (bit 12).
    pub const SPEED_ZERO: Statusword = Statusword::OPERATION_MODE_SPECIFIC_12;
}

impl Statusword {
    /// The bits' names for display (CiA 402 §6.3.3); bits 12 and 13
    /// depend on the mode of operation, so each names its meanings.
    pub const BIT_NAMES: [&'static str; 16] = [
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

    /// The device control state bits 0–3, 5 and 6 show (CiA 402 §6.3.3 Tab. 30), `None` for
    /// a combination no state has. 000Fh is FAULT REACTION ACTIVE, as the table has it (a
    /// personality that codes FAULT as 000Fh shows FAULT that way too).
    pub const fn state(self) -> Option<State> {
        let sw = self.0;
        Some(if sw & 0x4F == 0x00 {
            State::NotReadyToSwitchOn
        } else if sw & 0x4F == 0x40 {
            State::SwitchOnDisabled
        } else if sw & 0x6F == 0x21 {
            State::ReadyToSwitchOn
        } else if sw & 0x6F == 0x23 {
            State::SwitchedOn
        } else if sw & 0x6F == 0x27 {
            State::OperationEnabled
        } else if sw & 0x6F == 0x07 {
            State::QuickStopActive
        } else if sw & 0x4F == 0x0F {
            State::FaultReactionActive
        } else if sw & 0x4F == 0x08 {
            State::Fault
        } else {
            return None;
        })
    }
}

#[cfg(test)]
mod tests {
    use super::Statusword;
    use crate::device_control::State;

    #[test]
    fn every_state_reads_back_from_its_own_bits() {
        for s in [
            State::NotReadyToSwitchOn,
            State::SwitchOnDisabled,
            State::ReadyToSwitchOn,
            State::SwitchedOn,
            State::OperationEnabled,
            State::QuickStopActive,
            State::FaultReactionActive,
            State::Fault,
        ] {
            // With voltage enabled and remote set, as a running drive shows them.
            let sw = Statusword(s.statusword_bits(true) | 0x0210);
            assert_eq!(sw.state(), Some(s), "{s:?}");
        }
        assert_eq!(
            Statusword(State::Fault.statusword_bits(false)).state(),
            Some(State::FaultReactionActive),
            "CMMP-AS FAULT without 6510h:F0 bit 7 shows 000Fh"
        );
        assert_eq!(Statusword(0x0637).state(), Some(State::OperationEnabled));
        assert_eq!(Statusword(0x0025).state(), None, "bits 0 and 2 without 1");
    }
}
