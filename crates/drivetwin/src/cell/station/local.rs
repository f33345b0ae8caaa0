//! A station's local front ends: the CI terminal and the serial ports reach its objects as
//! a commissioning tool does, writes going in as SDO downloads of its CANopen node, so the
//! serial port, the CI terminal and CANopen see one set of objects (without a node, writes go
//! to the dictionary as the CoE side's do).

use canopen::{CanFrame, Node};
use od::{AbortCode, Forwarding, Instant, ObjectAccess};

use super::{Persisting, Station};

impl Station {
    /// A local interface of the drive (a serial port, the CI terminal, CMMP-AS §3.2.3) reaches
    /// its objects at `now`: reads as they are, writes as SDO downloads of its node, following
    /// the SDO rules of the present NMT state; what the drive sends meanwhile goes to `out`.
    pub fn local_access(
        &mut self,
        now: Instant,
        out: &mut dyn FnMut(CanFrame),
        f: &mut dyn FnMut(&mut dyn ObjectAccess),
    ) {
        self.model.step(now);
        let (node, access) = self.node_and_access();
        let mut console = Console { node, access, now };
        f(&mut console);
        self.service(now, out);
    }
}

/// A local interface's view of a drive: reads as they are, writes as SDO downloads of its node.
struct Console<'a> {
    node: Option<&'a mut Node>,
    access: Persisting<'a>,
    now: Instant,
}

impl<'a> Forwarding for Console<'a> {
    type Inner = Persisting<'a>;

    fn inner(&self) -> &Persisting<'a> {
        &self.access
    }
    fn inner_mut(&mut self) -> &mut Persisting<'a> {
        &mut self.access
    }

    fn on_write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        match self.node.as_mut() {
            Some(node) => node.local_write(self.now, index, sub, data, &mut self.access),
            None => self.access.write(index, sub, data),
        }
    }
}
