//! Requesting an AL state (the ESC reference kept beside the project, §4) and the set-up a slave
//! checks before it goes up: the mailbox sync managers before Pre-Op, the process-data sync
//! managers and FMMUs before Safe-Op (§2.5, §2.6, §4.2 table).
//!
//! One request is one write to AL control, as SOEM's `write_state`: Init → Op is refused by
//! the slave (0x0011), not walked through. That is the point of a checker.

use std::time::Duration;

use ethercat::fmmu::Fmmu;
use ethercat::master::sii_image;
use ethercat::master::{self as m, AlStatusBlock};
use ethercat::register::RegisterAddress as R;
use ethercat::sync_manager::SyncManager;
use ethercat::AlState;

use super::{EcatError, EcatMaster, FrameLink};

/// PDO assignment objects of SM2 (outputs) and SM3 (inputs), ETG.1000.6.
const RX_ASSIGN: u16 = 0x1C12;
const TX_ASSIGN: u16 = 0x1C13;
/// How long an error status identical to the one before a request is taken for stale.
const STALE_ERROR: Duration = Duration::from_millis(100);

/// What a state request did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StateChange {
    pub slave: u16,
    pub from: AlStatusBlock,
    pub to: AlStatusBlock,
}

impl<L: FrameLink> EcatMaster<L> {
    /// Requests `target` of slave `slave` (with error acknowledge) after the set-up the step
    /// needs, and waits up to `timeout` for it. A refusal (error bit) is an error with the
    /// AL status code.
    pub async fn request_state(
        &mut self,
        slave: u16,
        target: AlState,
        timeout: Duration,
        sdo_timeout: Duration,
    ) -> Result<StateChange, EcatError> {
        let before = self.al_status(slave).await?;
        let from = before.state().unwrap_or(AlState::Init);
        if before.state() == Some(target) && !before.error() {
            return Ok(StateChange {
                slave,
                from: before,
                to: before,
            });
        }
        match (from, target) {
            (AlState::Init, AlState::PreOp) => self.configure_mailbox(slave).await?,
            (AlState::PreOp, AlState::SafeOp) => {
                self.configure_process_data(slave, sdo_timeout).await?
            }
            _ => {}
        }
        self.write(
            slave,
            R::AlControl.addr(),
            &m::al_request(target).to_le_bytes(),
        )
        .await?;
        let start = tokio::time::Instant::now();
        let deadline = start + timeout;
        loop {
            let now = self.al_status(slave).await?;
            if now.state() == Some(target) && !now.error() {
                return Ok(StateChange {
                    slave,
                    from: before,
                    to: now,
                });
            }
            // The status from before the request may still show for a moment on a slave
            // whose firmware runs the state machine: an unchanged error counts only when
            // it persists (the twin answers within the same datagram).
            let stale = now == before && start.elapsed() < STALE_ERROR;
            if now.error() && !stale {
                return Err(EcatError::Refused {
                    slave,
                    from,
                    requested: target,
                    state: now.state(),
                    code: now.code,
                });
            }
            if tokio::time::Instant::now() >= deadline {
                return Err(EcatError::StateTimeout {
                    slave,
                    requested: target,
                    state: now.state(),
                    timeout,
                });
            }
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    }

    /// SM0 and SM1 from the SII (mailbox words and SYNC_M), in one 16-byte write at 0x0800
    /// as SOEM does (ESC reference §2.6, §2.8 step 31).
    async fn configure_mailbox(&mut self, slave: u16) -> Result<(), EcatError> {
        let image = self.read_sii(slave).await?;
        let Some([sm0, sm1]) = sii_image::mailbox_sync_managers(&image) else {
            return Err(EcatError::Sii {
                slave,
                what: "mailbox (words 0x18-0x1B)",
            });
        };
        let mut block = sm0.to_bytes().to_vec();
        block.extend_from_slice(&sm1.to_bytes());
        self.write(slave, R::sync_manager(0), &block).await
    }

    /// SM2 / SM3 sized from the PDO assignment read over CoE (or the SII default lengths without
    /// 1C12h / 1C13h), FMMU0 / FMMU1 onto them, as SOEM's `config_map` (ESC reference §2.8).
    ///
    /// The process-data watchdog is switched off (0x0420 = 0, "0 disables", ESC reference §2.1):
    /// this master exchanges no cyclic process data, and with the watchdog on a slave drops from Op
    /// back to Safe-Op with 0x001B a watchdog time (100 ms) after reaching it.
    async fn configure_process_data(
        &mut self,
        slave: u16,
        sdo_timeout: Duration,
    ) -> Result<(), EcatError> {
        let image = self.read_sii(slave).await?;
        let sm = |n: usize, what| {
            sii_image::sync_manager(&image, n).ok_or(EcatError::Sii { slave, what })
        };
        let (sm2, sm3) = (sm(2, "SM2 (outputs)")?, sm(3, "SM3 (inputs)")?);
        let outputs = self
            .pdo_bytes(slave, RX_ASSIGN, sdo_timeout)
            .await?
            .unwrap_or(sm2.length);
        let inputs = self
            .pdo_bytes(slave, TX_ASSIGN, sdo_timeout)
            .await?
            .unwrap_or(sm3.length);
        let sm2 = SyncManager::new(sm2.start, outputs, sm2.control, outputs > 0);
        let sm3 = SyncManager::new(sm3.start, inputs, sm3.control, inputs > 0);
        self.write(slave, R::sync_manager(2), &sm2.to_bytes())
            .await?;
        self.write(slave, R::sync_manager(3), &sm3.to_bytes())
            .await?;
        // Each slave its own 64 KiB of logical space: outputs, then inputs (as SOEM packs
        // them), so slaves configured one at a time never overlap.
        let base = u32::from(slave) << 16;
        let fmmu = |logical: u32, sm: &SyncManager, write: bool| Fmmu {
            logical_start: logical,
            length: sm.length,
            logical_start_bit: 0,
            logical_stop_bit: 7,
            physical_start: sm.start,
            physical_start_bit: 0,
            read_enable: !write,
            write_enable: write,
            enable: sm.length > 0,
        };
        let out = fmmu(base, &sm2, true);
        let inp = fmmu(base + u32::from(outputs), &sm3, false);
        self.write(slave, R::fmmu(0), &out.to_bytes()).await?;
        self.write(slave, R::fmmu(1), &inp.to_bytes()).await?;
        self.write(slave, R::WatchdogTimeProcessData.addr(), &[0, 0])
            .await
    }
}
