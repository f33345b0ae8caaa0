//! Node-ID and bit rate from a Nanotec controller's hexadecimal rotary switches, read once at
//! power-on (Nanotec §1.1.1, lines L263–310 of the manual's text kept beside the project). Pure
//! rules, no I/O: the cell file gives the switch positions, the EEPROM values are 2009h (node-ID)
//! and 2005h (bit-rate code).
//!
//! The manual's rules:
//! * Two switches (SMCI47-S) make a value 00h…FFh, one switch (PD4-N) 0h…Fh.
//! * 0: node-ID from EEPROM (2009h), 1 Mbit/s. 1…127 (PD4-N 1…7): node-ID = value, 1 Mbit/s.
//!   128 (PD4-N 8): node-ID and bit rate from EEPROM. 129…255 (PD4-N 9…15): node-ID =
//!   value − 128 (PD4-N value − 8), bit rate from EEPROM (2005h).
//! * 2005h codes 130…135 are 20, 50, 125, 250, 500, 1000 kbit/s (§1.1.3 step 4, L320–328).
//!   With another code the controller "answers on CAN but accepts no motion commands"
//!   (step 7, L333).
//! * 2009h can be written and stored, but when the switches give the node-ID it holds the
//!   switch value again after a restart (§11.10, L3512).
//!
//! Decision (digit order): §1.1.1 says the left switch gives the 1s digit and the right switch
//! the 16s digit, and works the example left = 1, right = 2 → 16·2 + 1 = 33 (L268, L288–292);
//! §1.1.3 step 1 (L316) says "left 0, right 1" gives the value 1, which by that rule is 16. The
//! rule and its worked example agree with each other and step 1 agrees with neither, so the
//! value is 16 · right + left (vector NT-NODE-01). Step 1's
//! "left 0, right 1" is read as the slip.

/// The rotary switches a device has (`rotary_switches` in its device file).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RotarySwitches {
    /// Two hexadecimal switches (SMCI47-S): value 00h…FFh.
    Two { left: u8, right: u8 },
    /// One hexadecimal switch (PD4-N): value 0h…Fh.
    One(u8),
}

/// A switch position outside 0…F.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BadPosition(pub u8);

impl core::fmt::Display for BadPosition {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "switch position {} (a hexadecimal switch has 0…15)",
            self.0
        )
    }
}

impl RotarySwitches {
    /// Checks each switch position (0…F).
    pub fn checked(self) -> Result<Self, BadPosition> {
        match self {
            RotarySwitches::Two { left, right } => {
                if let Some(bad) = [left, right].into_iter().find(|p| *p > 0xF) {
                    return Err(BadPosition(bad));
                }
            }
            RotarySwitches::One(p) if p > 0xF => return Err(BadPosition(p)),
            RotarySwitches::One(_) => {}
        }
        Ok(self)
    }

    /// The switch value: 16 · right + left (see the module's Decision), or the one switch.
    pub const fn value(self) -> u8 {
        match self {
            RotarySwitches::Two { left, right } => (right & 0xF) << 4 | (left & 0xF),
            RotarySwitches::One(p) => p & 0xF,
        }
    }

    /// The value that switches to "from EEPROM" for the bit rate: 80h, or 8 on one switch.
    const fn eeprom_bit(self) -> u8 {
        match self {
            RotarySwitches::Two { .. } => 0x80,
            RotarySwitches::One(_) => 0x8,
        }
    }
}

/// Bit rate of a 2005h code, kbit/s (§1.1.3 step 4): 130…135 → 20, 50, 125, 250, 500, 1000.
pub const fn bit_rate_kbit(code: u8) -> Option<u16> {
    match code {
        130 => Some(20),
        131 => Some(50),
        132 => Some(125),
        133 => Some(250),
        134 => Some(500),
        135 => Some(1000),
        _ => None,
    }
}

/// The 2005h default: 1 Mbit/s (§11.6, L3449).
pub const DEFAULT_BIT_RATE_CODE: u8 = 135;

/// What the controller uses after power-on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PowerOn {
    /// The node-ID on the bus, and what 2009h reads.
    pub node_id: u8,
    /// The bit rate; `None` when the switches take it from an EEPROM code outside 130…135.
    pub bit_rate_kbit: Option<u16>,
    /// Whether the bit rate is the EEPROM's (2005h): switch values 80h and above.
    pub bit_rate_from_eeprom: bool,
    /// Whether the switches gave the node-ID (then 2009h holds the switch value).
    pub node_id_from_switches: bool,
    /// False when the bit rate comes from an invalid EEPROM code: the controller answers on
    /// CAN but accepts no motion commands (§1.1.3 step 7).
    pub motion_allowed: bool,
}

