//! The std side of drivetwin: transports, the cell and its runtime, traces, exports and the
//! master commands. Everything here does I/O except the few pure rules it keeps beside them
//! (`cell::fieldbus_switches`, `value_text`, `export::esi`); the protocol and device logic
//! it drives is sans-IO.
//!
//! - [`can`]: the in-process CAN bus, socketcand and SocketCAN transports, CANopen drives;
//! - [`ecat`]: the EtherCAT chain of emulated slave controllers and its raw socket;
//! - [`modbus_tcp`]: Modbus TCP servers and the CMMO-ST's FHPP register map;
//! - [`serial`]: RS232 / RS485 lines on ptys or devices (the Kinco telegrams, Modbus RTU);
//! - [`cell`]: a cell of drives, its file, its runtime and clock, stored parameters;
//! - [`trace`]: pcap and candump writers and readers;
//! - [`export`]: ESI XML for EtherCAT configurators;
//! - [`master`]: the command-line master's protocol clients;
//! - [`web`]: the web console (HTTP API, live samples, the page);
//! - `sys`: the platform calls, the only place with `unsafe` code.
#![deny(unsafe_code)]

pub mod can;
pub mod cell;
pub mod ecat;
pub mod export;
pub mod master;
pub mod modbus_tcp;
pub mod scenario;
pub mod serial;
#[allow(unsafe_code)]
mod sys;
pub mod trace;
pub mod value_text;
pub mod web;
