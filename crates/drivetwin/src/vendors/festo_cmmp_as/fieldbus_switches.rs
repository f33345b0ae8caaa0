//! How a CMMP-AS finds its CANopen node number, bit rate, data profile and whether CAN is on
//! at all (CMMP-AS manual §2.3–2.4): the DIP block S1 of an M3's CAN module, or on an M0 the
//! digital inputs DIN0…DIN3, DIN8, DIN9, DIN12, DIN13, each added to the FCT base address.
//! Pure rules, no I/O: the cell file gives the switch positions and input levels; what they
//! select is the runtime's [`FieldbusSettings`].

use crate::cell::config::{FieldbusProfile as Profile, FieldbusSettings};

/// CAN bit rates the switches select, kbit/s, by the two-bit code (DIP6/DIP7, DIN12/DIN13;
/// manual Tab. 2.4, 2.8): OFF/OFF, ON/OFF, OFF/ON, ON/ON.
pub const BIT_RATES_KBIT: [u16; 4] = [125, 250, 500, 1000];

/// Highest CANopen node number; a larger base + offset is clamped to it (§2.3.1).
const MAX_NODE: u8 = 127;

fn bit_rate(low: bool, high: bool) -> u16 {
    let [r00, r01, r10, r11] = BIT_RATES_KBIT;
    match (high, low) {
        (false, false) => r00,
        (false, true) => r01,
        (true, false) => r10,
        (true, true) => r11,
    }
}

/// Node number from the FCT base address and the switch offset: the sum, clamped to 127;
/// base 0 with offset 0 is node 1 (Tab. 2.3 footnote 1, L466).
fn node_number(base: u8, offset: u8) -> u8 {
    match u16::from(base) + u16::from(offset) {
        0 => 1,
        n => n.min(u16::from(MAX_NODE)) as u8,
    }
}

/// Sum of the weights 1, 2, 4, … of the switches that are on.
fn weights(on: &[bool]) -> u8 {
    on.iter()
        .enumerate()
        .filter(|(_, &b)| b)
        .fold(0u8, |acc, (i, _)| acc | 1 << i)
}

/// M3: DIP1…DIP8 of block S1 (`dip[0]` = DIP1), read once at power-on or RESET (§2.3; later
/// changes wait for the next RESET, so there is no runtime input).
pub fn m3_power_on(base_address: u8, dip: [bool; 8]) -> FieldbusSettings {
    FieldbusSettings {
        // DIP1…5: offset 0…31 (Tab. 2.3).
        node_id: node_number(base_address, weights(&dip[..5])),
        // DIP6/DIP7 (Tab. 2.4).
        bit_rate_kbit: bit_rate(dip[5], dip[6]),
        // The M3 has no profile input: the FCT project chooses; CiA 402 is this manual's.
        profile: Profile::Cia402,
        // DIP8 (Tab. 2.5). The manual adds that DIP8 works only once the FCT project was
        // saved and the drive reset; the twin's cell file is that saved project.
        can_active: dip[7],
    }
}

/// Levels of the M0's fieldbus inputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct M0Inputs {
    /// DIN0…DIN3: node offset 0…15 (Tab. 2.7).
    pub din0_3: [bool; 4],
    /// CAN on (Tab. 2.10).
    pub din8: bool,
    /// Profile: LOW CiA 402, HIGH FHPP (Tab. 2.9).
    pub din9: bool,
    /// Bit rate (Tab. 2.8).
    pub din12: bool,
    pub din13: bool,
}

/// M0: the fieldbus settings and how they follow the inputs after a RESET (§2.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct M0Fieldbus {
    base_address: u8,
    /// FCT option "fieldbus parameterisation via DIN" (active in the delivery state).
    via_din: bool,
    /// Bit rate set in FCT, used when the option is off.
    fct_bit_rate_kbit: u16,
    settings: FieldbusSettings,
    din8: bool,
}

