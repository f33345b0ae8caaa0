//! CoE SDO transfers through a slave's mailbox (the ESC reference kept beside the project, §5.2,
//! §6.3): write the request into the receive mailbox SM0 once it is empty, poll the send mailbox
//! SM1 until it is full, read it. The messages are [`ethercat::master::sdo`]'s.

use std::time::Duration;

use ethercat::mailbox;
use ethercat::master::sdo::{self as msg, Response};
use ethercat::register::RegisterAddress as R;
use ethercat::sync_manager::{SyncManager, SM_LEN};
use od::AbortCode;

use super::{EcatError, EcatMaster, FrameLink};

/// The two mailbox sync managers as the slave has them configured.
#[derive(Debug, Clone, Copy)]
struct Mailboxes {
    /// SM0: master → slave.
    rx: SyncManager,
    /// SM1: slave → master.
    tx: SyncManager,
}

/// Status byte of SM `n` (0x0805 for SM0, 0x080D for SM1).
const fn sm_status(n: u8) -> u16 {
    R::sync_manager(n) + 5
}

fn sm_from(b: &[u8]) -> SyncManager {
    let mut a = [0u8; SM_LEN];
    for (d, s) in a.iter_mut().zip(b) {
        *d = *s;
    }
    SyncManager::from_bytes(&a)
}

impl<L: FrameLink> EcatMaster<L> {
    /// The mailbox sync managers, read back from the slave; an error when the mailbox does
    /// not run (SMs disabled, or the slave in Init).
    async fn mailboxes(&mut self, slave: u16) -> Result<Mailboxes, EcatError> {
        let b = self.read(slave, R::sync_manager(0), 2 * SM_LEN).await?;
        let rx = sm_from(b.get(..SM_LEN).unwrap_or(&[]));
        let tx = sm_from(b.get(SM_LEN..).unwrap_or(&[]));
        let state = self.al_status(slave).await?.state();
        let running = !matches!(state, None | Some(ethercat::AlState::Init));
        if !running || !rx.is_active() || !tx.is_active() {
            return Err(EcatError::NoMailbox { slave, state });
        }
        Ok(Mailboxes { rx, tx })
    }

    /// The next request counter for `slave`: 1 → 7 → 1. The first request of this process
    /// carries 0 ("counter not used", ESC reference §5.3): the slave drops a request whose counter
    /// equals the previous one's, and a previous `drivetwin ecat` run may have ended on the
    /// counter this run would start with.
    fn next_counter(&mut self, slave: u16) -> u8 {
        match self.counters.get_mut(&slave) {
            Some(c) => {
                *c = mailbox::next_counter(*c);
                *c
            }
            None => {
                self.counters.insert(slave, 0);
                0
            }
        }
    }

    async fn sm_full(&mut self, slave: u16, n: u8) -> Result<bool, EcatError> {
        let s = self.read(slave, sm_status(n), 1).await?;
        Ok(s.first()
            .is_some_and(|b| b & ethercat::sync_manager::STATUS_MAILBOX_FULL != 0))
    }

    /// Reads and drops a message left in SM1 (an old reply or an emergency), as ethercrab
    /// does before each request.
    async fn mailbox_flush(&mut self, slave: u16, mbx: &Mailboxes) -> Result<(), EcatError> {
        if self.sm_full(slave, 1).await? {
            let _ = self
                .datagram_read(slave, mbx.tx.start, usize::from(mbx.tx.length))
                .await?;
        }
        Ok(())
    }

    async fn datagram_read(
        &mut self,
        slave: u16,
        ado: u16,
        len: usize,
    ) -> Result<super::Reply, EcatError> {
        let zeros = vec![0u8; len];
        self.datagram(
            ethercat::Command::Fprd,
            ethercat::frame::Address::Physical {
                adp: ethercat::master::station_address(slave),
                ado,
            },
            &zeros,
        )
        .await
    }

    /// Writes one message (the whole SM0 window) once SM0 is empty.
    async fn mailbox_send(
        &mut self,
        slave: u16,
        mbx: &Mailboxes,
        window: &[u8],
        timeout: Duration,
    ) -> Result<(), EcatError> {
        let poll = MailboxPoll::new(slave, "receive mailbox stays full", timeout);
        loop {
            if !self.sm_full(slave, 0).await? {
                // Refused (WKC 0) while full (ESC reference §5.2): try again.
                if self.write_wkc(slave, mbx.rx.start, window).await?.wkc == 1 {
                    return Ok(());
                }
            }
            poll.pause().await?;
        }
    }

