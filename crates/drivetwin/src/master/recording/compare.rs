//! What differs between a recording and a replay of its requests: per step, each answer that
//! differs in its bytes, is missing, is new, or came later or sooner than the tolerance
//! allows.
//!
//! **Decision:** answers are matched per COB-ID in the order they came (the n-th 581h with
//! the n-th 581h), so two nodes' answers that interleave differently on the bus are no
//! difference, and one new frame does not shift every answer after it. Times compare each
//! answer's delay after its request, not the clock: a replay starts at another time.

use std::fmt;
use std::time::Duration;

use canopen::CanFrame;

use super::{time_matters, Answer, RecordedStep, Recording};

/// One way a replayed step differs from its recording.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Difference {
    /// The step's request is another frame (two recordings of different scripts).
    Request {
        recorded: CanFrame,
        replayed: CanFrame,
    },
    /// The step is in the recording and not in the replay.
    NotReplayed,
    /// The step is in the replay and not in the recording.
    NotRecorded,
    /// The `nth` answer on its COB-ID (from 1) carries other bytes.
    Bytes {
        nth: usize,
        recorded: Answer,
        replayed: Answer,
    },
    /// The recording has an answer the replay lacks.
    Missing { nth: usize, recorded: Answer },
    /// The replay has an answer the recording lacks.
    Extra { nth: usize, replayed: Answer },
    /// The same answer, its delay after the request further apart than the tolerance.
    Time {
        nth: usize,
        recorded: Answer,
        replayed: Answer,
    },
}

/// The differences of one step.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StepDifferences {
    /// From 1, as the recording numbers it.
    pub number: usize,
    pub label: String,
    /// The script's line (0: none).
    pub line: usize,
    pub differences: Vec<Difference>,
}

fn key(f: &CanFrame) -> (bool, u32) {
    (f.extended, f.id)
}

/// A frame as candump writes it, and what it means.
pub struct Shown<'a>(pub &'a CanFrame);

impl fmt::Display for Shown<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut text = String::new();
        let _ = canopen::decode::describe(self.0, &mut text);
        write!(f, "{} ({text})", crate::trace::pcap::candump_frame(self.0))
    }
}

/// Milliseconds to the microsecond.
pub struct Ms(pub Duration);

impl fmt::Display for Ms {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.3} ms", self.0.as_secs_f64() * 1000.0)
    }
}

impl fmt::Display for Difference {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Difference::Request { recorded, replayed } => write!(
                f,
                "request differs: recorded {}, replayed {}",
                Shown(recorded),
                Shown(replayed)
            ),
            Difference::NotReplayed => write!(f, "not replayed"),
            Difference::NotRecorded => write!(f, "not in the recording"),
            Difference::Bytes {
                nth,
                recorded,
                replayed,
            } => write!(
                f,
                "answer {nth} on {:03X} differs: recorded {}, replayed {}",
                recorded.frame.id,
                Shown(&recorded.frame),
                Shown(&replayed.frame)
            ),
            Difference::Missing { nth, recorded } => write!(
                f,
                "answer {nth} on {:03X} missing: recorded {} after {}",
                recorded.frame.id,
                Shown(&recorded.frame),
                Ms(recorded.after)
            ),
            Difference::Extra { nth, replayed } => write!(
                f,
                "answer {nth} on {:03X} not recorded: replayed {} after {}",
                replayed.frame.id,
                Shown(&replayed.frame),
                Ms(replayed.after)
            ),
            Difference::Time {
                nth,
                recorded,
                replayed,
            } => write!(
                f,
                "answer {nth} on {:03X} time: recorded after {}, replayed after {}",
                recorded.frame.id,
                Ms(recorded.after),
                Ms(replayed.after)
            ),
        }
    }
}

/// The answers of two runs of one step, matched per COB-ID.
fn answers(recorded: &[Answer], replayed: &[Answer], tolerance: Duration) -> Vec<Difference> {
    let mut keys: Vec<(bool, u32)> = Vec::new();
    for a in recorded.iter().chain(replayed) {
        if !keys.contains(&key(&a.frame)) {
            keys.push(key(&a.frame));
        }
    }
    let mut out = Vec::new();
    for k in keys {
        let mut r = recorded.iter().filter(|a| key(&a.frame) == k);
        let mut p = replayed.iter().filter(|a| key(&a.frame) == k);
        let mut nth = 0;
        loop {
            nth += 1;
            match (r.next(), p.next()) {
                (None, None) => break,
                (Some(a), None) => out.push(Difference::Missing { nth, recorded: *a }),
                (None, Some(b)) => out.push(Difference::Extra { nth, replayed: *b }),
                (Some(a), Some(b)) if a.frame != b.frame => out.push(Difference::Bytes {
                    nth,
                    recorded: *a,
                    replayed: *b,
                }),
                (Some(a), Some(b)) => {
                    if time_matters(&a.frame) && a.after.abs_diff(b.after) > tolerance {
                        out.push(Difference::Time {
                            nth,
                            recorded: *a,
                            replayed: *b,
                        });
                    }
                }
            }
        }
    }
    out
}

fn step_of(s: &RecordedStep, number: usize, differences: Vec<Difference>) -> StepDifferences {
    StepDifferences {
        number,
        label: s.step.label.clone(),
        line: s.step.line,
        differences,
    }
}

