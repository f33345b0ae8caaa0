//! One CANopen slave: NMT, the default SDO server channel, heartbeat and node guarding, SYNC,
//! PDOs and EMCY, wired to a frame stream. Sans-IO: `on_frame` and `poll` take the time and
//! return frames through `out`.

use core::time::Duration;

use heapless::Deque;
use od::{time::earliest, AbortCode, Cia301Options, Forwarding, Instant, ObjectAccess};

use crate::emcy::{register, EmcyProducer};
use crate::heartbeat::{ConsumerEvent, HeartbeatConsumer, HeartbeatProducer};
use crate::lss::{LssAction, LssAddress, LssSlave, LSS_REQUEST_ID, LSS_RESPONSE_ID};
use crate::nmt::{NmtCommand, NmtOutcome, NmtSlave, NmtState};
use crate::pdo::{PdoEvent, Pdos};
use crate::sdo_server::SdoServer;
use crate::CanFrame;

/// CiA 301 emergency codes the stack raises itself (§7.2.7.1, Tab. 21).
pub mod emcy_code {
    /// Life guard or heartbeat consumer error.
    pub const LIFE_GUARD_OR_HEARTBEAT: u16 = 0x8130;
    pub const PDO_LENGTH: u16 = 0x8210;
    pub const PDO_LENGTH_EXCEEDED: u16 = 0x8220;
    pub const SYNC_LENGTH: u16 = 0x8240;
}

/// Something the runtime must act on, because it owns what the stack does not (files, the
/// stored parameter set, the drive).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeEvent {
    /// NMT reset node: reload every object from the stored set, then call [`Node::boot`].
    ResetApplication,
    /// NMT reset communication: reload 1000h–1FFFh from the stored set, then [`Node::boot`].
    ResetCommunication,
    /// The NMT state changed.
    State(NmtState),
    /// A consumed heartbeat timed out or came back.
    Heartbeat(ConsumerEvent),
    /// Node guarding: no guarding request within the life time (the device's diagnostic table
    /// names the error it shows).
    LifeGuardingLost,
    /// A guarding request arrived again after a life-guarding error.
    LifeGuardingResumed,
    /// LSS "store configuration": persist this node-ID for the next power-on (CiA 305).
    LssStore { node_id: u8 },
    /// A SYNC was consumed (after the synchronous RPDOs were applied): the time base of
    /// interpolated position mode.
    Sync,
}

/// Events the runtime has not taken yet; the oldest are dropped when it never looks.
const EVENT_QUEUE: usize = 8;

/// Node guarding slave (CiA 301 §7.2.8.3.2.1).
#[derive(Debug, Default, Clone, Copy)]
struct Guarding {
    toggle: bool,
    life_deadline: Option<Instant>,
    lost: bool,
}

pub struct Node<const N: usize = 8192> {
    node_id: u8,
    nmt: NmtSlave,
    sdo: SdoServer<N>,
    producer: HeartbeatProducer,
    consumer: HeartbeatConsumer,
    guarding: Guarding,
    pdos: Pdos,
    emcy: EmcyProducer,
    opts: Cia301Options,
    /// Made at the first boot, from 1018h.
    lss: Option<LssSlave>,
    /// Index of the SDO download in progress (segments carry none).
    download_index: Option<u16>,
    events: Deque<NodeEvent, EVENT_QUEUE>,
    /// TPDO and EMCY deadlines as of the last `poll`.
    timers: Option<Instant>,
    /// A frame was handled: `poll` should run now (EMCY queued, PDOs started, …).
    poll_soon: Option<Instant>,
}

/// The dictionary as the SDO server of this node sees it: PDO parameters are refused in
/// Operational where the personality says so.
struct SdoView<'a> {
    od: &'a mut dyn ObjectAccess,
    lock_pdo_params: bool,
    life_time_max_ms: Option<u32>,
}

impl SdoView<'_> {
    /// The device file's `life_time_max_ms`: guard time × life time factor may not exceed it
    /// (the manual that sets it gives one minute); a write that would make it longer is
    /// refused with 0604 0043h (general parameter incompatibility).
    fn check_life_time(&self, index: u16, data: &[u8]) -> Result<(), AbortCode> {
        let Some(max) = self.life_time_max_ms else {
            return Ok(());
        };
        let guard = u32::from(self.od.read_u16(0x100C, 0).unwrap_or(0));
        let factor = u32::from(self.od.read_u8(0x100D, 0).unwrap_or(0));
        let product = match (index, data) {
            (0x100C, [lo, hi]) => u32::from(u16::from_le_bytes([*lo, *hi])) * factor,
            (0x100D, [f]) => guard * u32::from(*f),
            _ => return Ok(()),
        };
        if product > max {
            self.od.entry(index, 0)?;
            return Err(AbortCode::PARAMETER_INCOMPATIBLE);
        }
        Ok(())
    }
}

