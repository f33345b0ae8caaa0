//! A cell: the drives of one process on one bus, stepped on one clock. Frames a drive sends
//! reach the other drives of the cell as well as the bus; with a bit rate
//! ([`bus_timing`]) they do so when they have crossed the bus, after the arbitration.

pub mod bus_timing;
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
use bus_timing::{BusFigures, BusTiming, OUTSIDE};

pub struct Cell {
    pub drives: Vec<CanDrive>,
    queue: VecDeque<(CanFrame, Option<usize>)>,
    /// The bus's bit time; none: frames cross at once (no bit rate in the cell file).
    timing: Option<Box<BusTiming>>,
}

impl Cell {
    pub fn new(drives: Vec<CanDrive>) -> Self {
        Cell {
            drives,
            queue: VecDeque::new(),
            timing: None,
        }
    }

    /// The bus takes the time a real one does at `bitrate` bit/s; a frame waiting longer
    /// than `late_after` for it counts as late.
    pub fn with_bitrate(mut self, bitrate: u32, late_after: std::time::Duration) -> Self {
        self.timing = Some(Box::new(BusTiming::new(bitrate, late_after)));
        self
    }

    /// The bus's figures as of `now` (none without a bit rate).
    pub fn bus_figures(&mut self, now: Instant) -> Option<BusFigures> {
        self.timing.as_mut().map(|t| t.figures(now))
    }

    /// Boots every drive; the boot-up messages go to `out`.
    pub fn boot(&mut self, now: Instant, out: &mut Vec<CanFrame>) {
        let Cell { drives, queue, .. } = self;
        for (i, d) in drives.iter_mut().enumerate() {
            d.boot(now, &mut |f| queue.push_back((f, Some(i))));
        }
        self.deliver(now, out);
    }

    /// A frame from the bus (not from one of this cell's drives). With a bit rate it enters
    /// the arbitration now and reaches the drives when it has crossed the bus.
    pub fn on_frame(&mut self, now: Instant, frame: &CanFrame, out: &mut Vec<CanFrame>) {
        if let Some(t) = self.timing.as_mut() {
            t.submit(now, OUTSIDE, *frame);
            self.deliver(now, out);
            return;
        }
        let Cell { drives, queue, .. } = self;
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
        let Cell { drives, queue, .. } = self;
        let d = drives.get_mut(drive)?;
        let reply = d.ci_line(now, line, &mut |f| queue.push_back((f, Some(drive))));
        self.deliver(now, out);
        Some(reply)
    }

    /// A local interface (a serial port) of drive `drive` (cell order) reaches its objects
    /// at `now` through `f`; the frames the drive sends meanwhile go to `out`.
    pub fn local_access(
        &mut self,
        drive: usize,
        now: Instant,
        out: &mut Vec<CanFrame>,
        f: &mut dyn FnMut(&mut dyn od::ObjectAccess),
    ) {
        let Cell { drives, queue, .. } = self;
        let Some(d) = drives.get_mut(drive) else {
            return;
        };
        d.local_access(now, &mut |fr| queue.push_back((fr, Some(drive))), f);
        self.deliver(now, out);
    }

    /// Runs the drives' timers; returns the next deadline.
    pub fn poll(&mut self, now: Instant, out: &mut Vec<CanFrame>) -> Option<Instant> {
        let Cell { drives, queue, .. } = self;
        for (i, d) in drives.iter_mut().enumerate() {
            d.poll(now, &mut |f| queue.push_back((f, Some(i))));
        }
        self.deliver(now, out);
        self.deadline()
    }

    pub fn deadline(&self) -> Option<Instant> {
        let bus = self.timing.as_ref().and_then(|t| t.deadline());
        self.drives
            .iter()
            .fold(bus, |acc, d| earliest(acc, d.deadline()))
    }

    /// Sends queued frames to the bus and to every other drive of the cell, in order; with a
    /// bit rate, they enter the arbitration and go out as they cross the bus.
    fn deliver(&mut self, now: Instant, out: &mut Vec<CanFrame>) {
        if self.timing.is_some() {
            self.cross(now, out);
            return;
        }
        while let Some((frame, origin)) = self.queue.pop_front() {
            out.push(frame);
            let Cell { drives, queue, .. } = self;
            for (i, d) in drives.iter_mut().enumerate() {
                if Some(i) != origin {
                    d.on_frame(now, &frame, &mut |f| queue.push_back((f, Some(i))));
                }
            }
        }
    }

    /// Timed bus: the drives' new frames enter the arbitration at `now`; every frame that has
    /// crossed by `now` goes out (a drive's) and to the other drives at its end of frame,
    /// whose answers enter the arbitration then.
    fn cross(&mut self, now: Instant, out: &mut Vec<CanFrame>) {
        let Cell {
            drives,
            queue,
            timing,
        } = self;
        let Some(timing) = timing.as_mut() else {
            return;
        };
        let submit = |timing: &mut BusTiming,
                      at: Instant,
                      queue: &mut VecDeque<(CanFrame, Option<usize>)>| {
            while let Some((frame, origin)) = queue.pop_front() {
                let source = origin
                    .and_then(|i: usize| u16::try_from(i).ok())
                    .unwrap_or(OUTSIDE);
                timing.submit(at, source, frame);
            }
        };
        submit(timing, now, queue);
        while let Some(tx) = timing.poll(now) {
            let origin = (tx.source != OUTSIDE).then_some(usize::from(tx.source));
            if origin.is_some() {
                out.push(tx.frame);
            }
            for (i, d) in drives.iter_mut().enumerate() {
                if Some(i) != origin {
                    d.on_frame(tx.end, &tx.frame, &mut |f| queue.push_back((f, Some(i))));
                }
            }
            submit(timing, tx.end, queue);
        }
    }
}
