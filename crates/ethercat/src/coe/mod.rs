//! CANopen over EtherCAT (ETG.1000.6 §5.6; spec §5, §6): the device side of
//! the mailbox protocol CoE. Sans-IO: one complete mailbox message in (mailbox header, CoE
//! header, service data, as [`crate::Esc::mailbox_read`] hands it over), the reply mailbox
//! message out into a caller buffer whose length is the send mailbox (SM1) size.
//!
//! * [`sdo_server`]: SDO request/response: expedited, normal and segmented download and
//!   upload, abort, complete access (spec §6.2–§6.5);
//! * [`sdo_info`]: SDO information service (OD list with fragments, object and entry
//!   descriptions, SDO info error; spec §6.6);
//! * [`emergency`]: CoE emergency messages the device queues (spec §6.7, §5.6);
//! * [`abort`]: the SDO abort message and the CoE-only abort codes;
//! * [`mapping_lock`]: PDO assignment and mapping writable in Pre-Op only;
//! * [`pump`]: runs a [`CoeServer`] against an [`Esc`]'s mailbox sync managers.
//!
//! Mailbox-level decisions (spec §5):
//! * fewer than 6 bytes: mailbox error 0x0001 (syntax); length 0, type 0 (a master does not
//!   send error messages) or a length beyond the message: 0x0005 (invalid header); a type other
//!   than CoE: 0x0002 (protocol not supported; the slave speaks only CoE);
//!   a CoE message without its 2-byte CoE header: 0x0006 (data too short); an SDO request
//!   shorter than its 8-byte fixed part or an SDO information request shorter than its
//!   request: 0x0008 (invalid size, as SOES); CoE services other than SDO request (2) and SDO
//!   information (8), in particular PDOs through the mailbox (4–7): 0x0004 (service not
//!   supported).
//! * a request whose counter is not 0 and equals the previous request's counter is a
//!   repetition and is dropped without reply (spec §5.3, SOES `ESC_mbxprocess`); every message
//!   the server sends carries its own counter 1 → 7 → 1.
//! * the SDO abort is sent with CoE service 2 (SDO request), as SOEM requires (spec §6.5).

pub mod abort;
pub mod emergency;
pub mod mapping_lock;
pub mod sdo_info;
pub mod sdo_server;

use od::{DeviceDescription, ObjectAccess};

use crate::al_control::AlState;
use crate::esc::{Esc, MAILBOX_MAX, SM_MAILBOX_IN};
use crate::mailbox::{self, Mailbox, MailboxErrorDetail, MailboxType, HEADER_LEN};

pub use abort::{CA_NOT_SUPPORTED, LENGTH_EXCEEDS_MAILBOX};
pub use emergency::Emergency;
pub use mapping_lock::MappingLock;

/// CoE header length (bits 0–8 number, 12–15 service).
pub const COE_HEADER_LEN: usize = 2;

/// CoE services (CoE header bits 12–15, spec §6.1).
pub mod service {
    pub const EMERGENCY: u8 = 1;
    pub const SDO_REQUEST: u8 = 2;
    pub const SDO_RESPONSE: u8 = 3;
    pub const TX_PDO: u8 = 4;
    pub const RX_PDO: u8 = 5;
    pub const TX_PDO_REMOTE: u8 = 6;
    pub const RX_PDO_REMOTE: u8 = 7;
    pub const SDO_INFO: u8 = 8;
}

/// What a personality serves over CoE.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CoeConfig {
    /// SDO complete access (CA bit, spec §6.4). Advertise it in the SII (GENERAL byte 5 bit 5)
    /// only when this is on.
    pub complete_access: bool,
    /// SDO information service (spec §6.6); off: mailbox error 0x0004. SII GENERAL byte 5 bit 1.
    pub sdo_info: bool,
    /// Indices the device does not serve over CoE: SDO access gets 0602 0000h, SDO info leaves
    /// them out of the lists and answers their descriptions with an SDO info error.
    pub hidden: &'static [u16],
}

