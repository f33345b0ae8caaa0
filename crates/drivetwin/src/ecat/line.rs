//! The faults of a real EtherCAT line, as state of the chain: a cable pulled between two
//! slaves, a slave without power, a slave's clock off nominal. Sans-IO: the chain asks how far
//! a frame gets ([`Line::reach`]) and which slaves run ([`Line::powered`]).
//!
//! ETG.1000.4 (data link layer, loop control): every ESC port closes its loop by itself when
//! its link goes down ("auto" loop control, the reset value of DL control 0x0101), so a frame
//! that reaches the last slave whose port 1 still has a link returns from it to the master,
//! through every slave before it. Pulled between slave k and k + 1, the master sees k slaves
//! and the working counters of the rest drop out; the slaves behind see no frame at all.
//!
//! **Decision:** a slave without power breaks the line there. ETG.1000.4 has no bypass: the
//! frame travels through the ESC's own processing unit and ports, which without power have no
//! PHY link, so the neighbour before it sees its port 1 link go down and closes that loop, as
//! for a pulled cable. Powered on again, the ESC starts from its reset values (AL Init,
//! station address 0, SMs and FMMUs off) and the drive behind it boots as at power-on.

use std::collections::BTreeSet;

/// Why a line fault cannot be set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum LineError {
    #[error("the chain has no slave {position} (it has {len})")]
    NoSlave { position: usize, len: usize },
    #[error("the chain has {len} slaves: no cable after slave {after}")]
    NoCable { after: usize, len: usize },
}

/// The physical state of the line: where it is cut and which slaves have no power.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Line {
    /// The cable behind this many slaves is pulled (0: the master's own cable).
    cable_pulled_after: Option<usize>,
    /// Positions (0 = first slave from the master) without power.
    powered_off: BTreeSet<usize>,
}

impl Line {
    /// How many slaves, from the master, a frame passes before it returns (0: it is lost,
    /// the first slave's link is down).
    pub fn reach(&self, len: usize) -> usize {
        let cut = self.cable_pulled_after.unwrap_or(len);
        let dark = self.powered_off.first().copied().unwrap_or(len);
        len.min(cut).min(dark)
    }

    /// Whether slave `position` has power.
    pub fn powered(&self, position: usize) -> bool {
        !self.powered_off.contains(&position)
    }

    /// The cable behind `after` slaves pulled (0: between the master and the first slave).
    pub fn pull_cable(&mut self, after: usize, len: usize) -> Result<(), LineError> {
        if after >= len {
            return Err(LineError::NoCable { after, len });
        }
        self.cable_pulled_after = Some(after);
        Ok(())
    }

    /// The pulled cable plugged back.
    pub fn plug_cable(&mut self) {
        self.cable_pulled_after = None;
    }

    /// Where the cable is pulled, if it is.
    pub fn cable_pulled_after(&self) -> Option<usize> {
        self.cable_pulled_after
    }

    /// Slave `position` switched off or on; whether that changed anything.
    pub fn set_power(&mut self, position: usize, on: bool, len: usize) -> Result<bool, LineError> {
        if position >= len {
            return Err(LineError::NoSlave { position, len });
        }
        Ok(if on {
            self.powered_off.remove(&position)
        } else {
            self.powered_off.insert(position)
        })
    }

    /// Whether the cable behind `after` slaves carries a link (0: the master's own cable): it
    /// is plugged in and the slaves at both its ends have power. Behind the last slave there
    /// is no cable. The ports at its ends show it in their DL status (ETG.1000.4).
    pub fn linked(&self, after: usize, len: usize) -> bool {
        let powered_before = after == 0 || self.powered(after - 1);
        after < len
            && self.cable_pulled_after != Some(after)
            && powered_before
            && self.powered(after)
    }

    /// The slaves without power, in line order.
    pub fn powered_off(&self) -> impl Iterator<Item = usize> + '_ {
        self.powered_off.iter().copied()
    }

    /// No fault on the line.
    pub fn is_intact(&self) -> bool {
        self.cable_pulled_after.is_none() && self.powered_off.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_intact_line_reaches_every_slave() {
        assert_eq!(Line::default().reach(64), 64);
    }

    #[test]
    fn the_frame_returns_from_the_last_slave_before_a_cut_or_a_dark_slave() {
        let mut l = Line::default();
        l.pull_cable(32, 64).unwrap();
        assert_eq!(l.reach(64), 32);
        l.set_power(10, false, 64).unwrap();
        assert_eq!(l.reach(64), 10, "the nearer fault wins");
        l.plug_cable();
        assert_eq!(l.reach(64), 10);
        assert!(l.set_power(10, true, 64).unwrap());
        assert!(l.is_intact());
        l.pull_cable(0, 64).unwrap();
        assert_eq!(l.reach(64), 0, "the master's own cable: nothing returns");
    }

    #[test]
    fn a_cable_links_two_powered_slaves_and_none_follows_the_last() {
        let mut l = Line::default();
        assert!(l.linked(0, 3) && l.linked(2, 3));
        assert!(!l.linked(3, 3), "no cable behind the last slave");
        l.pull_cable(1, 3).unwrap();
        assert!(l.linked(0, 3) && !l.linked(1, 3) && l.linked(2, 3));
        l.plug_cable();
        l.set_power(1, false, 3).unwrap();
        assert!(l.linked(0, 3) && !l.linked(1, 3) && !l.linked(2, 3));
    }

    #[test]
    fn faults_beyond_the_chain_are_refused() {
        let mut l = Line::default();
        assert_eq!(
            l.pull_cable(2, 2),
            Err(LineError::NoCable { after: 2, len: 2 })
        );
        assert_eq!(
            l.set_power(5, false, 2),
            Err(LineError::NoSlave {
                position: 5,
                len: 2
            })
        );
    }
}
