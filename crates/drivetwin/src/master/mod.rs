//! The master side: commands that talk to real or virtual drives over a bus link.

pub mod cia402;
pub mod ecat;
pub mod link;
pub mod lss;
pub mod modbus_tcp;
pub mod pdo_config;
pub mod recorder;
pub mod recording;
pub mod sdo_client;
