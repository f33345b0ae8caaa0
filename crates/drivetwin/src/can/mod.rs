//! CAN transports and the CANopen drives on them: the in-process bus, the socketcand TCP
//! server, the SocketCAN bridge, and a drive's CiA 301 node.

pub mod bus;
pub mod bus_faults;
pub mod drive;
pub mod frame_budget;
pub mod socketcan;
pub mod socketcand;
