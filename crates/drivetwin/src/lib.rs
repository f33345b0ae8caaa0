//! The std side of drivetwin: transports, runtime, parameter storage and the master commands.
//! Everything here does I/O; the protocol and device logic it drives is sans-IO.

pub mod bus;
pub mod pcap;
pub mod socketcan;
pub mod socketcand;
pub mod can_drive;
pub mod cell;
pub mod param_store;
pub mod master;
pub mod cell_config;
pub mod value_text;
pub mod runtime;
pub mod trace;
