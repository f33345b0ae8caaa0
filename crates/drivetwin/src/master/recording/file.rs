//! The recording file: a candump log (`candump -l`'s format) whose interface names the
//! direction, `req` for a request sent and `ans` for an answer seen, with times in seconds
//! since the recording's start; `grep -v '^#'` leaves a plain candump log (python-can's
//! `CanutilsLogReader` reads it).
//! A `# step` line before each request says what the step does and how its answers were
//! gathered, so a recording replays without its script:
//!
//! ```text
//! # drivetwin recording 1
//! # ignore 080 100 701-77F
//! # step 1, window 0 ms, until 581 within 1000 ms: sdo read 1018:01 (line 4)
//! (0.000412) req 601#4018100100000000
//! (0.001203) ans 581#4318100119000000
//! ```
//!
//! Other `#` lines are comments. `diff <(cut -d' ' -f2- a.log) <(cut -d' ' -f2- b.log)`
//! compares two recordings without their times.

use std::fmt::Write as _;
use std::time::Duration;

use super::{Answer, AnswerRule, Awaited, CobRange, LineError, RecordedStep, Recording, Step};
use crate::trace::pcap::candump_frame;

const MAGIC: &str = "# drivetwin recording 1";
const REQUEST: &str = "req";
const ANSWER: &str = "ans";

/// `12 ms` or `0.400 ms`.
fn emit_ms(d: Duration) -> String {
    let micros = d.as_micros();
    if micros.is_multiple_of(1000) {
        format!("{} ms", micros / 1000)
    } else {
        format!("{}.{:03} ms", micros / 1000, micros % 1000)
    }
}

/// `12` or `0.400` (milliseconds, to the microsecond).
fn parse_ms(text: &str) -> Option<Duration> {
    let (whole, frac) = text.split_once('.').unwrap_or((text, ""));
    if frac.len() > 3 || !frac.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let ms: u64 = whole.parse().ok()?;
    let micros: u64 = if frac.is_empty() {
        0
    } else {
        format!("{frac:0<3}").parse().ok()?
    };
    Some(Duration::from_millis(ms) + Duration::from_micros(micros))
}

fn emit_time(d: Duration) -> String {
    format!("({}.{:06})", d.as_secs(), d.subsec_micros())
}

/// The step line's text after `# step N`.
fn emit_rule(rule: &AnswerRule) -> String {
    let mut text = format!(", window {}", emit_ms(rule.window));
    if let Some(a) = rule.until {
        let _ = write!(
            text,
            ", until {:03X} within {}",
            a.cob_id,
            emit_ms(a.timeout)
        );
    }
    text
}

/// Writes a recording.
pub fn emit(recording: &Recording) -> String {
    emit_noted(recording, &[])
}

/// Writes a recording with `notes` (what was run against what) as comments in its head.
pub fn emit_noted(recording: &Recording, notes: &[String]) -> String {
    let mut out = String::with_capacity(128 * recording.steps.len() + 256);
    out.push_str(MAGIC);
    out.push('\n');
    for note in notes {
        for line in note.lines() {
            let _ = writeln!(out, "# {line}");
        }
    }
    out.push_str("# times in seconds since the start; req: a request sent, ans: an answer seen\n");
    let ignore: Vec<String> = recording.ignore.iter().map(|r| r.to_string()).collect();
    let _ = writeln!(out, "# ignore {}", ignore.join(" "));
    for (i, s) in recording.steps.iter().enumerate() {
        let _ = write!(
            out,
            "# step {}{}: {}",
            i + 1,
            emit_rule(&s.step.rule),
            s.step.label
        );
        if s.step.line > 0 {
            let _ = write!(out, " (line {})", s.step.line);
        }
        out.push('\n');
        let _ = writeln!(
            out,
            "{} {REQUEST} {}",
            emit_time(s.sent_at),
            candump_frame(&s.step.request)
        );
        for a in &s.answers {
            let _ = writeln!(
                out,
                "{} {ANSWER} {}",
                emit_time(s.sent_at + a.after),
                candump_frame(&a.frame)
            );
        }
        if let Some(a) = s.step.rule.until.filter(|_| !s.awaited_came()) {
            let _ = writeln!(out, "# no {:03X} within {}", a.cob_id, emit_ms(a.timeout));
        }
    }
    out
}

