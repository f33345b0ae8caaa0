//! Modbus TCP on the device side: the servers and the FHPP register map of the CMMO-ST.

pub mod cell_drive;
pub mod cycle_server;
pub mod fhpp;
pub mod server;
