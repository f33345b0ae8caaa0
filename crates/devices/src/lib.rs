//! The device personalities, generated at build time from `devices/*.toml`.
#![no_std]
#![forbid(unsafe_code)]

include!(concat!(env!("OUT_DIR"), "/devices.rs"));

/// The personality called `name` (`cmmp-as`, …).
pub fn by_name(name: &str) -> Option<&'static od::DeviceDescription> {
    ALL.iter().copied().find(|d| d.name == name)
}

/// An LED panel address of an entry (Kinco ch. 9: `d3.01` is Din1_Function 2010h:03).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PanelAddress {
    pub key: &'static str,
    pub index: u16,
    pub sub: u8,
}

/// A Modbus register of an entry (Kinco §12.3: 3100h is the controlword 6040h); a value of
/// `words` > 1 takes the registers after it too, low word first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModbusRegister {
    pub register: u16,
    pub index: u16,
    pub sub: u8,
    pub words: u8,
}

/// The keys of a personality's entries besides index and sub-index (`panel`, `modbus` in the
/// device file), sorted by key.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Addresses {
    pub device: &'static str,
    pub panel: &'static [PanelAddress],
    pub modbus: &'static [ModbusRegister],
}

impl Addresses {
    /// The entry behind panel address `key` (`d3.01`).
    pub fn panel(&self, key: &str) -> Option<(u16, u8)> {
        self.panel
            .iter()
            .find(|p| p.key == key)
            .map(|p| (p.index, p.sub))
    }

    /// The panel addresses of entry `index`:`sub` (several for Kinco 2FF0h:01).
    pub fn panel_keys(&self, index: u16, sub: u8) -> impl Iterator<Item = &'static str> + '_ {
        self.panel
            .iter()
            .filter(move |p| p.index == index && p.sub == sub)
            .map(|p| p.key)
    }

    /// The Modbus register of entry `index`:`sub`.
    pub fn modbus_register(&self, index: u16, sub: u8) -> Option<&'static ModbusRegister> {
        self.modbus
            .iter()
            .find(|r| r.index == index && r.sub == sub)
    }
}

/// The panel addresses and Modbus registers of personality `name`.
pub fn addresses(name: &str) -> Option<&'static Addresses> {
    ALL_ADDRESSES.iter().copied().find(|a| a.device == name)
}