/// `, window 0 ms, until 581 within 1000 ms: LABEL (line 5)` after `# step N`.
fn parse_step_line(rest: &str, line: usize) -> Result<Step, LineError> {
    let bad = |what: &str| LineError::new(line, format!("step line: {what}"));
    let (rule_text, label) = rest
        .split_once(": ")
        .ok_or_else(|| bad("expected `: LABEL`"))?;
    let mut window = None;
    let mut until = None;
    for part in rule_text.split(", ").skip(1) {
        if let Some(ms) = part
            .strip_prefix("window ")
            .and_then(|t| t.strip_suffix(" ms"))
        {
            window = Some(parse_ms(ms).ok_or_else(|| bad("bad window"))?);
        } else if let Some(u) = part.strip_prefix("until ") {
            let (cob, ms) = u
                .split_once(" within ")
                .ok_or_else(|| bad("expected `until COB within N ms`"))?;
            let cob_id = u16::from_str_radix(cob, 16)
                .ok()
                .filter(|c| *c <= 0x7FF)
                .ok_or_else(|| bad("bad COB-ID"))?;
            let timeout = ms
                .strip_suffix(" ms")
                .and_then(parse_ms)
                .ok_or_else(|| bad("bad timeout"))?;
            until = Some(Awaited { cob_id, timeout });
        } else {
            return Err(bad(&format!("unknown part {part:?}")));
        }
    }
    let (label, script_line) = match label
        .strip_suffix(')')
        .and_then(|l| l.rsplit_once(" (line "))
    {
        Some((l, n)) => match n.parse::<usize>() {
            Ok(n) => (l, n),
            Err(_) => (label, 0),
        },
        None => (label, 0),
    };
    Ok(Step {
        label: label.to_string(),
        line: script_line,
        request: canopen::CanFrame::full(0, [0; 8]),
        rule: AnswerRule {
            window: window.ok_or_else(|| bad("no window"))?,
            until,
        },
    })
}

/// Reads a recording.
pub fn parse(text: &str) -> Result<Recording, LineError> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    match lines.next() {
        Some((_, l)) if l.trim() == MAGIC => {}
        _ => {
            return Err(LineError::new(
                1,
                format!("not a drivetwin recording (its first line is `{MAGIC}`)"),
            ))
        }
    }
    let mut ignore = Vec::new();
    let mut steps: Vec<RecordedStep> = Vec::new();
    // A step line read, its request not yet.
    let mut pending: Option<Step> = None;
    for (i, raw) in lines {
        let line = i + 1;
        let l = raw.trim();
        if let Some(list) = l.strip_prefix("# ignore") {
            ignore = list
                .split_whitespace()
                .map(|t| {
                    CobRange::parse(t)
                        .ok_or_else(|| LineError::new(line, format!("ignore: bad COB-ID {t:?}")))
                })
                .collect::<Result<_, _>>()?;
            continue;
        }
        if let Some(rest) = l.strip_prefix("# step ") {
            if pending.is_some() {
                return Err(LineError::new(line, "the step before has no request"));
            }
            let number_end = rest.find(',').unwrap_or(rest.len());
            let number: usize = rest
                .get(..number_end)
                .and_then(|n| n.parse().ok())
                .ok_or_else(|| LineError::new(line, "step line: no step number"))?;
            if number != steps.len() + 1 {
                return Err(LineError::new(
                    line,
                    format!("step {number} follows step {}", steps.len()),
                ));
            }
            pending = Some(parse_step_line(rest, line)?);
            continue;
        }
        if l.starts_with('#') {
            continue;
        }
        let parsed =
            crate::trace::parse_candump_lines(l).map_err(|e| LineError::new(line, e.what))?;
        let Some(frame_line) = parsed.first() else {
            continue;
        };
        match frame_line.interface {
            REQUEST => {
                let mut step = pending
                    .take()
                    .ok_or_else(|| LineError::new(line, "a request without a `# step` line"))?;
                step.request = frame_line.frame;
                steps.push(RecordedStep {
                    step,
                    sent_at: frame_line.time,
                    answers: Vec::new(),
                });
            }
            ANSWER => {
                if pending.is_some() {
                    return Err(LineError::new(line, "an answer before the step's request"));
                }
                let step = steps
                    .last_mut()
                    .ok_or_else(|| LineError::new(line, "an answer before the first step"))?;
                let after = frame_line
                    .time
                    .checked_sub(step.sent_at)
                    .ok_or_else(|| LineError::new(line, "an answer before its request"))?;
                step.answers.push(Answer {
                    after,
                    frame: frame_line.frame,
                });
            }
            other => {
                return Err(LineError::new(
                    line,
                    format!("direction {other:?} is neither `{REQUEST}` nor `{ANSWER}`"),
                ))
            }
        }
    }
    if pending.is_some() {
        return Err(LineError::new(
            text.lines().count(),
            "the last step has no request",
        ));
    }
    Ok(Recording { ignore, steps })
}

