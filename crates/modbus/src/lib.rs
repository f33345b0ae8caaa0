//! Modbus application protocol, sans-IO and `no_std`: request bytes in, response bytes out.
#![no_std]
#![forbid(unsafe_code)]
