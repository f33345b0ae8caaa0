//! The Nanotec drives' keys of a `[[drive]]` (their section of the cell file,
//! [`crate::cell::config::DeviceSection`]): the rotary switches (§1.1.1), which set node-ID and
//! bit rate at power-on, the motor connected (`motor_type`, 2004h:07, §1.2) and a stepper's
//! motor and load (`[drive.stepper]`, as the CMMO-ST's).

use drive::vendors::nanotec::rotary_switches::{self, power_on, PowerOn, RotarySwitches};
use serde::Deserialize;

use crate::cell::bus_rate::{NodeRate, RateCode, RateCodes, RateObject};
use crate::cell::config::{DeviceSection, DriveContext, Key, OwnRate, OwnSettings, SectionError};
use crate::cell::device_model::is_cia402;
use crate::cell::station::Commissioning;
use crate::vendors::festo_cmmo_st::cell_section::StepperSection;

/// The Nanotec drives' section.
pub const SECTION: DeviceSection = DeviceSection {
    devices: &["nanotec-pd4n", "nanotec-smci47s"],
    keys: &KEYS,
    read,
};

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
    /// A stepper's motor and load (`motor_type = "stepper"`, the default): the CMMO-ST's
    /// `[drive.stepper]` keys but `mode` (a Nanotec's closed loop is its object 2001h ENABLE_CL, §3.3).
    pub stepper: Option<StepperSection>,
}

/// The `[drive.motor]` keys a stepper does not have: its shaft, load and windings are
/// `[drive.stepper]`'s (the servo motor's nameplate currents and speed still commission
/// 6075h, 6073h, 6410h:03 and 6080h).
const SERVO_SHAFT_KEYS: [&str; 7] = [
    "inertia",
    "viscous_friction",
    "coulomb_friction",
    "load_torque",
    "torque_constant",
    "resistance",
    "inductance",
];

