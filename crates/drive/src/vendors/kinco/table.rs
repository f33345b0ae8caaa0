//! The Kinco position table (§6.4.1): 32 tasks run in mode 1
//! by the PosTable inputs. Each task has a target (absolute, relative to the last target or
//! to the actual position), a speed, one of 8 shared accelerations and decelerations, a delay
//! before the next task, the CTL register (next index, NEXT/STOP, the conditions Cond0
//! (level) and Cond1 (rising edge) with AND/OR, the mode, the start condition) and a loop
//! count.
//!
//! The flow: the rising edge of Start PosTable starts the task the PosTable Idx inputs
//! select (while a task runs, that task's start condition decides: ignore, wait for the
//! running one, or abort it); a finished task goes on to its next index after the delay when
//! NEXT is set, the condition holds and the loop check passes; Abort PosTable ends the flow
//! after the running task; an error or another mode ends it at once. Cur_Indexof_Table 3044h
//! shows the task, the PosTable Active output the flow.
//!
//! Decisions: this part prints no objects for the table ("Write table" of KincoServo writes
//! it, a .pft file), so the twin takes it through [`Drive::set_position_table`]; a condition
//! that is false when a task finishes is waited for (the flow stays at that task until it
//! holds), a Cond1 edge counts from the start of the task; the loop count of a task counts
//! its starts since Start PosTable; the flow stops after a task whose count has reached its
//! Loops, or before a next task whose count has (0: no limit).

use core::time::Duration;

use super::hooks::Kinco;
use super::{selected_index, DinFunction};
use crate::drive::{Drive, RPM_PER_INCREMENT_S};
use crate::trajectory::Limits;
use od::Instant;

/// Tasks in the table.
pub const TASKS: usize = 32;

/// One task of the table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Task {
    /// CTL Reg: bits 0–4 next index, 8 NEXT, 9 Cond0 on, 10 Cond1 on, 11 AND (1) / OR (0),
    /// 12–13 MODE (0 absolute, 1 relative to the target, 2 relative to the actual
    /// position), 14–15 StartCond (0 ignore, 1 wait, 2 abort).
    pub ctl: u16,
    /// Pos, increments.
    pub position: i32,
    /// Speed, rpm.
    pub speed_rpm: u32,
    /// The delay before the next task, ms.
    pub delay_ms: u32,
    /// Acc idx and Dec idx: one of [`PositionTable::accelerations`].
    pub acc: u8,
    pub dec: u8,
    /// Loops (0: no limit).
    pub loops: u16,
}

impl Task {
    fn next(&self) -> usize {
        usize::from(self.ctl & 0x1F)
    }
    fn goes_on(&self) -> bool {
        self.ctl & 0x0100 != 0
    }
    fn start_condition(&self) -> u16 {
        self.ctl >> 14
    }
}

/// The table as KincoServo writes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PositionTable {
    pub tasks: [Task; TASKS],
    /// The 8 shared accelerations / decelerations, rps/s.
    pub accelerations: [u32; 8],
}

impl Default for PositionTable {
    fn default() -> Self {
        PositionTable {
            tasks: [Task::default(); TASKS],
            accelerations: [100; 8],
        }
    }
}

/// Where the flow stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) enum Flow {
    #[default]
    Idle,
    Running(usize),
    /// Finished task `0`, waiting for its condition.
    Waiting(usize),
    /// The next task starts then.
    Delay(usize, Instant),
}

/// The table and its flow.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct TableRun {
    pub(crate) table: PositionTable,
    pub(crate) flow: Flow,
    /// A task to start when the running one finishes (StartCond "wait").
    queued: Option<usize>,
    abort_after: bool,
    cond1_edge: bool,
    counts: [u16; TASKS],
    /// The target of the last task, internal increments.
    last_target: f64,
    /// Edges the input cycle latched for the next logic cycle.
    pub(crate) start_edge: bool,
    pub(crate) abort_edge: bool,
    pub(crate) cond1_rising: bool,
}

impl<S: AsRef<[u8]> + AsMut<[u8]>> Drive<S, Kinco> {
    /// The position table KincoServo's "Write table" would write.
    pub fn set_position_table(&mut self, table: PositionTable) {
        self.vendor.table.table = table;
    }

    /// The position table flow is running (the PosTable Active output).
    pub(crate) fn kinco_table_active(&self) -> bool {
        self.vendor.table.flow != Flow::Idle
    }

    /// Ends the flow at once (an error, another mode, the enable gone).
    pub(crate) fn kinco_table_abort(&mut self) {
        self.vendor.table.flow = Flow::Idle;
        self.vendor.table.queued = None;
    }

