//! The names of the CMMO-ST diagnostic numbers (manual Appendix D),
//! as data: the master prints them next to the fault number of FC 0x07.

/// `(number, name)` of every diagnostic message of Appendix D.
pub const NAMES: &[(u8, &str)] = &[
    (0x01, "software error"),
    (0x02, "default parameter file invalid"),
    (0x05, "zero angle determination"),
    (0x06, "encoder (measuring system)"),
    (0x09, "offset determination for current measurement"),
    (0x0A, "general error"),
    (0x0B, "parameter file invalid"),
    (0x0C, "firmware update execution error"),
    (0x0D, "overcurrent"),
    (0x0E, "I²t malfunction motor"),
    (0x11, "software limit positive"),
    (0x12, "software limit negative"),
    (0x13, "positive direction locked"),
    (0x14, "negative direction locked"),
    (0x15, "output stage temperature exceeded"),
    (0x16, "output stage temperature too low"),
    (0x17, "logic voltage exceeded"),
    (0x18, "logic voltage too low"),
    (0x19, "real-time error LM-CPU"),
    (0x1A, "intermediate circuit voltage exceeded"),
    (0x1B, "intermediate circuit voltage too low"),
    (0x22, "homing"),
    (0x23, "no index pulse found"),
    (0x24, "drive function not supported in open-loop operation"),
    (0x25, "path calculation"),
    (0x27, "save parameters"),
    (0x28, "homing required"),
    (0x29, "target position behind negative software limit"),
    (0x2A, "target position behind positive software limit"),
    (0x2B, "firmware update, invalid firmware"),
    (0x2D, "I²t warning motor"),
    (0x2E, "index pulse too close to proximity sensor"),
    (0x2F, "following error"),
    (0x32, "FCT connection with master control"),
    (0x33, "output stage temperature warning"),
    (0x34, "safe torque off (STO)"),
    (0x37, "standstill monitoring"),
    (0x38, "parameter file access"),
    (0x39, "trace warning"),
    (0x3A, "homing timeout"),
    (0x3B, "homing method invalid"),
    (0x3C, "two edges in one cycle"),
    (0x3D, "start-up event"),
    (0x3E, "diagnostic memory"),
    (0x3F, "record invalid"),
    (0x40, "last teaching not successful"),
    (0x41, "system reset"),
    (0x43, "FCT connection without master control"),
    (0x44, "parameter file not compatible with firmware"),
    (0x45, "IO-Link system error"),
    (0x46, "IO-Link communication error"),
    (0x47, "Modbus connection with master control"),
    (0x48, "Modbus connection without master control"),
    // The manual prints "40h" twice; 4Ch is the inference of its extract kept beside the project.
    (0x4C, "value is out of range"),
    (0x4D, "bootloader memory error"),
    (0x4E, "overload 24V outputs"),
    (0x4F, "system information"),
];

/// The name of diagnostic `number`, or "unknown diagnostic".
pub fn name(number: u8) -> &'static str {
    NAMES
        .iter()
        .find(|(n, _)| *n == number)
        .map_or("unknown diagnostic", |(_, name)| name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_sorted_unique_and_found() {
        assert!(NAMES.windows(2).all(|w| w[0].0 < w[1].0));
        assert_eq!(name(0x28), "homing required");
        assert_eq!(name(0x47), "Modbus connection with master control");
        assert_eq!(name(0x03), "unknown diagnostic");
    }
}
