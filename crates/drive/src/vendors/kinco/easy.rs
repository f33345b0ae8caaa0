//! The Kinco EASY settings that act beyond storing a value (§4.3.1 Tab. 4-2, lines L575-600 of the
//! manual's text kept beside the project): Store_Data 2FF0h:01 / Store_Motor_Data 2FF0h:03 =
//! 1 save, EA00 / tn00 = 2 save and reboot, 3 reboot, and EA06, whose four digits (from the right)
//! are the load type (0 none, 1 belt, 2 ball screw), the application (0 P2P, 1 CNC, 2 master /
//! slave), the limit switches (0 default, 1 removed) and OUT5's polarity (0 normally closed,
//! 1 normally open); default 1001. "After saving, the drive sets the loop parameters by the load
//! type and the application"; after EASY "the drive sets the default stiffness and inertia ratio by
//! EA06" (§4.3.2), tn01 "belt 10, screw 13", tn02 "belt 50, screw 30".
//!
//! Decisions:
//! - EA06 has no object in the manual; the gap 3041h:03 between EA02 Command_Type 3041h:02
//!   and EA05 EASY_Analog_Speed 3041h:04 is taken (CHOSEN, both device files), so the bus
//!   reaches it as the panel does. A value with a digit out of its range is refused
//!   (0609 0030h);
//! - the limit-switch digit and OUT5's polarity act at once ("entered values take effect at
//!   once"): 1 takes P limit± (0010h / 0020h) off every DINx_Function, 0 leaves them;
//!   Dout_Polarity 2010h:0D bit 4 is the polarity;
//! - the load type sets Stiffness and Inertia_Ratio (and with them the loop, `kinco_loops.rs`)
//!   when the panel's EA00 / tn00 saves, as the note on EA00 says; load type 0 gives the
//!   device file's 12 / 3.0. The application digit changes nothing: the manual does not say
//!   what it sets;
//! - a save over the bus (2FF0h:01 = 1) asks the runtime to store the current set
//!   ([`od::ObjectDictionary::request_save`]) and does not touch the loop; 10 (initialise)
//!   stays a value the panel's lock reads;
//! - a reboot is the runtime's ([`DriveEvent::Reboot`]): it reloads the stored set and boots
//!   the nodes, as after NMT reset node.

use od::{AbortCode, ObjectAccess as _};

use super::hooks::Kinco;
use super::io::DINS;
use super::{DinFunction, DIN_FUNCTIONS};
use crate::drive::{Drive, DriveEvent};

/// The digits of EA06 from the right.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EasySettings {
    pub load: u8,
    pub application: u8,
    pub remove_limit_switches: bool,
    pub out5_normally_open: bool,
}

impl EasySettings {
    /// The digits of `v`; `None` where one is out of its range (or `v` > 9999).
    pub fn parse(v: i64) -> Option<Self> {
        if !(0..=9999).contains(&v) {
            return None;
        }
        let digit = |n: u32| ((v / 10i64.pow(n)) % 10) as u8;
        let (load, application, limits, out5) = (digit(0), digit(1), digit(2), digit(3));
        (load <= 2 && application <= 2 && limits <= 1 && out5 <= 1).then_some(EasySettings {
            load,
            application,
            remove_limit_switches: limits == 1,
            out5_normally_open: out5 == 1,
        })
    }

    /// Stiffness and Inertia_Ratio of the load type (tn01, tn02 defaults).
    pub fn stiffness_and_ratio(self) -> (i64, i64) {
        match self.load {
            1 => (10, 50),
            2 => (13, 30),
            _ => (12, 30),
        }
    }
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Kinco> {
    /// Store_Data 2FF0h:01 / Store_Motor_Data 2FF0h:03: 1 saves.
    pub(crate) fn kinco_write_store(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.od.write(index, sub, data)?;
        if data.first() == Some(&1) {
            self.od.request_save(1);
        }
        Ok(())
    }

    /// EA06 3041h:03: checked, stored, the limit switches and OUT5's polarity at once.
    pub(crate) fn kinco_write_easy_settings(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        let mut b = [0u8; 2];
        for (d, s) in b.iter_mut().zip(data) {
            *d = *s;
        }
        let settings = EasySettings::parse(i64::from(u16::from_le_bytes(b)))
            .ok_or(AbortCode::INVALID_VALUE)?;
        self.od.write(index, sub, data)?;
        if settings.remove_limit_switches {
            let limits = [DinFunction::PositiveLimit, DinFunction::NegativeLimit]
                .map(|f| DIN_FUNCTIONS.get(f as usize).map_or(0, |r| r.0))
                .iter()
                .fold(0u16, |a, c| a | c);
            for n in 0..DINS {
                let code = self.value(0x2010, 0x03 + n).clamp(0, 0xFFFF) as u16;
                if code & 0x8000 == 0 && code & limits != 0 {
                    self.kinco_store(0x2010, 0x03 + n, i64::from(code & !limits));
                }
            }
        }
        let polarity = self.value(0x2010, 0x0D);
        let bit = 1 << 4;
        let polarity = if settings.out5_normally_open {
            polarity | bit
        } else {
            polarity & !bit
        };
        self.kinco_store(0x2010, 0x0D, polarity);
        Ok(())
    }

    /// The panel's EA00 / tn00 save: the loop by EA06's load type, then Store_Data and
    /// Store_Motor_Data.
    pub(crate) fn kinco_easy_save(&mut self) -> Result<(), AbortCode> {
        if let Some(s) = EasySettings::parse(self.value(0x3041, 0x03)) {
            let (stiffness, ratio) = s.stiffness_and_ratio();
            self.kinco_store(0x3040, 0x08, stiffness);
            self.kinco_store(0x3040, 0x0B, ratio);
            self.kinco_apply_stiffness();
        }
        self.write(0x2FF0, 0x01, &[1])?;
        self.write(0x2FF0, 0x03, &[1])
    }

    /// Asks the runtime for a restart (EA00 / tn00 = 2 / 3).
    pub(crate) fn kinco_reboot(&mut self) {
        self.push_event(DriveEvent::Reboot);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// EA06's default 1001: belt, P2P, limit switches kept, OUT5 normally open.
    #[test]
    fn ea06_digits() {
        let d = EasySettings::parse(1001);
        assert_eq!(
            d,
            Some(EasySettings {
                load: 1,
                application: 0,
                remove_limit_switches: false,
                out5_normally_open: true,
            })
        );
        assert_eq!(d.map(EasySettings::stiffness_and_ratio), Some((10, 50)));
        assert_eq!(
            EasySettings::parse(112).map(|s| (s.load, s.application, s.remove_limit_switches)),
            Some((2, 1, true))
        );
        for bad in [3, 30, 200, 2000, 10000, -1] {
            assert_eq!(EasySettings::parse(bad), None, "{bad}");
        }
    }
}
