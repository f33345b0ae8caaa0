//! The CMMP-AS's CI terminal (§3.2.3, SDO simulation) as a terminal of the cell loop: the
//! lines are cut and answered by `drive::vendors::festo_cmmp_as::ci_terminal`, each answer
//! ending with CR alone (the module's decision there).

use drive::vendors::festo_cmmp_as::ci_terminal::{
    execute, syntax_error, Cut, LineCutter, ANSWER_END,
};
use od::ObjectAccess;

use crate::cell_loop::{Terminal, Typed};

/// One connection's CI terminal.
#[derive(Debug, Default)]
pub struct CiTerminal {
    lines: LineCutter,
}

/// A CI terminal for a new connection ([`crate::cell_loop::NewTerminal`]).
pub fn new() -> Box<dyn Terminal> {
    Box::new(CiTerminal::default())
}

impl Terminal for CiTerminal {
    fn push(&mut self, byte: u8) -> Option<Typed> {
        match self.lines.push(byte)? {
            Cut::Line(line) => Some(Typed::Line(line.to_vec())),
            Cut::TooLong => Some(Typed::TooLong),
        }
    }

    fn answer(&mut self, line: &[u8], od: &mut dyn ObjectAccess, answer: &mut Vec<u8>) {
        answer.extend_from_slice(execute(line, od).as_bytes());
        answer.push(ANSWER_END);
    }

    fn refuse(&mut self, answer: &mut Vec<u8>) {
        answer.extend_from_slice(syntax_error().as_bytes());
        answer.push(ANSWER_END);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CMMP-CI-02 through the terminal: a line ended by CR LF is answered once, with CR; a
    /// line longer than any command is refused as a syntax error.
    #[test]
    fn lines_are_cut_and_answered_with_cr() {
        let d = &devices::CMMP_AS;
        let mut od = od::ObjectDictionary::new(d, 1, vec![0u8; d.storage_size]).unwrap();
        let mut t = CiTerminal::default();
        let mut answer = Vec::new();
        for &b in b"?606000\r\n" {
            match t.push(b) {
                Some(Typed::Line(line)) => t.answer(&line, &mut od, &mut answer),
                Some(Typed::TooLong) => t.refuse(&mut answer),
                None => {}
            }
        }
        assert!(answer.starts_with(b"=606000:"), "{answer:?}");
        assert_eq!(answer.last(), Some(&b'\r'));
        assert_eq!(answer.iter().filter(|&&b| b == b'\r').count(), 1);
        for &b in b"=606000:0000000000\r" {
            assert!(matches!(t.push(b), None | Some(Typed::TooLong)));
        }
        let mut refused = Vec::new();
        t.refuse(&mut refused);
        assert_eq!(refused, b"!05040001\r");
    }
}