/// Every step whose answers differ, in order.
pub fn compare(
    recorded: &Recording,
    replayed: &Recording,
    tolerance: Duration,
) -> Vec<StepDifferences> {
    let mut out = Vec::new();
    let longest = recorded.steps.len().max(replayed.steps.len());
    for i in 0..longest {
        let number = i + 1;
        match (recorded.steps.get(i), replayed.steps.get(i)) {
            (Some(a), Some(b)) => {
                let differences = if a.step.request != b.step.request {
                    vec![Difference::Request {
                        recorded: a.step.request,
                        replayed: b.step.request,
                    }]
                } else {
                    answers(&a.answers, &b.answers, tolerance)
                };
                if !differences.is_empty() {
                    out.push(step_of(a, number, differences));
                }
            }
            (Some(a), None) => out.push(step_of(a, number, vec![Difference::NotReplayed])),
            (None, Some(b)) => out.push(step_of(b, number, vec![Difference::NotRecorded])),
            (None, None) => {}
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::master::recording::{AnswerRule, Step, DEFAULT_IGNORE};

    fn f(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(id, data).expect("frame")
    }

    fn answer(ms: u64, frame: CanFrame) -> Answer {
        Answer {
            after: Duration::from_millis(ms),
            frame,
        }
    }

    fn step(label: &str, request: CanFrame, answers: Vec<Answer>) -> RecordedStep {
        RecordedStep {
            step: Step {
                label: label.into(),
                line: 3,
                request,
                rule: AnswerRule {
                    window: Duration::ZERO,
                    until: None,
                },
            },
            sent_at: Duration::ZERO,
            answers,
        }
    }

    fn read(index_lo: u8, value: u8, ms: u64) -> RecordedStep {
        step(
            &format!("sdo read 60{index_lo:02X}:00"),
            f(0x601, &[0x40, index_lo, 0x60, 0, 0, 0, 0, 0]),
            vec![answer(
                ms,
                f(0x581, &[0x4F, index_lo, 0x60, 0, value, 0, 0, 0]),
            )],
        )
    }

    fn recording(steps: Vec<RecordedStep>) -> Recording {
        Recording {
            ignore: DEFAULT_IGNORE.to_vec(),
            steps,
        }
    }

    const TOLERANCE: Duration = Duration::from_millis(5);

    #[test]
    fn equal_runs_have_no_difference_within_the_tolerance() {
        let a = recording(vec![read(0x61, 1, 2), read(0x65, 9, 2)]);
        let b = recording(vec![read(0x61, 1, 6), read(0x65, 9, 1)]);
        assert_eq!(compare(&a, &b, TOLERANCE), []);
    }

    #[test]
    fn a_changed_object_is_the_one_step_reported() {
        let a = recording(vec![read(0x61, 1, 2), read(0x65, 9, 2), read(0x66, 3, 2)]);
        let b = recording(vec![read(0x61, 1, 2), read(0x65, 7, 2), read(0x66, 3, 2)]);
        let d = compare(&a, &b, TOLERANCE);
        assert_eq!(d.len(), 1);
        assert_eq!(d[0].number, 2);
        assert_eq!(d[0].label, "sdo read 6065:00");
        assert!(matches!(
            d[0].differences[..],
            [Difference::Bytes { nth: 1, .. }]
        ));
        let text = d[0].differences[0].to_string();
        assert!(text.contains("581#4F65600009000000"), "{text}");
        assert!(text.contains("581#4F65600007000000"), "{text}");
    }

    #[test]
    fn a_late_missing_or_new_answer_is_reported() {
        let a = recording(vec![read(0x61, 1, 2), read(0x65, 9, 2)]);
        let mut b = recording(vec![read(0x61, 1, 20), read(0x65, 9, 2)]);
        b.steps[1].answers.clear();
        b.steps[1]
            .answers
            .push(answer(1, f(0x81, &[0, 0x81, 0x11, 0, 0, 0, 0, 0])));
        let d = compare(&a, &b, TOLERANCE);
        assert_eq!(d.len(), 2);
        assert!(matches!(
            d[0].differences[..],
            [Difference::Time { nth: 1, .. }]
        ));
        assert!(matches!(
            d[1].differences[..],
            [
                Difference::Missing { nth: 1, .. },
                Difference::Extra { nth: 1, .. }
            ]
        ));
    }

    #[test]
    fn answers_match_per_cob_id_and_heartbeat_times_are_not_compared() {
        let hb = |ms| answer(ms, f(0x701, &[0x05]));
        let tpdo = |ms| answer(ms, f(0x181, &[0x37, 0x06]));
        let a = recording(vec![step(
            "nmt start node 1",
            f(0, &[1, 1]),
            vec![tpdo(1), hb(400)],
        )]);
        let b = recording(vec![step(
            "nmt start node 1",
            f(0, &[1, 1]),
            vec![hb(10), tpdo(2)],
        )]);
        assert_eq!(compare(&a, &b, TOLERANCE), []);
        let boot = |ms| answer(ms, f(0x701, &[0x00]));
        let a = recording(vec![step("reset", f(0, &[0x81, 1]), vec![boot(5)])]);
        let b = recording(vec![step("reset", f(0, &[0x81, 1]), vec![boot(500)])]);
        assert_eq!(
            compare(&a, &b, TOLERANCE).len(),
            1,
            "a boot-up's time counts"
        );
    }

    #[test]
    fn different_scripts_differ_in_their_requests_and_step_counts() {
        let a = recording(vec![read(0x61, 1, 2), read(0x65, 9, 2)]);
        let b = recording(vec![read(0x64, 1, 2)]);
        let d = compare(&a, &b, TOLERANCE);
        assert!(matches!(d[0].differences[..], [Difference::Request { .. }]));
        assert_eq!(d[1].differences, [Difference::NotReplayed]);
        assert_eq!(
            compare(&b, &a, TOLERANCE)[1].differences,
            [Difference::NotRecorded]
        );
    }
}