impl M0Fieldbus {
    /// Power-on or RESET with these input levels.
    pub fn reset(
        base_address: u8,
        via_din: bool,
        fct_bit_rate_kbit: u16,
        inputs: M0Inputs,
    ) -> Self {
        let mut m = M0Fieldbus {
            base_address,
            via_din,
            fct_bit_rate_kbit,
            settings: FieldbusSettings {
                node_id: node_number(base_address, 0),
                bit_rate_kbit: fct_bit_rate_kbit,
                // DIN9 is taken only here, at RESET (Tab. 2.6 fn. 2).
                profile: if via_din && inputs.din9 {
                    Profile::Fhpp
                } else {
                    Profile::Cia402
                },
                // Without the option FCT activates CAN (as soon as it releases device
                // control, which the twin's FCT never holds).
                can_active: !via_din,
            },
            din8: false,
        };
        m.on_inputs(inputs);
        m
    }

    pub fn settings(&self) -> FieldbusSettings {
        self.settings
    }

    /// New input levels. Node number and bit rate follow DIN0…3/DIN12/DIN13 only while CAN is
    /// off (Tab. 2.6 fn. 1); DIN8 switches CAN on at once on its rising edge, no reset needed
    /// (Tab. 2.10). A DIN8 already HIGH at RESET counts as that edge (decided: the manual
    /// names the edge only; a level read at RESET as the other inputs is the consistent
    /// reading). DIN8 going LOW switches CAN off again.
    pub fn on_inputs(&mut self, inputs: M0Inputs) {
        if !self.via_din {
            return;
        }
        let s = &mut self.settings;
        match (self.din8, inputs.din8) {
            (false, true) => s.can_active = true,
            (true, false) => s.can_active = false,
            _ => {}
        }
        // CAN off before or after this change: the inputs count (the ones present at the
        // rising edge are the ones CAN starts with).
        if !s.can_active || !self.din8 {
            s.node_id = node_number(self.base_address, weights(&inputs.din0_3));
            s.bit_rate_kbit = bit_rate(inputs.din12, inputs.din13);
        }
        self.din8 = inputs.din8;
    }

