//! The ESC's ports: the line (cable, power) decides their links, the DL status 0x0110 shows
//! them with auto loop control ([`crate::dl_status`], ETG.1000.4 §6.1.3).

use super::*;

impl<'a> Esc<'a> {
    /// Port `port`'s physical link came up or went down (a neighbour plugged in or out,
    /// powered on or off). Ports beyond 3 are ignored.
    pub fn set_port_link(&mut self, port: u8, link: bool) {
        let a = R::DlStatus.addr();
        let DlStatus(new) = DlStatus(self.rd16(a)).with_link(port, link);
        self.wr16(a, new);
    }

    /// The DL status as it is now.
    pub fn dl_status(&self) -> DlStatus {
        DlStatus(self.rd16(R::DlStatus.addr()))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_link_on_port_1_opens_its_loop_and_losing_it_closes_the_loop_again() {
        let mut esc = Esc::new(EscConfig::default(), Eeprom::None);
        assert_eq!(esc.read_u16(0x0110), register::DL_STATUS_LINE_END);
        esc.set_port_link(1, true);
        assert_eq!(esc.read_u16(0x0110), register::DL_STATUS_LINE_THROUGH);
        assert!(!esc.dl_status().port(1).unwrap().loop_closed);
        esc.set_port_link(1, false);
        assert_eq!(esc.read_u16(0x0110), register::DL_STATUS_LINE_END);
        esc.set_port_link(0, false);
        let p0 = esc.dl_status().port(0).unwrap();
        assert!(!p0.link && p0.loop_closed, "port 0: no link, loop closed");
    }
}
