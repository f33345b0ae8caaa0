//! One CANopen slave: NMT, the default SDO server channel and heartbeat, wired to a frame
//! stream. Sans-IO: `on_frame` and `poll` take the time and return frames through `out`.

use heapless::Deque;
use od::{time::earliest, Instant, ObjectAccess};

use crate::heartbeat::{ConsumerEvent, HeartbeatConsumer, HeartbeatProducer};
use crate::nmt::{NmtCommand, NmtOutcome, NmtSlave, NmtState};
use crate::sdo_server::SdoServer;
use crate::CanFrame;

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
}

/// Events the runtime has not taken yet; the oldest are dropped when it never looks.
const EVENT_QUEUE: usize = 8;

pub struct Node<const N: usize = 8192> {
    node_id: u8,
    nmt: NmtSlave,
    sdo: SdoServer<N>,
    producer: HeartbeatProducer,
    consumer: HeartbeatConsumer,
    events: Deque<NodeEvent, EVENT_QUEUE>,
}

impl<const N: usize> Node<N> {
    /// A node that has not booted yet: call [`Node::boot`] to send the boot-up message.
    pub fn new(node_id: u8) -> Self {
        Node {
            node_id,
            nmt: NmtSlave::default(),
            sdo: SdoServer::default(),
            producer: HeartbeatProducer::default(),
            consumer: HeartbeatConsumer::default(),
            events: Deque::new(),
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

    /// Initialisation finished: boot-up message `700h+id: 00`, then Pre-Operational.
    pub fn boot(&mut self, now: Instant, od: &dyn ObjectAccess, out: &mut dyn FnMut(CanFrame)) {
        self.sdo.reset();
        self.consumer.clear();
        out(self.error_control_frame(0x00));
        self.nmt.booted();
        self.producer.booted(now, od);
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
        let own = u16::from(self.node_id);
        match cob {
            0x000 => self.on_nmt(frame.payload(), out),
            c if c == 0x600 + own && !frame.rtr && self.nmt.state().serves_sdo() => {
                let sdo_tx = 0x580 + own;
                self.sdo.on_request(now, frame.payload(), od, &mut |r| {
                    out(CanFrame::full(sdo_tx, r))
                });
                // A download (segment, initiate or block) may have changed the heartbeat period.
                if matches!(frame.payload().first().map(|cs| cs >> 5), Some(0 | 1 | 6)) {
                    self.producer.refresh(now, od);
                }
            }
            // Another node's boot-up or heartbeat.
            c if (0x701..=0x77F).contains(&c) && c != 0x700 + own && frame.payload().len() == 1 => {
                let node = (c - 0x700) as u8;
                if let Some(e) = self.consumer.on_heartbeat(now, node, od) {
                    self.push(NodeEvent::Heartbeat(e));
                }
            }
            _ => {}
        }
    }

    fn on_nmt(&mut self, data: &[u8], _out: &mut dyn FnMut(CanFrame)) {
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
                    self.push(NodeEvent::State(s));
                }
            }
            Some(NmtOutcome::ResetApplication) => {
                self.halt_services();
                self.push(NodeEvent::ResetApplication);
            }
            Some(NmtOutcome::ResetCommunication) => {
                self.halt_services();
                self.push(NodeEvent::ResetCommunication);
            }
            None => {}
        }
    }

    fn halt_services(&mut self) {
        self.sdo.reset();
        self.producer.stop();
        self.consumer.clear();
    }

    /// Timers: heartbeat, SDO timeout, consumer timeouts. Returns the next deadline.
    pub fn poll(
        &mut self,
        now: Instant,
        od: &mut dyn ObjectAccess,
        out: &mut dyn FnMut(CanFrame),
    ) -> Option<Instant> {
        if self.nmt.state() == NmtState::Initialising {
            return None;
        }
        if self.producer.due(now, od) {
            out(self.error_control_frame(self.nmt.state().code()));
        }
        let sdo_tx = 0x580 + u16::from(self.node_id);
        self.sdo.poll(now, &mut |r| out(CanFrame::full(sdo_tx, r)));
        if let Some(e) = self.consumer.poll(now, od) {
            self.push(NodeEvent::Heartbeat(e));
        }
        self.deadline()
    }

    pub fn deadline(&self) -> Option<Instant> {
        earliest(
            earliest(self.producer.deadline(), self.sdo.deadline()),
            self.consumer.deadline(),
        )
    }
}
