//! The CMMP-AS digital inputs as the firmware reads them (CMMP-AS §5.13, §5.14): the levels
//! of DIN0 … DIN9, the switch assignment of 6510h:11 … :14, and 60FDh digital_inputs with
//! its manufacturer bits.
//!
//! The simulated axis is wired as the manual's default ([`WIRING`]): the switch at the
//! negative end of the travel on DIN6, the one at the positive end on DIN7, the home switch
//! on DIN9, all normally open (HIGH when actuated); DIN4 (output-stage enable) and DIN5
//! (controller enable) are HIGH while the hardware enables are present. 6510h:11 … :14 change
//! how the firmware reads these inputs, not the wiring, so a set-up that does not match the
//! switches shows as it would on the real drive.

use crate::digital_inputs::{profile_bits, InputWiring, Levels};
use crate::drive::named_switches::{NamedSwitch, SwitchInput};
use crate::travel::Inputs;

/// DIN0 (the first of DIN0 … DIN3, bits 24 … 27 of 60FDh).
pub const DIN0: u16 = 1 << 0;
/// DIN4 output-stage enable (§5.13, function 36).
pub const DIN4: u16 = 1 << 4;
/// DIN5 controller enable (§5.13).
pub const DIN5: u16 = 1 << 5;
/// DIN6 limit switch E0 (negative with 6510h:12 = 0, §5.14).
pub const DIN6: u16 = 1 << 6;
/// DIN7 limit switch E1 (positive with 6510h:12 = 0, §5.14).
pub const DIN7: u16 = 1 << 7;
/// DIN8 home switch with 6510h:13 = 1 (§5.14).
pub const DIN8: u16 = 1 << 8;
/// DIN9 home switch with 6510h:13 = 0 (default, §5.14).
pub const DIN9: u16 = 1 << 9;

/// The simulated axis on the manual's default inputs: E0 on DIN6, E1 on DIN7, the home switch
/// on DIN9, the hardware enables on DIN4 and DIN5.
pub const WIRING: InputWiring = InputWiring {
    negative_limit: DIN6,
    positive_limit: DIN7,
    home: DIN9,
    enables: DIN4 | DIN5,
};

/// 60FDh's manufacturer bits (§5.13, the 60FDh bit table, L4189–4197).
pub mod bit {
    /// DIN0 … DIN3 in bits 24 … 27.
    pub const DIN0_SHIFT: u32 = 24;
    pub const DIN8: u32 = 1 << 28;
    pub const DIN9: u32 = 1 << 29;
}

/// The switch assignment, 6510h:11 … :14 (§5.14).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SwitchConfig {
    /// 6510h:11 limit_switch_polarity: 1 normally open (default), 0 normally closed.
    pub limit_normally_open: bool,
    /// 6510h:12 limit_switch_selector: 0 DIN6 = E0 negative / DIN7 = E1 positive (default),
    /// 1 the other way round.
    pub limits_swapped: bool,
    /// 6510h:13 homing_switch_selector: 0 DIN9 (default), 1 DIN8.
    pub home_on_din8: bool,
    /// 6510h:14 homing_switch_polarity: 1 normally open (default), 0 normally closed.
    pub home_normally_open: bool,
}

impl Default for SwitchConfig {
    fn default() -> Self {
        SwitchConfig {
            limit_normally_open: true,
            limits_swapped: false,
            home_on_din8: false,
            home_normally_open: true,
        }
    }
}

impl SwitchConfig {
    /// From the object values 6510h:11, :12, :13, :14.
    pub fn from_objects(
        polarity: i64,
        selector: i64,
        home_selector: i64,
        home_polarity: i64,
    ) -> Self {
        SwitchConfig {
            limit_normally_open: polarity != 0,
            limits_swapped: selector == 1,
            home_on_din8: home_selector == 1,
            home_normally_open: home_polarity != 0,
        }
    }

    /// The inputs E0 and E1 read: DIN6 / DIN7, the other way round with 6510h:12 = 1.
    fn limit_inputs(&self) -> (u16, u16) {
        if self.limits_swapped {
            (DIN7, DIN6)
        } else {
            (DIN6, DIN7)
        }
    }

    /// The input the home switch is read from: DIN9, DIN8 with 6510h:13 = 1.
    fn home_input(&self) -> u16 {
        if self.home_on_din8 {
            DIN8
        } else {
            DIN9
        }
    }

    /// Which switches the firmware sees active: a normally open switch is active when its
    /// input is HIGH, a normally closed one when it is LOW (6510h:11, L4361–4381).
    pub fn switches(&self, levels: Levels) -> Inputs {
        let (e0, e1) = self.limit_inputs();
        let active = |din, normally_open: bool| levels.high(din) == normally_open;
        Inputs {
            negative_limit: active(e0, self.limit_normally_open),
            positive_limit: active(e1, self.limit_normally_open),
            home: active(self.home_input(), self.home_normally_open),
        }
    }

    /// The input carrying `switch` and the level the firmware reads as actuated.
    pub fn switch_input(&self, switch: NamedSwitch) -> SwitchInput {
        let (e0, e1) = self.limit_inputs();
        match switch {
            NamedSwitch::LimitNegative => SwitchInput {
                mask: e0,
                actuated_high: self.limit_normally_open,
            },
            NamedSwitch::LimitPositive => SwitchInput {
                mask: e1,
                actuated_high: self.limit_normally_open,
            },
            NamedSwitch::Home => SwitchInput {
                mask: self.home_input(),
                actuated_high: self.home_normally_open,
            },
        }
    }

    /// 60FDh digital_inputs: CiA 402's bits 0 … 3 (bit 3 interlock: DIN4 or DIN5 missing)
    /// and DIN0 … DIN3, DIN8, DIN9 in bits 24 … 29. The CAMC-D-8E8A extension (bits 16 … 23)
    /// is not fitted.
    pub fn digital_inputs(&self, levels: Levels) -> u32 {
        let mut v = profile_bits(self.switches(levels), WIRING.enables(levels));
        v |= u32::from(levels.0 & 0x000F) << bit::DIN0_SHIFT;
        if levels.high(DIN8) {
            v |= bit::DIN8;
        }
        if levels.high(DIN9) {
            v |= bit::DIN9;
        }
        v
    }
}