    fn start_task(&mut self, i: usize) {
        let Some(task) = self.vendor.table.table.tasks.get(i).copied() else {
            self.kinco_table_abort();
            return;
        };
        let run = &mut self.vendor.table;
        if let Some(c) = run.counts.get_mut(i) {
            *c = c.saturating_add(1);
        }
        run.cond1_edge = false;
        let offset = self.fg.position_to_internal(task.position) as f64;
        let target = match (task.ctl >> 12) & 0x3 {
            1 => self.vendor.table.last_target + offset,
            2 => self.actual_internal() as f64 + offset,
            _ => offset,
        };
        self.vendor.table.last_target = target;
        self.vendor.table.flow = Flow::Running(i);
        let e = self.od.description().entry(0x3044, 0);
        self.store(e, i as i64);
    }

    fn condition_holds(&self, task: &Task) -> bool {
        let cond0 = task.ctl & 0x0200 != 0;
        let cond1 = task.ctl & 0x0400 != 0;
        let c0 = self.kinco_din_active(DinFunction::PosTableCond0);
        let c1 = self.vendor.table.cond1_edge;
        match (cond0, cond1) {
            (false, false) => true,
            (true, false) => c0,
            (false, true) => c1,
            (true, true) if task.ctl & 0x0800 != 0 => c0 && c1,
            (true, true) => c0 || c1,
        }
    }

    /// The loop check before task `next` follows task `i`.
    fn loops_allow(&self, i: usize, next: usize) -> bool {
        let run = &self.vendor.table;
        let done = |k: usize| {
            let loops = run.table.tasks.get(k).map_or(0, |t| t.loops);
            loops != 0 && run.counts.get(k).copied().unwrap_or(0) >= loops
        };
        !done(i) && !done(next)
    }

    /// One cycle of the table in mode 1; `false` while no flow runs (the mode is plain
    /// profile position then).
    pub(crate) fn kinco_table_cycle(&mut self, dt: f64) -> bool {
        let run = &mut self.vendor.table;
        let (start, abort, cond1) = (run.start_edge, run.abort_edge, run.cond1_rising);
        run.start_edge = false;
        run.abort_edge = false;
        run.cond1_rising = false;
        if cond1 {
            self.vendor.table.cond1_edge = true;
        }
        if abort && self.kinco_table_active() {
            self.vendor.table.abort_after = true;
        }
        if start {
            let bits = [
                DinFunction::PosTableIdx0,
                DinFunction::PosTableIdx1,
                DinFunction::PosTableIdx2,
            ]
            .map(|f| {
                self.kinco_din_configured(f)
                    .then(|| self.kinco_din_active(f))
            });
            let i = usize::from(selected_index(&bits));
            match self.vendor.table.flow {
                Flow::Running(_) => {
                    let cond = self
                        .vendor
                        .table
                        .table
                        .tasks
                        .get(i)
                        .map_or(0, Task::start_condition);
                    match cond {
                        1 => self.vendor.table.queued = Some(i),
                        2 => self.start_task(i),
                        _ => {}
                    }
                }
                _ => {
                    self.vendor.table.counts = [0; TASKS];
                    self.vendor.table.abort_after = false;
                    self.vendor.table.last_target = self.traj.position;
                    self.start_task(i);
                }
            }
        }
        match self.vendor.table.flow {
            Flow::Idle => return false,
            Flow::Running(i) => {
                let task = self
                    .vendor
                    .table
                    .table
                    .tasks
                    .get(i)
                    .copied()
                    .unwrap_or_default();
                let acc = |k: u8| {
                    let rps2 = self
                        .vendor
                        .table
                        .table
                        .accelerations
                        .get(usize::from(k))
                        .copied()
                        .unwrap_or(0);
                    (f64::from(rps2) * 65536.0).max(1.0)
                };
                let lim = Limits {
                    velocity: (f64::from(task.speed_rpm) / RPM_PER_INCREMENT_S).max(1.0),
                    acceleration: acc(task.acc),
                    deceleration: acc(task.dec),
                };
                let target = self.vendor.table.last_target;
                let done = self.traj.step_to(target, 0.0, lim, dt);
                let v = self.traj.velocity;
                self.position_demand(v);
                if done {
                    self.task_finished(i);
                }
            }
            Flow::Waiting(i) => {
                self.hold(dt);
                self.task_finished(i);
            }
            Flow::Delay(i, at) => {
                self.hold(dt);
                if self.now >= at {
                    self.start_task(i);
                }
            }
        }
        self.target_reached = !matches!(self.vendor.table.flow, Flow::Running(_));
        true
    }

    fn task_finished(&mut self, i: usize) {
        let task = self
            .vendor
            .table
            .table
            .tasks
            .get(i)
            .copied()
            .unwrap_or_default();
        if let Some(q) = self.vendor.table.queued.take() {
            self.start_task(q);
            return;
        }
        if self.vendor.table.abort_after || !task.goes_on() {
            self.kinco_table_abort();
            return;
        }
        let next = task.next();
        if !self.loops_allow(i, next) {
            self.kinco_table_abort();
            return;
        }
        self.vendor.table.flow = if self.condition_holds(&task) {
            let delay = Duration::from_millis(u64::from(task.delay_ms));
            Flow::Delay(next, self.now + delay)
        } else {
            Flow::Waiting(i)
        };
    }
}
