//! Runs a scenario's timeline against a rig (the virtual clock, or a live cell): actions at
//! their times, expectations watched from their time until their `within` has passed.
//!
//! An object expectation is read after every action and every millisecond while it waits; a
//! frame or EMCY expectation looks at every frame on the bus from its start to its end, both
//! included.

use std::time::Duration;

use canopen::CanFrame;

use super::file::{Action, Expectation, Scenario, StepKind};
use super::report::{seconds, Outcome, Report};

/// How often an object expectation is read while it waits.
pub const READ_PERIOD: Duration = Duration::from_millis(1);

/// What a scenario runs against.
pub trait Rig {
    /// Runs the cell until `t` (the scenario's clock); every frame on bus `bus` goes to
    /// `seen` with its time.
    fn run_until(&mut self, t: Duration, seen: &mut dyn FnMut(usize, Duration, &CanFrame));
    /// Carries out `action` now; the frames it puts on the bus go to `seen`.
    fn act(
        &mut self,
        action: &Action,
        seen: &mut dyn FnMut(usize, Duration, &CanFrame),
    ) -> Result<(), String>;
    /// An object's value as an unsigned number (little-endian, as on CANopen) and its size
    /// in bytes.
    fn read(&mut self, node: Option<u8>, index: u16, sub: u8) -> Result<(u64, usize), String>;
    /// Why the cell has stopped, once a part of it has (a drive's load FMU that failed).
    fn stopped(&self) -> Option<String> {
        None
    }
}

struct Pending {
    step: usize,
    name: String,
    what: Expectation,
    from: Duration,
    until: Duration,
    /// Met (or, for an absence, broken) at this time.
    hit: Option<(Duration, String)>,
    last: Option<String>,
}

impl Pending {
    fn absent(&self) -> bool {
        matches!(
            self.what,
            Expectation::Emcy { absent: true, .. } | Expectation::Frame { absent: true, .. }
        )
    }

    fn wants_reads(&self) -> bool {
        matches!(self.what, Expectation::Object { .. }) && self.hit.is_none()
    }

    /// A frame on bus `bus` at `t`.
    fn frame(&mut self, bus: usize, t: Duration, f: &CanFrame) {
        if self.hit.is_some() || t < self.from || t > self.until {
            return;
        }
        let payload = f.payload();
        let matched = match &self.what {
            Expectation::Object { .. } => false,
            Expectation::Emcy {
                bus: b, node, code, ..
            } => {
                *b == bus
                    && match node {
                        Some(n) => f.id == 0x80 + u32::from(*n),
                        None => (0x81..=0xFF).contains(&f.id),
                    }
                    && payload.len() >= 2
                    && payload.get(..2) == Some(&code.to_le_bytes()[..])
            }
            Expectation::Frame {
                bus: b, id, prefix, ..
            } => *b == bus && f.id == *id && payload.starts_with(prefix),
        };
        if matched {
            let hex: String = payload.iter().map(|b| format!("{b:02X}")).collect();
            self.hit = Some((t, format!("{:03X}#{hex}", f.id)));
        }
    }

    fn outcome(&self) -> Outcome {
        let window = format!("from {} to {}", seconds(self.from), seconds(self.until));
        let (passed, detail) = match (&self.hit, self.absent()) {
            (Some((t, what)), false) => (true, format!("met at {} ({what})", seconds(*t))),
            (None, false) => (
                false,
                match &self.last {
                    Some(last) => format!("not met {window}; last seen {last}"),
                    None => format!("not met {window}"),
                },
            ),
            (Some((t, what)), true) => (false, format!("seen at {} ({what})", seconds(*t))),
            (None, true) => (true, format!("not seen {window}")),
        };
        Outcome {
            name: self.name.clone(),
            passed,
            detail,
        }
    }
}

/// Runs `scenario` against `rig`; the report names every expectation.
pub fn run(scenario: &Scenario, rig: &mut dyn Rig) -> Report {
    let mut pending: Vec<Pending> = Vec::new();
    let mut finished: Vec<Pending> = Vec::new();
    let mut errors = Vec::new();
    let mut frames = 0u64;
    let mut now = Duration::ZERO;
    let mut next = 0;
    loop {
        // Steps due now, in the file's order; the frames they send are seen after all have
        // started, so an expectation at the time of an action sees what the action sent.
        let mut sent: Vec<(usize, Duration, CanFrame)> = Vec::new();
        while let Some((at, kind)) = scenario.steps.get(next) {
            if *at > now {
                break;
            }
            match kind {
                StepKind::Act(a) => {
                    if let Err(e) = rig.act(a, &mut |b, t, f| sent.push((b, t, *f))) {
                        errors.push(format!("step {} at {}: {e}", next + 1, seconds(*at)));
                    }
                }
                StepKind::Expect { name, what, within } => pending.push(Pending {
                    step: next,
                    name: name.clone(),
                    what: what.clone(),
                    from: *at,
                    until: *at + *within,
                    hit: None,
                    last: None,
                }),
            }
            next += 1;
        }
        frames += sent.len() as u64;
        for (b, t, f) in &sent {
            for p in pending.iter_mut() {
                p.frame(*b, *t, f);
            }
        }
        for p in pending
            .iter_mut()
            .filter(|p| p.wants_reads() && p.from <= now)
        {
            read(rig, p, now);
        }
        // What has ended is set aside; the report gives them in the order of the steps.
        let (done, open): (Vec<Pending>, Vec<Pending>) = pending
            .into_iter()
            .partition(|p| p.until <= now || (p.hit.is_some() && !p.absent()));
        pending = open;
        finished.extend(done);
        let step_at = scenario.steps.get(next).map(|(at, _)| *at);
        let end_at = pending.iter().map(|p| p.until).min();
        let read_at = pending
            .iter()
            .any(Pending::wants_reads)
            .then(|| now + READ_PERIOD);
        let until_at = (now < scenario.until).then_some(scenario.until);
        let Some(target) = [step_at, end_at, read_at, until_at]
            .into_iter()
            .flatten()
            .min()
        else {
            break;
        };
        rig.run_until(target, &mut |b, t, f| {
            frames += 1;
            for p in pending.iter_mut() {
                p.frame(b, t, f);
            }
        });
        now = target;
        if let Some(why) = rig.stopped() {
            errors.push(format!("the cell stopped at {}: {why}", seconds(now)));
            break;
        }
    }
    finished.extend(pending);
    finished.sort_by_key(|p| p.step);
    let expectations: Vec<Outcome> = finished.iter().map(Pending::outcome).collect();
    Report {
        scenario: scenario.name.clone(),
        passed: errors.is_empty() && expectations.iter().all(|o| o.passed),
        expectations,
        errors,
        frames,
    }
}

fn read(rig: &mut dyn Rig, p: &mut Pending, now: Duration) {
    let Expectation::Object {
        node,
        index,
        sub,
        mask,
        equals,
    } = p.what
    else {
        return;
    };
    match rig.read(node, index, sub) {
        Ok((v, size)) => {
            // A negative `equals` is compared in the object's own width (-1 of an INTEGER16
            // is FFFFh).
            let width = match size {
                0 => 0,
                1..=7 => (1u64 << (8 * size)) - 1,
                _ => u64::MAX,
            };
            if v & mask & width == equals & mask & width {
                p.hit = Some((now, format!("{index:04X}:{sub:02X} = {v:#X}")));
            } else {
                p.last = Some(format!("{index:04X}:{sub:02X} = {v:#X}"));
            }
        }
        Err(e) => p.last = Some(e),
    }
}
