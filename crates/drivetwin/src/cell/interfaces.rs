//! Which interfaces a drive of the cell has, and which combinations the real device offers.
//! Pure rules, no I/O: the cell file lists a drive's interfaces (`interfaces = [...]`, or
//! what its keys imply), and [`check`] refuses a combination the device does not have,
//! naming the manual's rule, unless the drive sets `allow_unreal_interfaces = true` (a
//! testing key: the twin then serves what was asked, e.g. one CMMP-AS on CANopen and
//! EtherCAT at once to compare the two).
//!
//! The rules, as a table (data, not code):
//!
//! - CMMP-AS: CANopen on [X4] or EtherCAT (CAMC-EC in Ext2, M3 only), one fieldbus at a time:
//!   "If another fieldbus interface is plugged into Ext1/Ext2, DIP 8 activates that fieldbus
//!   instead of CANopen on [X4]" and EtherCAT "cannot be deactivated with DIP switch 8"
//!   (`spec/cmmp-as-1-communication.md` §2.3, §2.11). The CI terminal (RS232, §3.2.3) works
//!   beside either.
//! - CMMO-ST: Modbus TCP only (`spec/cmmo-st-fhpp.md` §2.5); no CANopen, no CI terminal.
//! - Devices not in the table: CANopen only, the CI terminal and Modbus refused.

use serde::Deserialize;

/// One interface of a drive, as the cell file names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InterfaceName {
    Canopen,
    Ethercat,
    ModbusTcp,
    CiTerminal,
}

impl InterfaceName {
    pub fn as_str(self) -> &'static str {
        match self {
            InterfaceName::Canopen => "canopen",
            InterfaceName::Ethercat => "ethercat",
            InterfaceName::ModbusTcp => "modbus-tcp",
            InterfaceName::CiTerminal => "ci-terminal",
        }
    }
}

/// What a device offers.
#[derive(Debug)]
pub struct Offer {
    pub device: &'static str,
    /// Every interface the device has.
    pub has: &'static [InterfaceName],
    /// Of these, at most one at a time.
    pub one_of: &'static [InterfaceName],
    /// The manual's rule behind `one_of`.
    pub rule: &'static str,
}

use InterfaceName::*;

pub const OFFERS: &[Offer] = &[
    Offer {
        device: "cmmp-as",
        has: &[Canopen, Ethercat, CiTerminal],
        one_of: &[Canopen, Ethercat],
        rule: "CMMP-AS manual §2.3 (spec/cmmp-as-1-communication.md): one fieldbus at a time; \
               with an interface in Ext1/Ext2 (CAMC-EC: EtherCAT) DIP 8 activates that \
               fieldbus instead of CANopen on [X4]",
    },
    Offer {
        device: "cmmo-st",
        has: &[ModbusTcp],
        one_of: &[],
        rule: "CMMO-ST manual §2.5 (spec/cmmo-st-fhpp.md): Modbus TCP is its fieldbus",
    },
];

/// What a device not in [`OFFERS`] is taken to have.
const DEFAULT_OFFER: Offer = Offer {
    device: "",
    has: &[Canopen],
    one_of: &[],
    rule: "a CANopen device",
};

pub fn offer(device: &str) -> &'static Offer {
    OFFERS
        .iter()
        .find(|o| o.device == device)
        .unwrap_or(&DEFAULT_OFFER)
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InterfaceError {
    #[error("{device} has no {interface} interface ({rule})")]
    Missing {
        device: String,
        interface: &'static str,
        rule: &'static str,
    },
    #[error(
        "{device}: {first} and {second} at once is not what the real device does ({rule}); \
         `allow_unreal_interfaces = true` on the drive allows it for testing"
    )]
    Combination {
        device: String,
        first: &'static str,
        second: &'static str,
        rule: &'static str,
    },
}

/// Whether `device` may run `wanted` together; `allow_unreal` lifts the one-at-a-time rule
/// (never a missing interface).
pub fn check(
    device: &str,
    wanted: &[InterfaceName],
    allow_unreal: bool,
) -> Result<(), InterfaceError> {
    let o = offer(device);
    if let Some(missing) = wanted.iter().find(|w| !o.has.contains(w)) {
        return Err(InterfaceError::Missing {
            device: device.into(),
            interface: missing.as_str(),
            rule: o.rule,
        });
    }
    let mut exclusive = wanted.iter().filter(|w| o.one_of.contains(w));
    if let (Some(first), Some(second)) = (exclusive.next(), exclusive.next()) {
        if !allow_unreal {
            return Err(InterfaceError::Combination {
                device: device.into(),
                first: first.as_str(),
                second: second.as_str(),
                rule: o.rule,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cmmp_as_runs_one_fieldbus_at_a_time() {
        assert_eq!(check("cmmp-as", &[Canopen, CiTerminal], false), Ok(()));
        assert_eq!(check("cmmp-as", &[Ethercat, CiTerminal], false), Ok(()));
        let e = check("cmmp-as", &[Canopen, Ethercat], false).unwrap_err();
        assert!(e.to_string().contains("§2.3"), "{e}");
        assert!(e.to_string().contains("allow_unreal_interfaces"), "{e}");
        assert_eq!(check("cmmp-as", &[Canopen, Ethercat], true), Ok(()));
    }

    #[test]
    fn a_missing_interface_is_refused_even_for_testing() {
        let e = check("cmmp-as", &[Canopen, ModbusTcp], true).unwrap_err();
        assert!(matches!(
            e,
            InterfaceError::Missing {
                interface: "modbus-tcp",
                ..
            }
        ));
        assert!(check("cmmo-st", &[Canopen], true).is_err());
        assert_eq!(check("cmmo-st", &[ModbusTcp], false), Ok(()));
        assert!(check("testbench", &[CiTerminal], false).is_err());
    }
}
