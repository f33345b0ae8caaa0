//! The cell loop's share of the serial lines ([`crate::serial`]): a line's event or deadline
//! reaches it with the drives of the cell, and what the drives sent meanwhile goes on their
//! buses.

use std::time::Instant;

use canopen::CanFrame;

use super::CellLoop;
use crate::cell::can_cell::CanCell;
use crate::cell::stations::StationId;
use crate::serial::LineDrives;

/// The drives of the cell as a serial line reaches them; the frames they send are kept.
struct SerialDrives<'a> {
    cell: &'a mut CanCell,
    sent: &'a mut Vec<(usize, CanFrame)>,
    frames: Vec<CanFrame>,
}

impl LineDrives for SerialDrives<'_> {
    fn access(
        &mut self,
        at: StationId,
        now: od::Instant,
        f: &mut dyn FnMut(&mut dyn od::ObjectAccess),
    ) {
        match self.cell.local_access(at, now, &mut self.frames, f) {
            Some(bus) => self.sent.extend(self.frames.drain(..).map(|fr| (bus, fr))),
            None => self.frames.clear(),
        }
    }
}

impl CellLoop {
    /// Line `i`'s port is readable (or writable again).
    pub(super) fn serial_event(&mut self, i: usize, now: Instant, readable: bool) {
        self.with_serial_drives(now, |lines, drives, t| {
            if let Some(line) = lines.get_mut(i) {
                if readable {
                    line.readable(t, drives);
                } else {
                    line.writable();
                }
            }
        });
    }

    /// Lines whose deadline has come.
    pub(super) fn serial_timers(&mut self, now: Instant) {
        self.with_serial_drives(now, |lines, drives, t| {
            for line in lines {
                if line.deadline().is_some_and(|d| d <= t) {
                    line.due(t, drives);
                }
            }
        });
    }

    /// Runs `f` on the lines with the cell's drives; what the drives sent meanwhile then goes
    /// on their buses. The scratch buffers are the loop's: no allocation per event.
    fn with_serial_drives(
        &mut self,
        now: Instant,
        f: impl FnOnce(&mut [crate::serial::line::SerialLine], &mut SerialDrives<'_>, od::Instant),
    ) {
        let t = self.now(now);
        let mut sent = std::mem::take(&mut self.serial_sent);
        let mut drives = SerialDrives {
            cell: &mut self.cell,
            sent: &mut sent,
            frames: std::mem::take(&mut self.out),
        };
        f(&mut self.serial, &mut drives, t);
        self.out = std::mem::take(&mut drives.frames);
        for (b, frame) in sent.drain(..) {
            self.bus(b, frame, super::Source::Drives, now);
        }
        self.serial_sent = sent;
    }
}