impl CoeConfig {
    /// Everything on, nothing hidden (the test bench and generic devices).
    pub const FULL: CoeConfig = CoeConfig {
        complete_access: true,
        sdo_info: true,
        hidden: &[],
    };

    /// What the SII baseline ([`SiiConfig::BASELINE`](crate::sii::SiiConfig::BASELINE))
    /// advertises: SDO information, no complete access, nothing hidden.
    pub const BASELINE: CoeConfig = CoeConfig {
        complete_access: false,
        sdo_info: true,
        hidden: &[],
    };

    /// What `desc`'s device file says its CoE serves (`[device.ethercat]`: `complete_access`,
    /// `sdo_info`, `coe_hidden`); [`CoeConfig::BASELINE`] for a description without an
    /// EtherCAT section.
    /// Complete access must agree with the SII's CoE details
    /// ([`SiiConfig::from_description`](crate::sii::SiiConfig::from_description) takes both
    /// from the same keys).
    pub fn from_description(desc: &DeviceDescription) -> Self {
        match desc.ethercat {
            Some(e) => CoeConfig {
                complete_access: e.complete_access,
                sdo_info: e.sdo_info,
                hidden: e.coe_hidden,
            },
            None => CoeConfig::BASELINE,
        }
    }

    fn is_hidden(&self, index: u16) -> bool {
        self.hidden.contains(&index)
    }
}

impl Default for CoeConfig {
    fn default() -> Self {
        CoeConfig::FULL
    }
}

/// Statistics of what the server received and sent.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CoeCounters {
    /// Requests dropped as repetitions (same non-zero counter as the previous one).
    pub duplicates: u32,
    /// Mailbox error replies sent.
    pub mailbox_errors: u32,
    /// SDO aborts sent.
    pub aborts_sent: u32,
    /// SDO aborts received from the master.
    pub aborts_received: u32,
    /// SDO info error replies sent.
    pub info_errors: u32,
    /// Emergencies sent.
    pub emergencies_sent: u32,
    /// Emergencies lost because the queue was full.
    pub emergencies_dropped: u32,
}

/// Queue depth of emergencies waiting for the send mailbox.
pub const EMERGENCY_QUEUE: usize = 8;

/// The CoE endpoint of one slave: SDO server, SDO information, emergencies. `N` is the
/// transfer buffer: the largest value (or complete-access image) a segmented transfer moves.
pub struct CoeServer<const N: usize = 8192> {
    pub(crate) desc: &'static DeviceDescription,
    pub(crate) config: CoeConfig,
    /// Counter of the last request taken (0: none yet / check disabled).
    last_rx_counter: u8,
    /// Counter of the last message sent.
    tx_counter: u8,
    pub(crate) transfer: sdo_server::Transfer,
    pub(crate) info: Option<sdo_info::ListFragments>,
    emergencies: heapless::Deque<Emergency, EMERGENCY_QUEUE>,
    pub(crate) counters: CoeCounters,
    pub(crate) buf: [u8; N],
}

impl<const N: usize> CoeServer<N> {
    pub fn new(desc: &'static DeviceDescription, config: CoeConfig) -> Self {
        CoeServer {
            desc,
            config,
            last_rx_counter: 0,
            tx_counter: 0,
            transfer: sdo_server::Transfer::Idle,
            info: None,
            emergencies: heapless::Deque::new(),
            counters: CoeCounters::default(),
            buf: [0; N],
        }
    }

    pub fn config(&self) -> &CoeConfig {
        &self.config
    }

    pub fn counters(&self) -> CoeCounters {
        self.counters
    }

    /// The mailbox (re)started or stopped (AL state Init): forget transfers in progress,
    /// pending fragments and the last request counter. Queued emergencies stay.
    pub fn reset(&mut self) {
        self.last_rx_counter = 0;
        self.transfer = sdo_server::Transfer::Idle;
        self.info = None;
    }

    /// A segmented SDO transfer or a fragmented SDO info reply is in progress: the master
    /// is expected to continue it, so no emergency goes out (spec §5.6).
    pub fn busy(&self) -> bool {
        self.info.is_some() || !matches!(self.transfer, sdo_server::Transfer::Idle)
    }

