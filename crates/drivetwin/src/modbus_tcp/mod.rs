//! Modbus TCP on the device side: the servers of a drive with a register map of its own
//! ([`crate::cell::modbus_device::ModbusDevice`]), in the cell loop or on a thread of its own.

pub mod cell_drive;
pub mod cycle_server;
pub mod device_thread;
pub mod server;
