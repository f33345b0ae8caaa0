//! EtherCAT on the slave side: the chain of emulated slave controllers and the raw Ethernet
//! socket it sits on.

pub mod chain;
pub mod line;
pub mod link;

/// Largest frame read: an Ethernet frame without FCS is at most 1514 bytes (1518 with a VLAN
/// tag); anything longer is not EtherCAT and is dropped as truncated.
pub const MAX_FRAME: usize = 1536;