impl<'a> Forwarding for SdoView<'a> {
    type Inner = dyn ObjectAccess + 'a;

    fn inner(&self) -> &Self::Inner {
        self.od
    }
    fn inner_mut(&mut self) -> &mut Self::Inner {
        self.od
    }

    fn on_write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        if self.lock_pdo_params && (0x1400..=0x1BFF).contains(&index) {
            // `pdo_config_outside_operational`: PDOs are parameterised outside Operational only.
            self.od.entry(index, sub)?;
            return Err(AbortCode::DEVICE_STATE);
        }
        self.check_life_time(index, data)?;
        self.od.write(index, sub, data)
    }
}

impl<const N: usize> Node<N> {
    /// A node that has not booted yet: call [`Node::boot`] to send the boot-up message.
    pub fn new(node_id: u8, opts: Cia301Options) -> Self {
        Node {
            node_id,
            nmt: NmtSlave::default(),
            sdo: SdoServer::default(),
            producer: HeartbeatProducer::default(),
            consumer: HeartbeatConsumer::default(),
            guarding: Guarding::default(),
            pdos: Pdos::new(opts),
            emcy: EmcyProducer::default(),
            opts,
            lss: None,
            download_index: None,
            events: Deque::new(),
            timers: None,
            poll_soon: None,
        }
    }

    pub fn node_id(&self) -> u8 {
        self.node_id
    }
    pub fn set_node_id(&mut self, node_id: u8) {
        self.node_id = node_id;
    }
    pub fn nmt_state(&self) -> NmtState {
        self.nmt.state()
    }

    fn push(&mut self, e: NodeEvent) {
        if self.events.is_full() {
            self.events.pop_front();
        }
        let _ = self.events.push_back(e);
    }

    pub fn take_event(&mut self) -> Option<NodeEvent> {
        self.events.pop_front()
    }

    /// The device raises an error: EMCY, 1001h, 1003h (CiA 301 §7.2.7).
    pub fn raise_error(
        &mut self,
        od: &mut dyn ObjectAccess,
        code: u16,
        register_bits: u8,
        vendor: [u8; 5],
    ) {
        self.emcy.raise(od, code, register_bits, vendor);
    }

    /// The EMCY of an active error again (its frame was lost).
    pub fn repeat_error(&mut self, code: u16) {
        self.emcy.repeat(code);
    }

    /// The device clears an error; the last one cleared sends EMCY 0000h.
    pub fn clear_error(&mut self, od: &mut dyn ObjectAccess, code: u16) {
        self.emcy.clear(od, code);
    }

    pub fn emcy(&self) -> &EmcyProducer {
        &self.emcy
    }

    /// The LSS slave, once the node has booted.
    pub fn lss(&self) -> Option<&LssSlave> {
        self.lss.as_ref()
    }

    /// Initialisation finished: boot-up message `700h+id: 00`, then Pre-Operational. A node
    /// without a node-ID (FFh) stays silent and serves only LSS until it gets one (CiA 305).
    pub fn boot(&mut self, now: Instant, od: &dyn ObjectAccess, out: &mut dyn FnMut(CanFrame)) {
        match self.lss.as_mut() {
            Some(l) => l.set_active_node_id(self.node_id),
            None => {
                let address = LssAddress::from_od(od).unwrap_or(LssAddress {
                    vendor_id: 0,
                    product_code: 0,
                    revision: 0,
                    serial: 0,
                });
                self.lss = Some(LssSlave::new(address, self.node_id));
            }
        }
        if !(1..=127).contains(&self.node_id) {
            self.nmt.resetting();
            self.halt_services(now);
            return;
        }
        self.sdo.reset();
        self.consumer.clear();
        // CiA 301, node guarding: only reset communication resets the toggle bit.
        self.guarding = Guarding::default();
        self.emcy.reset_communication();
        self.pdos.reload(od);
        self.pdos.set_operational(now, false);
        out(self.error_control_frame(0x00));
        self.nmt.booted();
        self.producer.booted(now, od);
        self.poll_soon = Some(now);
        self.push(NodeEvent::State(self.nmt.state()));
    }

