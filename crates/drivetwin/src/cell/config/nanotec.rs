//! The Nanotec drives' keys of a `[[drive]]`: the rotary switches (§1.1.1) and the motor
//! connected (`motor_type`, 2004h:07, §1.2).

use drive::vendors::nanotec::rotary_switches::RotarySwitches;
use serde::Deserialize;

use super::device_keys::Key;
use crate::cell::station::Commissioning;

/// The keys only a Nanotec (SMCI47-S, PD4-N) has.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NanotecKeys {
    /// Its hexadecimal rotary switches (§1.1.1): node-ID and bit rate at power-on; when they
    /// give a node-ID it wins over `node`.
    pub rotary_switches: Option<RotarySwitchesSection>,
    /// Its motor (2004h:07, §1.2 "Motortyp"): `"stepper"` (the default), `"bldc-hall"` or
    /// `"bldc-hall-encoder"`; see [`NanotecMotorType`].
    pub motor_type: Option<NanotecMotorType>,
}

/// What each key is, for the refusal of the key on another device.
pub const KEYS: [Key; 2] = [
    Key {
        name: "rotary_switches",
        what: "rotary switches (Nanotec §1.1.1)",
    },
    Key {
        name: "motor_type",
        what: "motor type 2004h:07 (Nanotec §1.2 \"Motortyp\")",
    },
];

/// `motor_type` of a Nanotec drive: the motor connected and the 2004h:07 it starts with
/// (Nanotec §1.2 "Motortyp", §11.5 sub 7: 0 stepper with or without quadrature encoder, 1 BLDC
/// with Hall sensors, 2 BLDC with Hall sensors and quadrature encoder).
///
/// A BLDC is `drive::bldc`'s default (DB57-like: 4 pole pairs, the DB57 Hall sequence that the
/// default 2004h:0C = 243015h turns) with `[drive.motor]` as its electrical and mechanical
/// data; it starts with 2004h:07 = 1 / 2 and the BLDC load-angle curve of Appendix 18.2 in
/// 200Ch:01 … 07. Values of `[drive.objects]` and a stored set still win, as for every
/// commissioning value.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum NanotecMotorType {
    Stepper,
    BldcHall,
    #[serde(alias = "bldc-encoder")]
    BldcHallEncoder,
}

impl NanotecMotorType {
    /// The value of 2004h:07.
    pub fn code(self) -> u8 {
        match self {
            NanotecMotorType::Stepper => 0,
            NanotecMotorType::BldcHall => 1,
            NanotecMotorType::BldcHallEncoder => 2,
        }
    }

    /// The commissioning values the motor type sets: 2004h:07 and, for a BLDC, the load-angle
    /// curve of Appendix 18.2 (200Ch:01 … 07), as the drive loads it when 2004h:07 selects a
    /// BLDC over SDO.
    pub(super) fn commissioning(self) -> Vec<Commissioning> {
        let mut v = vec![Commissioning {
            index: 0x2004,
            sub: 7,
            bytes: vec![self.code()],
        }];
        if self != NanotecMotorType::Stepper {
            let curve = drive::vendors::nanotec::default_load_angles(self.code());
            v.extend((1u8..).zip(curve).map(|(sub, a)| Commissioning {
                index: 0x200C,
                sub,
                bytes: a.to_le_bytes().to_vec(),
            }));
        }
        v
    }
}

/// `[drive.rotary_switches]`: `left` and `right` on a two-switch Nanotec (SMCI47-S; the value
/// is 16 · right + left, see `drive::vendors::nanotec::rotary_switches`), `switch` on a
/// one-switch one (PD4-N).
/// The EEPROM values they may select are 2009h (node-ID) and 2005h (bit rate) of
/// `[drive.objects]`, else the defaults.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotarySwitchesSection {
    pub left: Option<u8>,
    pub right: Option<u8>,
    pub switch: Option<u8>,
}

impl RotarySwitchesSection {
    /// The switches of a device that has `count` of them.
    pub(super) fn switches(&self, count: u8) -> Result<RotarySwitches, String> {
        let s = match (count, self.left, self.right, self.switch) {
            (2, left, right, None) => RotarySwitches::Two {
                left: left.unwrap_or(0),
                right: right.unwrap_or(0),
            },
            (1, None, None, Some(p)) => RotarySwitches::One(p),
            (2, ..) => return Err("two switches: `left` and `right`, no `switch`".into()),
            (1, ..) => return Err("one switch: `switch`, no `left`/`right`".into()),
            _ => return Err("the device has no rotary switches".into()),
        };
        s.checked().map_err(|e| e.to_string())
    }
}
