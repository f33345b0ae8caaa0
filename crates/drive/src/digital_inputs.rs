//! The digital inputs of a CiA 402 drive: the levels of its inputs, the simulated wiring of
//! the axis's switches and hardware enables to them, and 60FDh digital_inputs as CiA 402
//! defines it (§6.6.4): bit 0 negative limit switch, bit 1 positive limit switch, bit 2 home
//! switch, bit 3 interlock, bits 4 … 15 reserved, bits 16 … 31 manufacturer-specific.
//!
//! CiA 402 names no input terminals: which input carries which switch, and what the
//! manufacturer's bits show, is the vendor's ([`InputWiring`] and the hooks `switches`,
//! `digital_inputs`, `switch_input` of [`crate::personality::Vendor`]). The simulated
//! switches are normally open (HIGH when actuated), the hardware enables HIGH while present.

use crate::travel::Inputs;

/// Input levels, bit n = the vendor's input n ([`crate::drive::Drive::force_inputs`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Levels(pub u16);

/// 60FDh bits CiA 402 defines (§6.6.4).
pub mod bit {
    pub const NEGATIVE_LIMIT: u32 = 1 << 0;
    pub const POSITIVE_LIMIT: u32 = 1 << 1;
    pub const HOME_SWITCH: u32 = 1 << 2;
    /// A hardware enable the drive needs is missing.
    pub const INTERLOCK: u32 = 1 << 3;
    /// Bits 16 … 31: manufacturer-specific.
    pub const MANUFACTURER: u32 = 0xFFFF_0000;
}

/// Which inputs the simulated axis is wired to, each a mask of bit n = input n: the switch at
/// the negative end of the travel, the one at the positive end, the home switch, and the
/// hardware enables (all of them HIGH: present).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InputWiring {
    pub negative_limit: u16,
    pub positive_limit: u16,
    pub home: u16,
    pub enables: u16,
}

impl InputWiring {
    /// The standard drive's wiring. Decision: CiA 402 names no input terminals, so the
    /// inputs are numbered as the 60FDh bits they show (0 negative limit, 1 positive limit,
    /// 2 home switch), input 3 the hardware enable whose absence is the interlock of bit 3.
    pub const CIA402: InputWiring = InputWiring {
        negative_limit: 1 << 0,
        positive_limit: 1 << 1,
        home: 1 << 2,
        enables: 1 << 3,
    };

    /// Both hardware enables present: transition 2 may happen.
    pub fn enables(&self, levels: Levels) -> bool {
        levels.0 & self.enables == self.enables
    }

    /// The switches as wired (normally open: actuated is HIGH).
    pub fn switches(&self, levels: Levels) -> Inputs {
        Inputs {
            negative_limit: levels.high(self.negative_limit),
            positive_limit: levels.high(self.positive_limit),
            home: levels.high(self.home),
        }
    }

    /// 60FDh of a drive that reads its switches as wired and shows no manufacturer bits.
    pub fn digital_inputs(&self, levels: Levels) -> u32 {
        profile_bits(self.switches(levels), self.enables(levels))
    }
}

/// 60FDh's CiA 402 bits 0 … 3 for the switches as the drive reads them and its enables.
pub fn profile_bits(switches: Inputs, enables: bool) -> u32 {
    let mut v = 0;
    if switches.negative_limit {
        v |= bit::NEGATIVE_LIMIT;
    }
    if switches.positive_limit {
        v |= bit::POSITIVE_LIMIT;
    }
    if switches.home {
        v |= bit::HOME_SWITCH;
    }
    if !enables {
        v |= bit::INTERLOCK;
    }
    v
}

impl Levels {
    /// The levels of the simulated wiring: the travel's switches (normally open) and the
    /// hardware enables on the inputs `wiring` names.
    pub fn wired(wiring: &InputWiring, switches: Inputs, enables_present: bool) -> Self {
        let mut l = 0;
        if switches.negative_limit {
            l |= wiring.negative_limit;
        }
        if switches.positive_limit {
            l |= wiring.positive_limit;
        }
        if switches.home {
            l |= wiring.home;
        }
        if enables_present {
            l |= wiring.enables;
        }
        Levels(l)
    }

    /// Inputs in `mask` forced to the level in `levels` (a test, a fault injection).
    pub fn forced(self, mask: u16, levels: u16) -> Self {
        Levels((self.0 & !mask) | (levels & mask))
    }

    /// Any input of `inputs` HIGH.
    pub fn high(self, inputs: u16) -> bool {
        self.0 & inputs != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The standard wiring: switch n on input n, the enable on input 3; 60FDh shows bits 0 … 3
    /// and nothing of the manufacturer's.
    #[test]
    fn the_standard_wiring_shows_the_profile_bits_only() {
        let w = InputWiring::CIA402;
        let at_positive = Inputs {
            positive_limit: true,
            ..Inputs::default()
        };
        let levels = Levels::wired(&w, at_positive, true);
        assert_eq!(levels, Levels(0b1010));
        assert_eq!(w.digital_inputs(levels), bit::POSITIVE_LIMIT);
        let no_enable = levels.forced(1 << 3, 0);
        assert_eq!(
            w.digital_inputs(no_enable),
            bit::POSITIVE_LIMIT | bit::INTERLOCK
        );
        assert_eq!(w.digital_inputs(no_enable) & bit::MANUFACTURER, 0);
    }
}
