//! Modbus TCP drives on the loop: one connection per drive at a time, its requests answered
//! as they arrive ([`crate::modbus_tcp::cell_drive`]).

use std::net::SocketAddr;
use std::time::Instant;

use mio::net::TcpStream;

use super::connections::peer_has_closed;
use super::{CellLoop, Kind};

impl CellLoop {
    /// The CMMO-ST serves one connection at a time: a second one is closed at once without a
    /// byte, unless the first has been closed by its client meanwhile
    /// ([`crate::modbus_tcp::server`]).
    pub(super) fn accept_modbus(&mut self, stream: TcpStream, peer: SocketAddr, drive: usize) {
        if let Some(slot) = self.modbus_slot(drive) {
            let closed = self
                .slots
                .get(slot)
                .and_then(Option::as_ref)
                .is_some_and(|c| peer_has_closed(&c.stream));
            if !closed {
                tracing::warn!(%peer, "Modbus: one connection at a time, refusing");
                return;
            }
            self.close(slot, modbus::CloseReason::Peer);
        }
        let t = self.now(Instant::now());
        let Some(m) = self.modbus.get_mut(drive) else {
            return;
        };
        m.open_connection(t, &mut self.cell.stations);
        tracing::info!(%peer, "Modbus client connected");
        self.add(stream, peer, Kind::Modbus { drive });
    }

    /// The connection drive `drive`'s server has open.
    pub(super) fn modbus_slot(&self, drive: usize) -> Option<usize> {
        self.slots.iter().position(|c| {
            c.as_ref()
                .is_some_and(|c| matches!(c.kind, Kind::Modbus { drive: d } if d == drive))
        })
    }

    pub(super) fn close_modbus_of(&mut self, drive: usize) {
        if let Some(slot) = self.modbus_slot(drive) {
            // The drive has already seen the close (watchdog, stalled writes).
            self.remove(slot);
        }
    }

    /// A Modbus request's bytes on connection `slot` of drive `drive`, answered at `t`.
    pub(super) fn modbus_request(
        &mut self,
        slot: usize,
        drive: usize,
        bytes: &[u8],
        t: od::Instant,
    ) {
        if !matches!(self.slots.get(slot), Some(Some(_))) {
            return;
        }
        // The answer goes to the server's link's send buffer, its connection's.
        let result = match (self.modbus.get_mut(drive), self.modbus_links.get_mut(drive)) {
            (Some(m), Some(link)) => m.answer(
                bytes,
                t,
                link.inner_mut().as_vec_mut(),
                &mut self.cell.stations,
            ),
            _ => Ok(()),
        };
        self.mark_dirty(slot);
        if let Err(reason) = result {
            // The answers before a broken stream still go out.
            self.write_pending(slot);
            self.close(slot, reason);
        }
    }
}
