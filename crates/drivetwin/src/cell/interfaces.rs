//! Which interfaces a drive of the cell has, and which combinations the real device offers.
//! Pure rules, no I/O: the cell file lists a drive's interfaces (`interfaces = [...]`, or
//! what its keys imply), and [`check`] refuses a combination the device does not have,
//! naming the manual's rule, unless the drive sets `allow_unreal_interfaces = true` (a
//! testing key: the twin then serves what was asked, e.g. one CMMP-AS on CANopen and
//! EtherCAT at once to compare the two).
//!
//! The rules are the device files' (`interfaces`, `interfaces_one_of`, `interfaces_rule`:
//! `od::InterfaceOffer`): the CMMP-AS has CANopen, EtherCAT and the CI terminal, one fieldbus at a
//! time (the manual's extract kept beside the project, `cmmp-as-1-communication.md` §2.3); the
//! CMMO-ST Modbus TCP only; a device file without them its profile's fieldbus.

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

/// What `device` offers (a personality the twin does not know: CANopen only).
pub fn offer(device: &str) -> od::InterfaceOffer {
    crate::cell::eds_drive::by_name(device)
        .map(|d| d.interfaces)
        .unwrap_or(od::InterfaceOffer {
            has: &["canopen"],
            one_of: &[],
            rule: "a CANopen device",
        })
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
    #[error("--ethercat: the CMMO-ST has no EtherCAT (Modbus TCP only)")]
    WholeCellOnEthercat,
}

/// Whether `device` may run `wanted` together; `allow_unreal` lifts the one-at-a-time rule
/// (never a missing interface).
pub fn check(
    device: &str,
    wanted: &[InterfaceName],
    allow_unreal: bool,
) -> Result<(), InterfaceError> {
    let o = offer(device);
    if let Some(missing) = wanted.iter().find(|w| !o.has.contains(&w.as_str())) {
        return Err(InterfaceError::Missing {
            device: device.into(),
            interface: missing.as_str(),
            rule: o.rule,
        });
    }
    let mut exclusive = wanted.iter().filter(|w| o.one_of.contains(&w.as_str()));
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

/// Each drive's EtherCAT chain as `drivetwin run --ethercat IFNAME` and the cell FMU
/// (`drivetwin fmu --ethercat IFNAME`) resolve it, in `specs` (the drives of `file`, in order):
/// a drive whose `interfaces` list "ethercat" without naming a chain is on `ethercat_if`'s;
/// with `ethercat_if` and a cell file that names no interfaces and no chain at all, every
/// drive is on that chain instead of CAN (the form from before the cell loop served both).
/// A drive left without its chain keeps `Some(None)`: the caller says what names one.
pub fn resolve_ethercat_chains(
    file: &crate::cell::config::CellFile,
    specs: &mut [crate::cell::config::DriveSpec],
    ethercat_if: Option<&str>,
) -> Result<(), InterfaceError> {
    let Some(ifname) = ethercat_if else {
        return Ok(());
    };
    let whole_cell = file
        .drive
        .iter()
        .all(|d| d.interfaces.is_none() && d.ethercat.is_none());
    if whole_cell {
        if specs.iter().any(|s| s.fhpp.is_some()) {
            return Err(InterfaceError::WholeCellOnEthercat);
        }
        for s in specs.iter_mut() {
            s.canopen = false;
            s.ethercat = Some(None);
        }
    }
    for s in specs.iter_mut() {
        if let Some(chain @ None) = &mut s.ethercat {
            *chain = Some(ifname.to_owned());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::InterfaceName::*;
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
