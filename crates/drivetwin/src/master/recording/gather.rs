//! Which frames answer a request, and when its step is over: every frame within the step's
//! window, and until the awaited frame (an SDO response on 580h + node, a heartbeat or
//! boot-up on 700h + node) has come or its timeout has passed. Time is an argument: the time
//! since the request.

use std::time::Duration;

use canopen::CanFrame;

use super::{is_boot_up, Answer, AnswerRule, CobRange};

/// The answers of one step while it runs.
pub struct Gathering<'a> {
    rule: AnswerRule,
    ignore: &'a [CobRange],
    answers: Vec<Answer>,
    awaited_came: bool,
}

impl<'a> Gathering<'a> {
    pub fn new(rule: AnswerRule, ignore: &'a [CobRange]) -> Self {
        Gathering {
            rule,
            ignore,
            answers: Vec::new(),
            awaited_came: rule.until.is_none(),
        }
    }

    /// A frame seen `after` the request; kept when it is an answer.
    pub fn frame(&mut self, after: Duration, frame: CanFrame) {
        if self.done(after) {
            return;
        }
        let awaited = self
            .rule
            .until
            .is_some_and(|a| frame.cob_id() == Some(a.cob_id));
        // A boot-up is an event, never a heartbeat's phase: it always answers.
        let ignored = !is_boot_up(&frame)
            && frame
                .cob_id()
                .is_some_and(|c| self.ignore.iter().any(|r| r.contains(c)));
        if awaited && !self.awaited_came {
            self.awaited_came = true;
        } else if ignored {
            return;
        }
        self.answers.push(Answer { after, frame });
    }

    /// Whether the step is over at `after` the request.
    pub fn done(&self, after: Duration) -> bool {
        after >= self.deadline()
    }

    /// When the step ends if no further frame comes.
    pub fn deadline(&self) -> Duration {
        match self.rule.until {
            Some(a) if !self.awaited_came => self.rule.window.max(a.timeout),
            _ => self.rule.window,
        }
    }

    pub fn into_answers(self) -> Vec<Answer> {
        self.answers
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::master::recording::{Awaited, DEFAULT_IGNORE};

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    fn f(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(id, data).expect("frame")
    }

    #[test]
    fn an_sdo_step_ends_with_its_response_and_skips_heartbeats() {
        let rule = AnswerRule {
            window: Duration::ZERO,
            until: Some(Awaited {
                cob_id: 0x581,
                timeout: ms(1000),
            }),
        };
        let mut g = Gathering::new(rule, &DEFAULT_IGNORE);
        assert_eq!(g.deadline(), ms(1000));
        g.frame(ms(1), f(0x701, &[0x7F]));
        assert!(!g.done(ms(1)));
        g.frame(ms(2), f(0x581, &[0x60, 0x40, 0x60, 0, 0, 0, 0, 0]));
        assert!(g.done(ms(2)));
        g.frame(ms(3), f(0x181, &[1]));
        let answers = g.into_answers();
        assert_eq!(answers.len(), 1);
        assert_eq!(answers[0].after, ms(2));
    }

    #[test]
    fn an_nmt_step_keeps_the_awaited_heartbeat_and_a_window_keeps_everything_else() {
        let rule = AnswerRule {
            window: ms(50),
            until: Some(Awaited {
                cob_id: 0x701,
                timeout: ms(1500),
            }),
        };
        let mut g = Gathering::new(rule, &DEFAULT_IGNORE);
        g.frame(ms(5), f(0x181, &[0x37, 0x02]));
        g.frame(ms(10), f(0x702, &[0x05]));
        g.frame(ms(12), f(0x703, &[0x00]));
        g.frame(ms(20), f(0x701, &[0x05]));
        assert!(!g.done(ms(20)), "the window is not over");
        g.frame(ms(30), f(0x701, &[0x05]));
        assert!(g.done(ms(50)));
        let ids: Vec<u32> = g.into_answers().iter().map(|a| a.frame.id).collect();
        assert_eq!(ids, [0x181, 0x703, 0x701]);
    }

    #[test]
    fn a_missing_answer_ends_the_step_at_its_timeout() {
        let rule = AnswerRule {
            window: ms(10),
            until: Some(Awaited {
                cob_id: 0x581,
                timeout: ms(300),
            }),
        };
        let g = Gathering::new(rule, &[]);
        assert!(!g.done(ms(299)));
        assert!(g.done(ms(300)));
    }
}
