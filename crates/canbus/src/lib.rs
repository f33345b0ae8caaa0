//! A classic CAN bus (ISO 11898-1) as a model, sans-IO and `no_std`: the frame, how long it
//! occupies the wire, which of several ready frames wins the arbitration, each node's fault
//! confinement and the load of the bus over a window. Time is an argument; nothing here reads
//! a clock. CANopen (`canopen`) speaks in these frames; the runtime puts them on this bus.
#![no_std]
#![forbid(unsafe_code)]

pub mod bus_load;
pub mod fault_confinement;
pub mod frame;
pub mod frame_time;
pub mod timed_bus;

pub use frame::{CanFrame, FrameError};
