//! CiA 301 CANopen device stack, sans-IO and `no_std`: frames and a timestamp in, frames and
//! the next deadline out. It never reads a clock or touches a socket.
#![no_std]
#![forbid(unsafe_code)]

pub mod bus_load;
pub mod ci_terminal;
pub mod decode;
pub mod emcy;
pub mod fault_confinement;
pub mod frame;
pub mod frame_time;
pub mod heartbeat;
pub mod kinco_bit_rates;
pub mod kinco_dip_switches;
pub mod kinco_rs232;
pub mod lss;
pub mod nmt;
pub mod node;
pub mod pdo;
pub mod rotary_switches;
pub mod sdo_client;
pub mod sdo_crc;
pub mod sdo_server;
pub mod timed_bus;

pub use frame::CanFrame;
pub use nmt::{NmtCommand, NmtState};
pub use node::{Node, NodeEvent};
pub use sdo_client::SdoClient;
pub use sdo_server::SdoServer;
