//! CAN transports: the in-process bus, the socketcand TCP server and the SocketCAN bridge.
//! The drives on a bus, with their CiA 301 nodes, are the cell's ([`crate::cell::station`]).

pub mod bus;
pub mod frame_budget;
pub mod socketcan;
pub mod socketcand;
