//! The devices' reactions to their CAN controller's error states (`[device.bus_faults]`),
//! as the generated tables carry them.

use od::BusFaultReaction::{Clear, Fault, Raise, Repeat};
use od::BusFaultReactions;

/// CMMP-AS App. B.2, error 12-1 "CAN: bus off": a fault at bus off, its EMCY once back.
#[test]
fn the_cmmp_as_faults_at_bus_off_and_has_no_error_passive_entry() {
    let r = devices::CMMP_AS.bus_faults;
    assert_eq!(r.on_passive, []);
    assert_eq!(r.on_active, []);
    assert_eq!(r.on_bus_off, [Fault(0x8120)]);
    assert_eq!(r.on_recovered, [Repeat(0x8120)]);
}

/// Nanotec §17: 8120h and 8140h as CiA 301 uses them.
#[test]
fn the_nanotec_drives_react_as_cia_301() {
    for d in [&devices::NANOTEC_SMCI47S, &devices::NANOTEC_PD4N] {
        assert_eq!(d.bus_faults, BusFaultReactions::CIA_301, "{}", d.name);
    }
    let r = BusFaultReactions::CIA_301;
    assert_eq!(r.on_passive, [Raise(0x8120)]);
    assert_eq!(r.on_active, [Clear(0x8120)]);
    assert_eq!(r.on_bus_off, []);
    assert_eq!(
        r.on_recovered,
        [Raise(0x8140), Clear(0x8120), Clear(0x8140)]
    );
}

/// A device file without `[device.bus_faults]` gets CiA 301's usage.
#[test]
fn a_file_without_reactions_has_cia_301s() {
    for d in [&devices::KINCO_FD3, &devices::KINCO_CD3, &devices::CMMO_ST] {
        assert_eq!(d.bus_faults, BusFaultReactions::CIA_301, "{}", d.name);
    }
}
