//! The std side of drivetwin: transports, runtime, parameter storage and the master commands.
//! Everything here does I/O; the protocol and device logic it drives is sans-IO.

pub mod bus;
pub mod can_drive;
pub mod cell;
pub mod cell_config;
pub mod ci_console;
pub mod device_model;
pub mod esi;
pub mod ethercat_cell;
pub mod ethercat_link;
pub mod fhpp_modbus;
pub mod fieldbus_switches;
pub mod master;
pub mod modbus_cycle_server;
pub mod modbus_server;
#[cfg(target_os = "linux")]
pub mod net_interface;
pub mod param_store;
pub mod pcap;
pub mod realtime;
pub mod runtime;
pub mod socketcan;
pub mod socketcand;
pub mod trace;
pub mod value_text;