/// The node-ID and bit rate at power-on from the switches and the EEPROM values of 2009h and
/// 2005h.
pub fn power_on(switches: RotarySwitches, eeprom_node_id: u8, eeprom_bit_rate: u8) -> PowerOn {
    let value = switches.value();
    let eeprom_bit = switches.eeprom_bit();
    let node = value & !eeprom_bit;
    let rate_from_eeprom = value & eeprom_bit != 0;
    let (bit_rate_kbit, motion_allowed) = if rate_from_eeprom {
        let r = bit_rate_kbit(eeprom_bit_rate);
        (r, r.is_some())
    } else {
        (Some(1000), true)
    };
    PowerOn {
        node_id: if node == 0 { eeprom_node_id } else { node },
        bit_rate_kbit,
        bit_rate_from_eeprom: rate_from_eeprom,
        node_id_from_switches: node != 0,
        motion_allowed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two(left: u8, right: u8) -> RotarySwitches {
        RotarySwitches::Two { left, right }.checked().unwrap()
    }

    /// NT-NODE-01: left = 1, right = 2 → value 16·2 + 1 = 33 → node 33 at 1 Mbit/s.
    #[test]
    fn nt_node_01_left_is_the_ones_digit() {
        let s = two(1, 2);
        assert_eq!(s.value(), 33);
        let p = power_on(s, 1, DEFAULT_BIT_RATE_CODE);
        assert_eq!((p.node_id, p.bit_rate_kbit), (33, Some(1000)));
        assert!(p.node_id_from_switches && p.motion_allowed);
        // §1.1.3 step 1's "left 0, right 1" is 16 by the rule, not 1 (the Decision above).
        assert_eq!(two(0, 1).value(), 16);
        assert_eq!(two(1, 0).value(), 1);
    }

    /// NT-NODE-02: value 00h → node-ID from EEPROM (2009h), 1 Mbit/s.
    #[test]
    fn nt_node_02_zero_takes_the_node_id_from_eeprom() {
        let p = power_on(two(0, 0), 42, 132);
        assert_eq!((p.node_id, p.bit_rate_kbit), (42, Some(1000)));
        assert!(!p.node_id_from_switches);
    }

    /// NT-NODE-03: value 81h → node 81h − 80h = 1, bit rate from EEPROM (2005h); 80h: both
    /// from EEPROM.
    #[test]
    fn nt_node_03_high_bit_takes_the_bit_rate_from_eeprom() {
        let p = power_on(two(1, 8), 42, 132);
        assert_eq!((p.node_id, p.bit_rate_kbit), (1, Some(125)));
        let p = power_on(two(0, 8), 42, 132);
        assert_eq!((p.node_id, p.bit_rate_kbit), (42, Some(125)));
        let p = power_on(two(0xF, 0xF), 42, 134);
        assert_eq!((p.node_id, p.bit_rate_kbit), (127, Some(500)));
    }

    /// NT-NODE-04: PD4-N (one switch) value 9 → node 9 − 8 = 1, bit rate from EEPROM; 1…7 are
    /// node 1…7 at 1 Mbit/s; 8 both from EEPROM.
    #[test]
    fn nt_node_04_pd4n_single_switch() {
        let one = |p| RotarySwitches::One(p).checked().unwrap();
        let p = power_on(one(9), 42, 133);
        assert_eq!((p.node_id, p.bit_rate_kbit), (1, Some(250)));
        for n in 1..=7 {
            let p = power_on(one(n), 42, 133);
            assert_eq!((p.node_id, p.bit_rate_kbit), (n, Some(1000)));
        }
        let p = power_on(one(8), 42, 133);
        assert_eq!((p.node_id, p.bit_rate_kbit), (42, Some(250)));
        let p = power_on(one(0), 42, 133);
        assert_eq!((p.node_id, p.bit_rate_kbit), (42, Some(1000)));
        assert_eq!(RotarySwitches::One(16).checked(), Err(BadPosition(16)));
        assert_eq!(
            RotarySwitches::Two { left: 0, right: 17 }.checked(),
            Err(BadPosition(17))
        );
    }

    /// NT-NODE-05: 2005h codes 130…135 are 20, 50, 125, 250, 500, 1000 kbit/s.
    #[test]
    fn nt_node_05_bit_rate_codes() {
        let rates: [Option<u16>; 6] = core::array::from_fn(|i| bit_rate_kbit(130 + i as u8));
        assert_eq!(rates, [20, 50, 125, 250, 500, 1000].map(Some));
        assert_eq!(bit_rate_kbit(129), None);
        assert_eq!(bit_rate_kbit(136), None);
    }

    /// NT-NODE-06: 2005h := 134, stored, power cycle with switch = node + 128 → 500 kbit/s.
    #[test]
    fn nt_node_06_stored_bit_rate_after_power_cycle() {
        let p = power_on(two(5, 8), 1, 134);
        assert_eq!((p.node_id, p.bit_rate_kbit), (5, Some(500)));
    }

    /// NT-NODE-07: switch = node + 128 and 2005h outside 130…135 → answers on CAN, but no
    /// motion commands.
    #[test]
    fn nt_node_07_invalid_stored_bit_rate_blocks_motion() {
        let p = power_on(two(5, 8), 1, 0);
        assert_eq!(p.node_id, 5);
        assert_eq!(p.bit_rate_kbit, None);
        assert!(!p.motion_allowed);
        // With switches 1…127 the EEPROM code is ignored (§1.1.3 step 1).
        assert!(power_on(two(5, 0), 1, 0).motion_allowed);
    }

    /// NT-NODE-09: switches select node 5; 2009h := 7 stored; after the power cycle 2009h
    /// reads 5 (the switch value).
    #[test]
    fn nt_node_09_switch_node_id_wins_over_2009h() {
        let p = power_on(two(5, 0), 7, DEFAULT_BIT_RATE_CODE);
        assert_eq!(p.node_id, 5);
        assert!(p.node_id_from_switches, "2009h reads the switch value");
        assert_eq!(power_on(two(0, 0), 7, DEFAULT_BIT_RATE_CODE).node_id, 7);
    }
}