    fn error_control_frame(&self, byte: u8) -> CanFrame {
        CanFrame {
            id: 0x700 + u32::from(self.node_id),
            extended: false,
            rtr: false,
            len: 1,
            data: [byte, 0, 0, 0, 0, 0, 0, 0],
        }
    }

    fn sync_cob(od: &dyn ObjectAccess) -> u16 {
        od.read_u32(0x1005, 0)
            .map(|v| (v & 0x7FF) as u16)
            .unwrap_or(0x080)
    }

    /// Handles one frame from the bus.
    pub fn on_frame(
        &mut self,
        now: Instant,
        frame: &CanFrame,
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(CanFrame),
    ) {
        let Some(cob) = frame.cob_id() else {
            return; // CANopen uses 11-bit identifiers only
        };
        if cob == LSS_REQUEST_ID {
            if !self.opts.lss_unsupported {
                self.on_lss(frame.payload(), out);
            }
            return;
        }
        let own = u16::from(self.node_id);
        let state = self.nmt.state();
        if state == NmtState::Initialising {
            return;
        }
        self.poll_soon = Some(now);
        match cob {
            0x000 => self.on_nmt(now, frame.payload(), od, out),
            c if c == 0x600 + own && !frame.rtr && state.serves_sdo() => {
                let sdo_tx = 0x580 + own;
                let lock =
                    self.opts.pdo_config_outside_operational && state == NmtState::Operational;
                let mut view = SdoView {
                    od,
                    lock_pdo_params: lock,
                    life_time_max_ms: self.opts.life_time_max_ms,
                };
                self.sdo
                    .on_request(now, frame.payload(), &mut view, &mut |r| {
                        out(CanFrame::full(sdo_tx, r))
                    });
                // A download may have changed the heartbeat period or a PDO: the index comes
                // with the initiate frame, segments belong to the last one.
                let p = frame.payload();
                match p.first().map(|cs| cs >> 5) {
                    Some(1 | 6) => {
                        self.download_index = match p {
                            [_, lo, hi, ..] => Some(u16::from_le_bytes([*lo, *hi])),
                            _ => None,
                        }
                    }
                    Some(0) => {}
                    _ => self.download_index = None,
                }
                if let Some(i) = self.download_index {
                    self.object_written(now, i, od);
                }
            }
            // Node guarding request: an RTR, or over socketcand (which carries no RTR) a
            // zero-length frame (the notes on open-source systems kept beside the project, §3.3).
            c if c == 0x700 + own && (frame.rtr || frame.payload().is_empty()) => {
                self.on_guarding(now, od, out)
            }
            // Another node's boot-up or heartbeat.
            c if (0x701..=0x77F).contains(&c) && c != 0x700 + own && frame.payload().len() == 1 => {
                let node = (c - 0x700) as u8;
                if let Some(e) = self.consumer.on_heartbeat(now, node, od) {
                    if let ConsumerEvent::Resumed { .. } = e {
                        self.emcy.clear(od, emcy_code::LIFE_GUARD_OR_HEARTBEAT);
                    }
                    self.push(NodeEvent::Heartbeat(e));
                }
            }
            c if c == Self::sync_cob(od) && state == NmtState::Operational => {
                self.on_sync(now, frame.payload(), od, out);
            }
            _ if state == NmtState::Operational => match self.pdos.on_frame(frame, od) {
                Some(PdoEvent::LengthError { .. }) => {
                    self.emcy
                        .raise(od, emcy_code::PDO_LENGTH, register::COMMUNICATION, [0; 5])
                }
                Some(PdoEvent::LengthExceeded { .. }) => self.emcy.raise(
                    od,
                    emcy_code::PDO_LENGTH_EXCEEDED,
                    register::COMMUNICATION,
                    [0; 5],
                ),
                Some(PdoEvent::LengthOk { .. }) => {
                    self.emcy.clear(od, emcy_code::PDO_LENGTH);
                    self.emcy.clear(od, emcy_code::PDO_LENGTH_EXCEEDED);
                }
                None => {}
            },
            _ => {}
        }
    }

    /// Re-reads what depends on an object that was just written: the heartbeat period, the
    /// PDO parameters.
    fn object_written(&mut self, now: Instant, index: u16, od: &mut dyn ObjectAccess) {
        match index {
            0x1017 => self.producer.refresh(now, od),
            i if self.affects_pdos(i) => self.pdos.reload(od),
            _ => {}
        }
        self.poll_soon = Some(now);
    }