#[cfg(test)]
mod tests {
    use super::*;
    use canopen::CanFrame;

    fn f(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(id, data).expect("frame")
    }

    fn sample() -> Recording {
        Recording {
            ignore: super::super::DEFAULT_IGNORE.to_vec(),
            steps: vec![
                RecordedStep {
                    step: Step {
                        label: "sdo read 1018:01".into(),
                        line: 4,
                        request: f(0x601, &[0x40, 0x18, 0x10, 1, 0, 0, 0, 0]),
                        rule: AnswerRule {
                            window: Duration::ZERO,
                            until: Some(Awaited {
                                cob_id: 0x581,
                                timeout: Duration::from_millis(1000),
                            }),
                        },
                    },
                    sent_at: Duration::from_micros(412),
                    answers: vec![Answer {
                        after: Duration::from_micros(791),
                        frame: f(0x581, &[0x43, 0x18, 0x10, 1, 0x1D, 0, 0, 0]),
                    }],
                },
                RecordedStep {
                    step: Step {
                        label: "SYNC".into(),
                        line: 0,
                        request: f(0x080, &[]),
                        rule: AnswerRule {
                            window: Duration::from_micros(2400),
                            until: None,
                        },
                    },
                    sent_at: Duration::from_millis(2),
                    answers: vec![],
                },
            ],
        }
    }

    #[test]
    fn a_recording_is_a_candump_log_with_step_lines_and_reads_back() {
        let text = emit(&sample());
        assert_eq!(
            text,
            "# drivetwin recording 1\n\
             # times in seconds since the start; req: a request sent, ans: an answer seen\n\
             # ignore 080 100 701-77F\n\
             # step 1, window 0 ms, until 581 within 1000 ms: sdo read 1018:01 (line 4)\n\
             (0.000412) req 601#4018100100000000\n\
             (0.001203) ans 581#431810011D000000\n\
             # step 2, window 2.400 ms: SYNC\n\
             (0.002000) req 080#\n"
        );
        assert_eq!(parse(&text).expect("parse"), sample());
        let frames = crate::trace::parse_candump(&text).expect("a candump log");
        assert_eq!(frames.len(), 3);
    }

    #[test]
    fn a_missing_awaited_answer_is_noted() {
        let mut r = sample();
        r.steps[0].answers.clear();
        let text = emit(&r);
        assert!(text.contains("# no 581 within 1000 ms\n"), "{text}");
        assert_eq!(parse(&text).expect("parse"), r);
    }

    #[test]
    fn a_bad_recording_is_refused_with_its_line() {
        let good = emit(&sample());
        assert_eq!(parse("(0.1) req 601#40").unwrap_err().line, 1);
        let e = parse(&good.replace(" req ", " tx ")).unwrap_err();
        assert_eq!(e.line, 5, "{e}");
        let e = parse(&good.replace("(0.001203)", "(0.000001)")).unwrap_err();
        assert_eq!(e.line, 6, "{e}");
        assert!(e.what.contains("before its request"), "{e}");
        let e = parse(&good.replace("# step 2", "# step 3")).unwrap_err();
        assert_eq!(e.line, 7, "{e}");
        let e = parse(&good.replace("window 0 ms", "window x ms")).unwrap_err();
        assert_eq!(e.line, 4, "{e}");
        let e = parse(&good.replace("(0.002000) req 080#\n", "")).unwrap_err();
        assert!(e.what.contains("no request"), "{e}");
        let e = parse(&good.replace("601#4018100100000000", "601#40181")).unwrap_err();
        assert_eq!(e.line, 5, "{e}");
    }
}
