//! Reading a slave's SII EEPROM through the ESC's EEPROM interface 0x0500–0x050F
//! (the ESC reference kept beside the project, §2.4), as SOEM and ethercrab do it.

use std::time::Duration;

use ethercat::master::sii_image::{self, Identity};
use ethercat::master::{self as m, EepromStatus};
use ethercat::register::RegisterAddress as R;
use ethercat::DlStatus;

use super::{EcatError, EcatMaster, FrameLink};

/// How long the EEPROM may stay busy (SOEM `EC_TIMEOUTEEP` is 20 ms; generous here).
const EEPROM_TIMEOUT: Duration = Duration::from_millis(200);

/// What `scan` reports of one slave.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlaveInfo {
    /// 1-based position in the line.
    pub number: u16,
    pub station: u16,
    pub identity: Identity,
    /// SII string 1 (SOEM's slave name), lossy UTF-8.
    pub name: Option<String>,
    pub al: m::AlStatusBlock,
    /// DL status 0x0110: its ports' links and loops, where a line is cut.
    pub dl: DlStatus,
}

impl<L: FrameLink> EcatMaster<L> {
    /// Waits until the EEPROM interface is idle; returns whether reads give 8 bytes.
    async fn eeprom_idle(&mut self, slave: u16) -> Result<bool, EcatError> {
        let deadline = tokio::time::Instant::now() + EEPROM_TIMEOUT;
        loop {
            let b = self.read(slave, R::SiiControl.addr(), 2).await?;
            let word = u16::from_le_bytes([
                b.first().copied().unwrap_or(0),
                b.get(1).copied().unwrap_or(0),
            ]);
            match EepromStatus::from_u16(word) {
                EepromStatus::Ready { read_8 } => return Ok(read_8),
                EepromStatus::Error(status) => {
                    // A NOP clears the error bits (ESC reference §2.4), so the next command can
                    // run.
                    self.write(slave, R::SiiControl.addr(), &[0, 0]).await?;
                    return Err(EcatError::Eeprom { slave, status });
                }
                EepromStatus::Busy if tokio::time::Instant::now() >= deadline => {
                    return Err(EcatError::EepromBusy {
                        slave,
                        timeout: EEPROM_TIMEOUT,
                    })
                }
                EepromStatus::Busy => tokio::time::sleep(Duration::from_micros(200)).await,
            }
        }
    }

    /// 4 or 8 bytes of the EEPROM from word `word` (ESC reference §2.4 steps 1–4).
    pub async fn eeprom_read(&mut self, slave: u16, word: u16) -> Result<Vec<u8>, EcatError> {
        self.eeprom_idle(slave).await?;
        self.write(slave, R::SiiControl.addr(), &m::eeprom_read_command(word))
            .await?;
        let read_8 = self.eeprom_idle(slave).await?;
        self.read(slave, R::SiiData.addr(), if read_8 { 8 } else { 4 })
            .await
    }

    /// The SII image from word 0 up to its END category (at most 4 KiB). The EEPROM is
    /// taken for the master first (0x0500 = 2, then 0; ESC reference §2.8 steps 16–17) and offered
    /// back to the PDI afterwards if it was before (0x0500 bit 0, as SOEM leaves it).
    pub async fn read_sii(&mut self, slave: u16) -> Result<Vec<u8>, EcatError> {
        let config = R::SiiConfig.addr();
        let to_pdi = self
            .read(slave, config, 1)
            .await?
            .first()
            .copied()
            .unwrap_or(0)
            & 0x01;
        self.write(slave, config, &[0x02]).await?;
        self.write(slave, config, &[0x00]).await?;
        let mut image = Vec::new();
        while !sii_image::is_complete(&image) {
            let word = u16::try_from(image.len() / 2).unwrap_or(u16::MAX);
            let chunk = self.eeprom_read(slave, word).await?;
            if chunk.is_empty() {
                break;
            }
            image.extend_from_slice(&chunk);
        }
        if to_pdi != 0 {
            self.write(slave, config, &[to_pdi]).await?;
        }
        Ok(image)
    }

    /// Identity, name and AL status of slave `slave`.
    pub async fn slave_info(&mut self, slave: u16) -> Result<SlaveInfo, EcatError> {
        let image = self.read_sii(slave).await?;
        let al = self.al_status(slave).await?;
        let dl = self.dl_status(slave).await?;
        Ok(SlaveInfo {
            number: slave,
            station: m::station_address(slave),
            identity: sii_image::identity(&image),
            name: sii_image::name(&image).map(|n| String::from_utf8_lossy(n).into_owned()),
            al,
            dl,
        })
    }
}
