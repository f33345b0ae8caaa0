//! A cell: the drives of one process on one bus, stepped on one clock. Frames a drive sends
//! reach the other drives of the cell as well as the bus.

pub mod ci_console;
pub mod config;
pub mod control;
pub mod device_model;
pub mod fieldbus_switches;
pub mod interfaces;
pub mod param_store;
pub mod poll_loop;
pub mod realtime;
pub mod runtime;

use std::collections::VecDeque;

use canopen::CanFrame;
use od::{time::earliest, Instant};

use crate::can::drive::CanDrive;

pub struct Cell {
    pub drives: Vec<CanDrive>,
    queue: VecDeque<(CanFrame, Option<usize>)>,
}

impl Cell {
    pub fn new(drives: Vec<CanDrive>) -> Self {
        Cell {
            drives,
            queue: VecDeque::new(),
        }
    }

    /// Boots every drive; the boot-up messages go to `out`.
    pub fn boot(&mut self, now: Instant, out: &mut Vec<CanFrame>) {
        let Cell { drives, queue } = self;
        for (i, d) in drives.iter_mut().enumerate() {
            d.boot(now, &mut |f| queue.push_back((f, Some(i))));
        }
        self.deliver(now, out);
    }

    /// A frame from the bus (not from one of this cell's drives).
    pub fn on_frame(&mut self, now: Instant, frame: &CanFrame, out: &mut Vec<CanFrame>) {
        let Cell { drives, queue } = self;
        for (i, d) in drives.iter_mut().enumerate() {
            d.on_frame(now, frame, &mut |f| queue.push_back((f, Some(i))));
        }
        self.deliver(now, out);
    }

    /// A line typed at the CI terminal of drive `drive` (cell order); `None` without it.
    pub fn ci_line(
        &mut self,
        drive: usize,
        now: Instant,
        line: &[u8],
        out: &mut Vec<CanFrame>,
    ) -> Option<canopen::ci_terminal::Reply> {
        let Cell { drives, queue } = self;
        let d = drives.get_mut(drive)?;
        let reply = d.ci_line(now, line, &mut |f| queue.push_back((f, Some(drive))));
        self.deliver(now, out);
        Some(reply)
    }

    /// Runs the drives' timers; returns the next deadline.
    pub fn poll(&mut self, now: Instant, out: &mut Vec<CanFrame>) -> Option<Instant> {
        let Cell { drives, queue } = self;
        for (i, d) in drives.iter_mut().enumerate() {
            d.poll(now, &mut |f| queue.push_back((f, Some(i))));
        }
        self.deliver(now, out);
        self.deadline()
    }

    pub fn deadline(&self) -> Option<Instant> {
        self.drives
            .iter()
            .fold(None, |acc, d| earliest(acc, d.deadline()))
    }

    /// Sends queued frames to the bus and to every other drive of the cell, in order.
    fn deliver(&mut self, now: Instant, out: &mut Vec<CanFrame>) {
        while let Some((frame, origin)) = self.queue.pop_front() {
            out.push(frame);
            let Cell { drives, queue } = self;
            for (i, d) in drives.iter_mut().enumerate() {
                if Some(i) != origin {
                    d.on_frame(now, &frame, &mut |f| queue.push_back((f, Some(i))));
                }
            }
        }
    }
}