    /// Waits for SM1 to fill and reads the message.
    async fn mailbox_receive(
        &mut self,
        slave: u16,
        mbx: &Mailboxes,
        timeout: Duration,
    ) -> Result<Vec<u8>, EcatError> {
        let poll = MailboxPoll::new(slave, "no SDO response", timeout);
        loop {
            if self.sm_full(slave, 1).await? {
                let r = self
                    .datagram_read(slave, mbx.tx.start, usize::from(mbx.tx.length))
                    .await?;
                if r.wkc == 1 {
                    return Ok(r.data);
                }
            }
            poll.pause().await?;
        }
    }

    /// Sends the request `build` writes (given the zeroed window and the counter) and returns
    /// the answer, emergencies skipped, together with what `build` returned.
    async fn sdo_exchange<T>(
        &mut self,
        slave: u16,
        mbx: &Mailboxes,
        timeout: Duration,
        build: impl FnOnce(&mut [u8], u8) -> Option<T>,
    ) -> Result<(Vec<u8>, T), EcatError> {
        let mut window = vec![0u8; usize::from(mbx.rx.length)];
        let counter = self.next_counter(slave);
        let extra = build(&mut window, counter).ok_or_else(|| EcatError::Protocol {
            slave,
            what: format!("the receive mailbox ({} bytes) is too small", mbx.rx.length),
        })?;
        self.mailbox_send(slave, mbx, &window, timeout).await?;
        loop {
            let reply = self.mailbox_receive(slave, mbx, timeout).await?;
            match msg::parse_response(&reply) {
                Ok(Response::Emergency) => continue,
                Ok(Response::MailboxError(detail)) => {
                    return Err(EcatError::MailboxError { slave, detail })
                }
                Ok(_) => return Ok((reply, extra)),
                Err(e) => {
                    return Err(EcatError::Protocol {
                        slave,
                        what: format!("undecodable mailbox reply ({e:?})"),
                    })
                }
            }
        }
    }

