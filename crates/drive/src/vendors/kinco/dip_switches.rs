//! The station number of a Kinco FD3 from its DIP switches SW1…SW8, read once at power-on (Kinco
//! CD3 / FD3 manual §3.8, Tab. 3-8, lines L504-518 of its text kept beside the project). Pure
//! rules, no I/O: the cell file gives the switch positions.
//!
//! The manual's rules:
//! * SW1…SW8 are a binary number, SW1 = bit 0 … SW8 = bit 7: SW1 → 1, SW2 → 2, SW1 + SW2 → 3,
//!   SW3 → 4, all ON → 255 (the KINCO-DIP vectors).
//! * All OFF: the station number is the stored one, changeable in 2F80h:01 (printed
//!   "0x2F800108", KINCO-DIP-06). A change applies after a reboot.
//! * Only the FD3-LA / -CA have the switches (L347); the CD3 takes 100Bh.
//!
//! * The table gives no bit rate: the CAN bit rate is CAN_Baudrate 2F81h (its codes are the
//!   device file's `can_bit_rate`).
//!
//! Decision: a switch value above 127 is a valid RS232 / RS485 station number (the panel's
//! 100Bh range is 0~255, L2144) but not a CANopen node-ID (1…127, §11.1): [`can_node_id`]
//! gives `None` for it, and the cell file refuses it (`[drive.dip_switches]`) rather than give
//! the node another ID.

/// Where the station number comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Station {
    /// The switches give it (1…255).
    Switches(u8),
    /// All switches OFF: the stored value (2F80h:01).
    Stored,
}

/// The station number of switches SW1…SW8 (`on[0]` is SW1).
pub fn station(on: [bool; 8]) -> Station {
    let value = on
        .iter()
        .enumerate()
        .fold(0u8, |acc, (bit, &sw)| acc | (u8::from(sw) << bit));
    if value == 0 {
        Station::Stored
    } else {
        Station::Switches(value)
    }
}

/// The CANopen node-ID of a station number: 1…127, else none.
pub fn can_node_id(station: u8) -> Option<u8> {
    (1..=127).contains(&station).then_some(station)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sw(list: &[usize]) -> [bool; 8] {
        let mut on = [false; 8];
        for &n in list {
            if let Some(s) = on.get_mut(n - 1) {
                *s = true;
            }
        }
        on
    }

    /// SW1 → 1, SW2 → 2, SW1 + SW2 → 3, SW3 → 4, all ON → 255.
    #[test]
    fn kinco_dip_01_to_05_binary_station() {
        assert_eq!(station(sw(&[1])), Station::Switches(1), "KINCO-DIP-01");
        assert_eq!(station(sw(&[2])), Station::Switches(2), "KINCO-DIP-02");
        assert_eq!(station(sw(&[1, 2])), Station::Switches(3), "KINCO-DIP-03");
        assert_eq!(station(sw(&[3])), Station::Switches(4), "KINCO-DIP-04");
        assert_eq!(station([true; 8]), Station::Switches(255), "KINCO-DIP-05");
        assert_eq!(can_node_id(255), None, "RS232/RS485 only");
        assert_eq!(can_node_id(4), Some(4));
    }

    /// KINCO-DIP-06: all OFF → the stored station number (2F80h:01).
    #[test]
    fn kinco_dip_06_all_off_is_stored() {
        assert_eq!(station([false; 8]), Station::Stored);
    }
}
