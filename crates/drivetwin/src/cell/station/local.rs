//! A station's local front ends: the CI terminal and the serial ports reach its objects as
//! a commissioning tool does, writes going in as SDO downloads of its CANopen node, so the
//! serial port, the CI terminal and CANopen see one set of objects (without a node, writes go
//! to the dictionary as the CoE side's do).

use canopen::{CanFrame, Node};
use od::{AbortCode, Entry, Instant, ObjectAccess};

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

impl ObjectAccess for Console<'_> {
    fn entry(&self, index: u16, sub: u8) -> Result<&'static Entry, AbortCode> {
        self.access.entry(index, sub)
    }
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        self.access.read(index, sub, buf)
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        match self.node.as_mut() {
            Some(node) => node.local_write(self.now, index, sub, data, &mut self.access),
            None => self.access.write(index, sub, data),
        }
    }
    fn write_internal(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.access.write_internal(index, sub, data)
    }
}