    /// Queue an emergency (spec §6.7); it is sent by [`CoeServer::poll`] when the send
    /// mailbox is free and no transfer is in progress. A full queue refuses (and counts) it.
    pub fn queue_emergency(&mut self, emcy: Emergency) -> Result<(), Emergency> {
        self.emergencies.push_back(emcy).inspect_err(|_| {
            self.counters.emergencies_dropped = self.counters.emergencies_dropped.saturating_add(1);
        })
    }

    /// Emergencies waiting to be sent.
    pub fn pending_emergencies(&self) -> usize {
        self.emergencies.len()
    }

    /// Handle one request message (mailbox header + CoE header + data; trailing padding to
    /// the SM window is ignored). The reply goes to `out`, whose length is the send mailbox
    /// size; returns its length, or `None` when there is nothing to answer (a repeated
    /// counter, an abort from the master) or `out` cannot hold even an error reply.
    pub fn process(
        &mut self,
        request: &[u8],
        od: &mut dyn ObjectAccess,
        out: &mut [u8],
    ) -> Option<usize> {
        let out = out.get_mut(..out.len().min(MAILBOX_MAX))?;
        if request.len() < HEADER_LEN {
            return self.mailbox_error(out, MailboxErrorDetail::Syntax);
        }
        let m = Mailbox::new_unchecked(request);
        let length = m.length();
        if length == 0
            || m.mailbox_type() == MailboxType::Error
            || HEADER_LEN + length > request.len()
        {
            return self.mailbox_error(out, MailboxErrorDetail::InvalidHeader);
        }
        let counter = m.counter();
        if counter != 0 && counter == self.last_rx_counter {
            self.counters.duplicates = self.counters.duplicates.saturating_add(1);
            return None;
        }
        self.last_rx_counter = counter;
        if m.mailbox_type() != MailboxType::Coe {
            return self.mailbox_error(out, MailboxErrorDetail::UnsupportedProtocol);
        }
        let payload = m.payload();
        let Some(coe) = payload.get(..COE_HEADER_LEN) else {
            return self.mailbox_error(out, MailboxErrorDetail::SizeTooShort);
        };
        let svc = coe.get(1).copied().unwrap_or(0) >> 4;
        match svc {
            service::SDO_REQUEST => {
                if payload.len() < COE_HEADER_LEN + 8 {
                    return self.mailbox_error(out, MailboxErrorDetail::InvalidSize);
                }
                // Any request ends a pending fragmented SDO info reply.
                self.info = None;
                self.sdo_request(payload, od, out)
            }
            service::SDO_INFO if self.config.sdo_info => {
                self.transfer = sdo_server::Transfer::Idle;
                self.sdo_info_request(payload, od, out)
            }
            _ => self.mailbox_error(out, MailboxErrorDetail::ServiceNotSupported),
        }
    }

    /// The next unsolicited message: a further fragment of an SDO info reply, else a queued
    /// emergency when no transfer is in progress. `out` is the send mailbox.
    pub fn poll(&mut self, out: &mut [u8]) -> Option<usize> {
        let out = out.get_mut(..out.len().min(MAILBOX_MAX))?;
        if self.info.is_some() {
            return self.next_list_fragment(out);
        }
        if self.busy() {
            return None;
        }
        let emcy = *self.emergencies.front()?;
        let n = self.write_message(out, MailboxType::Coe, |p| emcy.encode(p))?;
        self.emergencies.pop_front();
        self.counters.emergencies_sent = self.counters.emergencies_sent.saturating_add(1);
        Some(n)
    }

    pub(crate) fn mailbox_error(
        &mut self,
        out: &mut [u8],
        detail: MailboxErrorDetail,
    ) -> Option<usize> {
        let counter = self.next_tx_counter();
        let n = mailbox::write_error_reply(out, detail, counter)?;
        self.counters.mailbox_errors = self.counters.mailbox_errors.saturating_add(1);
        Some(n)
    }

    fn next_tx_counter(&mut self) -> u8 {
        self.tx_counter = mailbox::next_counter(self.tx_counter);
        self.tx_counter
    }