    /// A write from outside the bus (the CI terminal's SDO simulation): the rules of an SDO
    /// download in the present NMT state, and the same effects.
    pub fn local_write(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        data: &[u8],
        od: &mut dyn ObjectAccess,
    ) -> Result<(), AbortCode> {
        let lock =
            self.opts.pdo_config_outside_operational && self.nmt.state() == NmtState::Operational;
        SdoView {
            od: &mut *od,
            lock_pdo_params: lock,
            life_time_max_ms: self.opts.life_time_max_ms,
        }
        .write(index, sub, data)?;
        self.object_written(now, index, od);
        Ok(())
    }

    /// Objects whose change the PDO layer must re-read: PDO parameters and transmit masks.
    fn affects_pdos(&self, index: u16) -> bool {
        (0x1400..=0x1BFF).contains(&index)
            || self
                .opts
                .tpdo_transmit_mask_index
                .is_some_and(|base| (base..base + 8).contains(&index))
    }

    fn on_lss(&mut self, data: &[u8], out: &mut dyn FnMut(CanFrame)) {
        let Some(lss) = self.lss.as_mut() else {
            return;
        };
        let action = lss.on_request(data, &mut |r| out(CanFrame::full(LSS_RESPONSE_ID, r)));
        match action {
            Some(LssAction::StoreConfiguration) => {
                let node_id = lss.pending_node_id();
                self.push(NodeEvent::LssStore { node_id });
            }
            // An unconfigured node got its node-ID: reset communication with it now.
            Some(LssAction::ResetCommunication { node_id }) => {
                self.node_id = node_id;
                self.nmt.resetting();
                self.push(NodeEvent::ResetCommunication);
            }
            _ => {}
        }
    }

    fn on_sync(
        &mut self,
        now: Instant,
        data: &[u8],
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(CanFrame),
    ) {
        // CiA 301 §7.2.5: with 1019h the SYNC carries a counter byte; without, none. A device
        // without 1019h takes both.
        let ok = match od.read_u8(0x1019, 0) {
            Some(0) => data.is_empty(),
            Some(_) => data.len() == 1,
            None => data.len() <= 1,
        };
        if !ok {
            self.emcy
                .raise(od, emcy_code::SYNC_LENGTH, register::COMMUNICATION, [0; 5]);
            return;
        }
        self.emcy.clear(od, emcy_code::SYNC_LENGTH);
        self.pdos.on_sync(now, od, out);
        self.push(NodeEvent::Sync);
    }

    fn on_guarding(
        &mut self,
        now: Instant,
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(CanFrame),
    ) {
        // CiA 301: with both configured only the heartbeat runs.
        if od.read_u16(0x1017, 0).unwrap_or(0) != 0 {
            return;
        }
        // Decision (a manual's node-state query by RTR prints no toggle bit): CiA 301's
        // toggle in bit 7 for every personality; it starts at 0, so the first answer is the
        // manual's 7Fh.
        let byte = self.nmt.state().code() | if self.guarding.toggle { 0x80 } else { 0 };
        self.guarding.toggle = !self.guarding.toggle;
        out(self.error_control_frame(byte));
        let guard_ms = u64::from(od.read_u16(0x100C, 0).unwrap_or(0));
        let factor = u64::from(od.read_u8(0x100D, 0).unwrap_or(0));
        // Life time = guard time × life time factor; 0 in either disables life guarding.
        self.guarding.life_deadline =
            (guard_ms > 0 && factor > 0).then(|| now + Duration::from_millis(guard_ms * factor));
        if self.guarding.lost {
            self.guarding.lost = false;
            self.emcy.clear(od, self.life_guard_code());
            self.push(NodeEvent::LifeGuardingResumed);
        }
    }

    /// The EMCY code of a life-guarding error: CiA 301's 8130h unless the device file gives its
    /// own (`life_guard_emcy_code`).
    fn life_guard_code(&self) -> u16 {
        self.opts
            .life_guard_emcy_code
            .unwrap_or(emcy_code::LIFE_GUARD_OR_HEARTBEAT)
    }

