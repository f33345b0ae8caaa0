//! How the thread that plays a drive's fieldbus task is scheduled: the cell loop, whose turn
//! answers a master's frame, is to run as soon as the frame arrives, not after the
//! neighbours' turns of a few milliseconds that a normal-priority thread waits behind on a
//! busy CPU.
//!
//! Two ways, both for the loop's thread alone (the console's threads run `SCHED_BATCH`, the
//! threads the loop starts begin at normal priority, `sys::sched`):
//! - `SCHED_FIFO` at a priority (`--rt-priority`), as a drive's firmware runs its fieldbus
//!   task: it runs before every normal thread, and needs the privilege to;
//! - a short time slice under the fair scheduler (`--sched-slice-us`, EEVDF, Linux 6.12+):
//!   no privilege; a woken loop is picked before neighbours whose slices are the default.
//!
//! What is asked and refused stops the cell with the reason: a twin that runs its loop at
//! normal priority while its user believes it real-time measures the wrong thing.

use std::io;
use std::time::Duration;

/// The shortest slice the fair scheduler takes (`sched_setattr(2)`: 100 µs … 100 ms).
pub const MIN_SLICE: Duration = Duration::from_micros(100);
/// The longest slice the fair scheduler takes.
pub const MAX_SLICE: Duration = Duration::from_millis(100);

/// How the cell loop's thread is to be scheduled; the default leaves it as it is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LoopScheduling {
    /// `SCHED_FIFO` at this priority (1…99).
    pub rt_priority: Option<u8>,
    /// A time slice of its own under the fair scheduler.
    pub slice: Option<Duration>,
}

/// Why the loop's thread could not be scheduled as asked.
#[derive(Debug, thiserror::Error)]
pub enum SchedulingError {
    #[error("real-time priority {0}: must be 1…99")]
    Priority(u8),
    #[error("time slice of {0:?}: the fair scheduler takes 100 µs … 100 ms")]
    Slice(Duration),
    #[error("--rt-priority and --sched-slice-us both given: a SCHED_FIFO thread has no slice")]
    Both,
    #[error(
        "SCHED_FIFO {priority} for the cell loop refused ({source}): run as root, or give the \
         binary CAP_SYS_NICE (setcap cap_sys_nice+ep), or raise RLIMIT_RTPRIO to {priority} \
         (ulimit -r); or leave --rt-priority out"
    )]
    FifoRefused { priority: u8, source: io::Error },
    #[error("a {slice:?} time slice for the cell loop refused ({source})")]
    SliceRefused { slice: Duration, source: io::Error },
    #[error(
        "a {0:?} time slice for the cell loop: this kernel keeps no slice of a thread's own \
         (Linux 6.12 and later do); use --rt-priority, or leave --sched-slice-us out"
    )]
    SliceNotKept(Duration),
    #[error("no thread to try the cell loop's scheduling on: {0}")]
    Probe(io::Error),
}

impl LoopScheduling {
    /// Nothing asked: the thread keeps what it has.
    pub fn is_default(&self) -> bool {
        *self == LoopScheduling::default()
    }

    /// Checks the values alone, without touching a thread.
    pub fn validate(&self) -> Result<(), SchedulingError> {
        match (self.rt_priority, self.slice) {
            (Some(_), Some(_)) => Err(SchedulingError::Both),
            (Some(p), None) if !(1..=99).contains(&p) => Err(SchedulingError::Priority(p)),
            (None, Some(s)) if !(MIN_SLICE..=MAX_SLICE).contains(&s) => {
                Err(SchedulingError::Slice(s))
            }
            _ => Ok(()),
        }
    }

    /// Schedules the calling thread as asked.
    pub fn apply(&self) -> Result<(), SchedulingError> {
        self.validate()?;
        if let Some(priority) = self.rt_priority {
            crate::sys::sched::set_fifo(priority)
                .map_err(|source| SchedulingError::FifoRefused { priority, source })?;
        }
        if let Some(slice) = self.slice {
            let kept = crate::sys::sched::set_slice(slice)
                .map_err(|source| SchedulingError::SliceRefused { slice, source })?;
            if kept.is_zero() {
                return Err(SchedulingError::SliceNotKept(slice));
            }
        }
        Ok(())
    }

    /// Whether [`Self::apply`] would succeed, tried on a thread that ends at once: a refusal
    /// is told before the cell says it runs.
    pub fn probe(&self) -> Result<(), SchedulingError> {
        if self.is_default() {
            return Ok(());
        }
        let this = *self;
        std::thread::Builder::new()
            .name("sched-probe".into())
            .spawn(move || this.apply())
            .map_err(SchedulingError::Probe)?
            .join()
            .unwrap_or(Ok(()))
    }
}

/// `SCHED_FIFO` at `priority` (1…99) for the calling thread. Needs `CAP_SYS_NICE` (root).
pub fn set_fifo_priority(priority: u8) -> io::Result<()> {
    LoopScheduling {
        rt_priority: Some(priority),
        slice: None,
    }
    .apply()
    .map_err(|e| match e {
        SchedulingError::FifoRefused { source, .. } => source,
        e => io::Error::new(io::ErrorKind::InvalidInput, e),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_of_range_priority_is_refused() {
        assert_eq!(
            set_fifo_priority(0).unwrap_err().kind(),
            io::ErrorKind::InvalidInput
        );
        assert_eq!(
            set_fifo_priority(100).unwrap_err().kind(),
            io::ErrorKind::InvalidInput
        );
    }

    #[test]
    fn slices_outside_the_fair_scheduler_s_range_and_both_ways_at_once_are_refused() {
        let slice = |us| LoopScheduling {
            rt_priority: None,
            slice: Some(Duration::from_micros(us)),
        };
        assert!(matches!(
            slice(99).validate(),
            Err(SchedulingError::Slice(_))
        ));
        assert!(matches!(
            slice(100_001).validate(),
            Err(SchedulingError::Slice(_))
        ));
        assert!(slice(100).validate().is_ok());
        let both = LoopScheduling {
            rt_priority: Some(10),
            slice: Some(Duration::from_micros(200)),
        };
        assert!(matches!(both.validate(), Err(SchedulingError::Both)));
    }
}
