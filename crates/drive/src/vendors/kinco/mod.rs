//! The Kinco FD / CD drives.

pub mod bit_rates;
pub mod dip_switches;
pub mod rs232;
pub mod rtu;
