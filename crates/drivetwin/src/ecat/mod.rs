//! EtherCAT on the slave side: the chain of emulated slave controllers and the raw Ethernet
//! socket it sits on.

pub mod chain;
pub mod link;
#[cfg(target_os = "linux")]
pub mod net_interface;
