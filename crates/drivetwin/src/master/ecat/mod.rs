//! A minimal EtherCAT master, enough to check a chain (`drivetwin ecat`): count the slaves,
//! give them station addresses, read their SII identity, step their AL state machine and run
//! CoE SDO transfers through their mailbox. The full master is SOEM or ethercrab; this one
//! sends one datagram per frame and waits for it, which is all a check needs.
//!
//! The frames are built and read with the sans-IO codecs of the `ethercat` crate
//! ([`ethercat::frame::FrameWriter`], [`ethercat::master`]); [`link::FrameLink`] carries them
//! (a raw socket on Linux, [`link::SocketLink`]).
//!
//! Conventions (the ESC reference kept beside the project, §2.8, SOEM `ecx_config_init`): slaves
//! are numbered from 1 in wire order; slave n gets station address 0x1000 + n (APWR 0x0010);
//! everything after that is configured addressing (FPRD/FPWR) and expects a working counter of 1.

pub mod link;
mod sdo;
mod sii;
mod state;

use std::time::Duration;

use ethercat::datagram::{self, Command};
use ethercat::frame::{self, Address, FrameWriter};
use ethercat::master::{self as m, AlStatusBlock};
use ethercat::register::RegisterAddress as R;
use ethercat::{AlState, AlStatusCode, DlStatus};
use od::AbortCode;

pub use link::FrameLink;
pub use sii::SlaveInfo;
pub use state::StateChange;

/// Why a master operation failed.
#[derive(Debug, thiserror::Error)]
pub enum EcatError {
    #[error("EtherCAT link: {0}")]
    Io(#[from] std::io::Error),
    #[error("no frame came back within {0:?} (nothing connected, or the line is open)")]
    NoReply(Duration),
    #[error("cannot build the frame: {0:?}")]
    Frame(frame::WireError),
    #[error("{what}: working counter {wkc}, expected {expected}")]
    WorkingCounter {
        what: String,
        wkc: u16,
        expected: u16,
    },
    #[error("no slave {slave} on the wire ({count} found)")]
    NoSuchSlave { slave: u16, count: u16 },
    #[error("slave {slave}: SII EEPROM error, status {status:#06x}")]
    Eeprom { slave: u16, status: u16 },
    #[error("slave {slave}: SII EEPROM still busy after {timeout:?}")]
    EepromBusy { slave: u16, timeout: Duration },
    #[error("slave {slave}: the SII describes no {what}")]
    Sii { slave: u16, what: &'static str },
    #[error(
        "slave {slave}: {} -> {} refused, stays in {}: AL status code {code}",
        m::state_name(*from), m::state_name(*requested), state_text(*state)
    )]
    Refused {
        slave: u16,
        from: AlState,
        requested: AlState,
        state: Option<AlState>,
        code: AlStatusCode,
    },
    #[error(
        "slave {slave}: still {} after {timeout:?} waiting for {}",
        state_text(*state), m::state_name(*requested)
    )]
    StateTimeout {
        slave: u16,
        requested: AlState,
        state: Option<AlState>,
        timeout: Duration,
    },
    #[error("slave {slave}: the mailbox is not running (AL state {}; it needs Pre-Op)", state_text(*state))]
    NoMailbox { slave: u16, state: Option<AlState> },
    #[error("slave {slave}: no mailbox answer within {timeout:?} ({what})")]
    MailboxTimeout {
        slave: u16,
        what: &'static str,
        timeout: Duration,
    },
    #[error("slave {slave}: mailbox error {detail:#06x}")]
    MailboxError { slave: u16, detail: u16 },
    #[error("slave {slave}: SDO {index:04X}:{sub:02X}: abort {}", abort_text(*code))]
    Abort {
        slave: u16,
        index: u16,
        sub: u8,
        code: AbortCode,
    },
    #[error("slave {slave}: {what}")]
    Protocol { slave: u16, what: String },
}

fn state_text(s: Option<AlState>) -> &'static str {
    s.map_or("an invalid state", m::state_name)
}

/// The text of an abort code: CiA 301's, or ETG.1000.6's CoE-only codes (ESC reference §6.5).
pub fn abort_description(code: AbortCode) -> Option<&'static str> {
    match code {
        ethercat::coe::CA_NOT_SUPPORTED => Some("Complete access not supported"),
        ethercat::coe::LENGTH_EXCEEDS_MAILBOX => Some("Object length exceeds mailbox size"),
        _ => code.description(),
    }
}

/// An abort code with its text, `0x06020000 (Object does not exist …)`.
pub fn abort_text(code: AbortCode) -> String {
    match abort_description(code) {
        Some(t) => format!("0x{:08X} ({t})", code.0),
        None => format!("0x{:08X} (unknown abort code)", code.0),
    }
}

/// What one datagram brought back.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    pub data: Vec<u8>,
    pub wkc: u16,
}

/// The master on one link.
pub struct EcatMaster<L> {
    link: L,
    index: u8,
    /// How long to wait for one frame to come back.
    pub frame_timeout: Duration,
    /// How often a frame that did not come back is sent again (SOEM resends the same frame,
    /// ESC reference §1.1).
    pub retries: u32,
    /// Mailbox counters per slave (ESC reference §5.3).
    counters: std::collections::HashMap<u16, u8>,
}

impl<L: FrameLink> EcatMaster<L> {
    pub fn new(link: L) -> Self {
        EcatMaster {
            link,
            index: 0,
            frame_timeout: Duration::from_millis(50),
            retries: 2,
            counters: Default::default(),
        }
    }