    fn on_nmt(
        &mut self,
        now: Instant,
        data: &[u8],
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(CanFrame),
    ) {
        // CiA 301: NMT frames have 2 bytes; others are not NMT node control.
        let [cs, target] = match data {
            [a, b] => [*a, *b],
            _ => return,
        };
        if target != 0 && target != self.node_id {
            return;
        }
        let Some(cmd) = NmtCommand::from_cs(cs) else {
            return;
        };
        let before = self.nmt.state();
        match self.nmt.command(cmd) {
            Some(NmtOutcome::State(s)) => {
                if s == NmtState::Stopped {
                    self.sdo.reset(); // a transfer in progress is dropped silently
                }
                if s != before {
                    self.pdos.reload(od);
                    self.pdos.set_operational(now, s == NmtState::Operational);
                    self.push(NodeEvent::State(s));
                }
                // `nmt_command_answered_with_state` (a manual prints the node's answer to
                // `000: 80 01` as `701: 7F` and to `000: 01 01` as `701: 05`).
                // Decision: CiA 301 has no NMT answer, but that manual labels both lines
                // "Antwort Node 1", with heartbeat off by default: the personality sends the
                // state byte as a heartbeat carries it (no guarding toggle). CiA masters take
                // it as an extra heartbeat.
                if self.opts.nmt_command_answered_with_state {
                    out(self.error_control_frame(s.code()));
                }
            }
            Some(NmtOutcome::ResetApplication) => {
                self.halt_services(now);
                self.take_pending_node_id();
                self.push(NodeEvent::ResetApplication);
            }
            Some(NmtOutcome::ResetCommunication) => {
                self.halt_services(now);
                self.take_pending_node_id();
                self.push(NodeEvent::ResetCommunication);
            }
            None => {}
        }
    }

    /// CiA 305: a node-ID configured by LSS becomes active at the next reset.
    fn take_pending_node_id(&mut self) {
        if let Some(lss) = self.lss.as_mut() {
            let id = lss.pending_node_id();
            lss.set_active_node_id(id);
            self.node_id = lss.active_node_id();
        }
    }

    fn halt_services(&mut self, now: Instant) {
        self.sdo.reset();
        self.producer.stop();
        self.consumer.clear();
        self.guarding = Guarding::default();
        self.pdos.set_operational(now, false);
    }

    /// Timers: heartbeat, SDO timeout, consumer and life guarding, TPDOs, EMCY inhibit.
    /// Returns the next deadline.
    pub fn poll(
        &mut self,
        now: Instant,
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(CanFrame),
    ) -> Option<Instant> {
        let state = self.nmt.state();
        if state == NmtState::Initialising {
            // Waiting for the application to boot the node after a reset: nothing runs, so
            // nothing is due (a deadline left at `now` would have the runtime poll for ever).
            self.poll_soon = None;
            self.timers = None;
            return None;
        }
        if self.producer.due(now, od) {
            out(self.error_control_frame(state.code()));
        }
        let sdo_tx = 0x580 + u16::from(self.node_id);
        self.sdo.poll(now, &mut |r| out(CanFrame::full(sdo_tx, r)));
        if let Some(e) = self.consumer.poll(now, od) {
            if let ConsumerEvent::Lost { .. } = e {
                self.emcy.raise(
                    od,
                    emcy_code::LIFE_GUARD_OR_HEARTBEAT,
                    register::COMMUNICATION,
                    [0; 5],
                );
            }
            self.push(NodeEvent::Heartbeat(e));
        }
        if self.guarding.life_deadline.is_some_and(|d| now >= d) {
            self.guarding.life_deadline = None;
            self.guarding.lost = true;
            let code = self.life_guard_code();
            self.emcy.raise(od, code, register::COMMUNICATION, [0; 5]);
            self.push(NodeEvent::LifeGuardingLost);
        }
        let pdo_deadline = self.pdos.poll(now, od, out);
        let emcy_deadline = self
            .emcy
            .poll(now, od, state.serves_sdo(), &mut |cob, data| {
                out(CanFrame::full(cob, data))
            });
        self.timers = earliest(pdo_deadline, emcy_deadline);
        self.poll_soon = None;
        self.deadline()
    }

    /// When `poll` must next run: timers, and at once after a frame was handled.
    pub fn deadline(&self) -> Option<Instant> {
        if self.nmt.state() == NmtState::Initialising {
            return None;
        }
        earliest(
            earliest(
                earliest(self.producer.deadline(), self.sdo.deadline()),
                earliest(self.consumer.deadline(), self.guarding.life_deadline),
            ),
            earliest(self.timers, self.poll_soon),
        )
    }
}
