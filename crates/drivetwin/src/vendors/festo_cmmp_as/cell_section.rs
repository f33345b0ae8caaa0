//! The CMMP-AS's keys of a `[[drive]]` (its section of the cell file,
//! [`crate::cell::config::DeviceSection`]): its fieldbus switches (`[drive.switches]`, manual
//! §2.3–2.4), which set node number, bit rate and CAN activation, and its CI terminal
//! (`ci_terminal`, §3.2.3).

use serde::Deserialize;

use super::fieldbus_switches::{m3_power_on, M0Fieldbus, M0Inputs, BIT_RATES_KBIT};
use crate::cell::bus_rate::NodeRate;
use crate::cell::config::{
    eight_switches, DeviceSection, DriveContext, FieldbusSettings, Key, OwnRate, OwnSettings,
    Ports, SectionError,
};

/// The CMMP-AS's section.
pub const SECTION: DeviceSection = DeviceSection {
    devices: &["cmmp-as"],
    keys: &KEYS,
    read,
};

/// The keys only a CMMP-AS has.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CmmpAsKeys {
    /// The switch positions or input levels that give node number, bit rate and CAN
    /// activation (manual §2.3–2.4); when given, its node number wins over `node`.
    pub switches: Option<SwitchesSection>,
    /// TCP address (loopback only) of the drive's CI terminal, the debug console whose SDO
    /// simulation the manual describes (§3.2.3); none by default.
    pub ci_terminal: Option<String>,
}

/// What each key is, for the refusal of the key on another device.
pub const KEYS: [Key; 2] = [
    Key {
        name: "switches",
        what: "CMMP-AS switches (DIP block S1 or the fieldbus inputs, CMMP-AS §2.3–2.4)",
    },
    Key {
        name: "ci_terminal",
        what: "CI terminal (the CMMP-AS's debug console, §3.2.3)",
    },
];

/// `[drive.switches]`: how a CMMP-AS's fieldbus settings come from its hardware.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwitchesSection {
    /// `m3` (DIP block S1 of the CAN module) or `m0` (digital inputs).
    pub variant: SwitchVariant,
    /// The FCT base node address (default 0).
    #[serde(default)]
    pub base_address: u8,
    /// M3: the DIP switches that are ON (1…8); M0: the inputs that are HIGH (0…3, 8, 9,
    /// 12, 13).
    #[serde(default)]
    pub on: Vec<u8>,
    /// M0: FCT option "fieldbus parameterisation via DIN" (on in the delivery state).
    #[serde(default = "yes")]
    pub via_din: bool,
    /// M0 without the DIN option: the bit rate set in FCT, kbit/s.
    #[serde(default = "default_fct_bit_rate")]
    pub fct_bit_rate_kbit: u16,
}

fn yes() -> bool {
    true
}
fn default_fct_bit_rate() -> u16 {
    125
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum SwitchVariant {
    M3,
    M0,
}

/// Reads a CMMP-AS's keys: the switches' node-ID and bit rate, the CI terminal.
fn read(table: toml::Table, drive: &DriveContext<'_>) -> Result<OwnSettings, SectionError> {
    let keys = CmmpAsKeys::deserialize(toml::Value::Table(table))?;
    let fieldbus = match &keys.switches {
        Some(sw) => {
            let err = SectionError::key("switches");
            if !drive.desc.fieldbus_switches {
                return Err(err(format!("{} has no CMMP-AS switches", drive.desc.name)));
            }
            Some(sw.settings().map_err(err)?)
        }
        None => None,
    };
    let switches = fieldbus.zip(keys.switches.as_ref().map(SwitchesSection::rate_key));
    Ok(OwnSettings {
        node: fieldbus.map(|f| f.node_id),
        fieldbus,
        rate: Some(OwnRate::Fixed(node_rate(switches))),
        ports: Ports {
            ci_terminal: keys.ci_terminal,
            ..Ports::default()
        },
        ..OwnSettings::default()
    })
}

/// A CMMP-AS's bit rate: its `[drive.switches]` (`key` names the switches or inputs that set
/// the rate), or without them an M3 whose block S1 has only DIP8 (CANopen on) ON.
///
/// Decision: the manual prints no delivery state of S1 (Tab. 2.3–2.5). A drive without
/// `[drive.switches]` is taken as DIP6/DIP7 OFF, 125 kbit/s: the untouched position, and the
/// slowest rate the drive offers, so the twin is never faster than a real one.
pub fn node_rate(switches: Option<(FieldbusSettings, &str)>) -> NodeRate {
    match switches {
        Some((f, key)) => NodeRate::new(f.bit_rate_kbit, key),
        None => NodeRate::new(
            125,
            "[drive.switches] (none: DIP6/DIP7 OFF, CMMP-AS Tab. 2.4)",
        ),
    }
}

impl SwitchesSection {
    /// What sets the bit rate, for messages: the switches, the inputs or FCT.
    fn rate_key(&self) -> &'static str {
        match (self.variant, self.via_din) {
            (SwitchVariant::M3, _) => "[drive.switches] DIP6/DIP7",
            (SwitchVariant::M0, true) => "[drive.switches] DIN12/DIN13",
            (SwitchVariant::M0, false) => "[drive.switches] fct_bit_rate_kbit",
        }
    }

    /// The settings at power-on.
    pub fn settings(&self) -> Result<FieldbusSettings, String> {
        match self.variant {
            SwitchVariant::M3 => {
                let dip =
                    eight_switches(&self.on, |n| format!("DIP {n}: the M3 block has DIP 1…8"))?;
                Ok(m3_power_on(self.base_address, dip))
            }
            SwitchVariant::M0 => {
                let mut i = M0Inputs::default();
                for &n in &self.on {
                    match n {
                        0..=3 => {
                            if let Some(din) = i.din0_3.get_mut(usize::from(n)) {
                                *din = true;
                            }
                        }
                        8 => i.din8 = true,
                        9 => i.din9 = true,
                        12 => i.din12 = true,
                        13 => i.din13 = true,
                        _ => {
                            return Err(format!(
                                "DIN{n}: the M0 fieldbus inputs are DIN0…3, 8, 9, 12, 13"
                            ))
                        }
                    }
                }
                if !BIT_RATES_KBIT.contains(&self.fct_bit_rate_kbit) {
                    return Err(format!(
                        "fct_bit_rate_kbit {}: one of {BIT_RATES_KBIT:?}",
                        self.fct_bit_rate_kbit
                    ));
                }
                Ok(
                    M0Fieldbus::reset(self.base_address, self.via_din, self.fct_bit_rate_kbit, i)
                        .settings(),
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The factory rate: a CMMP-AS without switches runs at 125 kbit/s.
    #[test]
    fn without_switches_125_kbit() {
        assert_eq!(node_rate(None).kbit, 125);
    }

    /// CMMP-NODE-05 through the rate: DIP6/DIP7 ON/ON is 1 Mbit/s, named by the key.
    #[test]
    fn cmmp_as_switches_give_the_rate() {
        let mut dip = [false; 8];
        dip[5] = true;
        dip[6] = true;
        let r = node_rate(Some((m3_power_on(0, dip), "[drive.switches] DIP6/DIP7")));
        assert_eq!(
            (r.kbit, r.set_by.as_str()),
            (1000, "[drive.switches] DIP6/DIP7")
        );
    }
}