    /// SDO upload (read) of `index:sub`: expedited, normal or segmented.
    pub async fn sdo_upload(
        &mut self,
        slave: u16,
        index: u16,
        sub: u8,
        timeout: Duration,
    ) -> Result<Vec<u8>, EcatError> {
        let mbx = self.mailboxes(slave).await?;
        self.mailbox_flush(slave, &mbx).await?;
        let (reply, ()) = self
            .sdo_exchange(slave, &mbx, timeout, |w, c| {
                msg::upload(w, c, index, sub).map(|_| ())
            })
            .await?;
        let unexpected = |r: &Response<'_>| EcatError::Protocol {
            slave,
            what: format!("unexpected answer to an upload of {index:04X}:{sub:02X}: {r:?}"),
        };
        let (size, mut data) = match msg::parse_response(&reply) {
            Ok(Response::UploadExpedited { data, .. }) => return Ok(data.to_vec()),
            Ok(Response::UploadNormal { size, data, .. }) => (size, data.to_vec()),
            Ok(Response::Abort { code, .. }) => {
                return Err(EcatError::Abort {
                    slave,
                    index,
                    sub,
                    code,
                })
            }
            Ok(r) => return Err(unexpected(&r)),
            Err(_) => unreachable_protocol(slave)?,
        };
        let Some(size) = size.and_then(|s| usize::try_from(s).ok()) else {
            return Ok(data);
        };
        let mut toggle = false;
        while data.len() < size {
            let (reply, ()) = self
                .sdo_exchange(slave, &mbx, timeout, |w, c| {
                    msg::upload_segment(w, c, toggle).map(|_| ())
                })
                .await?;
            match msg::parse_response(&reply) {
                Ok(Response::UploadSegment {
                    toggle: t,
                    last,
                    data: d,
                }) if t == toggle => {
                    data.extend_from_slice(d);
                    if last {
                        break;
                    }
                }
                Ok(Response::Abort { code, .. }) => {
                    return Err(EcatError::Abort {
                        slave,
                        index,
                        sub,
                        code,
                    })
                }
                Ok(r) => {
                    self.sdo_abort(slave, &mbx, index, sub, AbortCode::TOGGLE_BIT)
                        .await;
                    return Err(unexpected(&r));
                }
                Err(_) => unreachable_protocol(slave)?,
            }
            toggle = !toggle;
        }
        data.truncate(size);
        Ok(data)
    }

    /// SDO download (write) of `data` to `index:sub`: expedited, normal or segmented.
    pub async fn sdo_download(
        &mut self,
        slave: u16,
        index: u16,
        sub: u8,
        data: &[u8],
        timeout: Duration,
    ) -> Result<(), EcatError> {
        let mbx = self.mailboxes(slave).await?;
        self.mailbox_flush(slave, &mbx).await?;
        let (reply, (_, mut pos)) = self
            .sdo_exchange(slave, &mbx, timeout, |w, c| {
                msg::download(w, c, index, sub, data)
            })
            .await?;
        let abort = |code| EcatError::Abort {
            slave,
            index,
            sub,
            code,
        };
        match msg::parse_response(&reply) {
            Ok(Response::DownloadInitiate { .. }) => {}
            Ok(Response::Abort { code, .. }) => return Err(abort(code)),
            Ok(r) => {
                return Err(EcatError::Protocol {
                    slave,
                    what: format!(
                        "unexpected answer to a download of {index:04X}:{sub:02X}: {r:?}"
                    ),
                })
            }
            Err(_) => unreachable_protocol(slave)?,
        }
        let mut toggle = false;
        while pos < data.len() {
            let rest = data.get(pos..).unwrap_or(&[]);
            let (reply, (_, taken)) = self
                .sdo_exchange(slave, &mbx, timeout, |w, c| {
                    msg::download_segment(w, c, toggle, rest)
                })
                .await?;
            match msg::parse_response(&reply) {
                Ok(Response::DownloadSegment { toggle: t }) if t == toggle => {}
                Ok(Response::Abort { code, .. }) => return Err(abort(code)),
                Ok(r) => {
                    self.sdo_abort(slave, &mbx, index, sub, AbortCode::TOGGLE_BIT)
                        .await;
                    return Err(EcatError::Protocol {
                        slave,
                        what: format!("unexpected answer to a segment: {r:?}"),
                    });
                }
                Err(_) => unreachable_protocol(slave)?,
            }
            pos += taken;
            toggle = !toggle;
        }
        Ok(())
    }

    /// Ends a transfer the master gives up (no answer expected).
    async fn sdo_abort(
        &mut self,
        slave: u16,
        mbx: &Mailboxes,
        index: u16,
        sub: u8,
        code: AbortCode,
    ) {
        let mut window = vec![0u8; usize::from(mbx.rx.length)];
        let counter = self.next_counter(slave);
        if msg::abort(&mut window, counter, index, sub, code).is_some() {
            let _ = self
                .mailbox_send(slave, mbx, &window, Duration::from_millis(100))
                .await;
        }
    }

    /// Bytes of process data the PDOs assigned by `assign` (1C12h outputs, 1C13h inputs)
    /// map, read over CoE as SOEM's `config_map` does (ESC reference §7.1); `None` when the slave
    /// has no such object.
    pub async fn pdo_bytes(
        &mut self,
        slave: u16,
        assign: u16,
        timeout: Duration,
    ) -> Result<Option<u16>, EcatError> {
        let count = match self.sdo_upload(slave, assign, 0, timeout).await {
            Ok(d) => d.first().copied().unwrap_or(0),
            Err(EcatError::Abort { code, .. }) if code == AbortCode::NO_OBJECT => return Ok(None),
            Err(e) => return Err(e),
        };
        let mut bits = 0u32;
        for i in 1..=count {
            let pdo = le_uint(&self.sdo_upload(slave, assign, i, timeout).await?) as u16;
            let entries = le_uint(&self.sdo_upload(slave, pdo, 0, timeout).await?) as u8;
            for e in 1..=entries {
                let entry = le_uint(&self.sdo_upload(slave, pdo, e, timeout).await?);
                bits += entry as u32 & 0xFF;
            }
        }
        u16::try_from(bits.div_ceil(8))
            .map(Some)
            .map_err(|_| EcatError::Protocol {
                slave,
                what: format!("{assign:04X}h maps {bits} bits"),
            })
    }
}

/// Little-endian unsigned value of up to 8 bytes.
fn le_uint(b: &[u8]) -> u64 {
    b.iter()
        .take(8)
        .rev()
        .fold(0u64, |acc, &x| (acc << 8) | u64::from(x))
}

/// `sdo_exchange` returns only replies that decode; kept as an error, not a panic.
fn unreachable_protocol<T>(slave: u16) -> Result<T, EcatError> {
    Err(EcatError::Protocol {
        slave,
        what: "undecodable mailbox reply".into(),
    })
}

/// Polling a mailbox sync manager: every 500 µs until the timeout, then the error that says
/// what did not happen.
struct MailboxPoll {
    slave: u16,
    what: &'static str,
    timeout: Duration,
    deadline: tokio::time::Instant,
}

impl MailboxPoll {
    fn new(slave: u16, what: &'static str, timeout: Duration) -> Self {
        MailboxPoll {
            slave,
            what,
            timeout,
            deadline: tokio::time::Instant::now() + timeout,
        }
    }

    /// Waits before the next try, or fails once the time is up.
    async fn pause(&self) -> Result<(), EcatError> {
        if tokio::time::Instant::now() >= self.deadline {
            return Err(EcatError::MailboxTimeout {
                slave: self.slave,
                what: self.what,
                timeout: self.timeout,
            });
        }
        tokio::time::sleep(Duration::from_micros(500)).await;
        Ok(())
    }
}