    /// Write a message: `body` fills the payload and returns its length; the header follows.
    pub(crate) fn write_message(
        &mut self,
        out: &mut [u8],
        kind: MailboxType,
        body: impl FnOnce(&mut [u8]) -> Option<usize>,
    ) -> Option<usize> {
        let n = body(out.get_mut(HEADER_LEN..)?)?;
        self.finish(out, kind, n)
    }

    /// Put the header in front of the `n` payload bytes already in `out[6..]`.
    pub(crate) fn finish(&mut self, out: &mut [u8], kind: MailboxType, n: usize) -> Option<usize> {
        let len = u16::try_from(n).ok()?;
        if out.len() < HEADER_LEN + n {
            return None;
        }
        let counter = self.next_tx_counter();
        let mut m = Mailbox::new_unchecked(out.get_mut(..HEADER_LEN)?);
        m.set_header(len, 0, kind, counter);
        Some(HEADER_LEN + n)
    }
}

/// Serve the mailbox of `esc` once: when the send mailbox (SM1) is free, answer the request
/// waiting in the receive mailbox (SM0), else post the next fragment of an SDO info reply,
/// else a queued emergency. A request stays in SM0 while SM1 is full. Returns whether a
/// message was posted. In AL state Init (mailbox stopped) the server is reset.
pub fn pump<const N: usize>(
    esc: &mut Esc<'_>,
    coe: &mut CoeServer<N>,
    od: &mut dyn ObjectAccess,
) -> bool {
    let mut out = [0u8; MAILBOX_MAX];
    match serve(esc, coe, od, &mut out).and_then(|n| out.get(..n)) {
        Some(msg) => esc.mailbox_write(msg).is_ok(),
        None => false,
    }
}

/// Whether [`serve`] has anything to do for `esc` now: the mailbox stopped (the server is
/// reset), or the send mailbox is free and a request waits in the receive mailbox, a further
/// fragment of an SDO info reply is pending or an emergency can go out. Otherwise `serve`
/// returns `None` and changes nothing, so a device may skip it: the mailbox is idle in
/// nearly every cycle of a slave in Op.
pub fn due<const N: usize>(esc: &Esc<'_>, coe: &CoeServer<N>) -> bool {
    if !esc.mailbox_running() {
        return true;
    }
    esc.mailbox_write_ready()
        && (esc.mailbox_waiting()
            || coe.info.is_some()
            || (!coe.busy() && !coe.emergencies.is_empty()))
}

/// As [`pump`], but the message is left in `out` (its length returned) for the caller to post
/// with [`Esc::mailbox_write`] when it is ready: a device that answers a request only once a
/// slow action is done (1010h "save" writing its file) holds the reply meanwhile, and serves
/// nothing else, while the ESC goes on answering frames.
pub fn serve<const N: usize>(
    esc: &mut Esc<'_>,
    coe: &mut CoeServer<N>,
    od: &mut dyn ObjectAccess,
    out: &mut [u8; MAILBOX_MAX],
) -> Option<usize> {
    if !esc.mailbox_running() {
        coe.reset();
        return None;
    }
    if !esc.mailbox_write_ready() {
        return None;
    }
    let size = esc
        .sync_manager(SM_MAILBOX_IN)
        .map_or(0, |s| usize::from(s.length))
        .min(MAILBOX_MAX);
    let out = out.get_mut(..size)?;
    // ETG.1000.6: the PDO configuration changes in Pre-Op only.
    let locked = matches!(esc.al_state(), AlState::SafeOp | AlState::Op);
    // A request first: a master that sends one has given up any fragmented reply. It is read
    // where it lies in the ESC's memory (no copy: the server is called in every cycle of
    // every slave, and a request is rare there).
    let n = match esc.mailbox_read() {
        Some(m) => {
            let mut od = MappingLock::new(od, locked);
            coe.process(m.get(..MAILBOX_MAX).unwrap_or(m), &mut od, out)
        }
        None => coe.poll(out),
    };
    n.filter(|&n| n <= out.len())
}