/// What each key is, for the refusal of the key on another device.
pub const KEYS: [Key; 3] = [
    Key {
        name: "rotary_switches",
        what: "rotary switches (Nanotec §1.1.1)",
    },
    Key {
        name: "motor_type",
        what: "motor type 2004h:07 (Nanotec §1.2 \"Motortyp\")",
    },
    Key {
        name: "stepper",
        what: "stepper motor and load (the CMMO-ST's and a Nanotec stepper's [drive.stepper])",
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
    pub fn commissioning(self) -> Vec<Commissioning> {
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
    pub fn switches(&self, count: u8) -> Result<RotarySwitches, String> {
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

/// Reads a Nanotec's keys: the rotary switches' node-ID and bit rate, the motor type.
fn read(table: toml::Table, drive: &DriveContext<'_>) -> Result<OwnSettings, SectionError> {
    let keys = NanotecKeys::deserialize(toml::Value::Table(table))?;
    let desc = drive.desc;
    let rotary = match &keys.rotary_switches {
        Some(rs) => {
            let err = SectionError::key("rotary_switches");
            let switches = rs.switches(desc.rotary_switches).map_err(err)?;
            let eeprom = |index| drive.stored_u8(index, 0).map_err(err);
            let p = power_on(switches, eeprom(0x2009)?, eeprom(0x2005)?);
            if !(1..=127).contains(&p.node_id) {
                return Err(err(format!("node-ID {} from 2009h", p.node_id)));
            }
            if !p.motion_allowed {
                tracing::warn!(
                    node = p.node_id,
                    "2005h holds no bit-rate code (130…135): the controller answers on \
                     CAN but accepts no motion commands (Nanotec §1.1.3 step 7)"
                );
            }
            Some(p)
        }
        None => None,
    };
    let mut own = OwnSettings {
        node: rotary.map(|p| p.node_id),
        // NT-NODE-07: no bit-rate code in 2005h, the controller takes no motion command.
        no_enables: rotary.is_some_and(|p| !p.motion_allowed),
        ..OwnSettings::default()
    };
    if !desc.baud_rates.is_empty() {
        let code = drive
            .rate_code(0x2005)
            .map_err(SectionError::key("objects"))?;
        own.rate = Some(rate(rotary, code));
    }
    if let Some(t) = keys.motor_type {
        if !(is_cia402(desc) && desc.entry(0x2004, 7).is_some()) {
            return Err(SectionError::Key {
                key: "motor_type",
                what: format!("{} has no motor type 2004h:07 (a Nanotec's)", desc.name),
            });
        }
        if t != NanotecMotorType::Stepper {
            own.bldc = Some(drive::bldc::BldcData::default());
        }
        own.commissioning = t.commissioning();
    }
    let stepper_motor = keys
        .motor_type
        .is_none_or(|t| t == NanotecMotorType::Stepper);
    if let Some(section) = &keys.stepper {
        let err = SectionError::key("stepper");
        if !stepper_motor {
            return Err(err(
                "the motor is a BLDC (`motor_type`): its data are [drive.motor]'s".into(),
            ));
        }
        if section.mode.is_some() {
            return Err(err(
                "stepper.mode: a Nanotec's closed loop is its object 2001h (ENABLE_CL, \
                 Nanotec §3.3), set in [drive.objects]"
                    .into(),
            ));
        }
        let (data, _) = section.stepper().map_err(err)?;
        own.stepper = Some(data);
    }
    if stepper_motor {
        if let Some(toml::Value::Table(motor)) = drive.drive.rest.get("motor") {
            if let Some(k) = SERVO_SHAFT_KEYS.iter().find(|k| motor.contains_key(**k)) {
                return Err(SectionError::Key {
                    key: "motor",
                    what: format!(
                        "motor.{k}: a Nanotec stepper's shaft and load are [drive.stepper]'s \
                         (holding_torque, load_inertia, load_torque, viscous_friction, \
                         coulomb_friction); [drive.motor] is a BLDC's (`motor_type`)"
                    ),
                });
            }
        }
    }
    // §11.10: with a node-ID from the switches, 2009h reads the switch value.
    if let Some(p) = rotary.filter(|p| p.node_id_from_switches) {
        own.commissioning_last.push(Commissioning {
            index: 0x2009,
            sub: 0,
            bytes: vec![p.node_id],
        });
    }
    Ok(own)
}

/// A Nanotec's bit rate: its rotary switches at power-on (§1.1.1), or without
/// `[drive.rotary_switches]` switches set to the node-ID, which fix 1 Mbit/s. Switches 80h and
/// above take the rate from 2005h (`code_2005h`), which a stored set may change; a code outside
/// 130…135 sets none (§1.1.3 step 7: the controller still answers on CAN, so it follows the
/// bus).
pub fn rate(power_on: Option<PowerOn>, code_2005h: RateCode) -> OwnRate {
    match power_on {
        None => OwnRate::Fixed(NodeRate::new(
            1000,
            "[drive.rotary_switches] (none: switches at the node-ID fix 1 Mbit/s, \
             Nanotec §1.1.1)",
        )),
        Some(p) if p.bit_rate_from_eeprom => OwnRate::Object(RateObject::new(
            0x2005,
            "rotary switches 80h and above",
            code_2005h,
            RateCodes::Vendor(rotary_switches::bit_rate_kbit),
        )),
        Some(_) => OwnRate::Fixed(NodeRate::new(
            1000,
            "[drive.rotary_switches] (1…127 fix 1 Mbit/s)",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// A Nanotec's 2005h as its cell file sets it.
    fn code_2005h(code: u8) -> RateCode {
        RateCode::new(0, Some(code))
    }

    /// The rate of `rate`.
    fn kbit(rate: &OwnRate) -> Option<u16> {
        match rate {
            OwnRate::Fixed(r) => Some(r.kbit),
            OwnRate::Object(o) => o.rate().map(|r| r.kbit),
        }
    }

    /// The factory rate: a Nanotec without rotary switches runs at 1 Mbit/s.
    #[test]
    fn without_switches_1_mbit() {
        assert_eq!(kbit(&rate(None, code_2005h(135))), Some(1000));
    }

    /// NT-NODE-03 / NT-NODE-06 / NT-NODE-07 through the rate: switches ≥ 80h take 2005h,
    /// 1…127 fix 1 Mbit/s, an invalid 2005h sets none (the node follows the bus).
    #[test]
    fn nanotec_switches_and_2005h_give_the_rate() {
        let two = |left, right| RotarySwitches::Two { left, right };
        let r = rate(Some(power_on(two(5, 8), 1, 134)), code_2005h(134));
        let OwnRate::Object(object) = &r else {
            panic!("2005h sets the rate");
        };
        let r = object.rate().unwrap();
        assert_eq!(r.kbit, 500);
        assert!(r.set_by.contains("\"2005:00\" = 134"), "{}", r.set_by);
        let r = rate(Some(power_on(two(5, 0), 1, 134)), code_2005h(134));
        assert_eq!(kbit(&r), Some(1000));
        assert_eq!(
            kbit(&rate(Some(power_on(two(5, 8), 1, 0)), code_2005h(0))),
            None
        );
    }

    /// A stored 2005h wins: switches 80h + node with 2005h = 133 (250 kbit/s, §1.1.3 step 4).
    #[test]
    fn a_stored_2005h_wins() {
        let switches = RotarySwitches::Two { left: 1, right: 8 };
        let OwnRate::Object(object) = rate(Some(power_on(switches, 1, 135)), code_2005h(135))
        else {
            panic!("2005h sets the rate");
        };
        let object = object.stored(133, Path::new("state/n.params"));
        assert_eq!(object.index(), 0x2005);
        assert_eq!(object.rate().map(|r| r.kbit), Some(250));
    }
}
