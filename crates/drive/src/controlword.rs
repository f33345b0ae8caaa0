//! The controlword 6040h (CiA 402 §6.3.2; CMMP-AS §6.1.3 Tab. 6.4; Nanotec §3.2 / §4.2): bits
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
        /// Bit 9 (PP): change on set-point (Nanotec §5.1; CiA 402 v3).
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
