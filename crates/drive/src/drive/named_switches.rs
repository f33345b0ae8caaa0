//! The limit and home switches by name: which digital input carries each function on this
//! drive, and the level that makes the drive read the switch as actuated. A console, a
//! scenario or a cell file says `limit_positive` instead of a DIN mask.
//!
//! * CiA 402's default: the inputs of the vendor's wiring (`INPUT_WIRING`), read as wired
//!   (normally open, actuated HIGH). The Nanotec (§9.1, §5.3): the reference switch on input 6,
//!   no limit-switch input.
//! * CMMP-AS (§5.14): E0 / E1 on DIN6 / DIN7, swapped with 6510h:12 = 1; the home switch on
//!   DIN9, DIN8 with 6510h:13 = 1. Actuated is HIGH for a normally open contact
//!   (6510h:11 / :14 = 1), LOW for a normally closed one.
//! * Kinco (Tab. 6-1, §5.5): the first DIN whose function code 2010h:03 … :09 has P limit+,
//!   P limit− or Home Signal; the limit switches are normally closed (an input at 0 blocks
//!   its direction), the home switch normally open, both through Din_Polarity 2010h:01
//!   (`Internal = Real XOR NOT Polarity`).
//!
//! Forcing goes through [`Drive::force_inputs`]'s mask, so the switch stays where it is put
//! until it is released (`None`: back to the simulated travel).

use super::Drive;
use crate::personality::Vendor;

/// A switch of the axis, by its function.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NamedSwitch {
    LimitPositive,
    LimitNegative,
    Home,
}

impl NamedSwitch {
    /// `limit_positive` / `positive_limit` / `limit+` (the Kinco's "P limit+"), `E1`;
    /// `limit_negative` / `negative_limit` / `limit-`, `E0`; `home` / `home_switch` /
    /// `reference` / `home_signal`.
    pub fn parse(name: &str) -> Option<Self> {
        // Lower case, ' ' and '-' as '_', in a buffer of its own (no allocation).
        let mut buf = [0u8; 24];
        let t = name.trim().as_bytes();
        let b = buf.get_mut(..t.len())?;
        for (o, c) in b.iter_mut().zip(t) {
            *o = match c.to_ascii_lowercase() {
                b' ' | b'-' => b'_',
                c => c,
            };
        }
        let n = core::str::from_utf8(b).ok()?;
        Some(match n {
            "limit_positive" | "positive_limit" | "limit+" | "p_limit+" | "e1" => {
                NamedSwitch::LimitPositive
            }
            "limit_negative" | "negative_limit" | "limit_" | "p_limit_" | "e0" => {
                NamedSwitch::LimitNegative
            }
            "home" | "home_switch" | "reference" | "reference_switch" | "home_signal" => {
                NamedSwitch::Home
            }
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            NamedSwitch::LimitPositive => "limit_positive",
            NamedSwitch::LimitNegative => "limit_negative",
            NamedSwitch::Home => "home",
        }
    }
}

/// Where a switch is wired on this drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SwitchInput {
    /// Bit n = the input [`Drive::force_inputs`] calls bit n (the vendor's numbering: CMMP-AS
    /// DINn, Kinco DINn+1).
    pub mask: u16,
    /// The wire level that makes the drive read the switch as actuated.
    pub actuated_high: bool,
}

impl<S: AsRef<[u8]> + AsMut<[u8]>, V: Vendor> Drive<S, V> {
    /// The input carrying `switch` (`None`: no input has its function).
    pub fn switch_input(&self, switch: NamedSwitch) -> Option<SwitchInput> {
        V::switch_input(self, switch)
    }

    /// The input carrying `switch` as the vendor's `INPUT_WIRING` has it, actuated HIGH (a
    /// normally open switch read as wired); `None` where the wiring has no input for it.
    pub(crate) fn wired_switch_input(&self, switch: NamedSwitch) -> Option<SwitchInput> {
        let w = V::INPUT_WIRING;
        let mask = match switch {
            NamedSwitch::LimitNegative => w.negative_limit,
            NamedSwitch::LimitPositive => w.positive_limit,
            NamedSwitch::Home => w.home,
        };
        if mask == 0 {
            return None;
        }
        Some(SwitchInput {
            mask,
            actuated_high: true,
        })
    }

    /// The inputs forced from outside: (mask, levels), bit n as [`Drive::force_inputs`].
    pub fn forced_inputs(&self) -> (u16, u16) {
        (self.forced_mask, self.forced_levels)
    }

    /// Puts `switch` where it is: actuated (`Some(true)`), released (`Some(false)`) or back to
    /// the simulated travel (`None`). Returns its input, `None` where no input has it.
    pub fn set_switch(
        &mut self,
        switch: NamedSwitch,
        actuated: Option<bool>,
    ) -> Option<SwitchInput> {
        let input = self.switch_input(switch)?;
        let (mut mask, mut levels) = (self.forced_mask, self.forced_levels);
        match actuated {
            None => mask &= !input.mask,
            Some(on) => {
                mask |= input.mask;
                if on == input.actuated_high {
                    levels |= input.mask;
                } else {
                    levels &= !input.mask;
                }
            }
        }
        self.force_inputs(mask, levels);
        Some(input)
    }
}
