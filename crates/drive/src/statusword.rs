//! The statusword 6041h (CiA 402 §6.3.3; CMMP-AS §6.1.4 Tab. 6.6–6.7; Nanotec §3.3 / §4.3):
//! bits 0–3, 5, 6 show the device control state, the others the drive and the mode.

use crate::bit_word::bit_word;

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
        /// Bit 8: manufacturer-specific (CMMP-AS: moving; Nanotec: PLL sync complete).
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
