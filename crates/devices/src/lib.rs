//! The device personalities, generated at build time from `devices/*.toml`.
#![no_std]
#![forbid(unsafe_code)]

include!(concat!(env!("OUT_DIR"), "/devices.rs"));

/// The personality called `name` (`cmmp-as`, …).
pub fn by_name(name: &str) -> Option<&'static od::DeviceDescription> {
    ALL.iter().copied().find(|d| d.name == name)
}
