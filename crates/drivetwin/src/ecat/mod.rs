//! EtherCAT on the slave side: the chain of emulated slave controllers, one module per
//! concept of what a slave does, and the raw Ethernet socket the chain sits on.

pub mod chain;
pub mod coe_dispatch;
pub mod frame_tap;
pub mod line;
pub mod link;
pub mod process_data;
pub mod slave;
pub mod slave_drive;
pub mod sync0;

/// Largest frame read: an Ethernet frame without FCS is at most 1514 bytes (1518 with a VLAN
/// tag); anything longer is not EtherCAT and is dropped as truncated.
pub const MAX_FRAME: usize = 1536;
