//! EtherCAT slave controller emulation, sans-IO and `no_std`: an Ethernet frame in, the same
//! frame processed out, as the ESC chip does on the fly (ETG.1000).
//!
//! "spec §n" in this crate is a section of `ethercat-esc.md`, the notes on ETG.1000 and on what
//! SOEM, ethercrab and KickCAT expect of a slave, kept beside the project with the manuals'
//! extracts.
//!
//! Layout (one file per concept, named as ethercrab names it):
//! * wire views: [`frame`] (Ethernet + EtherCAT header, [`frame::FrameWriter`]),
//!   [`datagram`] (datagram header, [`datagram::Command`]), [`mailbox`] (mailbox header);
//! * ESC: [`register`] (address map, write masks, reset values), [`fmmu`],
//!   [`sync_manager`], [`eeprom`] (SII interface 0x0500), [`al_control`] and
//!   [`al_status_code`] (application-layer state machine), [`dl_status`] (ports: link
//!   and loop), [`esc`] (the controller);
//! * [`sii`]: the SII EEPROM image;
//! * [`sync_monitor`]: when the device takes outputs (frame or SYNC0) and loses sync;
//! * [`master`]: the master side (addressing, SII reads, AL requests, SDO client messages).
//!
//! No allocation, no `unsafe`, and no panics on anything that comes from the wire: every
//! access to frame bytes and ESC memory is bounds-checked and treats a short buffer as an
//! error to count, not a crash.
#![no_std]
#![forbid(unsafe_code)]

pub mod al_control;
pub mod al_status_code;
pub mod coe;
pub mod datagram;
pub mod dl_status;
pub mod eeprom;
pub mod esc;
mod field;
pub mod fmmu;
pub mod frame;
pub mod mailbox;
pub mod master;
pub mod register;
pub mod sii;
pub mod sync_manager;
pub mod sync_monitor;

pub use al_control::{AlControl, AlState, AlStatus};
pub use al_status_code::AlStatusCode;
pub use datagram::{Command, Datagram};
pub use dl_status::{DlStatus, PortStatus};
pub use eeprom::Eeprom;
pub use esc::{
    process_chain, process_chain_with, AlHook, ClockError, ErrorCounters, Esc, EscConfig,
    FixedProcessData, FrameOutcome, MailboxLayout, NoHook, PdiError,
};
pub use fmmu::Fmmu;
pub use frame::{Address, EthernetFrame, Frame, FrameWriter, WireError};
pub use sync_manager::SyncManager;
pub use sync_monitor::{Sync0Outcome, SyncMode, SyncMonitor, SYNC_MODES};
