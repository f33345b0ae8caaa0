//! EtherCAT slave controller emulation, sans-IO and `no_std`: an Ethernet frame in, the same
//! frame processed out, as the ESC chip does on the fly (ETG.1000, spec/ethercat-esc.md).
#![no_std]
#![forbid(unsafe_code)]

pub mod sii;
