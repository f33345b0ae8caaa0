//! CiA 301 CANopen device stack, sans-IO and `no_std`: frames and a timestamp in, frames and
//! the next deadline out. It never reads a clock or touches a socket.
#![no_std]
#![forbid(unsafe_code)]

pub mod decode;
pub mod emcy;
pub mod frame;
pub mod heartbeat;
pub mod lss;
pub mod nmt;
pub mod node;
pub mod pdo;
pub mod sdo_client;
pub mod sdo_crc;
pub mod sdo_server;

pub use frame::CanFrame;
pub use nmt::{NmtCommand, NmtState};
pub use node::{Node, NodeEvent};
pub use sdo_client::SdoClient;
pub use sdo_server::SdoServer;
