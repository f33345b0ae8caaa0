//! What a device does when its CAN controller changes error state (ISO 11898-1 fault
//! confinement: error active, error passive, bus off), as its manual gives it: device data
//! (`[device.bus_faults]` of a device file), CiA 301's usage where a file says nothing.
//!
//! CiA 301's emergency error codes: 8120h "CAN in error-passive mode", 8140h "recovered from
//! bus off".

/// One reaction of a device to a change of its CAN controller's error state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BusFaultReaction {
    /// The CiA 301 EMCY producer raises the error (EMCY, 1001h, 1003h).
    Raise(u16),
    /// … clears it (EMCY 0000h when it was the last).
    Clear(u16),
    /// A drive fault with its fault reaction; a fault reset clears it.
    Fault(u16),
    /// The EMCY of an active error again (lost while the node was off the bus).
    Repeat(u16),
}

/// A device's reactions to each change of error state, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BusFaultReactions {
    /// Error active (or bus off) → error passive.
    pub on_passive: &'static [BusFaultReaction],
    /// Error passive → error active.
    pub on_active: &'static [BusFaultReaction],
    /// → bus off.
    pub on_bus_off: &'static [BusFaultReaction],
    /// Bus off → error active (a node off the bus sent nothing meanwhile).
    pub on_recovered: &'static [BusFaultReaction],
}

impl BusFaultReactions {
    /// CiA 301's usage (as CANopenNode has it): 8120h is raised when the node goes error
    /// passive and cleared when it is active again; 8140h is set at bus off and cleared on
    /// recovery. Off the bus nothing leaves, so both EMCYs go out once it is back.
    pub const CIA_301: BusFaultReactions = BusFaultReactions {
        on_passive: &[BusFaultReaction::Raise(0x8120)],
        on_active: &[BusFaultReaction::Clear(0x8120)],
        on_bus_off: &[],
        on_recovered: &[
            BusFaultReaction::Raise(0x8140),
            BusFaultReaction::Clear(0x8120),
            BusFaultReaction::Clear(0x8140),
        ],
    };
}

impl Default for BusFaultReactions {
    fn default() -> Self {
        BusFaultReactions::CIA_301
    }
}