    pub fn link_mut(&mut self) -> &mut L {
        &mut self.link
    }

    /// One datagram in one frame, sent until it comes back (or the retries run out).
    pub async fn datagram(
        &mut self,
        command: Command,
        address: Address,
        data: &[u8],
    ) -> Result<Reply, EcatError> {
        self.index = self.index.wrapping_add(1);
        let index = self.index;
        let mut buf = vec![
            0u8;
            frame::ETHERNET_HEADER_LEN
                + frame::HEADER_LEN
                + datagram::HEADER_LEN
                + data.len()
                + datagram::WKC_LEN
        ];
        let mut w = FrameWriter::ethernet(&mut buf, m::MASTER_MAC).map_err(EcatError::Frame)?;
        w.push(command, index, address, data)
            .map_err(EcatError::Frame)?;
        let len = w.finish();
        buf.truncate(len);
        for _ in 0..=self.retries {
            let mut frame = buf.clone();
            if self
                .link
                .round_trip(&mut frame, index, self.frame_timeout)
                .await?
            {
                // The link checked that this is our reply.
                if let Some(dg) = m::reply_datagram(&frame, index) {
                    return Ok(Reply {
                        data: dg.data().to_vec(),
                        wkc: dg.wkc(),
                    });
                }
            }
        }
        Err(EcatError::NoReply(self.frame_timeout))
    }

    /// Number of slaves: the working counter of a BRD (every slave adds 1, ESC reference §1.4).
    pub async fn count_slaves(&mut self) -> Result<u16, EcatError> {
        let r = self
            .datagram(
                Command::Brd,
                Address::Physical {
                    adp: 0,
                    ado: R::Type.addr(),
                },
                &[0, 0],
            )
            .await?;
        Ok(r.wkc)
    }

    /// Gives slaves 1…`count` their station addresses 0x1000 + n by position (APWR 0x0010).
    pub async fn assign_addresses(&mut self, count: u16) -> Result<(), EcatError> {
        for n in 1..=count {
            let r = self
                .datagram(
                    Command::Apwr,
                    Address::Physical {
                        adp: m::auto_increment(n - 1),
                        ado: R::ConfiguredStationAddress.addr(),
                    },
                    &m::station_address(n).to_le_bytes(),
                )
                .await?;
            expect_wkc(&r, 1, || format!("slave {n}: APWR station address"))?;
        }
        Ok(())
    }

    /// Counts the slaves and gives them station addresses; returns the count. Changes
    /// nothing else: states, sync managers and mailboxes stay as they are.
    pub async fn attach(&mut self) -> Result<u16, EcatError> {
        let count = self.count_slaves().await?;
        self.assign_addresses(count).await?;
        Ok(count)
    }

    /// FPRD of `len` bytes at `ado` of slave `slave` (1-based).
    pub async fn read(&mut self, slave: u16, ado: u16, len: usize) -> Result<Vec<u8>, EcatError> {
        let zeros = vec![0u8; len];
        let r = self
            .datagram(
                Command::Fprd,
                Address::Physical {
                    adp: m::station_address(slave),
                    ado,
                },
                &zeros,
            )
            .await?;
        expect_wkc(&r, 1, || format!("slave {slave}: FPRD {ado:#06x}"))?;
        Ok(r.data)
    }

    /// FPWR of `data` at `ado` of slave `slave`.
    pub async fn write(&mut self, slave: u16, ado: u16, data: &[u8]) -> Result<(), EcatError> {
        let r = self.write_wkc(slave, ado, data).await?;
        expect_wkc(&r, 1, || format!("slave {slave}: FPWR {ado:#06x}"))
    }

    /// FPWR that returns the working counter instead of checking it (a mailbox write is
    /// refused with 0 while the mailbox is full).
    async fn write_wkc(&mut self, slave: u16, ado: u16, data: &[u8]) -> Result<Reply, EcatError> {
        self.datagram(
            Command::Fpwr,
            Address::Physical {
                adp: m::station_address(slave),
                ado,
            },
            data,
        )
        .await
    }

    /// AL status and status code (0x0130–0x0135).
    pub async fn al_status(&mut self, slave: u16) -> Result<AlStatusBlock, EcatError> {
        let b = self
            .read(slave, R::AlStatus.addr(), m::AL_STATUS_BLOCK)
            .await?;
        AlStatusBlock::parse(&b).ok_or_else(|| EcatError::Protocol {
            slave,
            what: "short AL status".into(),
        })
    }
    /// DL status (0x0110): the links and loops of the slave's ports (ETG.1000.4).
    pub async fn dl_status(&mut self, slave: u16) -> Result<DlStatus, EcatError> {
        let b = self.read(slave, R::DlStatus.addr(), 2).await?;
        match b.as_slice() {
            &[lo, hi] => Ok(DlStatus(u16::from_le_bytes([lo, hi]))),
            _ => Err(EcatError::Protocol {
                slave,
                what: "short DL status".into(),
            }),
        }
    }
}

fn expect_wkc(r: &Reply, expected: u16, what: impl FnOnce() -> String) -> Result<(), EcatError> {
    if r.wkc == expected {
        Ok(())
    } else {
        Err(EcatError::WorkingCounter {
            what: what(),
            wkc: r.wkc,
            expected,
        })
    }
}

#[cfg(test)]
pub(crate) mod tests;
