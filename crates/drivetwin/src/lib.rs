//! The std side of drivetwin: transports, the cell and its runtime, traces, exports and the
//! master commands. Everything here does I/O except the few pure rules it keeps beside them
//! (`value_text`, `export::esi`); the protocol and device logic
//! it drives is sans-IO.
//!
//! The modules are layered, and none uses one above it (`scripts/structure` checks that no
//! two import each other):
//!
//! - [`cell`]: what runs: a cell of drives (stations) on its CAN buses, each drive with its
//!   dictionary and stored parameters, the cell file, the control handle, wire faults;
//! - the transports, each using the cell and nothing above it:
//!   - [`can`]: the in-process CAN bus, the socketcand and SocketCAN transports;
//!   - [`ecat`]: the EtherCAT chain of emulated slave controllers and its raw socket;
//!   - [`modbus_tcp`]: Modbus TCP servers and the CMMO-ST's FHPP register map;
//!   - [`serial`]: RS232 / RS485 lines on ptys or devices (the Kinco telegrams, Modbus RTU);
//!   - [`trace`]: pcap and candump writers and readers;
//! - [`cell_loop`]: a cell with its transports on a clock: real time (one thread owns every
//!   socket) or virtual ([`cell_loop::virtual_clock`]);
//! - [`scenario`]: scripted runs of a cell;
//! - [`cell_fmu`]: a cell as an FMI 3.0 co-simulation FMU on the virtual clock;
//! - [`web`]: the web console (HTTP API, live samples, the page);
//! - [`master`]: the command-line master's protocol clients;
//! - [`vendors`]: what serves or speaks to one vendor's devices only (a device's own web
//!   pages, a vendor protocol's master), one folder per device family; the layers above
//!   name no vendor and get these through the seams of one value (`vendors::VENDORS`);
//! - [`export`] and [`value_text`]: ESI XML for EtherCAT configurators, values as text;
//! - [`sys`]: the platform calls, the only place with `unsafe` code; public so that the
//!   benches and tests reach a socket through the same safe calls as the runtime.
#![deny(unsafe_code)]

pub mod can;
pub mod cell;
pub mod cell_fmu;
pub mod cell_loop;
pub mod cosim;
pub mod ecat;
pub mod export;
pub mod master;
pub mod modbus_tcp;
pub mod scenario;
pub mod serial;
#[allow(unsafe_code)]
pub mod sys;
pub mod trace;
pub mod value_text;
pub mod vendors;
pub mod web;
