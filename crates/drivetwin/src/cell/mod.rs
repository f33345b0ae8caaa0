//! The runtime: a cell is the stations of one process and the buses between them, stepped on
//! one clock. A station ([`station::Station`]) is one drive with all its front ends; the cell
//! holds its stations in one list ([`stations::Stations`]) and a CAN bus
//! ([`can_segment::SegmentBus`]) names the stations on it by [`stations::StationId`]. The list
//! and the buses together are a [`can_cell::CanCell`], which the cell loop (with each bus's
//! transports beside it), the virtual clock and the scenario rig run and the EtherCAT chains
//! join.

pub mod bus_faults;
pub mod bus_rate;
pub mod bus_timing;
pub mod can_cell;
pub mod can_segment;
pub mod ci_console;
pub mod config;
pub mod control;
pub mod device_model;
pub mod diagnostics;
pub mod eds_drive;
pub mod eds_ethercat;
pub mod ethercat_line;
pub mod fault_injector;
pub mod front_fault_injector;
pub mod interfaces;
pub mod lateness;
pub mod link;
pub mod load_control;
pub mod modbus_device;
pub mod next_turn;
pub mod param_saver;
pub mod param_store;
pub mod planned;
pub mod realtime;
pub mod station;
pub mod stations;
pub mod storage_request;
pub mod terminal;
pub mod tracer;
pub mod wire_faults;

mod vendor_seams;
pub use vendor_seams::Vendors;