    /// The bit rate FCT sets when the DIN option is off.
    pub fn fct_bit_rate_kbit(&self) -> u16 {
        self.fct_bit_rate_kbit
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dips(on: &[usize]) -> [bool; 8] {
        let mut d = [false; 8];
        for &i in on {
            d[i - 1] = true;
        }
        d
    }

    /// CMMP-NODE-01: base 0; DIP1, DIP2, DIP4, DIP5 ON, DIP3 OFF → offset 27, node 27.
    #[test]
    fn cmmp_node_01_dip_offset_27() {
        assert_eq!(m3_power_on(0, dips(&[1, 2, 4, 5, 8])).node_id, 27);
    }

    /// CMMP-NODE-02: base 0, DIP1–5 OFF → node 1.
    #[test]
    fn cmmp_node_02_offset_0_base_0_is_node_1() {
        assert_eq!(m3_power_on(0, dips(&[8])).node_id, 1);
        // Any other base is taken as it is.
        assert_eq!(m3_power_on(5, dips(&[8])).node_id, 5);
    }

    /// CMMP-NODE-03: base 120 + offset 27 is clamped to 127.
    #[test]
    fn cmmp_node_03_sum_clamped_to_127() {
        assert_eq!(m3_power_on(120, dips(&[1, 2, 4, 5])).node_id, 127);
        assert_eq!(m3_power_on(255, dips(&[1, 2, 3, 4, 5])).node_id, 127);
        assert_eq!(m3_power_on(96, dips(&[1, 2, 3, 4, 5])).node_id, 127);
        assert_eq!(m3_power_on(95, dips(&[1, 2, 3, 4, 5])).node_id, 126);
    }

    /// CMMP-NODE-04: M0, option "via DIN" active, base 0; DIN0, DIN1, DIN3 HIGH, DIN2 LOW →
    /// node 11; with the option inactive the node is the FCT base address.
    #[test]
    fn cmmp_node_04_m0_node_from_din0_3() {
        let inputs = M0Inputs {
            din0_3: [true, true, false, true],
            ..M0Inputs::default()
        };
        assert_eq!(
            M0Fieldbus::reset(0, true, 125, inputs).settings().node_id,
            11
        );
        assert_eq!(
            M0Fieldbus::reset(7, false, 125, inputs).settings().node_id,
            7
        );
    }

    /// CMMP-NODE-05: M3 DIP6/DIP7 OFF/OFF, ON/OFF, OFF/ON, ON/ON → 125, 250, 500, 1000 kbit/s.
    #[test]
    fn cmmp_node_05_m3_bit_rate() {
        let rates: Vec<u16> = [&[][..], &[6], &[7], &[6, 7]]
            .iter()
            .map(|on| m3_power_on(0, dips(on)).bit_rate_kbit)
            .collect();
        assert_eq!(rates, [125, 250, 500, 1000]);
    }

    /// CMMP-NODE-06: M0 DIN12/DIN13 select 125…1000 kbit/s, accepted only while CAN is off.
    #[test]
    fn cmmp_node_06_m0_bit_rate_only_while_can_is_off() {
        let at = |din12, din13| M0Inputs {
            din12,
            din13,
            ..M0Inputs::default()
        };
        let rates: Vec<u16> = [(false, false), (true, false), (false, true), (true, true)]
            .iter()
            .map(|&(a, b)| {
                M0Fieldbus::reset(0, true, 125, at(a, b))
                    .settings()
                    .bit_rate_kbit
            })
            .collect();
        assert_eq!(rates, [125, 250, 500, 1000]);
        // CAN on at 500 kbit/s: DIN12/DIN13 and DIN0…3 changes are ignored until it is off.
        let mut m = M0Fieldbus::reset(0, true, 125, at(false, true));
        m.on_inputs(M0Inputs {
            din8: true,
            ..at(false, true)
        });
        m.on_inputs(M0Inputs {
            din8: true,
            din0_3: [true; 4],
            ..at(true, true)
        });
        let s = m.settings();
        assert_eq!((s.can_active, s.bit_rate_kbit, s.node_id), (true, 500, 1));
        m.on_inputs(at(true, true));
        let s = m.settings();
        assert_eq!((s.can_active, s.bit_rate_kbit), (false, 1000));
    }

    /// CMMP-NODE-07: DIN9 at RESET picks CiA 402 (LOW) or FHPP (HIGH) and is ignored after;
    /// a DIN8 LOW→HIGH edge activates CANopen at once, without a reset.
    #[test]
    fn cmmp_node_07_m0_profile_at_reset_and_din8_edge() {
        let low = M0Inputs::default();
        let fhpp = M0Inputs { din9: true, ..low };
        assert_eq!(
            M0Fieldbus::reset(0, true, 125, low).settings().profile,
            Profile::Cia402
        );
        let mut m = M0Fieldbus::reset(0, true, 125, fhpp);
        assert_eq!(m.settings().profile, Profile::Fhpp);
        assert!(!m.settings().can_active);
        m.on_inputs(M0Inputs { din8: true, ..low });
        assert!(m.settings().can_active, "the DIN8 edge, no reset");
        assert_eq!(m.settings().profile, Profile::Fhpp, "DIN9 only at RESET");
        // HIGH already at RESET: on from the start.
        let on = M0Fieldbus::reset(0, true, 125, M0Inputs { din8: true, ..low });
        assert!(on.settings().can_active);
        // Without the DIN option FCT activates CAN, with its own bit rate.
        let fct = M0Fieldbus::reset(3, false, 500, fhpp);
        let s = fct.settings();
        assert_eq!(
            (s.can_active, s.bit_rate_kbit, s.profile),
            (true, 500, Profile::Cia402)
        );
        assert_eq!(fct.fct_bit_rate_kbit(), 500);
    }

    /// CMMP-NODE-08: M3 DIP8 OFF/ON → CANopen deactivated/activated.
    #[test]
    fn cmmp_node_08_m3_dip8_activates_canopen() {
        assert!(!m3_power_on(0, dips(&[1, 2])).can_active);
        assert!(m3_power_on(0, dips(&[1, 2, 8])).can_active);
    }
}
