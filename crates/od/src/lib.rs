//! The CiA 301 object dictionary of one drive: the static description of its objects
//! (generated at build time from `devices/*.toml`), the values behind them, and the access
//! rules every protocol front end goes through.
//!
//! `no_std`, no allocation: a dictionary's values live in one byte buffer whose size the
//! description fixes, so the same code runs on a microcontroller.
#![no_std]
#![forbid(unsafe_code)]

pub mod abort_code;
pub mod access;
pub mod brake_timing;
pub mod bus_faults;
pub mod cob_id;
pub mod data_type;
pub mod description;
pub mod diagnostic;
pub mod dictionary;
pub mod eds;
pub mod forwarding;
pub mod parameter_file;
pub mod pdo_rules;
pub mod plant_supervision;
pub mod serial_ports;
pub mod time;
pub mod value;

pub use abort_code::AbortCode;
pub use access::Access;
pub use brake_timing::BrakeTiming;
pub use bus_faults::{BusFaultReaction, BusFaultReactions};
pub use data_type::DataType;
pub use description::{
    Behaviour, CanBitRateCodes, Cia301Options, DeviceDescription, Entry, EthercatSlave,
    FhppParameters, InterfaceOffer, Limit, Object, ObjectKind, Profile, SerialBitRateCodes,
};
pub use diagnostic::{Diagnostic, Reaction};
pub use dictionary::{ObjectAccess, ObjectDictionary, StorageRequest};
pub use forwarding::Forwarding;
pub use plant_supervision::PlantSupervision;
pub use serial_ports::{ProtocolSelect, SerialPort, SerialProtocol};
pub use time::Instant;
pub use value::Value;
