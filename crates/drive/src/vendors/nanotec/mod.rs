//! The Nanotec SMCI / PD drives.

pub mod rotary_switches;
