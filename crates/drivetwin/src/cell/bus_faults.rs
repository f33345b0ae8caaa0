//! What a drive does when its CAN controller changes error state (`canbus::fault_confinement`):
//! the reactions its device description lists (`od::BusFaultReactions`, a device file's
//! `[device.bus_faults]`, CiA 301's usage for a file without one), picked by the transition.

use canbus::fault_confinement::{ErrorState, Transition};
use od::{BusFaultReaction, BusFaultReactions};

/// Error register bits with a communication error: generic (bit 0) and communication (bit 4).
pub const COMMUNICATION_REGISTER: u8 = 0x11;

/// The reactions of a device with `reactions` to `t`.
pub fn react(reactions: &BusFaultReactions, t: Transition) -> &'static [BusFaultReaction] {
    match (t.from, t.to) {
        (_, ErrorState::Passive) => reactions.on_passive,
        (ErrorState::Passive, ErrorState::Active) => reactions.on_active,
        (_, ErrorState::BusOff) => reactions.on_bus_off,
        (ErrorState::BusOff, ErrorState::Active) => reactions.on_recovered,
        (ErrorState::Active, ErrorState::Active) => &[],
    }
}
