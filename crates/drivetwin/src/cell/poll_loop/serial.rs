//! The cell loop's share of the serial lines ([`crate::serial`]): a line's event or deadline
//! reaches it with the drives of the cell, and what the drives sent meanwhile goes on their
//! buses.

use std::time::Instant;

use canopen::CanFrame;

use super::{BusState, CellLoop, OnBus};
use crate::serial::LineDrives;

/// The drives of the cell as a serial line reaches them; the frames they send are kept.
struct SerialDrives<'a> {
    buses: &'a mut [BusState],
    sent: &'a mut Vec<(usize, CanFrame)>,
    frames: Vec<CanFrame>,
}

impl LineDrives for SerialDrives<'_> {
    fn access(
        &mut self,
        at: OnBus,
        now: od::Instant,
        f: &mut dyn FnMut(&mut dyn od::ObjectAccess),
    ) {
        let Some(bus) = self.buses.get_mut(at.bus) else {
            return;
        };
        bus.cell.local_access(at.drive, now, &mut self.frames, f);
        self.sent
            .extend(self.frames.drain(..).map(|fr| (at.bus, fr)));
    }
}

impl CellLoop {
    /// Line `i`'s port is readable (or writable again).
    pub(super) fn serial_event(&mut self, i: usize, now: Instant, readable: bool) {
        let t = self.now(now);
        let mut sent = Vec::new();
        let mut drives = SerialDrives {
            buses: &mut self.buses,
            sent: &mut sent,
            frames: std::mem::take(&mut self.out),
        };
        if let Some(line) = self.serial.get_mut(i) {
            if readable {
                line.readable(t, &mut drives);
            } else {
                line.writable();
            }
        }
        self.out = std::mem::take(&mut drives.frames);
        self.serial_sent(sent, now);
    }

    /// Lines whose deadline has come.
    pub(super) fn serial_timers(&mut self, now: Instant) {
        let t = self.now(now);
        let mut sent = Vec::new();
        let mut drives = SerialDrives {
            buses: &mut self.buses,
            sent: &mut sent,
            frames: std::mem::take(&mut self.out),
        };
        for line in &mut self.serial {
            if line.deadline().is_some_and(|d| d <= t) {
                line.due(t, &mut drives);
            }
        }
        self.out = std::mem::take(&mut drives.frames);
        self.serial_sent(sent, now);
    }

    fn serial_sent(&mut self, sent: Vec<(usize, CanFrame)>, now: Instant) {
        for (b, frame) in sent {
            self.bus(b, frame, super::Source::Drives, now);
        }
    }
}
