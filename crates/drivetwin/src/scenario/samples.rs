//! A virtual-clock rig that samples its drives at a fixed period while a scenario runs
//! (`drivetwin scenario FILE --samples out.csv`): the native trajectory an importer of the
//! cell as an FMU is compared with (docs/cosimulation.md).
//!
//! The wrapped rig runs from sample instant to sample instant; the virtual clock jumps between
//! deadlines only, so cutting a run at the sample instants changes nothing of it.

use std::io::Write;
use std::time::Duration;

use canopen::CanFrame;

use super::file::Action;
use super::runner::Rig;
use super::virtual_rig::VirtualRig;

/// The CSV header of [`Sampled`]'s rows.
pub const HEADER: &str =
    "time_s,node,position_rad,velocity_rad_s,current_a,statusword,position_actual";

/// `rig`, sampled every `every` (at 0, `every`, 2·`every`, …) into `out`.
pub struct Sampled<'a, W: Write> {
    rig: &'a mut VirtualRig,
    every: Duration,
    next: Duration,
    nodes: Vec<u8>,
    out: W,
    error: Option<std::io::Error>,
}

impl<'a, W: Write> Sampled<'a, W> {
    /// Writes the header; the first sample is taken at 0 when the run starts.
    pub fn new(rig: &'a mut VirtualRig, every: Duration, mut out: W) -> std::io::Result<Self> {
        writeln!(out, "{HEADER}")?;
        let nodes = rig.nodes();
        Ok(Sampled {
            rig,
            every: every.max(Duration::from_nanos(1)),
            next: Duration::ZERO,
            nodes,
            out,
            error: None,
        })
    }

    /// The first write error, if any, once the run is over.
    pub fn finish(mut self) -> std::io::Result<()> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.out.flush()
    }

    fn sample(&mut self, t: Duration) {
        for node in &self.nodes {
            let Ok(p) = self.rig.probe(*node) else {
                continue;
            };
            let row = writeln!(
                self.out,
                "{},{node},{},{},{},{},{}",
                t.as_secs_f64(),
                p.position_rad,
                p.velocity_rad_s,
                p.current_a,
                p.statusword,
                p.position_actual
            );
            if let (Err(e), None) = (row, &self.error) {
                self.error = Some(e);
            }
        }
    }
}

impl<W: Write> Rig for Sampled<'_, W> {
    fn run_until(&mut self, t: Duration, seen: &mut dyn FnMut(usize, Duration, &CanFrame)) {
        while self.next <= t {
            let at = self.next;
            self.rig.run_until(at, seen);
            self.sample(at);
            self.next = at + self.every;
        }
        self.rig.run_until(t, seen);
    }

    fn act(
        &mut self,
        action: &Action,
        seen: &mut dyn FnMut(usize, Duration, &CanFrame),
    ) -> Result<(), String> {
        self.rig.act(action, seen)
    }

    fn read(&mut self, node: Option<u8>, index: u16, sub: u8) -> Result<(u64, usize), String> {
        self.rig.read(node, index, sub)
    }

    fn stopped(&self) -> Option<String> {
        self.rig.stopped()
    }
}
