//! The DL status register 0x0110–0x0111 (ETG.1000.4 §6.1.3 "DL status"; ESC datasheet
//! section II, 0x0110): per port a physical link bit (bit 4 + n), a loop bit (bit 8 + 2n:
//! 0 open, 1 closed) and a communication bit (bit 9 + 2n), beside the PDI bits 0–2.
//!
//! Loop control "auto" (the reset value of DL control 0x0101 for ports 0 and 1): a port
//! whose link comes up opens its loop and communicates; a port whose link goes down closes
//! its loop, so the frame turns round in that ESC and goes back to the master. A slave at the
//! end of a line shows a link on port 0 only ([`crate::register::DL_STATUS_LINE_END`]), one
//! inside it on ports 0 and 1 ([`crate::register::DL_STATUS_LINE_THROUGH`]).

/// Ports an ESC has at most.
pub const PORTS: u8 = 4;

/// The register as read or held.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DlStatus(pub u16);

/// One port as the DL status shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PortStatus {
    /// A physical link on the port.
    pub link: bool,
    /// The port's loop is closed: frames turn round here instead of leaving through it.
    pub loop_closed: bool,
    /// Communication established on the port.
    pub communication: bool,
}

/// The bits of port `n`: link, loop, communication.
fn bits(port: u8) -> Option<(u16, u16, u16)> {
    (port < PORTS).then(|| (1 << (4 + port), 1 << (8 + 2 * port), 1 << (9 + 2 * port)))
}

impl DlStatus {
    /// Port `port` (0..[`PORTS`]).
    pub fn port(self, port: u8) -> Option<PortStatus> {
        let (link, loop_closed, communication) = bits(port)?;
        Some(PortStatus {
            link: self.0 & link != 0,
            loop_closed: self.0 & loop_closed != 0,
            communication: self.0 & communication != 0,
        })
    }

    /// The register after port `port`'s link came up or went down, under auto loop control:
    /// with a link the loop opens and communication is established, without one the loop
    /// closes. Unchanged for a port the ESC does not have.
    pub fn with_link(self, port: u8, up: bool) -> DlStatus {
        let Some((link, loop_closed, communication)) = bits(port) else {
            return self;
        };
        DlStatus(if up {
            (self.0 | link | communication) & !loop_closed
        } else {
            (self.0 | loop_closed) & !(link | communication)
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::register::{DL_STATUS_LINE_END, DL_STATUS_LINE_THROUGH};

    #[test]
    fn a_line_end_links_port_0_only_and_a_link_on_port_1_makes_it_a_line_through() {
        let end = DlStatus(DL_STATUS_LINE_END);
        let p0 = end.port(0).unwrap();
        assert!(p0.link && !p0.loop_closed && p0.communication);
        let p1 = end.port(1).unwrap();
        assert!(!p1.link && p1.loop_closed && !p1.communication);
        assert_eq!(end.with_link(1, true), DlStatus(DL_STATUS_LINE_THROUGH));
        assert_eq!(end.with_link(1, true).with_link(1, false), end);
        assert_eq!(end.with_link(4, true), end);
        assert_eq!(end.port(4), None);
    }
}
