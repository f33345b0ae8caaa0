//! What a device description exports for master tools (ESI XML for EtherCAT configurators).

pub mod esi;
