//! The codes Kinco drives store for their line speeds (Kinco CD3 / FD3 manual §9.5,
//! lines L2145-2154 of its text kept beside the project):
//!
//! * RS232_Baudrate 2FE0h, U2BRG 2FE1h and RS485_Baudrate 2FE2h hold a divider code:
//!   1080 = 9600, 540 = 19200, 270 = 38400, 90 = 115200 bit/s (KINCO-232-10). All four fit
//!   code = 10 368 000 / bit rate, but only these four are listed (2FE0h and 2FE1h list the last
//!   three).
//! * CAN_Baudrate 2F81h: 100 = 1 Mbit/s, 50 = 500, 25 = 250, 12 = 125, 5 = 50 kbit/s
//!   (KINCO-CAN-06). 125 kbit/s is 12, not 12.5: a lookup, not code × 10.
//!
//! Decision: a code outside the lists gives `None`, also 180 (57 600 bit/s by the formula, but
//! not listed); the runtime then keeps the line speed it has (U2BRG) or refuses the line
//! (2FE0h, 2FE2h at power-on), and the CAN bus keeps 500 kbit/s, rather than guess a divider.

/// The serial divider codes and their bit rates (2FE0h-2FE2h).
pub const SERIAL: [(u16, u32); 4] = [(1080, 9600), (540, 19200), (270, 38400), (90, 115_200)];

/// The CAN codes and their bit rates in kbit/s (2F81h).
pub const CAN: [(u8, u16); 5] = [(100, 1000), (50, 500), (25, 250), (12, 125), (5, 50)];

/// The CAN bit rate of the 2F81h default 50, kbit/s; kept for a code outside [`CAN`].
pub const DEFAULT_CAN_KBIT: u16 = 500;

/// The bit rate of a serial code (2FE0h, 2FE1h, 2FE2h).
pub fn serial_bit_rate(code: u16) -> Option<u32> {
    SERIAL.iter().find(|(c, _)| *c == code).map(|&(_, b)| b)
}

/// The serial code of a bit rate.
pub fn serial_code(bit_rate: u32) -> Option<u16> {
    SERIAL.iter().find(|(_, b)| *b == bit_rate).map(|&(c, _)| c)
}

/// The CAN bit rate in kbit/s of a 2F81h code.
pub fn can_kbit(code: u8) -> Option<u16> {
    CAN.iter().find(|(c, _)| *c == code).map(|&(_, k)| k)
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

    /// KINCO-CAN-06: 100, 50 (default), 25, 12, 5 → 1000, 500, 250, 125, 50 kbit/s.
    #[test]
    fn kinco_can_06_can_codes() {
        assert_eq!(
            [100, 50, 25, 12, 5].map(can_kbit),
            [Some(1000), Some(500), Some(250), Some(125), Some(50)]
        );
        assert_eq!(can_kbit(13), None);
    }
}
