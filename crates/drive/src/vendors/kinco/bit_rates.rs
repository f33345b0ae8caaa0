//! The codes Kinco drives store for their serial line speeds (Kinco CD3 / FD3 manual §9.5,
//! lines L2145-2154 of its text kept beside the project): RS232_Baudrate 2FE0h, U2BRG 2FE1h
//! and RS485_Baudrate 2FE2h hold a divider code: 1080 = 9600, 540 = 19200, 270 = 38400,
//! 90 = 115200 bit/s (KINCO-232-10). All four fit code = 10 368 000 / bit rate, but only these
//! four are listed (2FE0h and 2FE1h list the last three). The CAN bit rate's codes (CAN_Baudrate
//! 2F81h, KINCO-CAN-06) are device data: `can_bit_rate` in `devices/kinco-fd3.toml`.
//!
//! Decision: a code outside the list gives `None`, also 180 (57 600 bit/s by the formula, but
//! not listed); the runtime then keeps the line speed it has (U2BRG) or refuses the line
//! (2FE0h, 2FE2h at power-on), rather than guess a divider.

/// The serial divider codes and their bit rates (2FE0h-2FE2h).
pub const SERIAL: [(u16, u32); 4] = [(1080, 9600), (540, 19200), (270, 38400), (90, 115_200)];

/// The bit rate of a serial code (2FE0h, 2FE1h, 2FE2h).
pub fn serial_bit_rate(code: u16) -> Option<u32> {
    SERIAL.iter().find(|(c, _)| *c == code).map(|&(_, b)| b)
}

/// The serial code of a bit rate.
pub fn serial_code(bit_rate: u32) -> Option<u16> {
    SERIAL.iter().find(|(_, b)| *b == bit_rate).map(|&(c, _)| c)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// KINCO-232-10: 540, 270 (default), 90 → 19200, 38400, 115200; 1080 → 9600 (RS485);
    /// every code is 10 368 000 / bit rate.
    #[test]
    fn kinco_232_10_serial_codes() {
        assert_eq!(serial_bit_rate(540), Some(19200));
        assert_eq!(serial_bit_rate(270), Some(38400));
        assert_eq!(serial_bit_rate(90), Some(115_200));
        assert_eq!(serial_bit_rate(1080), Some(9600));
        assert_eq!(serial_bit_rate(135), None, "76800 is not listed");
        for (code, baud) in SERIAL {
            assert_eq!(u32::from(code), 10_368_000 / baud);
            assert_eq!(serial_code(baud), Some(code));
        }
    }
}
