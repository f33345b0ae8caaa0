//! What a drive does when its CAN controller changes error state (`canbus::fault_confinement`),
//! as its manual gives it: a table, one row per personality, CiA 301's usage for the rest.
//!
//! - CiA 301 (its emergency error codes): EMCY 8120h "CAN in error-passive mode" when
//!   the node goes passive, cleared (EMCY 0000h) when it is active again; 8140h "recovered
//!   from bus off" once back on the bus.
//! - CMMP-AS (manual App. B.2, error 12-1): "CAN: bus off", EMCY 8120h,
//!   a configurable fault reaction; the manual has no error-passive entry. The fault is raised
//!   when the controller goes bus off and its EMCY goes out once the node is back (a node off
//!   the bus sends nothing); a fault reset clears it.
//! - Nanotec (Nanotec §17): MONITORING_COMM_PASSIVE 8120h and
//!   MONITORING_COMM_BUSRECOVERY 8140h, as CiA 301.

use canbus::fault_confinement::{ErrorState, Transition};

/// One reaction of a drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reaction {
    /// The CiA 301 EMCY producer raises the error (EMCY, 1001h, 1003h).
    Raise(u16),
    /// … clears it (EMCY 0000h when it was the last).
    Clear(u16),
    /// A drive fault with its fault reaction; a fault reset clears it.
    Fault(u16),
    /// The EMCY of an active error again (lost while the node was off the bus).
    Repeat(u16),
}

use Reaction::*;

/// A personality's reactions to each change of error state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BusFaultReactions {
    pub device: &'static str,
    pub on_passive: &'static [Reaction],
    /// Error passive → error active.
    pub on_active: &'static [Reaction],
    pub on_bus_off: &'static [Reaction],
    /// Bus off → error active (a node off the bus sent nothing meanwhile).
    pub on_recovered: &'static [Reaction],
}

/// Error register bits with a communication error: generic (bit 0) and communication (bit 4).
pub const COMMUNICATION_REGISTER: u8 = 0x11;

/// CiA 301's usage (CANopenNode): 8140h is set at bus off and cleared on recovery; off the bus
/// nothing leaves, so both EMCYs go out once it is back.
const CIA_301: BusFaultReactions = BusFaultReactions {
    device: "",
    on_passive: &[Raise(0x8120)],
    on_active: &[Clear(0x8120)],
    on_bus_off: &[],
    on_recovered: &[Raise(0x8140), Clear(0x8120), Clear(0x8140)],
};

pub const REACTIONS: &[BusFaultReactions] = &[
    BusFaultReactions {
        device: "cmmp-as",
        on_passive: &[],
        on_active: &[],
        on_bus_off: &[Fault(0x8120)],
        // Decision: the 12-1 EMCY, lost while the bus was off, is sent once back; the drive
        // stays in FAULT until a fault reset, which clears it (EMCY 0000h).
        on_recovered: &[Repeat(0x8120)],
    },
    BusFaultReactions {
        device: "nanotec-smci47s",
        ..CIA_301
    },
    BusFaultReactions {
        device: "nanotec-pd4n",
        ..CIA_301
    },
];

pub fn reactions(device: &str) -> &'static BusFaultReactions {
    REACTIONS
        .iter()
        .find(|r| r.device == device)
        .unwrap_or(&CIA_301)
}

/// The reactions of `device` to `t`.
pub fn react(device: &str, t: Transition) -> &'static [Reaction] {
    let r = reactions(device);
    match (t.from, t.to) {
        (_, ErrorState::Passive) => r.on_passive,
        (ErrorState::Passive, ErrorState::Active) => r.on_active,
        (_, ErrorState::BusOff) => r.on_bus_off,
        (ErrorState::BusOff, ErrorState::Active) => r.on_recovered,
        (ErrorState::Active, ErrorState::Active) => &[],
    }
}
