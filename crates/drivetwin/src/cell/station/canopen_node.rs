//! A station's CANopen front end, when its drive is on a CAN bus: its CiA 301 node on the
//! bus (boot-up, the frames it receives) and its CAN controller's error states. A station
//! without a node ignores them: it is on no CAN bus.

use canopen::CanFrame;
use od::Instant;

use super::Station;

impl Station {
    /// Its CAN controller changed error state: the reactions of its device description
    /// ([`crate::cell::bus_faults`]).
    pub fn can_state_changed(
        &mut self,
        now: Instant,
        t: canbus::fault_confinement::Transition,
        out: &mut dyn FnMut(CanFrame),
    ) {
        use crate::cell::bus_faults::{react, COMMUNICATION_REGISTER};
        use od::BusFaultReaction as Reaction;
        tracing::warn!(
            node = self.node_id(),
            from = t.from.name(),
            to = t.to.name(),
            "CAN controller"
        );
        let reactions = &self.model.od().description().bus_faults;
        let Station { model, canopen, .. } = self;
        let Some(node) = canopen.as_mut() else {
            return;
        };
        for r in react(reactions, t) {
            match *r {
                Reaction::Raise(code) => {
                    node.raise_error(model, code, COMMUNICATION_REGISTER, [0; 5])
                }
                Reaction::Clear(code) => node.clear_error(model, code),
                Reaction::Repeat(code) => node.repeat_error(code),
                Reaction::Fault(code) => {
                    if let Some(d) = model.drive_mut() {
                        // Raised once; its cause is gone with the bus back, so a fault reset
                        // clears it. Its EMCY is lost with the bus off; `recovered` sends it.
                        d.inject_fault(code, COMMUNICATION_REGISTER);
                        d.clear_fault(code);
                    }
                }
            }
        }
        self.poll(now, out);
    }

    /// Power-on finished: boot-up message.
    pub fn boot(&mut self, now: Instant, out: &mut dyn FnMut(CanFrame)) {
        self.model.step(now);
        self.boot_node(now, out);
    }

    pub fn on_can_frame(&mut self, now: Instant, frame: &CanFrame, out: &mut dyn FnMut(CanFrame)) {
        // The drive first runs up to the frame's time, so the frame acts on the right cycle.
        self.model.step(now);
        let (Some(node), mut access) = self.node_and_access() else {
            return;
        };
        node.on_frame(now, frame, &mut access, out);
        self.service(now, out);
    }
}
