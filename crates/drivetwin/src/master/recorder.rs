//! Runs the steps of a script, or the requests of a recording, against a node over a link and
//! records every request and its answers with their times (`master::recording` decides what
//! answers; this only moves frames and reads the clock).

use std::future::Future;
use std::task::{Context, Poll, Waker};

use tokio::time::Instant;

use super::link::{Link, LinkError};
use super::recording::gather::Gathering;
use super::recording::script::{Action, Script};
use super::recording::{CobRange, RecordedStep, Recording, Step};

/// Frames already queued when a step starts are read and dropped, at most this many.
const MAX_STALE: usize = 4096;

/// The future's output if it is ready now, without waiting.
fn poll_once<F: Future>(future: F) -> Option<F::Output> {
    let mut future = std::pin::pin!(future);
    match future
        .as_mut()
        .poll(&mut Context::from_waker(Waker::noop()))
    {
        Poll::Ready(out) => Some(out),
        Poll::Pending => None,
    }
}

/// A recording being made.
pub struct Recorder<'a> {
    link: &'a mut Link,
    start: Instant,
    ignore: Vec<CobRange>,
    steps: Vec<RecordedStep>,
}

impl<'a> Recorder<'a> {
    pub fn new(link: &'a mut Link, ignore: Vec<CobRange>) -> Self {
        Recorder {
            link,
            start: Instant::now(),
            ignore,
            steps: Vec::new(),
        }
    }

    /// Frames that came after the last step ended belong to no step: a late answer is not
    /// taken for the next request's.
    async fn drop_stale(&mut self) -> Result<(), LinkError> {
        // Polled once, no timer: a zero timeout waits for the timer's next tick (1 ms), and
        // a program for the device sends its next request at once. `recv` is cancel-safe.
        for _ in 0..MAX_STALE {
            match poll_once(self.link.recv()) {
                Some(frame) => {
                    let frame = frame?;
                    tracing::debug!(?frame, "a frame between steps");
                }
                None => break,
            }
        }
        Ok(())
    }

    /// Sends one request, gathers its answers and keeps the step; returns the awaited
    /// answer's data, if it came.
    async fn run_step(&mut self, step: Step) -> Result<Option<Vec<u8>>, LinkError> {
        self.drop_stale().await?;
        let sent = Instant::now();
        self.link.send(&step.request).await?;
        let mut gathering = Gathering::new(step.rule, &self.ignore);
        // A link lost during the step ends it; the step stays in the recording as far as it got.
        let mut lost = None;
        while !gathering.done(sent.elapsed()) {
            let deadline = sent + gathering.deadline();
            match tokio::time::timeout_at(deadline, self.link.recv()).await {
                Ok(Ok(frame)) => gathering.frame(sent.elapsed(), frame),
                Ok(Err(e)) => {
                    lost = Some(e);
                    break;
                }
                Err(_) => {}
            }
        }
        let answers = gathering.into_answers();
        let awaited = step.rule.until.and_then(|a| {
            answers
                .iter()
                .find(|x| x.frame.cob_id() == Some(a.cob_id))
                .map(|x| x.frame.payload().to_vec())
        });
        self.steps.push(RecordedStep {
            step,
            sent_at: sent.saturating_duration_since(self.start),
            answers,
        });
        match lost {
            Some(e) => Err(e),
            None => Ok(awaited),
        }
    }

    /// Runs every action of a script; an SDO transfer sends its next request after each answer.
    pub async fn run_script(&mut self, script: Script) -> Result<(), LinkError> {
        for action in script.actions {
            match action {
                Action::Frame(step) => {
                    self.run_step(step).await?;
                }
                Action::Sdo(mut transfer) => {
                    let mut step = transfer.first();
                    loop {
                        let answer = self.run_step(step).await?;
                        match transfer.next(answer.as_deref()) {
                            Some(next) => step = next,
                            None => break,
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// Sends the requests of a recording, each with its recorded rule.
    pub async fn replay(&mut self, recording: &Recording) -> Result<(), LinkError> {
        for s in &recording.steps {
            self.run_step(s.step.clone()).await?;
        }
        Ok(())
    }

    pub fn finish(self) -> Recording {
        Recording {
            ignore: self.ignore,
            steps: self.steps,
        }
    }
}
